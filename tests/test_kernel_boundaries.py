"""The five compiled kernels against their Python forms ON the edges of their predicates (issue #36: the twin kept,
its sameness proved where a random sample almost never lands).

Every comparison, range test and clamp of a kernel is a place where a changed rounding in one form (a sum
regrouped, a product reordered) flips a branch the other form does not flip. Random examples reach such an edge
with probability ~2**-52; these tests put the inputs there: for each predicate, the input value that lands
exactly on its edge (found by construction with exact arithmetic, or by bisection over the floats' order when
the edge is a rounded quantity) and the floats 1 and 2 ulps either side, in exhaustive grids over the inputs
that feed it. The outputs are compared bit for bit (``-0.0`` and NaN signs included). Units: cm, s, cm/s.

In CI (CI=true) every kernel must have been built; the tests switch the kernels on themselves, so they compare
both forms in the kernels-off CI pass (``FUZZYNAV_KERNEL=python``) too.
"""

from __future__ import annotations

import itertools
import math
import struct
from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
import pytest

import fuzzynav.pedestrians.social_force as sf
from fuzzynav.numerics import compiled, orca_lp
from fuzzynav.numerics import geometry as geo
from fuzzynav.numerics.clearance import segment_point_clearance
from fuzzynav.numerics.portable_math import norm2, sin_cos_deg
from fuzzynav.pedestrians import orca as pedestrian_orca
from fuzzynav.pedestrians.orca import PedestrianOrcaConfig, PedestrianOrcaModel
from fuzzynav.sensing import laser, raycast, tracking
from fuzzynav.sensing.laser import LaserConfig, LaserScan
from fuzzynav.sensing.raycast import cast_rays
from tests.conftest import require_compiled

# -- the edges and the comparison ------------------------------------------------------------------------------


def ulps(x: float, k: int = 2) -> list[float]:
    """``x`` and the ``k`` floats on either side of it, in increasing order."""
    below, above = [], []
    lo = hi = float(x)
    for _ in range(k):
        lo, hi = math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf)
        below.append(lo)
        above.append(hi)
    return [*below[::-1], float(x), *above]


def _order(x: float) -> int:
    """The float's rank among the floats (monotonic; -0.0 and 0.0 share 0)."""
    (i,) = struct.unpack("<q", struct.pack("<d", x))
    return i if i >= 0 else -(i & 0x7FFF_FFFF_FFFF_FFFF)


def _float(rank: int) -> float:
    (x,) = struct.unpack("<d", struct.pack("<Q", rank if rank >= 0 else (-rank) | (1 << 63)))
    return x


def edge(predicate: Callable[[float], bool], lo: float, hi: float) -> float:
    """The float x in (lo, hi] with ``predicate(x) != predicate(x's predecessor)``: where a rounded quantity
    crosses its threshold, found by bisection over the floats' order (``predicate(lo) != predicate(hi)``)."""
    a, b = _order(lo), _order(hi)
    at_lo = predicate(lo)
    assert predicate(hi) != at_lo, "the predicate does not change between lo and hi"
    while b - a > 1:
        m = (a + b) // 2
        if predicate(_float(m)) == at_lo:
            a = m
        else:
            b = m
    return _float(b)


def assert_same_bits(got, want) -> None:
    """Bitwise equality of two results (arrays, floats, tuples or lists of them); a NaN matches a NaN of either sign
    (the kernels document that a NaN's sign bit may differ: nothing observes it, the logs write null)."""
    if isinstance(got, (tuple, list)):
        assert isinstance(want, (tuple, list)) and len(got) == len(want), (got, want)
        for g, w in zip(got, want, strict=True):
            assert_same_bits(g, w)
        return
    g, w = np.asarray(got), np.asarray(want)
    assert g.shape == w.shape and g.dtype == w.dtype, (g, w)
    if g.dtype == np.float64:
        assert np.array_equal(np.isnan(g), np.isnan(w)), (got, want)
        g, w = np.where(np.isnan(g), np.nan, g).view(np.uint64), np.where(np.isnan(w), np.nan, w).view(np.uint64)
    assert np.array_equal(g, w), (got, want)


