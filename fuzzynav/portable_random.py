"""Random draws that give the same numbers on every CPU, operating system and build.

numpy's ``Generator.random`` is exact everywhere (53 random bits times 2**-53), but its ``normal`` uses
the C library's ``exp``/``log1p`` in the ziggurat's rare branches, and its ``uniform`` computes
``low + (high - low) * u`` in C, which a compiler may fuse into one FMA on ARM64. Here the bits come from
``Generator.random`` and every transformation is done with :mod:`fuzzynav.portable_math`'s operations.
"""

from __future__ import annotations

import numpy as np

from fuzzynav.portable_math import log_array, sin_cos_deg_array


def uniform(rng: np.random.Generator, low: float, high: float) -> float:
    """One draw from [low, high)."""
    return low + (high - low) * float(rng.random())


def normal(rng: np.random.Generator, mean: float, std: float, size: int) -> np.ndarray:
    """``size`` draws from N(mean, std²) (Box–Muller: each pair of uniforms gives two normals)."""
    pairs = (size + 1) // 2
    u = rng.random((2, pairs))
    radius = np.sqrt(-2.0 * log_array(1.0 - u[0]))  # 1 - u is in (0, 1]: the logarithm is finite
    s, c = sin_cos_deg_array(360.0 * u[1])
    z = np.concatenate([radius * c, radius * s])[:size]
    return mean + std * z
