"""The faster sensing and tracking code of issue #19 (target 3) gives the same bits as the straightforward forms it
replaced: the references below are those forms, kept here only to compare against (log content must not change).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzynav.numerics.portable_math import fsum_dot, fsum_mean, norm2
from fuzzynav.scenarios.scenario import Circle, StaticObstacle
from fuzzynav.scenarios.world import _MAX_BOUNDING_DISCS, World, world_of
from fuzzynav.sensing import tracking
from fuzzynav.sensing.laser import LaserConfig, LaserScan, beam_directions
from fuzzynav.sensing.raycast import cast_rays
from fuzzynav.sensing.sonar import Sonar, SonarConfig


def _fit_disc_reference(points: np.ndarray) -> tuple[float, float, float, float]:
    """Kasa's fit with numpy arrays and :mod:`fuzzynav.numerics.portable_math`'s correctly rounded sums."""
    mx, my = fsum_mean(points[:, 0]), fsum_mean(points[:, 1])
    u, v = points[:, 0] - mx, points[:, 1] - my
    z = u * u + v * v
    suu, svv, suv = fsum_dot(u, u), fsum_dot(v, v), fsum_dot(u, v)
    suz, svz = fsum_dot(u, z), fsum_dot(v, z)
    det = suu * svv - suv * suv
    if not det > 1e-12 * (suu + svv) * (suu + svv):
        return float(mx), float(my), math.inf, math.inf
    a = (suz * svv - svz * suv) / (2.0 * det)
    b = (svz * suu - suz * suv) / (2.0 * det)
    r = math.sqrt(a * a + b * b + fsum_mean(z))
    du, dv = u - a, v - b
    residual = np.sqrt(du * du + dv * dv) - r
    return float(mx + a), float(my + b), r, math.sqrt(fsum_mean(residual * residual))


def _segment_reference(scan: LaserScan, gap_cm: float) -> list[np.ndarray]:
    """Clusters by a cumulative label over the beams rotated to start at the first cluster start."""
    n = len(scan.ranges)
    ret = scan.returned
    if not ret.any():
        return []
    pts = scan.xy
    to_next = np.concatenate([pts[1:], pts[:1]]) - pts
    linked = ret & np.concatenate([ret[1:], ret[:1]]) & (norm2(to_next) <= gap_cm)
    if linked.all():
        return [np.arange(n)]
    starts = ret & ~np.concatenate([linked[-1:], linked[:-1]])
    first = int(np.argmax(starts))
    order = np.concatenate([np.arange(first, n), np.arange(first)])
    label = np.cumsum(starts[order])
    keep = ret[order]
    return np.split(order[keep], np.nonzero(np.diff(label[keep]))[0] + 1)


def _random_scan(rng: np.random.Generator, n: int = 360) -> LaserScan:
    """A scan of walls and a few discs at random (some beams return nothing)."""
    x, y = rng.uniform(100, 900, 2)
    segments = np.array([[0, 0, 1000, 0], [1000, 0, 1000, 1000], [1000, 1000, 0, 1000], [0, 1000, 0, 0]], float)
    discs = np.column_stack([rng.uniform(0, 1000, (6, 2)), rng.uniform(5, 40, 6)])
    config = LaserConfig(beams=n)
    d = beam_directions(config, float(rng.uniform(0, 360)))
    ranges, hit = cast_rays(np.array([x, y]), d, segments, discs, config.range_cm)
    return LaserScan(ranges=ranges, directions=d, labels=hit, origin=(float(x), float(y)), range_cm=config.range_cm)


@pytest.mark.parametrize("seed", range(40))
def test_clusters_and_disc_fits_are_the_reference_bits(seed):
    rng = np.random.default_rng(seed)
    scan = _random_scan(rng)
    fast, ref = tracking.segment(scan, 15.0), _segment_reference(scan, 15.0)
    assert len(fast) == len(ref)
    for a, b in zip(fast, ref, strict=True):
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes()
        if len(a) >= 3:
            pts = scan.xy[a]
            assert repr(tracking.fit_disc(pts)) == repr(_fit_disc_reference(pts))


def test_disc_fit_of_collinear_and_tiny_clusters_is_the_reference():
    rng = np.random.default_rng(7)
    for pts in (np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]), rng.normal(0, 1e-3, (3, 2)) + 500.0,
                rng.normal(300.0, 20.0, (80, 2))):
        assert repr(tracking.fit_disc(pts)) == repr(_fit_disc_reference(pts))


def test_detections_keep_clusters_the_reference_way():
    """detect() filters on extent and nearest range for all clusters at once: the same detections as one by one."""
    config = tracking.TrackerConfig()
    for seed in range(20):
        scan = _random_scan(np.random.default_rng(100 + seed))
        expected = []
        for beams in _segment_reference(scan, config.cluster_gap_cm):
            if len(beams) < config.min_points:
                continue
            pts = scan.xy[beams]
            if float(norm2(pts.max(0) - pts.min(0))) > 2.0 * config.max_radius_cm:
                continue
            cx, cy, radius, rms = _fit_disc_reference(pts)
            if radius > config.max_radius_cm or rms > config.max_fit_rms_cm:
                continue
            if math.sqrt((cx - scan.origin[0]) ** 2 + (cy - scan.origin[1]) ** 2) <= float(scan.ranges[beams].min()):
                continue
            expected.append((cx, cy, radius, beams.tolist()))
        got = [(d.x, d.y, d.radius, d.beams.tolist()) for d in tracking.detect(scan, config)]
        assert repr(got) == repr(expected)


def test_stacked_sonar_wedges_are_the_per_sector_ones():
    equal = Sonar(SonarConfig(), 20.0)
    assert equal._stacked is not None
    per_sector = Sonar(SonarConfig(), 20.0)
    per_sector._stacked = None  # the general path (sectors of different widths)
    import shapely

    for x, y, h in ((500.0, 500.0, 0.0), (123.456, 789.01, 33.3), (0.0, -5.5, 271.9)):
        a = shapely.get_coordinates(equal.wedges(x, y, h))
        b = shapely.get_coordinates(per_sector.wedges(x, y, h))
        assert a.tobytes() == b.tobytes()
    uneven = Sonar(SonarConfig(left=(30.0, 100.0)), 20.0)
    assert uneven._stacked is None and len(uneven.wedges(500.0, 500.0, 10.0)) == 3


def test_shared_world_is_read_only_and_keyed_by_exact_inputs():
    obstacles = (StaticObstacle(circle=Circle((300.0, 300.0), 40.0)),)
    a = world_of((0.0, 0.0, 1000.0, 800.0), obstacles)
    assert world_of((0.0, 0.0, 1000.0, 800.0), list(obstacles)) is a
    assert world_of((-0.0, 0.0, 1000.0, 800.0), obstacles) is not a  # equal numbers, other bits
    assert not a.segments.flags.writeable and not a.circles.flags.writeable
    fresh = World((0.0, 0.0, 1000.0, 800.0), obstacles)
    assert fresh.segments.tobytes() == a.segments.tobytes() and fresh.circles.tobytes() == a.circles.tobytes()


def _geos_contact(world: World, p0: np.ndarray, p1: np.ndarray, radius: float) -> bool:
    """static_contact's answer by GEOS alone (the form before its quick "far from everything" test)."""
    path = shapely.points(p1) if math.dist(p0, p1) < 1e-9 else shapely.linestrings(np.array([p0, p1], dtype=float))
    with np.errstate(divide="ignore", invalid="ignore"):
        return bool(shapely.dwithin(world.solid, path, radius - 1e-9))


