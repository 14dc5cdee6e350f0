"""The compiled ray caster (fuzzynav.sensing._raycast) gives its numpy form's bits: ranges and hit indices.

Worlds drawn at random (segments of any orientation, zero-length ones, segments through the origin and parallel
to beams, circles around the origin or touching it, rays grazing a rim, coincident objects for ties), rays in
random and in axis directions. In CI (CI=true) the kernel must have been built.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzynav.sensing import raycast
from fuzzynav.sensing.laser import LaserConfig, beam_directions
from fuzzynav.sensing.raycast import cast_rays, nearest_numpy
from tests.conftest import require_compiled

require_compiled(raycast._raycast, "_raycast")

coord = st.one_of(st.floats(-400, 400, allow_nan=False), st.integers(-300, 300).map(float))


@st.composite
def worlds(draw):
    ox, oy = draw(coord), draw(coord)
    segments = []
    for _ in range(draw(st.integers(0, 12))):
        kind = draw(st.sampled_from(["any", "point", "through_origin", "axis"]))
        x1, y1 = draw(coord), draw(coord)
        if kind == "point":
            x2, y2 = x1, y1
        elif kind == "through_origin":
            x2, y2 = 2 * ox - x1, 2 * oy - y1
        elif kind == "axis":
            x2, y2 = (x1, draw(coord)) if draw(st.booleans()) else (draw(coord), y1)
        else:
            x2, y2 = draw(coord), draw(coord)
        segments.append((x1, y1, x2, y2))
    if segments and draw(st.booleans()):
        segments.append(segments[0])  # a coincident copy: the lower index must win the tie
    circles = []
    for _ in range(draw(st.integers(0, 10))):
        kind = draw(st.sampled_from(["any", "around_origin", "touching"]))
        r = draw(st.floats(0.0, 150.0))
        if kind == "around_origin":
            circles.append((ox + draw(st.floats(-10, 10)), oy + draw(st.floats(-10, 10)), r + 10.0))
        elif kind == "touching":
            circles.append((ox + r, oy, r))
        else:
            circles.append((draw(coord), draw(coord), r))
    return ox, oy, np.array(segments, float).reshape(-1, 4), np.array(circles, float).reshape(-1, 3)


def _both(ox, oy, directions, segments, circles, max_range):
    outs = []
    for fn in (raycast._raycast.nearest, nearest_numpy):
        best, hit = np.full(len(directions), float(max_range)), np.full(len(directions), -1, dtype=np.int64)
        fn(ox, oy, np.ascontiguousarray(directions), segments, np.arange(len(segments), dtype=np.int64), circles,
           len(segments) + np.arange(len(circles), dtype=np.int64), best, hit)
        outs.append((best.tobytes(), hit.tobytes()))
    return outs


@given(worlds(), st.floats(0, 360), st.sampled_from([8, 360]), st.floats(1.0, 1000.0))
@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_kernel_gives_the_numpy_forms_bits(world, heading, beams, max_range):
    ox, oy, segments, circles = world
    directions = beam_directions(LaserConfig(beams=beams), heading)
    kernel, numpy_form = _both(ox, oy, directions, segments, circles, max_range)
    assert kernel == numpy_form


@given(worlds())
@settings(max_examples=100, deadline=None)
def test_axis_and_diagonal_rays_too(world):
    ox, oy, segments, circles = world
    s = np.sqrt(0.5)
    directions = np.array([[1, 0], [0, 1], [-1, 0], [0, -1], [s, s], [-s, s], [s, -s], [-s, -s]], float)
    kernel, numpy_form = _both(ox, oy, directions, segments, circles, 250.0)
    assert kernel == numpy_form


def _cast_both(monkeypatch, origin, directions, segments, circles, max_range):
    on = cast_rays(origin, directions, segments, circles, max_range)
    with monkeypatch.context() as m:
        m.setenv("FUZZYNAV_KERNEL", "python")
        off = cast_rays(origin, directions, segments, circles, max_range)
    return (on[0].tobytes(), on[1].tobytes()), (off[0].tobytes(), off[1].tobytes())


@given(worlds(), st.floats(0, 360), st.sampled_from([8, 360]), st.floats(1.0, 400.0), st.data())
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.function_scoped_fixture])
def test_cast_rays_whole_with_its_culling_gives_the_numpy_forms_bits(monkeypatch, world, heading, beams, max_range,
                                                                     data):
    """The kernel's ``cast`` culls as the numpy form does: objects just inside and just beyond the range, far
    away, and with NaN coordinates (never hit) are added to the drawn world."""
    ox, oy, segments, circles = world
    edge = max_range * data.draw(st.sampled_from([1 - 1e-9, 1.0, 1 + 1e-9, 1 + 2e-9, 3.0]))
    angle = np.deg2rad(data.draw(st.floats(0, 360)))
    px, py = ox + edge * np.cos(angle), oy + edge * np.sin(angle)
    extra_segments = [(px - 50 * np.sin(angle), py + 50 * np.cos(angle), px + 50 * np.sin(angle),
                       py - 50 * np.cos(angle)), (px, py, px, py), (np.nan, 0.0, 1.0, 1.0)]
    extra_circles = [(px + 5 * np.cos(angle), py + 5 * np.sin(angle), 5.0), (ox + 1e6, oy, 10.0),
                     (np.nan, oy, 1.0)]
    order = data.draw(st.permutations(range(len(segments) + 3)))
    segments = np.vstack([segments, extra_segments])[list(order)]
    circles = np.vstack([circles, extra_circles])
    directions = beam_directions(LaserConfig(beams=beams), heading)
    on, off = _cast_both(monkeypatch, np.array([ox, oy]), directions, segments, circles, max_range)
    assert on == off


@given(worlds(), st.floats(-720, 720), st.sampled_from([8, 90, 360]), st.floats(1.0, 400.0),
       st.sampled_from([0.0, 1.0, 30.0]), st.integers(0, 3), st.integers(0, 2**32 - 1))
@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.function_scoped_fixture])
def test_a_whole_laser_frame_gives_the_numpy_forms_bits(monkeypatch, world, heading, beams, range_cm, noise_std,
                                                        n_static_circles, seed):
    """laser.scan with the kernel (``laser_frame``: directions, ranges, noise, labels, end points) and without:
    every array the same bits, and the noise stream left at the same place."""
    from fuzzynav.numerics.portable_random import NormalStream
    from fuzzynav.sensing.laser import scan

    ox, oy, segments, circles = world
    static_circles, discs = circles[:n_static_circles], circles[n_static_circles:]
    config = LaserConfig(range_cm=range_cm, beams=beams, noise_std_cm=noise_std)
    frames, nexts = [], []
    for off in (False, True):
        with monkeypatch.context() as m:
            if off:
                m.setenv("FUZZYNAV_KERNEL", "python")
            noise = NormalStream(np.random.default_rng(seed))
            frames.append(scan(config, ox, oy, heading, segments, static_circles, discs, noise))
            nexts.append(noise.draw(0.0, 1.0, 3).tobytes())
    a, b = frames
    for name in ("ranges", "directions", "labels", "xy"):
        assert getattr(a, name).tobytes() == getattr(b, name).tobytes(), name
        assert getattr(a, name).dtype == getattr(b, name).dtype and getattr(a, name).shape == getattr(b, name).shape
    assert a.origin == b.origin and nexts[0] == nexts[1]


def test_cast_rays_is_the_same_with_the_kernel_switched_off(monkeypatch):
    rng = np.random.default_rng(4)
    segments = np.column_stack([rng.uniform(-300, 300, (30, 4))])
    circles = np.column_stack([rng.uniform(-300, 300, (20, 2)), rng.uniform(1, 50, 20)])
    d = beam_directions(LaserConfig(), 33.0)
    on = cast_rays(np.array([5.0, -7.0]), d, segments, circles, 250.0)
    monkeypatch.setenv("FUZZYNAV_KERNEL", "python")
    off = cast_rays(np.array([5.0, -7.0]), d, segments, circles, 250.0)
    assert on[0].tobytes() == off[0].tobytes() and on[1].tobytes() == off[1].tobytes()
    assert (on[1] >= 0).sum() > 100  # the world is hit: the comparison means something


@pytest.mark.parametrize(("which", "bad"), [
    (0, np.zeros((4, 3))),  # directions with 3 columns
    (0, np.zeros((4, 2), np.float32)),
    (1, np.zeros((2, 4))[:, ::2].copy()),  # 2 columns, not 4
    (2, np.zeros(3, np.int64)),  # ids of another length
    (5, np.zeros(5)),  # best of another length
    (6, np.zeros(4)),  # hit as floats
    (0, np.zeros((8, 2))[::2]),  # not contiguous
])
def test_bad_buffers_are_refused(which, bad):
    args = [np.zeros((4, 2)), np.zeros((2, 4)), np.zeros(2, np.int64), np.zeros((1, 3)), np.zeros(1, np.int64),
            np.zeros(4), np.zeros(4, np.int64)]
    args[which] = bad
    with pytest.raises((ValueError, BufferError, TypeError)):
        raycast._raycast.nearest(0.0, 0.0, *args)


@pytest.mark.parametrize(("which", "bad"), [
    (0, np.zeros((4, 3))),  # directions with 3 columns
    (1, np.zeros((2, 3))),  # segments with 3 columns
    (2, np.zeros((2, 4))),  # circles with 4 columns
    (3, np.zeros(5)),  # best of another length
    (4, np.zeros(4)),  # hit as floats
    (2, np.zeros((8, 3))[::2]),  # not contiguous
])
def test_cast_refuses_bad_buffers(which, bad):
    args = [np.zeros((4, 2)), np.zeros((2, 4)), np.zeros((1, 3)), np.zeros(4), np.zeros(4, np.int64)]
    args[which] = bad
    with pytest.raises((ValueError, BufferError, TypeError)):
        raycast._raycast.cast(0.0, 0.0, 250.0, 250.0, *args)


def test_laser_frame_refuses_bad_buffers():
    n = 8
    good = [np.zeros(n), np.zeros(n), np.zeros((1, 4)), np.zeros((0, 3)), None, np.zeros(n), np.zeros((n, 2)),
            np.zeros(n, np.int64), np.zeros((n, 2))]
    for which, bad in [(0, np.zeros(n + 1)), (4, np.zeros(n - 1)), (6, np.zeros((n, 3))), (7, np.zeros(n)),
                       (8, np.zeros((n, 2))[::-1]), (2, np.zeros((1, 4), np.float32))]:
        args = list(good)
        args[which] = bad
        with pytest.raises((ValueError, BufferError, TypeError)):
            raycast._raycast.laser_frame(0.0, 0.0, 0.0, 1.0, 250.0, 250.0, 4, 249.0, *args)


def test_read_only_outputs_are_refused():
    best = np.zeros(4)
    best.flags.writeable = False
    with pytest.raises((ValueError, BufferError, TypeError)):
        raycast._raycast.nearest(0.0, 0.0, np.zeros((4, 2)), np.zeros((0, 4)), np.zeros(0, np.int64),
                                 np.zeros((0, 3)), np.zeros(0, np.int64), best, np.zeros(4, np.int64))


def test_integer_and_strided_worlds_are_cast_as_the_numpy_form_casts_them(monkeypatch):
    segments = np.array([[-100, -100, 100, -100], [100, -100, 100, 100]])  # ints
    circles = np.array([[0.0, 50.0, 10.0, 0.0, 40.0, 5.0]]).reshape(2, 3)[::-1]  # a reversed view
    d = beam_directions(LaserConfig(), 0.0)[::-1]
    on = cast_rays(np.array([0.0, 0.0]), d, segments, circles, 250.0)
    monkeypatch.setenv("FUZZYNAV_KERNEL", "python")
    off = cast_rays(np.array([0.0, 0.0]), d, segments, circles, 250.0)
    assert on[0].tobytes() == off[0].tobytes() and on[1].tobytes() == off[1].tobytes() and (on[1] >= 0).any()