@pytest.fixture
def both(monkeypatch) -> Callable:
    """``both(fn, *args)``: ``fn(*args)`` with the kernels on and with ``FUZZYNAV_KERNEL=python`` (whatever the
    environment the tests run in)."""
    def run(fn: Callable, *args):
        with monkeypatch.context() as m:
            m.delenv(compiled.KERNEL_ENV, raising=False)
            with np.errstate(all="ignore"):
                on = fn(*args)
            m.setenv(compiled.KERNEL_ENV, "python")
            with np.errstate(all="ignore"):
                off = fn(*args)
        return on, off
    return run


# -- closest approach (fuzzynav/numerics/_closest_approach.c) ----------------------------------------------------


def _perturbed(rel0: tuple[float, float], step: tuple[float, float], k: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Every combination of the four coordinates moved by up to ``k`` ulps: (5**4, 2) arrays for k = 2."""
    grid = np.array(list(itertools.product(*(ulps(c, k) for c in (*rel0, *step)))))
    return np.ascontiguousarray(grid[:, :2]), np.ascontiguousarray(grid[:, 2:])


CLOSEST_APPROACH_EDGES = {
    # s = 0 exactly: the step perpendicular to the relative position (the clamp at 0)
    "perpendicular": ((3.0, 4.0), (-4.0, 3.0)),
    "perpendicular, other side": ((-30.0, 40.0), (-40.0, -30.0)),
    # s = 1 exactly: the closest point at the step's end (the clamp at 1)
    "meets at the end": ((-6.0, -8.0), (6.0, 8.0)),
    # 0 < s < 1 with the distance exactly a collision radius (30 cm at s = 0.5)
    "exactly at a radius": ((30.0, 40.0), (0.0, -80.0)),
    # the relative velocity zero, and a subnormal one (dd > 0 or not; dd underflows to 0 for tiny steps)
    "no relative motion": ((30.0, 40.0), (0.0, 0.0)),
    "a subnormal step": ((30.0, 40.0), (5e-324, -5e-324)),
    "a step whose square underflows": ((1e-160, 0.0), (-1e-160, 1e-170)),
    "signed zeros": ((-0.0, 0.0), (0.0, -0.0)),
}


@pytest.mark.parametrize("name", CLOSEST_APPROACH_EDGES)
def test_closest_approach_on_its_clamps_and_radius(both, name):
    require_compiled(geo._kernel, "_closest_approach")
    rel0, step = _perturbed(*CLOSEST_APPROACH_EDGES[name])
    on, off = both(geo.closest_approach, rel0, step)
    assert_same_bits(on, off)
    if name == "exactly at a radius":
        assert 30.0 in on.tolist()


def test_clearance_ties_zero_moves_and_points_on_the_move(both):
    """segment_point_clearance (the same kernel file): points at equal distances (ties for the minimum), on the
    move itself, at its ends; a move of zero length; moves at ulps from each case."""
    require_compiled(geo._kernel, "_closest_approach")
    start = np.array([10.0, 20.0])
    points = np.array([[10.0, 50.0], [10.0, -10.0], [40.0, 20.0], [-20.0, 20.0], [25.0, 20.0], [10.0, 20.0]])
    ends = np.array(list(itertools.product(ulps(10.0), ulps(20.0))) + list(itertools.product(ulps(40.0), ulps(20.0)))
                    + list(itertools.product(ulps(10.0), ulps(50.0))) + list(itertools.product(ulps(34.0), ulps(52.0))))
    for pts in (points, points[:4], points[[0, 0, 1]], np.vstack([points, [[np.nan, 0.0]]])):
        on, off = both(segment_point_clearance, start, ends, pts)
        assert_same_bits(on, off)


# -- ray casting (fuzzynav/sensing/_raycast.c) ---------------------------------------------------------------------

AXES = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])


def _rays() -> np.ndarray:
    """The four axis directions and directions 1 and 2 ulps off +x (each still of length 1 to rounding)."""
    off = [(math.sqrt(1.0 - e * e), e) for e in (5e-324, 1e-300, 2.220446049250313e-16, -2.220446049250313e-16)]
    return np.ascontiguousarray(np.vstack([AXES, off]))


def _cast_grid(both, segments: np.ndarray, circles: np.ndarray, max_range: float,
               origins: list[tuple[float, float]]) -> None:
    for origin in origins:
        on, off = both(cast_rays, np.array(origin), _rays(), segments.reshape(-1, 4), circles.reshape(-1, 3),
                       max_range)
        assert_same_bits(on, off)


def test_rays_tangent_to_a_circle(both):
    """disc = b² - c exactly 0 (the ray grazes the rim), the circle's centre and radius moved by ulps."""
    require_compiled(raycast._raycast, "_raycast")
    circles = np.array([[cx, cy, r] for cx in ulps(50.0) for cy in ulps(10.0) for r in ulps(10.0)])
    for circle in circles:
        _cast_grid(both, np.zeros((0, 4)), circle, 250.0, [(0.0, 0.0)])


def test_origin_on_a_circle_rim_and_a_circle_behind(both):
    """c = |centre|² - r² exactly 0 (the origin on the rim: inside, range 0, or not), and t = b - √disc at 0."""
    require_compiled(raycast._raycast, "_raycast")
    for cx, cy, r in itertools.product(ulps(6.0), ulps(8.0), ulps(10.0)):
        _cast_grid(both, np.zeros((0, 4)), np.array([cx, cy, r]), 250.0, [(0.0, 0.0)])
        _cast_grid(both, np.zeros((0, 4)), np.array([-cx - 20.0, cy, r]), 250.0, [(0.0, 0.0)])


def test_segments_at_their_ends_parallel_and_of_zero_length(both):
    """u exactly 0 and 1 (a beam through an end), t exactly 0 (the origin on the segment), the cross product at
    the parallel threshold 1e-12 and at 0, zero-length segments: each coordinate at ulps from the edge."""
    require_compiled(raycast._raycast, "_raycast")
    cases = []
    for y in ulps(0.0, 3):
        cases += [(100.0, y, 100.0, 50.0), (100.0, -50.0, 100.0, y), (0.0, y, 0.0, 30.0), (-10.0, 0.0, 10.0, y)]
    for ey in ulps(1e-12, 3) + ulps(-1e-12, 3):
        cases += [(50.0, -1.0, 150.0, -1.0 + ey), (50.0, 0.0, 150.0, ey)]
    for x in ulps(100.0):
        cases += [(x, 0.0, x, 0.0), (x, 5e-324, 100.0, 0.0)]
    for case in cases:
        _cast_grid(both, np.array(case), np.zeros((0, 3)), 250.0, [(0.0, 0.0), (-0.0, -0.0)])


def test_hits_at_the_range_and_the_culling_reach(both):
    """A hit at exactly max_range (not nearer than the cap: no hit), and objects at exactly the culling reach
    (kept or dropped), each at ulps either side."""
    require_compiled(raycast._raycast, "_raycast")
    reach = raycast.cull_reach(250.0)
    for x in ulps(250.0) + ulps(reach):
        _cast_grid(both, np.array([x, -50.0, x, 50.0]), np.zeros((0, 3)), 250.0, [(0.0, 0.0)])
        _cast_grid(both, np.array([x, 0.0, x + 10.0, 0.0]), np.zeros((0, 3)), 250.0, [(0.0, 0.0)])
        _cast_grid(both, np.zeros((0, 4)), np.array([x + 10.0, 0.0, 10.0]), 250.0, [(0.0, 0.0)])
    for max_range in ulps(100.0):
        _cast_grid(both, np.array([100.0, -5.0, 100.0, 5.0]), np.array([110.0, 0.0, 10.0]), max_range, [(0.0, 0.0)])


def test_equal_distances_the_lower_index_wins(both):
    """Ties: coincident segments, a segment and a circle at the same distance, two circles, in either order."""
    require_compiled(raycast._raycast, "_raycast")
    seg = np.array([100.0, -20.0, 100.0, 20.0])
    circle = np.array([110.0, 0.0, 10.0])
    for segments, circles in [(np.vstack([seg, seg]), np.zeros((0, 3))),
                              (seg, circle), (np.zeros((0, 4)), np.vstack([circle, circle])),
                              (np.vstack([seg, seg[[2, 3, 0, 1]]]), np.vstack([circle, [105.0, 0.0, 5.0]]))]:
        for x in ulps(0.0):
            _cast_grid(both, segments, circles, 250.0, [(x, 0.0), (0.0, x)])


def test_a_laser_frame_at_its_noise_clip(both):
    """laser.scan's noise clip: a noisy range exactly 0 and exactly the range's predecessor, at ulps either side
    (the draws of a stand-in noise stream)."""
    require_compiled(raycast._raycast, "_raycast")
    config = LaserConfig(range_cm=250.0, beams=8, noise_std_cm=1.0)
    hit = 100.0
    top = math.nextafter(250.0, 0.0)
    draws = np.array(ulps(-hit) + ulps(top - hit) + ulps(0.0) + ulps(150.0 + 1e-13))
    segments = np.array([[hit, -1e6, hit, 1e6], [-hit, -1e6, -hit, 1e6], [-1e6, hit, 1e6, hit],
                         [-1e6, -hit, 1e6, -hit]])

    class Draws:
        def __init__(self, values: np.ndarray) -> None:
            self.values = values

        def draw(self, mean: float, std: float, size: int) -> np.ndarray:
            return self.values[:size].copy()

    def frame(values: np.ndarray) -> tuple:
        f = laser.scan(config, 0.0, 0.0, 0.0, segments, np.zeros((0, 3)), np.zeros((0, 3)), Draws(values))
        return f.ranges, f.directions, f.labels, f.xy

    for start in range(0, len(draws), config.beams):
        chunk = np.resize(draws[start:], config.beams)
        on, off = both(frame, chunk)
        assert_same_bits(on, off)


# -- tracking (fuzzynav/sensing/_tracking.c) -----------------------------------------------------------------------


def _scan(points: np.ndarray, origin: tuple[float, float] = (0.0, 0.0), returned: np.ndarray | None = None
          ) -> LaserScan:
    """A frame whose beams end at ``points`` (n, 2) cm (all returned unless ``returned`` says otherwise)."""
    n = len(points)
    ranges = np.where(returned if returned is not None else True, norm2(points - origin), 500.0)
    frame = LaserScan(ranges=ranges, directions=np.zeros((n, 2)), labels=np.zeros(n, dtype=np.int64),
                      origin=origin, range_cm=500.0)
    frame.__dict__["xy"] = np.ascontiguousarray(points, dtype=np.float64)
    return frame


def _detections(scan: LaserScan, config: tracking.TrackerConfig) -> list:
    return [(d.x, d.y, d.radius, d.beams) for d in tracking.detect(scan, config)]


def _arc(n: int, radius: float, centre: tuple[float, float], first_deg: float, step_deg: float) -> np.ndarray:
    angles = np.deg2rad(first_deg + step_deg * np.arange(n))
    return np.column_stack([centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)])