_coord = st.floats(-200.0, 1200.0, allow_nan=False)


@st.composite
def _worlds_and_paths(draw):
    """A world of up to 14 circles and triangles (more than _MAX_BOUNDING_DISCS, so both paths are taken) and a
    short path whose ends are often near an obstacle's rim or a wall (where the quick test must defer to GEOS)."""
    obstacles = []
    for _ in range(draw(st.integers(0, 14))):
        cx, cy = draw(st.floats(50.0, 950.0)), draw(st.floats(50.0, 750.0))
        if draw(st.booleans()):
            obstacles.append(StaticObstacle(circle=Circle((cx, cy), draw(st.floats(1.0, 120.0)))))
        else:
            d = draw(st.lists(st.floats(-80.0, 80.0), min_size=4, max_size=4))
            obstacles.append(StaticObstacle(polygon=((cx, cy), (cx + 60.0 + d[0], cy + d[1]),
                                                     (cx + d[2], cy + 60.0 + d[3]))))
    world = World((0.0, 0.0, 1000.0, 800.0), obstacles)
    if obstacles and draw(st.booleans()):  # start at a rim point plus a little: the touching cases
        ring = shapely.get_coordinates(world.obstacles)
        x, y = ring[draw(st.integers(0, len(ring) - 1))]
        p0 = np.array([x + draw(st.floats(-30.0, 30.0)), y + draw(st.floats(-30.0, 30.0))])
    else:
        p0 = np.array([draw(_coord), draw(_coord)])
    p1 = p0 + np.array([draw(st.floats(-45.0, 45.0)), draw(st.floats(-45.0, 45.0))])
    return world, p0, p1, draw(st.sampled_from([0.0, 1e-3, 5.0, 20.0, 23.7]))


