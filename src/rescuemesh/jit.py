"""`compiled`: numba's `njit` with its on-disk cache, wherever a writable folder for it can be found.

Owns: the decorator every compiled kernel of the package uses, and where their cache lives. Must not
know: what any kernel computes.

numba caches a compiled function next to its source (`__pycache__`), else in NUMBA_CACHE_DIR, else in
the user's cache folder (~/.cache), and refuses `cache=True` at import when none of these is
writable (a read-only install on a robot, a locked-down account). Then this module points numba at
a folder under the system's temporary directory and, if even that cannot be written, compiles
without a cache: the robot still runs, it only compiles at every start (docs/design.md, "Speed").
"""

from __future__ import annotations

import functools
import os
import tempfile
from collections.abc import Callable

import numba

#: Where kernels are cached when no folder numba looks in is writable.
FALLBACK_CACHE_DIR = os.path.join(tempfile.gettempdir(), "rescuemesh-numba-cache")


def compiled(signature=None, **options) -> Callable:
    """`numba.njit(signature, cache=True, nogil=True, **options)`, cached in a writable folder, or not
    cached at all when there is none (see the module docstring)."""
    options.setdefault("nogil", True)

    def decorate(function: Callable) -> Callable:
        try:
            return _njit(signature, function, cache=True, **options)
        except RuntimeError:  # "cannot cache function ...: no locator available"
            pass
        if _writable(FALLBACK_CACHE_DIR) and numba.config.CACHE_DIR != FALLBACK_CACHE_DIR:
            numba.config.CACHE_DIR = FALLBACK_CACHE_DIR
            try:
                return _njit(signature, function, cache=True, **options)
            except RuntimeError:
                pass
        return _njit(signature, function, cache=False, **options)

    return decorate


def _njit(signature, function: Callable, **options) -> Callable:
    if signature is None:
        return numba.njit(**options)(function)
    return numba.njit(signature, **options)(function)


def _writable(folder: str) -> bool:
    try:
        os.makedirs(folder, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def compiled_on_first_call(signature=None, **options) -> Callable:
    """`compiled(signature, **options)`, built at import when numba's cache holds the function (loading
    it costs milliseconds), else at its first call: a robot process without a writable cache joins
    its world before it compiles (each kernel costs 0.3 to 2 s of CPU to compile)."""

    def decorate(function: Callable) -> Callable:
        if _cached(function, options):
            return compiled(signature, **options)(function)
        kernel = None

        @functools.wraps(function)
        def call(*args):
            nonlocal kernel
            if kernel is None:
                kernel = compiled(signature, **options)(function)
            return kernel(*args)

        return call

    return decorate


def _cached(function: Callable, options: dict) -> bool:
    """Whether numba's cache index for `function` exists where numba would look for it now."""
    try:
        lazy = numba.njit(cache=True, **{"nogil": True, **options})(function)  # compiles nothing yet
        return os.path.exists(lazy._cache._cache_file._index_path)
    except (RuntimeError, AttributeError):  # no cache folder; another numba's internals
        return False
