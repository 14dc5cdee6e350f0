"""Portable numerics at the bottom of every layer: the same bits on every CPU (no BLAS/LAPACK, no SIMD
reductions, no libm transcendental functions on the simulation path), geometry helpers, RVO2's linear
program, and the loader of the optional compiled kernels."""
