"""The ORCA kernel (fuzzynav/pedestrians/_orca.c) against its Python form ON the edges of its predicates (issue #36:
the twin kept, its sameness proved where a random sample almost never lands).

Every comparison, range test and clamp of the kernel is a place where a changed rounding in one form (a sum
regrouped, a product reordered) flips a branch the other form does not flip. Random examples reach such an edge
with probability ~2**-52; these tests put the inputs there: for each predicate, the input value that lands
exactly on its edge (found by construction with exact arithmetic, or by bisection over the floats' order when
the edge is a rounded quantity) and the floats 1 and 2 ulps either side, in exhaustive grids over the inputs
that feed it. The outputs are compared bit for bit (``-0.0`` and NaN signs included). Units: cm, s, cm/s.

In CI (CI=true) the kernel must have been built; the tests call both forms themselves (whatever
``FUZZYNAV_KERNEL`` says), so they compare them in the kernels-off CI pass (``FUZZYNAV_KERNEL=python``) too.
"""

from __future__ import annotations

import itertools
import math
import struct
from collections.abc import Callable
from types import SimpleNamespace

import numpy as np

from fuzzynav.numerics import orca_lp
from fuzzynav.numerics.portable_math import norm2
from fuzzynav.pedestrians import orca as pedestrian_orca
from fuzzynav.pedestrians.orca import PedestrianOrcaConfig, PedestrianOrcaModel
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

