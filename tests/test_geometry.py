"""fuzzynav.numerics.geometry: closest approach over a step and angle wrapping (hand-computed cases and properties)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from fuzzynav.numerics import geometry as geo
from fuzzynav.numerics.portable_math import dist

COORD = st.floats(-1e4, 1e4, allow_nan=False, allow_subnormal=False)
POINT = st.tuples(COORD, COORD)
ANGLE = st.floats(-1e6, 1e6, allow_nan=False)


def _a(*points) -> np.ndarray:
    return np.array(points, dtype=float)


def test_head_on_discs_meet_halfway_through_the_step():
    # robot 0 -> 100 cm along x, obstacle 100 -> 0 cm: they pass each other at the middle of the step
    p0, p1, o0, o1 = _a(0, 0), _a(100, 0), _a((100, 0)), _a((0, 0))
    assert geo.swept_distance(p0, p1, o0, o1).tolist() == [0.0]
    assert geo.closest_approach_fraction(p0 - o0, (p1 - p0) - (o1 - o0)).tolist() == [0.5]


def test_crossing_paths_with_an_offset_in_time():
    # robot along +x from (0, 0), obstacle along +y from (50, -30), both 60 cm over the step:
    # relative position (-50 + 0, 30 - 60 s) ... (-50 + 60 s - 0, 30 - 60 s): |(-50 + 60 s, 30 - 60 s)|
    # is smallest at s = (50·60 + 30·60) / (2·3600) = 2/3, where it is |(-10, -10)| = 10·√2
    got = geo.swept_distance(_a(0, 0), _a(60, 0), _a((50, -30)), _a((50, 30)))
    assert got[0] == pytest.approx(10.0 * math.sqrt(2.0), rel=1e-15)
    s = geo.closest_approach_fraction(_a((-50, 30)), _a((60, -60)))
    assert s[0] == pytest.approx(2.0 / 3.0, rel=1e-15)


def test_the_fraction_is_clamped_to_the_step():
    # moving apart: closest at the start; approaching but not yet there at the end: closest at the end
    assert geo.closest_approach_fraction(_a(10, 0), _a(5, 0)) == 0.0
    assert geo.closest_approach_fraction(_a(100, 0), _a(-30, 0)) == 1.0
    assert geo.closest_approach(_a(100, 0), _a(-30, 0)) == 70.0
    # nothing moves (zero relative step): no division by zero, the start distance
    assert geo.closest_approach_fraction(_a(3, 4), _a(0, 0)) == 0.0
    assert geo.closest_approach(_a(3, 4), _a(0, 0)) == 5.0


def test_same_motion_keeps_the_distance():
    # both move by the same vector: the relative position never changes
    got = geo.swept_distance(_a(0, 0), _a(40, 30), _a((0, 25)), _a((40, 55)))
    assert got.tolist() == [25.0]


def test_segment_point_distance_hand_cases():
    a, b = _a(0, 0), _a(10, 0)
    points = _a((5, 3), (-4, 3), (13, -4), (10, 0), (0, 0))
    assert geo.segment_point_distance(a, b, points).tolist() == [3.0, 5.0, 5.0, 0.0, 0.0]
    # a degenerate segment is its one point
    assert geo.segment_point_distance(a, a, _a((3, 4))).tolist() == [5.0]


def test_segment_point_distance_broadcasts_moves_against_points():
    # three moves from one start (S, 1, 2) against two points (P, 2): an (S, P) table
    ends = _a((10, 0), (0, 10), (0, 0))
    got = geo.segment_point_distance(_a(0, 0), ends[:, None, :], _a((5, 2), (0, 20)))
    assert got.shape == (3, 2)
    assert got.tolist() == [[2.0, 20.0], [5.0, 10.0], [math.sqrt(29.0), 20.0]]


@given(POINT, POINT, POINT, POINT)
def test_closest_approach_is_symmetric_and_within_the_endpoint_distances(p0, p1, o0, o1):
    p0, p1, o0, o1 = (np.array(v) for v in (p0, p1, o0, o1))
    ab = geo.swept_distance(p0, p1, o0[None], o1[None])[0]
    ba = geo.swept_distance(o0, o1, p0[None], p1[None])[0]
    assert ab == ba  # the same operations on negated inputs: the same bits
    start, end = dist(p0, o0), dist(p1, o1)
    slack = 1e-12 * (1.0 + max(start, end))
    assert 0.0 <= ab <= min(start, end) + slack


@given(POINT, POINT, POINT)
def test_segment_point_distance_is_the_minimum_along_the_segment(a, b, q):
    a, b, q = (np.array(v) for v in (a, b, q))
    got = geo.segment_point_distance(a, b, q[None])[0]
    samples = a + np.linspace(0.0, 1.0, 201)[:, None] * (b - a)
    sampled = min(dist(p, q) for p in samples)
    slack = 1e-9 * (1.0 + dist(a, q) + dist(b, q))
    assert got <= sampled + slack
    # the sample nearest the true minimum is at most half a sample spacing along the segment away
    assert sampled <= got + dist(a, b) / 400.0 + slack
    assert geo.segment_point_distance(b, a, q[None])[0] == pytest.approx(got, rel=1e-12, abs=1e-9)


@given(ANGLE)
def test_wrap_ranges_and_idempotence(angle):
    w360, w180 = geo.wrap_360(angle), geo.wrap_180(angle)
    # Python's float % may round a tiny negative angle up to exactly 360 (-1e-20 % 360 == 360.0)
    assert 0.0 <= w360 <= 360.0
    assert -180.0 <= w180 < 180.0
    assert geo.wrap_180(w180) == w180
    if w360 < 360.0:
        assert geo.wrap_360(w360) == w360
    # the same direction: a whole number of turns apart (up to the rounding of the remainder)
    turns = (angle - w180) / 360.0
    assert abs(turns - round(turns)) < 1e-9


@given(st.lists(ANGLE, min_size=1, max_size=20), ANGLE)
def test_array_and_float_forms_give_the_same_bits(angles, other):
    arr = np.array(angles)
    assert geo.wrap_360(arr).tolist() == [geo.wrap_360(a) for a in angles]
    assert geo.wrap_180(arr).tolist() == [geo.wrap_180(a) for a in angles]
    assert geo.angle_difference_deg(arr, other).tolist() == [geo.angle_difference_deg(a, other) for a in angles]


def test_wrap_hand_cases():
    assert [geo.wrap_360(a) for a in (0.0, 360.0, 370.0, -10.0, -360.0, 720.5)] == [0.0, 0.0, 10.0, 350.0, 0.0,
                                                                                     0.5]
    assert [geo.wrap_180(a) for a in (0.0, 180.0, -180.0, 190.0, -190.0, 540.0)] == [0.0, -180.0, -180.0,
                                                                                      -170.0, 170.0, -180.0]


def test_angle_difference_takes_the_short_way_round():
    assert geo.angle_difference_deg(10.0, 350.0) == 20.0
    assert geo.angle_difference_deg(350.0, 10.0) == -20.0
    assert geo.angle_difference_deg(90.0, 270.0) == -180.0
    assert geo.angle_difference_deg(45.0, 45.0) == 0.0


def _kept_inside_one_by_one(x, v, radii, bounds):
    x, v = x.copy(), v.copy()
    for i, r in enumerate(radii.tolist()):
        for axis, lo, hi in ((0, bounds[0], bounds[2]), (1, bounds[1], bounds[3])):
            lo_r, hi_r = lo + r, hi - r
            if not lo_r <= hi_r:
                continue  # wider than the world: that coordinate is kept
            if x[i, axis] < lo_r:
                x[i, axis] = lo_r
                v[i, axis] = 0.0 if v[i, axis] < 0.0 else v[i, axis]
            elif x[i, axis] > hi_r:
                x[i, axis] = hi_r
                v[i, axis] = 0.0 if v[i, axis] > 0.0 else v[i, axis]
    return x, v


@given(st.integers(0, 6).flatmap(lambda n: st.tuples(
    st.lists(st.tuples(COORD, COORD), min_size=n, max_size=n), st.lists(st.tuples(COORD, COORD), min_size=n,
                                                                        max_size=n),
    st.lists(st.floats(0, 600), min_size=n, max_size=n))),
       st.sampled_from([(0, 0, 1000, 800), (-500.0, -500.0, 500.0, 500.0), (0, 0, 100, 100)]))
def test_keep_inside_moves_each_disc_back_and_stops_it_at_the_wall(discs, bounds):
    positions, velocities = (np.array(a, dtype=float).reshape(-1, 2) for a in discs[:2])
    radii = np.array(discs[2], dtype=float)
    got = geo.keep_inside(positions, velocities, radii, bounds)
    want = _kept_inside_one_by_one(positions, velocities, radii, bounds)
    assert [a.tobytes() for a in got] == [a.tobytes() for a in want]
    assert got[0] is not positions and got[1] is not velocities


def test_clearance_is_each_moves_distance_to_its_nearest_return():
    """segment_point_clearance by hand: moves east, north and of zero length from the origin against three
    returns (3-4-5 triangles: exact distances), and ``inf`` for every move when there are no returns."""
    from fuzzynav.numerics.clearance import segment_point_clearance

    ends = np.array([[10.0, 0.0], [0.0, 10.0], [0.0, 0.0]])
    points = np.array([[5.0, 3.0], [20.0, 0.0], [-4.0, 3.0]])
    assert segment_point_clearance(np.zeros(2), ends, points).tolist() == [3.0, 4.0, 5.0]
    assert segment_point_clearance(np.zeros(2), ends, np.zeros((0, 2))).tolist() == [np.inf] * 3
    assert segment_point_clearance(np.zeros(2), ends, None).tolist() == [np.inf] * 3
