"""UniformStream: the uniform doubles of a numpy Generator, drawn a block at a time; and the
counter-based uniforms that compiled loops draw (`counter_key`, `counter_uniform`).

Owns: handing out a Generator's `random()` values one or a few at a time, cheaply; the keyed hash
behind the counter-based draws. Must not know: what the numbers are for (fading, PER, delays), who
owns the stream.

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

from rescuemesh.jit import compiled

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


# --- counter-based uniforms ------------------------------------------------------------------------
#
# A compiled loop over receivers cannot pull numbers from a numpy Generator per receiver, and a
# draw must not depend on who else is in the team. So each draw is a pure function of its key:
#     u = counter_uniform(counter_key(seed, purpose, a, b, counter), j)
# (the j-th number of the draw keyed by the run's seed, what it is for, the two radios' addresses
# and a counter, e.g. the sender's transmission number). The hash is SplitMix64's output function
# (Steele, Lea and Flood, "Fast splittable pseudorandom number generators", OOPSLA 2014; the
# generator Java's SplittableRandom and numpy's SeedSequence documentation cite), chained over the
# key's words: each word is XORed into the state, which is then mixed. SplitMix64 passes BigCrush;
# the 53 high bits of the mixed word make a double in [0, 1), as numpy's `random()` does.

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_TO_UNIT = 1.0 / 9007199254740992.0  # 2**-53
#: Keys are 64-bit: a seed is reduced to its low 64 bits.
SEED_MASK = (1 << 64) - 1


@compiled("u8(u8)")
def splitmix64(z):
    """SplitMix64's step: add the golden gamma, then mix (a bijection on 64-bit words)."""
    z = z + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _MIX1
    z = (z ^ (z >> np.uint64(27))) * _MIX2
    return z ^ (z >> np.uint64(31))


@compiled("u8(u8, i8, i8, i8, i8)")
def counter_key(seed, purpose, a, b, counter):
    """The key of one draw: the run's `seed` (64 bits), its `purpose`, radios `a` and `b`, a `counter`."""
    x = splitmix64(seed)
    x = splitmix64(x ^ np.uint64(purpose))
    x = splitmix64(x ^ np.uint64(a))
    x = splitmix64(x ^ np.uint64(b))
    return splitmix64(x ^ np.uint64(counter))


@compiled("f8(u8, i8)")
def counter_uniform(key, j):
    """The `j`-th uniform in [0, 1) of the draw keyed `key`."""
    return float(splitmix64(key ^ (np.uint64(j) * _GOLDEN)) >> np.uint64(11)) * _TO_UNIT