def test_clusters_split_exactly_at_the_gap(both):
    """Two arcs whose nearest beams are exactly ``cluster_gap_cm`` apart (the link length as both forms compute
    it) and 1 and 2 ulps either side: one cluster or two; also across the wrap-around from the last beam to the
    first, and with a beam that did not return between them."""
    require_compiled(tracking._tracking, "_tracking")
    a = _arc(5, 20.0, (200.0, 0.0), 160.0, 10.0)
    b = _arc(5, 20.0, (200.0, 0.0), 215.0, 10.0)
    for points in (np.vstack([a, b]), np.vstack([b, a])):
        link = float(norm2(points[5] - points[4]))
        wrap = float(norm2(points[0] - points[-1]))
        for gap in ulps(link) + ulps(wrap):
            config = tracking.TrackerConfig(cluster_gap_cm=gap)
            for returned in (None, np.arange(10) != 7):
                on, off = both(_detections, _scan(points, returned=returned), config)
                assert_same_bits(on, off)


def test_clusters_at_min_points_extent_radius_and_fit_limits(both):
    """A cluster of exactly ``min_points`` beams (and one fewer and more), its extent exactly
    2 · ``max_radius_cm``, its fitted radius exactly ``max_radius_cm``, its RMS residual exactly
    ``max_fit_rms_cm`` — each limit at ulps either side."""
    require_compiled(tracking._tracking, "_tracking")
    rng = np.random.default_rng(36)
    points = _arc(6, 20.0, (150.0, 30.0), 150.0, 12.0) + rng.normal(0.0, 0.3, (6, 2))
    scan = _scan(points)
    _, _, radius, rms = tracking.fit_disc(points)
    extent = float(norm2(points.max(axis=0) - points.min(axis=0)))
    for min_points in (5, 6, 7):
        on, off = both(_detections, scan, tracking.TrackerConfig(min_points=min_points, cluster_gap_cm=20.0))
        assert_same_bits(on, off)
    for max_radius in ulps(extent / 2.0) + ulps(radius):
        on, off = both(_detections, scan, tracking.TrackerConfig(max_radius_cm=max_radius, cluster_gap_cm=20.0))
        assert_same_bits(on, off)
    for max_rms in ulps(rms):
        on, off = both(_detections, scan, tracking.TrackerConfig(max_fit_rms_cm=max_rms, cluster_gap_cm=20.0))
        assert_same_bits(on, off)
        assert on == [] if max_rms < rms else len(on) == 1


