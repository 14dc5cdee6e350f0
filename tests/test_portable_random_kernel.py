"""The compiled Box-Muller transform (fuzzynav.numerics._portable_random) gives the numpy form's normals to the last
bit:
on uniforms drawn at random, on the edges of their range (0, just below 1, the quadrant boundaries of the angle)
and through NormalStream's blocks. In CI (CI=true) the kernel must have been built."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzynav.numerics import portable_random
from fuzzynav.numerics.portable_random import NormalStream, standard_normal
from tests.conftest import require_compiled

require_compiled(portable_random._kernel, "_portable_random")


class _Fixed:
    """A generator whose ``random`` returns given uniforms (shaped as asked)."""

    def __init__(self, u: np.ndarray) -> None:
        self.u = u

    def random(self, shape):
        return self.u.reshape(shape)


def _both(monkeypatch, u: np.ndarray, size: int) -> tuple[bytes, bytes]:
    on = standard_normal(_Fixed(u), size)
    with monkeypatch.context() as m:
        m.setenv("FUZZYNAV_KERNEL", "python")
        off = standard_normal(_Fixed(u), size)
    assert on.dtype == off.dtype and on.shape == off.shape == (size,)
    return on.tobytes(), off.tobytes()


EDGES = [0.0, 2.0**-53, 0.5, 0.25, 0.75, 1.0 - 2.0**-53, 1.0 - 2.0**-20, 0.125, 0.375, 0.625, 0.875, 1e-300]
uniform = st.one_of(st.floats(0.0, 1.0, exclude_max=True), st.sampled_from(EDGES))


@given(st.lists(st.tuples(uniform, uniform), min_size=1, max_size=40), st.booleans())
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_the_kernel_gives_the_numpy_forms_bits(monkeypatch, pairs, odd):
    u = np.array(pairs, dtype=float).T.copy()  # (2, pairs): row 0 the radius's uniforms, row 1 the angle's
    size = 2 * u.shape[1] - (1 if odd else 0)
    on, off = _both(monkeypatch, u, size)
    assert on == off


def test_every_quarter_turn_and_its_neighbours(monkeypatch):
    """The angle's quadrant boundaries (360 u1 a multiple of 45 degrees) and one ulp either side of them."""
    base = np.arange(0, 8) / 8.0
    u1 = np.concatenate([base, np.nextafter(base, 1.0), np.nextafter(base, -1.0).clip(0.0)])
    u0 = np.linspace(0.0, 0.999, len(u1))
    on, off = _both(monkeypatch, np.stack([u0, u1]), 2 * len(u1))
    assert on == off


def test_a_stream_draws_the_same_values_with_the_kernel_switched_off(monkeypatch):
    a = NormalStream(np.random.default_rng(7))
    first = np.concatenate([a.draw(0.0, 2.0, 360) for _ in range(30)])  # crosses a block
    with monkeypatch.context() as m:
        m.setenv("FUZZYNAV_KERNEL", "python")
        b = NormalStream(np.random.default_rng(7))
        second = np.concatenate([b.draw(0.0, 2.0, 360) for _ in range(30)])
    assert first.tobytes() == second.tobytes()
    assert abs(first.mean()) < 0.1 and abs(first.std() - 2.0) < 0.1  # they are normals


@pytest.mark.parametrize("which", range(7))
def test_bad_buffers_are_refused(which):
    args = [np.zeros(4), np.zeros(4), *portable_random._SERIES, np.zeros(8)]
    args[which] = np.zeros(3, np.float32) if which != 6 else np.zeros(7)
    with pytest.raises((ValueError, BufferError, TypeError)):
        portable_random._kernel.normal_pairs(*args)
