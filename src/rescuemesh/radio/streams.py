"""UniformStream: the uniform doubles of a numpy Generator, drawn a block at a time.

Owns: handing out a Generator's `random()` values one or a few at a time, cheaply. Must not know:
what the numbers are for (fading, PER, delays), who owns the stream.

Why: `rng.random(3).tolist()` costs about 0.6 us and `rng.random()` 0.3 us, mostly call overhead;
a team of 30 makes 1.7 million receptions a run, each drawing three. One `rng.random(128).tolist()`
costs about 0.015 us a number.

Why it is exact: `Generator.random` makes each double from the next 64-bit output of the bit
generator, in order, and keeps nothing between calls (only 32-bit draws buffer half a word). So
the numbers of any sequence of `random()` / `random(n)` calls, concatenated, are the same as those
of one `random(total)`: a stream gives exactly the numbers the generator would have given, in the
same order. The generator runs ahead of what was handed out, so once wrapped it must be drawn from
only through its stream.
"""

from __future__ import annotations

import numpy as np

#: Doubles drawn from the generator at a time.
BLOCK = 128


class UniformStream:
    """Uniforms in [0, 1) from `generator`, in its order; draw only through this once wrapped."""

    __slots__ = ("_generator", "_block", "_buffer", "_next")

    def __init__(self, generator: np.random.Generator, block: int = BLOCK) -> None:
        if block < 1:
            raise ValueError(f"block must be >= 1, got {block}")
        self._generator = generator
        self._block = int(block)
        self._buffer: list[float] = []
        self._next = 0

    def random(self) -> float:
        """The next uniform (as the generator's `random()` would give it)."""
        i = self._next
        if i >= len(self._buffer):
            self._refill(1)
            i = 0
        self._next = i + 1
        return self._buffer[i]

    def take(self, n: int) -> list[float]:
        """The next `n` uniforms (as the generator's `random(n).tolist()` would give them)."""
        i = self._next
        j = i + n
        if j > len(self._buffer):
            self._refill(n)
            i, j = 0, n
        self._next = j
        return self._buffer[i:j]

    def _refill(self, n: int) -> None:
        """Keep what is left, then draw at least enough for `n` more, in the generator's order."""
        rest = self._buffer[self._next:]
        self._buffer = rest + self._generator.random(max(self._block, n - len(rest))).tolist()
        self._next = 0


def uniforms(rng: np.random.Generator | UniformStream, n: int) -> list[float]:
    """The next `n` uniforms of `rng`, a Generator or a UniformStream (the same numbers either way)."""
    if type(rng) is UniformStream:
        return rng.take(n)
    return rng.random(n).tolist()