def test_degenerate_disc_fits(both):
    """Kasa's fit on collinear clusters (det exactly 0), coincident points, and a point moved off the line
    across the degenerate-fit threshold det > 1e-12 (suu + svv)² (found by bisection), at ulps either side."""
    require_compiled(tracking._tracking, "_tracking")
    line = np.array([[100.0, 0.0], [100.0, 5.0], [100.0, 10.0], [100.0, 15.0]])
    same = np.array([[100.0, 0.0]] * 4)

    def bent(dx: float) -> np.ndarray:
        p = line.copy()
        p[1, 0] += dx
        return p

    def fits(dx: float) -> bool:
        return math.isfinite(tracking.fit_disc(bent(dx))[2])

    flip = edge(fits, 0.0, 1.0)
    config = tracking.TrackerConfig(max_radius_cm=1e300, max_fit_rms_cm=1e300, cluster_gap_cm=30.0)
    for points in [line, same, *(bent(dx) for dx in ulps(flip, 3))]:
        on, off = both(_detections, _scan(points), config)
        assert_same_bits(on, off)


# -- social force (fuzzynav/pedestrians/_social_force.c) -----------------------------------------------------------


def _forces(x, v, pref, o_pos0, o_vel, radii, segments, circles, config, tau=0.0):
    args = (np.array(x, float).reshape(-1, 2), np.array(v, float).reshape(-1, 2),
            np.array(pref, float).reshape(-1, 2), np.array(o_pos0, float).reshape(-1, 2),
            np.array(o_vel, float).reshape(-1, 2), tau, np.array(radii, float),
            np.array(segments, float).reshape(-1, 4), np.array(circles, float).reshape(-1, 3), config,
            sin_cos_deg(config.fov_deg)[1])
    with np.errstate(all="ignore"):
        want = sf._substep_force_numpy(*args)
    assert_same_bits(sf._substep_force_kernel(*args), want)


