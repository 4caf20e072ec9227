"""CPython's math.hypot, compiled: what a kernel calls where the Python it replaced called math.hypot.

Owns: `py_hypot` (two coordinates) and `py_hypot3` (three). Must not know: what the distances are for
(the controller's geometry in nav/pursuit_kernels.py, the link budget's antenna distance in radio/ble.py).

CPython (3.10 and later) computes hypot with scaling, Veltkamp-Dekker splitting, compensated sums and a
correction of the square root ("vector_norm" in Modules/mathmodule.c); libm's hypot, which numba's
math.hypot calls, differs from it in the last bit for about one pair in a thousand, and the runs would
change with it. Both functions here are that algorithm, operation for operation, on three coordinates:
a third coordinate of 0 adds exact zeros to every sum, so py_hypot(a, b) is py_hypot3(a, b, 0.0) bit for
bit, as math.hypot(a, b) is math.hypot(a, b, 0.0). Checked against math.hypot on random and special
values in tests/oracles/test_pymath.py.
"""

from __future__ import annotations

import math

from rescuemesh.jit import compiled

_T27 = 134217729.0  # 2 ** 27 + 1: Veltkamp-Dekker's splitting constant for doubles


@compiled()  # no signature: compiled into its callers
def py_hypot3(a, b, c):
    """math.hypot(a, b, c) as CPython 3.10+ computes it, bit for bit."""
    x0, x1, x2 = abs(a), abs(b), abs(c)
    if math.isnan(x0) or math.isnan(x1) or math.isnan(x2):
        return math.inf if math.isinf(x0) or math.isinf(x1) or math.isinf(x2) else math.nan
    mx = x0
    if x1 > mx:
        mx = x1
    if x2 > mx:
        mx = x2
    if math.isinf(mx) or mx == 0.0:
        return mx
    _, max_e = math.frexp(mx)
    if max_e < -1023:  # subnormal: divide by the largest instead of scaling
        csum, frac1 = 1.0, 0.0
        for x in (x0, x1, x2):
            x = x / mx
            x = x * x
            old = csum
            csum += x
            frac1 += (old - csum) + x
        return mx * math.sqrt(csum - 1.0 + frac1)
    scale = math.ldexp(1.0, -max_e)
    csum, frac1, frac2, frac3 = 1.0, 0.0, 0.0, 0.0
    for x in (x0, x1, x2):
        x = x * scale
        t = x * _T27
        hi = t - (t - x)
        lo = x - hi
        x = hi * hi
        old = csum
        csum += x
        frac1 += (old - csum) + x
        x = 2.0 * hi * lo
        old = csum
        csum += x
        frac2 += (old - csum) + x
        frac3 += lo * lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2 + frac3))
    t = h * _T27
    hi = t - (t - h)
    lo = h - hi
    x = -hi * hi
    old = csum
    csum += x
    frac1 += (old - csum) + x
    x = -2.0 * hi * lo
    old = csum
    csum += x
    frac2 += (old - csum) + x
    x = -lo * lo
    old = csum
    csum += x
    frac3 += (old - csum) + x
    x = csum - 1.0 + (frac1 + frac2 + frac3)
    return (h + x / (2.0 * h)) / scale


@compiled()
def py_hypot(a, b):
    """math.hypot(a, b) as CPython 3.10+ computes it, bit for bit."""
    return py_hypot3(a, b, 0.0)
