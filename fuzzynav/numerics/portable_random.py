"""Random draws that give the same numbers on every CPU, operating system and build.

numpy's ``Generator.random`` is exact everywhere (53 random bits times 2**-53), but its ``normal`` uses
the C library's ``exp``/``log1p`` in the ziggurat's rare branches, and its ``uniform`` computes
``low + (high - low) * u`` in C, which a compiler may fuse into one FMA on ARM64. Here the bits come from
``Generator.random`` and every transformation is done with :mod:`fuzzynav.numerics.portable_math`'s operations.
"""

from __future__ import annotations

import numpy as np

from fuzzynav.numerics.portable_math import log_array, sin_cos_deg_array


def uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """One draw from [low, high)."""
    return low + (high - low) * float(rng.random())


def standard_normal(rng: np.random.Generator, size: int) -> np.ndarray:
    """``size`` draws from N(0, 1) (Box–Muller: each pair of uniforms gives two normals)."""
    pairs = (size + 1) // 2
    u = rng.random((2, pairs))
    radius = np.sqrt(-2.0 * log_array(1.0 - u[0]))  # 1 - u is in (0, 1]: the logarithm is finite
    s, c = sin_cos_deg_array(360.0 * u[1])
    return np.concatenate([radius * c, radius * s])[:size]


class NormalStream:
    """Normal draws from one generator, made :attr:`BLOCK` at a time: a few hundred values per call would
    cost numpy's per-call overhead several times over (the laser draws one value per beam every step). The
    n-th value drawn is the same whatever sizes the values are requested in."""

    BLOCK = 8192

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self._block = np.empty(0)
        self._used = 0

    def draw(self, mean: float, std: float, size: int) -> np.ndarray:
        """The next ``size`` draws from N(mean, std²)."""
        used = self._used
        if used + size <= len(self._block):  # the usual case: a view of the block, no copy (the same values)
            self._used = used + size
            return mean + std * self._block[used:used + size]
        out = np.empty(size)
        filled = 0
        while filled < size:
            if self._used == len(self._block):
                self._block, self._used = standard_normal(self.rng, self.BLOCK), 0
            k = min(size - filled, len(self._block) - self._used)
            out[filled:filled + k] = self._block[self._used:self._used + k]
            filled += k
            self._used += k
        return mean + std * out