SF_CONFIGS = [sf.SocialForceConfig(), sf.SocialForceConfig(step_ahead="desired_direction"),
              sf.SocialForceConfig(fov_deg=90.0, fov_weight=0.0)]


def _sf_kernel() -> None:
    require_compiled(sf._kernel, "_social_force")


@pytest.mark.parametrize("config", SF_CONFIGS)
def test_social_force_coincident_and_on_the_step_ahead(config):
    """r = 0 (another at the very place), r - v_β Δt = 0 (at its place Δt ahead) and u² - s² = 0 (b = 0, on the
    segment between), each coordinate at ulps either side."""
    _sf_kernel()
    o_vel = (0.0, 5.0)  # Δt = 2 s: the step ahead is (0, 10)
    for px, py in itertools.product(ulps(0.0), ulps(0.0) + ulps(10.0) + ulps(3.0)):
        _forces([(px, py)], [(1.0, 0.0)], [(100.0, 0.0)], [(0.0, 0.0)], [o_vel], [25.0], [], [], config)


@pytest.mark.parametrize("config", SF_CONFIGS)
def test_social_force_b_at_its_floor_and_the_field_of_view(config):
    """b crossing ``B_FLOOR_CM`` and the field-of-view test ``towards >= |f| cos φ`` flipping: both edges found by
    bisection over one coordinate, then grids at ulps either side."""
    _sf_kernel()
    other_vel = np.array([0.0, 5.0])
    step = config.step_time_s

    def b_of(px: float) -> float:
        rel = np.array([px, 3.0])
        r1, r2 = norm2(rel), norm2(rel - other_vel * step)
        s, u = norm2(other_vel) * step, r1 + r2
        return 0.5 * float(np.sqrt(max(u * u - s * s, 0.0)))

    flip_b = edge(lambda px: b_of(px) > sf.B_FLOOR_CM, 0.0, 10.0)
    cos_fov = sin_cos_deg(config.fov_deg)[1]
    rel = np.array([[40.0, 30.0]])

    def seen(pref_y: float) -> bool:
        f = sf.agent_repulsion(rel, np.zeros((1, 2)), config.agent_strength_cm2_s2, config.agent_range_cm,
                               config.step_time_s)[0]
        e = np.array([100.0, pref_y]) / norm2(np.array([100.0, pref_y]))
        return bool(-(e[0] * f[0] + e[1] * f[1]) >= float(norm2(f)) * cos_fov)

    lo, hi = (-1e4, 1e4) if seen(-1e4) != seen(1e4) else (-1e4, 0.0)
    flip_fov = edge(seen, lo, hi)
    for px in ulps(flip_b, 3):
        _forces([(px, 3.0)], [(1.0, 0.0)], [(100.0, 0.0)], [(0.0, 0.0)], [other_vel], [25.0], [], [], config)
    for pref_y in ulps(flip_fov, 3):
        _forces([(40.0, 30.0)], [(0.0, 0.0)], [(100.0, pref_y)], [(0.0, 0.0)], [(0.0, 0.0)], [25.0], [], [], config)