@settings(max_examples=600, deadline=None)
@given(_worlds_and_paths())
def test_static_contact_is_geos_answer(case):
    """The quick bound says "clear" only where GEOS says so too: the contact flag (and the episode) is unchanged."""
    world, p0, p1, radius = case
    assert world.static_contact(p0, p1, radius) == _geos_contact(world, p0, p1, radius)


def test_static_contact_quick_test_is_taken_and_deferred():
    """Far from everything the answer comes without GEOS; near a rim, at the walls, with NaN or with many
    obstacles it is GEOS's."""
    obstacles = (StaticObstacle(circle=Circle((300.0, 300.0), 40.0)),
                 StaticObstacle(polygon=((600.0, 100.0), (700.0, 100.0), (650.0, 200.0))))
    w = World((0.0, 0.0, 1000.0, 800.0), obstacles)
    r = 20.0
    assert w._clear_of_everything(np.array([500.0, 500.0]), np.array([520.0, 500.0]), r)
    for p0, p1 in (([300.0, 230.0], [300.0, 245.0]),   # 15 cm from the circle's bounding disc
                   ([300.0, 200.0], [300.0, 261.0]),   # the path ends inside it
                   ([15.0, 400.0], [30.0, 400.0])):    # at the wall
        a, b = np.array(p0), np.array(p1)
        assert not w._clear_of_everything(a, b, r)
        assert w.static_contact(a, b, r) == _geos_contact(w, a, b, r)
    assert w.static_contact(np.array([300.0, 200.0]), np.array([300.0, 261.0]), r)
    nan = np.array([np.nan, 400.0]), np.array([30.0, 400.0])
    assert not w._clear_of_everything(*nan, r)  # GEOS's error, as before
    with pytest.raises(shapely.errors.GEOSException):
        w.static_contact(*nan, r)
    many = World((0.0, 0.0, 1000.0, 800.0), [StaticObstacle(circle=Circle((50.0 + 60.0 * k, 700.0), 5.0))
                                            for k in range(_MAX_BOUNDING_DISCS + 1)])
    assert many.bounding_discs is None
    huge = World((0.0, 0.0, 1e300, 800.0), obstacles)  # built directly: beyond a scenario's numbers, GEOS only
    assert huge.bounding_discs is None and not huge._clear_of_everything(np.array([5e299, 400.0]),
                                                                         np.array([5e299, 420.0]), r)
    assert not many._clear_of_everything(np.array([500.0, 300.0]), np.array([520.0, 300.0]), r)