@pytest.mark.parametrize("config", SF_CONFIGS)
def test_social_force_walls_at_contact(config):
    """A pedestrian whose disc touches a wall or circle exactly (gap 0), stands on a wall's line (no direction),
    at a wall's end (the foot's clamp), at a circle's centre, by a zero-length wall: ulps either side."""
    _sf_kernel()
    segments = [(0.0, 0.0, 100.0, 0.0), (200.0, 50.0, 200.0, 50.0)]
    circles = [(300.0, 0.0, 20.0)]
    places = ([(50.0, y) for y in ulps(25.0) + ulps(0.0)] + [(x, 10.0) for x in ulps(0.0) + ulps(100.0)]
              + [(x, 0.0) for x in ulps(345.0) + ulps(300.0)] + [(200.0, y) for y in ulps(75.0) + ulps(50.0)])
    for p in places:
        for pref in [(0.0, 0.0), (-0.0, 5e-324), (100.0, 0.0)]:
            _forces([p], [(0.0, 0.0)], [pref], [], [], [25.0], segments, circles, config)


# -- ORCA pedestrians (fuzzynav/pedestrians/_orca.c) -----------------------------------------------------------------


def _orca_model(config: PedestrianOrcaConfig, radii: list[float]) -> PedestrianOrcaModel:
    model = PedestrianOrcaModel.__new__(PedestrianOrcaModel)
    model.config = config
    model._obstacles = None
    model.radii = np.array(radii, dtype=float)
    return model


WORLD = SimpleNamespace(bounds=(0.0, 0.0, 1000.0, 1000.0),
                        polygons=(np.array([[400.0, 400.0], [600.0, 400.0], [600.0, 600.0], [400.0, 600.0]]),),
                        circles=np.array([[800.0, 800.0, 20.0]]))


def _substep(config: PedestrianOrcaConfig, x, v, pref, radii, max_speed, others=(), world=WORLD, h=0.25) -> None:
    """One substep of the own pedestrians ``x`` among ``others`` (position, velocity, radius) by both forms."""
    x, v, pref = (np.array(a, float).reshape(-1, 2) for a in (x, v, pref))
    o_pos = np.array([o[0] for o in others], float).reshape(-1, 2)
    o_vel = np.array([o[1] for o in others], float).reshape(-1, 2)
    o_rad = [o[2] for o in others]
    model = _orca_model(config, radii)
    args = (x, np.vstack([x, o_pos]), np.vstack([v, o_vel]), np.array(list(radii) + o_rad, float),
            [0.5] * len(x) + [1.0] * len(others), v, pref, np.array(max_speed, float), world, h)
    assert_same_bits(model._substep_compiled(*args), model._substep_python(*args))


def _orca_kernel() -> None:
    require_compiled(pedestrian_orca._kernel, "_orca")


def test_orca_touching_discs_and_overlap_cases():
    """dist² = (r1 + r2)² exactly (touching: the horizon's program or the overlap's), w = 0 in the overlap
    (the relative velocity exactly the cut-off's centre), coincident centres: each coordinate at ulps."""
    _orca_kernel()
    config = PedestrianOrcaConfig()
    for ox, oy in itertools.product(ulps(130.0), ulps(140.0)):
        _substep(config, [(100.0, 100.0)], [(10.0, 0.0)], [(100.0, 0.0)], [25.0], [130.0],
                 [((ox, oy), (-10.0, 0.0), 25.0)])
    # overlapping, the relative velocity (v - v_other) exactly rel / dt: w = 0
    for vx in ulps(-40.0) + ulps(40.0):
        _substep(config, [(100.0, 100.0)], [(vx, 0.0)], [(50.0, 0.0)], [25.0], [130.0],
                 [((110.0, 100.0), (0.0, 0.0), 25.0)], h=0.25)
    for ox in ulps(100.0):
        _substep(config, [(100.0, 100.0)], [(10.0, 0.0)], [(50.0, 0.0)], [25.0], [130.0],
                 [((ox, 100.0), (0.0, 0.0), 25.0)])


def test_orca_cut_off_arc_or_leg_at_the_time_horizon():
    """The relative velocity crossing from the cut-off arc (1/τ) to a leg — w·p < 0 and (w·p)² > r² |w|², the
    time horizon's boundary — found by bisection over the other's velocity, and the neighbour distance exactly
    ``neighbor_dist_cm``: ulps either side."""
    _orca_kernel()
    config = PedestrianOrcaConfig(time_horizon_s=2.0)
    p, r = (200.0, 30.0), 50.0
    inv_tau = 1.0 / config.time_horizon_s

    def arc(vx: float, vy: float) -> bool:  # orca_lp.orca_line's test, for the relative velocity (vx, -vy)
        w = (vx - inv_tau * p[0], -vy - inv_tau * p[1])
        w_dot_p = w[0] * p[0] + w[1] * p[1]
        return w_dot_p < 0.0 and w_dot_p * w_dot_p > r * r * (w[0] * w[0] + w[1] * w[1])

    for vx in (10.0, 3.7, 12.34, 0.1, 7.77):  # the edge for several own velocities: its rounding differs
        for vy in ulps(edge(lambda vy, vx=vx: arc(vx, vy), 0.0, 1e4), 3):
            _substep(config, [(100.0, 100.0)], [(vx, 0.0)], [(100.0, 0.0)], [25.0], [130.0],
                     [((300.0, 130.0), (0.0, vy), 25.0)])
    d = float(norm2(np.array([300.0, 130.0]) - np.array([100.0, 100.0])))
    for dist in ulps(d):
        _substep(PedestrianOrcaConfig(neighbor_dist_cm=dist), [(100.0, 100.0)], [(10.0, 0.0)], [(100.0, 0.0)],
                 [25.0], [130.0], [((300.0, 130.0), (-50.0, 0.0), 25.0)])


def test_orca_linear_program_edges():
    """The linear program: a constraint line tangent to the speed disc (feasible or not: 2-D program or the 3-D
    fallback, found by bisection over the top speed), exactly parallel constraints (two identical neighbours),
    opposite ones squeezing a pedestrian (infeasible: the fallback's bisector of parallel lines), nearly
    parallel ones at the |sin| threshold (bisection), and the preferred speed exactly the top speed."""
    _orca_kernel()
    config = PedestrianOrcaConfig()
    me, v, pref = (100.0, 100.0), (10.0, 0.0), (100.0, 0.0)
    other = ((180.0, 100.0), (-200.0, 0.0), 25.0)
    line = orca_lp.orca_line((80.0, 0.0), (210.0, 0.0), 50.0, config.time_horizon_s, 0.25, 1.0, v)

    def falls_back(top: float) -> bool:
        return orca_lp.choose_velocity([line], 0, top, pref).fallback

    flip = edge(falls_back, 1e-6, 1e4) if falls_back(1e-6) != falls_back(1e4) else 10.0
    for top in ulps(flip, 3):
        _substep(config, [me], [v], [pref], [25.0], [top], [other])
    _substep(config, [me], [v], [pref], [25.0], [130.0], [other, other])
    for y in ulps(100.0):
        _substep(config, [me], [v], [(0.0, 0.0)], [25.0], [5.0],
                 [((150.0, y), (-300.0, 0.0), 25.0), ((50.0, 100.0), (300.0, 0.0), 25.0)])

    def parallel(dy: float) -> bool:
        a = orca_lp.orca_line((80.0, 0.0), (210.0, 0.0), 50.0, config.time_horizon_s, 0.25, 1.0, v)
        b = orca_lp.orca_line((80.0, dy), (210.0, 0.0), 50.0, config.time_horizon_s, 0.25, 1.0, v)
        return abs(orca_lp._det(a.direction, b.direction)) <= orca_lp._PARALLEL

    flip = edge(parallel, 0.0, 1.0)
    for dy in ulps(flip, 3):
        _substep(config, [me], [v], [pref], [25.0], [130.0], [other, ((180.0, 100.0 + dy), (-200.0, 0.0), 25.0)])
    for top in ulps(100.0):
        _substep(config, [me], [v], [(60.0, 80.0)], [25.0], [top], [other])


def test_orca_walls_and_circles_at_reach_and_contact():
    """A pedestrian at exactly its radius from a wall, from a polygon's vertex (its foot exactly at the vertex)
    and from a circle's rim; an edge and a circle exactly at the reach time_horizon_obst · top speed + radius
    (found by bisection over the top speed): ulps either side."""
    _orca_kernel()
    config = PedestrianOrcaConfig()
    for x in ulps(25.0):
        _substep(config, [(x, 500.0)], [(-10.0, 0.0)], [(-50.0, 10.0)], [25.0], [130.0])
    for x, y in itertools.product(ulps(385.0), ulps(380.0)):  # 25 cm from the vertex (400, 400)
        _substep(config, [(x, y)], [(10.0, 10.0)], [(50.0, 50.0)], [25.0], [130.0])
    for x in ulps(400.0 - 25.0) + ulps(400.0):
        _substep(config, [(x, 500.0)], [(10.0, 0.0)], [(50.0, 0.0)], [25.0], [130.0])
    for x in ulps(800.0 - 45.0) + ulps(800.0):
        _substep(config, [(x, 800.0)], [(10.0, 0.0)], [(50.0, 0.0)], [25.0], [130.0])

    def wall_within(top: float) -> bool:
        model = _orca_model(config, [25.0])
        return bool(model._edges_within_reach(model._obstacles_of(WORLD), np.array([[300.0, 500.0]]),
                                              np.array([top]))[0])

    for top in ulps(edge(wall_within, 0.0, 1e4), 3):
        _substep(config, [(300.0, 500.0)], [(10.0, 0.0)], [(50.0, 0.0)], [25.0], [top])
    # an oblique edge, the pedestrian's distance to it rounded (the foot on it inexact): the reach crossing it (the
    # edge joining the pedestrian's list), for several positions along it
    world = SimpleNamespace(bounds=WORLD.bounds, polygons=(np.array([[400.0, 300.0], [700.0, 350.0], [450.0, 500.0]]),),
                            circles=np.zeros((0, 3)))
    model = _orca_model(config, [25.0])
    obstacles = model._obstacles_of(world)
    (oblique,) = [k for k, p in enumerate(obstacles.points.tolist()) if p == [400.0, 300.0]]
    for place in [(560.3, 260.7), (431.1, 257.9), (650.05, 301.3), (512.34567, 268.8), (553.0736224220667, 277.0278),
                  (501.0761775227262, 265.39958693835453)]:
        def oblique_within(top: float, place=place) -> bool:
            return oblique in model._edges_within_reach(obstacles, np.array([place]), np.array([top]))[0]

        for top in ulps(edge(oblique_within, 0.0, 1e4), 3):
            _substep(config, [place], [(10.0, 0.0)], [(50.0, 0.0)], [25.0], [top], world=world)
    gap = float(norm2(np.array([800.0, 800.0]) - np.array([700.0, 800.0]))) - 20.0 - 25.0
    for top in ulps(gap / config.time_horizon_obst_s, 3):
        _substep(config, [(700.0, 800.0)], [(10.0, 0.0)], [(50.0, 0.0)], [25.0], [top])

