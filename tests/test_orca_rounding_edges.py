"""The ORCA kernel (fuzzynav/pedestrians/_orca.c) against its Python form where a regrouped sum or product in one
form flips a branch the other does not (issue #36: the twin kept, its sameness proved on the boundary cases).

``tests/test_orca_boundaries.py`` puts inputs on each predicate's edge by bisection over one input and steps
1-3 ulps either side. That misses a regrouping whenever one ulp of the input moves the compared quantities by
more than the two groupings differ: both groupings then flip between the same two inputs. Here, for each
predicate, a seeded and bounded search bisects to the edge as the C form computes it, from many base inputs,
and keeps the inputs 0-3 ulps from it where a plausible regrouping of the compared quantities decides the other
way (an alternative grouping of the same formula: a product reassociated, a sum distributed, a reciprocal
multiplied). At those inputs the two forms must still give the same bits: the cases the search finds on this
machine's IEEE doubles (the same on every CPU) are kept below as fixed cases, and the search runs as a test
too. Units: cm, s, cm/s.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
import pytest

from fuzzynav.numerics import geometry as geo
from fuzzynav.numerics import orca_lp
from fuzzynav.numerics.portable_math import hypot
from fuzzynav.pedestrians import orca as pedestrian_orca
from fuzzynav.pedestrians.orca import PedestrianOrcaConfig
from tests.conftest import require_compiled
from tests.test_orca_boundaries import WORLD, _orca_model, _substep, edge, ulps

ME = (100.0, 100.0)  # the own pedestrian's position (cm) in the neighbour cases


@pytest.fixture(autouse=True)
def _orca_kernel() -> None:
    require_compiled(pedestrian_orca._kernel, "_orca")


def _disagree(reference: Callable[[float], bool], groupings: dict[str, Callable[[float], bool]], at: float
              ) -> list[tuple[str, float]]:
    """The (grouping, input) pairs among the inputs 0-3 ulps from ``at`` where a grouping decides otherwise than
    ``reference``."""
    return [(name, x) for x in ulps(at, 3) for name, grouping in groupings.items() if grouping(x) != reference(x)]


def _first(found: list[tuple[str, tuple]], keep: int) -> list[tuple[str, tuple]]:
    """The first ``keep`` cases of each grouping in ``found`` (the forms are compared on those: each comparison
    runs a substep in both)."""
    count: dict[str, int] = {}
    kept = []
    for name, case in found:
        count[name] = count.get(name, 0) + 1
        if count[name] <= keep:
            kept.append((name, case))
    return kept


# -- the cut-off arc or a leg (orca_lp.orca_line): w·p < 0 and (w·p)² > r² |w|² ----------------------------------


def _arc_groupings(p: tuple[float, float], rel_vel: tuple[float, float], r: float, inv_tau: float
                   ) -> dict[str, bool]:
    """orca_line's arc/leg decision for the relative position ``p`` (cm), relative velocity ``rel_vel`` (cm/s),
    combined radius ``r`` (cm) and 1/τ ``inv_tau`` (1/s): ``"C"`` as both forms compute it, then regroupings."""
    px, py = p
    r_sq = r * r
    w = (rel_vel[0] - inv_tau * px, rel_vel[1] - inv_tau * py)
    w_sq = w[0] * w[0] + w[1] * w[1]
    w_dot_p = w[0] * px + w[1] * py
    w_dot_p2 = (rel_vel[0] * px + rel_vel[1] * py) - inv_tau * (px * px + py * py)
    w_len = hypot(w[0], w[1])
    return {
        "C": w_dot_p < 0.0 and w_dot_p * w_dot_p > r_sq * w_sq,
        "r*(r*|w|^2)": w_dot_p < 0.0 and w_dot_p * w_dot_p > r * (r * w_sq),
        "v.p - |p|^2/tau": w_dot_p2 < 0.0 and w_dot_p2 * w_dot_p2 > r_sq * w_sq,
        "(w.p)*(w.p/|w|^2) > r^2": w_dot_p < 0.0 and w_dot_p * (w_dot_p / w_sq) > r_sq,
        "|w|^2 as hypot^2": w_dot_p < 0.0 and w_dot_p * w_dot_p > r_sq * (w_len * w_len),
        "(r*w)^2": w_dot_p < 0.0 and w_dot_p * w_dot_p > (r * w[0]) * (r * w[0]) + (r * w[1]) * (r * w[1]),
    }


ARC_CONFIG = PedestrianOrcaConfig(time_horizon_s=2.0)


def _arc_case(other: tuple[float, float], v: tuple[float, float], radii: tuple[float, float]) -> None:
    """Both forms for the own pedestrian at ME moving at ``v`` (cm/s) by a standing other at ``other`` (cm),
    preferring to head for it at more than its top speed: its ORCA line, through about ``v``, binds."""
    pref = (2.0 * (other[0] - ME[0]), 2.0 * (other[1] - ME[1]))
    _substep(ARC_CONFIG, [ME], [v], [pref], [radii[0]], [130.0], [(other, (0.0, 0.0), radii[1])])


def _arc_search(n: int, seed: int = 36) -> list[tuple[str, tuple]]:
    """Arc/leg cases (grouping, (other, v, radii)) from ``n`` seeded base inputs. The relative velocity is the own
    velocity v = λ·(a leg's direction): the decision flips where v passes the leg's tangent point on the cut-off
    circle, where the arc's and the leg's lines meet through v itself (so the line binds the program); λ is
    bisected to the C form's edge and the inputs 0-3 ulps from it kept where a regrouping decides otherwise."""
    rng = np.random.default_rng(seed)
    inv_tau = 1.0 / ARC_CONFIG.time_horizon_s
    found = []
    for _ in range(n):
        radii = (float(rng.uniform(15.0, 35.0)), float(rng.uniform(15.0, 35.0)))
        r = radii[0] + radii[1]
        other = (ME[0] + float(rng.uniform(100.0, 300.0)), ME[1] + float(rng.uniform(-150.0, 150.0)))
        p = (other[0] - ME[0], other[1] - ME[1])
        dist_sq = p[0] * p[0] + p[1] * p[1]
        leg = math.sqrt(dist_sq - r * r)
        side = 1.0 if rng.uniform() < 0.5 else -1.0
        d = ((p[0] * leg - side * p[1] * r) / dist_sq, (side * p[0] * r + p[1] * leg) / dist_sq)
        tangent = leg * inv_tau  # |the tangent point| (cm/s)

        def groupings(lam: float, p=p, d=d, r=r) -> dict[str, bool]:
            v = (lam * d[0], lam * d[1])
            return _arc_groupings(p, (v[0] - 0.0, v[1] - 0.0), r, inv_tau)

        def arc(lam: float, groupings=groupings) -> bool:
            return groupings(lam)["C"]

        lo, hi = 0.5 * tangent, 1.5 * tangent
        if arc(lo) == arc(hi):
            continue
        alternatives = {name: (lambda lam, name=name, g=groupings: g(lam)[name])
                        for name in groupings(lo) if name != "C"}
        found += [(name, (other, (lam * d[0], lam * d[1]), radii))
                  for name, lam in _disagree(arc, alternatives, edge(arc, lo, hi))]
    return found


# found by _first(_arc_search(1000), 4) (float.hex: the exact inputs (other, v, radii))
ARC_CASES = {
    "v.p - |p|^2/tau": [
        (("0x1.7ac438147f8a4p+8", "0x1.1c102e775767bp+6"),
         ("0x1.0c6123b7341e5p+7", "-0x1.14f910e9177e8p+5"),
         ("0x1.29cd767c3a9f2p+4", "0x1.6f6f8e3147e53p+4")),
        (("0x1.1d0440428381bp+8", "-0x1.a5f003033be00p-2"),
         ("0x1.8ad4534fa29b9p+6", "-0x1.d6098ac094185p+4"),
         ("0x1.47c0b277ff649p+4", "0x1.6fa89e3fc0520p+4")),
        (("0x1.8198a136c7ad4p+8", "0x1.9e18f1289229ep+5"),
         ("0x1.19975a86e14d7p+7", "0x1.13a218483cd62p+3"),
         ("0x1.04f3d3753f158p+5", "0x1.07bef0d73a33cp+5")),
        (("0x1.206b96b5d6b1ap+8", "0x1.4d34fbb0e2ab3p+7"),
         ("0x1.4945a542360cep+6", "0x1.a0bfb2e08bc16p+5"),
         ("0x1.9df1e4d58e790p+4", "0x1.29b0f38fe2077p+4")),
    ],
    "(r*w)^2": [
        (("0x1.968905d85d757p+7", "0x1.16cefb7066a5ap+6"),
         ("0x1.ec1a89355dcf1p+4", "-0x1.102d9728bc987p+5"),
         ("0x1.f72420275caa8p+4", "0x1.8d74b84a2652fp+4")),
        (("0x1.5c524739e67c6p+8", "0x1.743c91cddac1ap+7"),
         ("0x1.b38310269cdb3p+6", "0x1.0e9dd04e70993p+6"),
         ("0x1.a8466e8eb9571p+4", "0x1.f6547342fe5aap+4")),
        (("0x1.6a7da2166f8d3p+8", "0x1.619768076251dp+7"),
         ("0x1.d500305bc26dcp+6", "0x1.001b70cf079f5p+6"),
         ("0x1.0bf2171dc1be7p+5", "0x1.8e8bc10d2181cp+4")),
        (("0x1.c9a4251cd0bd2p+7", "-0x1.7c8d64d8aedf8p+3"),
         ("0x1.2a7d4b1438531p+6", "-0x1.7739620abcc83p+4"),
         ("0x1.0f6bd9340ef1ap+5", "0x1.119019617e0edp+5")),
    ],
    "|w|^2 as hypot^2": [
        (("0x1.f6371fce5a7c6p+7", "0x1.0364fb0a204e0p+4"),
         ("0x1.43e3f13df768ap+6", "-0x1.5018db469b9a3p+4"),
         ("0x1.2177962b14e5cp+4", "0x1.9111e9828bbd0p+4")),
        (("0x1.6179c1ce30cdap+8", "0x1.ef3f0db343ccep+6"),
         ("0x1.efc3a9515f624p+6", "-0x1.b2ff0ff512263p+3"),
         ("0x1.08e5733a95fd2p+5", "0x1.2315077e68c5cp+4")),
        (("0x1.5c524739e67c6p+8", "0x1.743c91cddac1ap+7"),
         ("0x1.b38310269cdb3p+6", "0x1.0e9dd04e70993p+6"),
         ("0x1.a8466e8eb9571p+4", "0x1.f6547342fe5aap+4")),
        (("0x1.6a7da2166f8d3p+8", "0x1.619768076251dp+7"),
         ("0x1.d500305bc26dcp+6", "0x1.001b70cf079f5p+6"),
         ("0x1.0bf2171dc1be7p+5", "0x1.8e8bc10d2181cp+4")),
    ],
    "(w.p)*(w.p/|w|^2) > r^2": [
        (("0x1.e147b47120000p+7", "0x1.f1712901dc07cp+4"),
         ("0x1.28841125b3233p+6", "-0x1.adb61c73347d8p+3"),
         ("0x1.79540adb437f6p+4", "0x1.3278144d63bfap+4")),
        (("0x1.21e21b09ba0a6p+8", "0x1.7f6d6cacd22e2p+6"),
         ("0x1.65a17208c3bbcp+6", "-0x1.74db132cec816p+4"),
         ("0x1.68cd9ea7ad18dp+4", "0x1.55512bb10bf1ap+4")),
        (("0x1.942973dc472c6p+7", "0x1.37127164d530bp+6"),
         ("0x1.3fb33a4bde388p+5", "0x1.03448c077867fp+4"),
         ("0x1.cdcbe2204596fp+4", "0x1.e196a8137d9abp+4")),
        (("0x1.282eceb640932p+8", "0x1.260033732a30ep+6"),
         ("0x1.5aabba2464ef0p+6", "-0x1.363dc41384363p+5"),
         ("0x1.719e4527a7b9bp+4", "0x1.06b41dd2b324bp+5")),
    ],
    "r*(r*|w|^2)": [
        (("0x1.0b952dd8e5ae6p+8", "0x1.96c7e8d11cd80p+6"),
         ("0x1.2f5e41cea6378p+6", "-0x1.8223b8929a34ep+4"),
         ("0x1.68da8c675177ep+4", "0x1.de0bcc123aec4p+4")),
        (("0x1.6a7da2166f8d3p+8", "0x1.619768076251dp+7"),
         ("0x1.d500305bc26dcp+6", "0x1.001b70cf079f5p+6"),
         ("0x1.0bf2171dc1be7p+5", "0x1.8e8bc10d2181cp+4")),
        (("0x1.c9a4251cd0bd2p+7", "-0x1.7c8d64d8aedf8p+3"),
         ("0x1.2a7d4b1438531p+6", "-0x1.7739620abcc83p+4"),
         ("0x1.0f6bd9340ef1ap+5", "0x1.119019617e0edp+5")),
        (("0x1.21e21b09ba0a6p+8", "0x1.7f6d6cacd22e2p+6"),
         ("0x1.65a17208c3bbcp+6", "-0x1.74db132cec816p+4"),
         ("0x1.68cd9ea7ad18dp+4", "0x1.55512bb10bf1ap+4")),
    ],
}


@pytest.mark.parametrize("name", ARC_CASES)
def test_orca_arc_or_leg_where_a_regrouping_decides_otherwise(name):
    for case in ARC_CASES[name]:
        _arc_case(*(tuple(float.fromhex(c) for c in pair) for pair in case))


def test_orca_arc_or_leg_search():
    """The search finds inputs where each regrouping decides otherwise, and the two forms agree on all of them."""
    found = _first(_arc_search(1000), 4)
    names = {name for name, _ in found}
    assert names == set(_arc_groupings((1.0, 0.0), (0.0, 0.0), 0.5, 0.5)) - {"C"}, names
    for _, case in found:
        _arc_case(*case)


# -- an edge within reach (PedestrianOrcaModel._edges_within_reach): |x − foot|² < reach² ----------------------

OBLIQUE_WORLD = SimpleNamespace(bounds=WORLD.bounds,
                                polygons=(np.array([[400.0, 300.0], [700.0, 350.0], [450.0, 500.0]]),),
                                circles=np.zeros((0, 3)))
OBLIQUE = ((400.0, 300.0), (700.0, 350.0))  # the edge's ends (cm); the obstacle is on its left
REACH_CONFIG = PedestrianOrcaConfig()


def _reach_groupings(x: tuple[float, float], top: float, r: float) -> dict[str, bool]:
    """Whether the pedestrian at ``x`` (cm, its foot on the edge between its ends) of radius ``r`` (cm) and top
    speed ``top`` (cm/s) has OBLIQUE within reach: ``"C"`` as both forms compute it, then regroupings."""
    (a0, a1), (b0, b1) = OBLIQUE
    ex, ey = b0 - a0, b1 - a1
    fax, fay = x[0] - a0, x[1] - a1
    length_sq = ex * ex + ey * ey
    dot = fax * ex + fay * ey
    along = dot / length_sq
    reach = REACH_CONFIG.time_horizon_obst_s * top + r
    reach_sq = reach * reach

    def foot_sq(along: float) -> float:
        fx, fy = x[0] - (a0 + along * ex), x[1] - (a1 + along * ey)
        return fx * fx + fy * fy

    fx, fy = fax - along * ex, fay - along * ey
    foot_len = math.sqrt(foot_sq(along))
    return {
        "C": foot_sq(along) < reach_sq,
        "(x-a) - along*e": fx * fx + fy * fy < reach_sq,
        "|x-a|^2 - along^2*|e|^2": (fax * fax + fay * fay) - along * along * length_sq < reach_sq,
        "|x-foot|^2 as hypot^2": foot_len * foot_len < reach_sq,
        "along = (x-a).e * (1/|e|^2)": foot_sq(dot * (1.0 / length_sq)) < reach_sq,
    }


def _reach_case(place: tuple[float, float], top: tuple[float]) -> None:
    """Both forms for the pedestrian at ``place`` below OBLIQUE, moving along it, preferring to walk at it: the
    edge's line (a leg's) binds."""
    _substep(REACH_CONFIG, [place], [(100.0, 0.0)], [(-30.0, 80.0)], [25.0], [top[0]], world=OBLIQUE_WORLD)


def _reach_search(n: int, seed: int = 36) -> list[tuple[str, tuple]]:
    """Reach cases (grouping, (place, (top,))) from ``n`` seeded places at 30-200 cm below OBLIQUE: the top speed
    bisected to the C form's edge (checked against _edges_within_reach itself), the inputs 0-3 ulps from it kept
    where a regrouping decides otherwise."""
    rng = np.random.default_rng(seed)
    (a0, a1), (b0, b1) = OBLIQUE
    normal = (b1 - a1, -(b0 - a0))
    scale = 1.0 / math.hypot(*normal)
    model = _orca_model(REACH_CONFIG, [25.0])
    obstacles = model._obstacles_of(OBLIQUE_WORLD)
    (k,) = [k for k, p in enumerate(obstacles.points.tolist()) if p == list(OBLIQUE[0])]
    found = []
    for _ in range(n):
        t, dist = float(rng.uniform(0.05, 0.95)), float(rng.uniform(30.0, 200.0)) * scale
        place = (a0 + t * (b0 - a0) + dist * normal[0], a1 + t * (b1 - a1) + dist * normal[1])

        def within(top: float, place=place) -> bool:
            return _reach_groupings(place, top, 25.0)["C"]

        at = edge(within, 0.0, 1e4)
        for top in ulps(at, 3):
            listed = k in model._edges_within_reach(obstacles, np.array([place]), np.array([top]))[0]
            assert listed == within(top), (place, top)
        alternatives = {name: (lambda top, name=name, place=place: _reach_groupings(place, top, 25.0)[name])
                        for name in _reach_groupings(place, 1.0, 25.0) if name != "C"}
        found += [(name, (place, (top,))) for name, top in _disagree(within, alternatives, at)]
    return found


# found by _first(_reach_search(300), 4) (float.hex: the exact inputs (place, (top,)))
REACH_CASES = {
    "|x-foot|^2 as hypot^2": [
        (("0x1.50452e7d8bdccp+9", "0x1.eaf9e3902ed85p+7"), ("0x1.d6e24c433e2e5p+3",)),
        (("0x1.e704a5365170bp+8", "0x1.9142f2972f2a8p+7"), ("0x1.176eee0fe4351p+4",)),
        (("0x1.216ff9d425e76p+9", "0x1.f84621aecea2bp+7"), ("0x1.4a5bf864cabc5p+3",)),
        (("0x1.1d3ff55bb8e46p+9", "0x1.427065b7123c3p+7"), ("0x1.bfc0421b4eaf6p+4",)),
    ],
    "|x-a|^2 - along^2*|e|^2": [
        (("0x1.35503b9d211dcp+9", "0x1.b3e231370f4afp+7"), ("0x1.26072c2df5f68p+4",)),
        (("0x1.0409bfd7b691dp+9", "0x1.b664ca26631b3p+7"), ("0x1.dc7143f3a2fd3p+3",)),
        (("0x1.0409bfd7b691dp+9", "0x1.b664ca26631b3p+7"), ("0x1.dc7143f3a2fd4p+3",)),
        (("0x1.0409bfd7b691dp+9", "0x1.b664ca26631b3p+7"), ("0x1.dc7143f3a2fd5p+3",)),
    ],
    "(x-a) - along*e": [
        (("0x1.35503b9d211dcp+9", "0x1.b3e231370f4afp+7"), ("0x1.26072c2df5f69p+4",)),
        (("0x1.ea56b52d59b0dp+8", "0x1.0424ef3d7e523p+8"), ("0x1.754ffd169f363p+2",)),
        (("0x1.ea56b52d59b0dp+8", "0x1.0424ef3d7e523p+8"), ("0x1.754ffd169f364p+2",)),
        (("0x1.ea56b52d59b0dp+8", "0x1.0424ef3d7e523p+8"), ("0x1.754ffd169f365p+2",)),
    ],
    "along = (x-a).e * (1/|e|^2)": [
        (("0x1.37ef288ffd6ebp+9", "0x1.f6e0a762c13c4p+7"), ("0x1.7e1b6c499f379p+3",)),
        (("0x1.37ef288ffd6ebp+9", "0x1.f6e0a762c13c4p+7"), ("0x1.7e1b6c499f37ap+3",)),
        (("0x1.04a59cc64529bp+9", "0x1.ba7c3634f0715p+7"), ("0x1.d0cf1a401d3f9p+3",)),
        (("0x1.04a59cc64529bp+9", "0x1.ba7c3634f0715p+7"), ("0x1.d0cf1a401d3fap+3",)),
    ],
}


@pytest.mark.parametrize("name", REACH_CASES)
def test_orca_edge_within_reach_where_a_regrouping_decides_otherwise(name):
    for case in REACH_CASES[name]:
        _reach_case(*(tuple(float.fromhex(c) for c in pair) for pair in case))


def test_orca_edge_within_reach_search():
    """The search finds inputs where each regrouping decides otherwise, and the two forms agree on all of them."""
    found = _first(_reach_search(300), 4)
    names = {name for name, _ in found}
    assert names == set(_reach_groupings((0.0, 0.0), 1.0, 25.0)) - {"C"}, names
    for _, case in found:
        _reach_case(*case)


# -- touching discs (orca_lp.orca_line): |p|² > (r1 + r2)², the time horizon's program or the overlap's ----------


def _touch_groupings(p: tuple[float, float], r1: float, r2: float) -> dict[str, bool]:
    """Whether orca_line takes the time horizon's branch (not the overlap's) for the other at ``p`` (cm) and the
    radii ``r1``, ``r2`` (cm): ``"C"`` as both forms compute it, then regroupings."""
    px, py = p
    r = r1 + r2
    return {
        "C": px * px + py * py > r * r,
        "px^2 > r^2 - py^2": px * px > r * r - py * py,
        "hypot(p) > r": hypot(px, py) > r,
        "r1^2 + 2 r1 r2 + r2^2": px * px + py * py > r1 * r1 + 2.0 * r1 * r2 + r2 * r2,
        "(px - r)(px + r) + py^2 > 0": (px - r) * (px + r) + py * py > 0.0,
    }


def _touch_case(other: tuple[float, float], radii: tuple[float, float]) -> None:
    """Both forms for the own pedestrian at ME walking at the standing other at ``other`` (cm), preferring to go on:
    the line (of the overlap or of the time horizon) binds."""
    pref = (2.0 * (other[0] - ME[0]), 2.0 * (other[1] - ME[1]))
    _substep(PedestrianOrcaConfig(), [ME], [(0.25 * pref[0], 0.25 * pref[1])], [pref], [radii[0]], [130.0],
             [(other, (0.0, 0.0), radii[1])])


def _touch_search(n: int, seed: int = 36) -> list[tuple[str, tuple]]:
    """Touching cases (grouping, (other, radii)) from ``n`` seeded radii and offsets across: the other's x
    bisected to the C form's edge, the inputs 0-3 ulps from it kept where a regrouping decides otherwise."""
    rng = np.random.default_rng(seed)
    found = []
    for _ in range(n):
        r1, r2 = float(rng.uniform(15.0, 35.0)), float(rng.uniform(15.0, 35.0))
        oy = ME[1] + float(rng.uniform(-0.9, 0.9)) * (r1 + r2)

        def groupings(ox: float, oy=oy, r1=r1, r2=r2) -> dict[str, bool]:
            return _touch_groupings((ox - ME[0], oy - ME[1]), r1, r2)

        def apart(ox: float, groupings=groupings) -> bool:
            return groupings(ox)["C"]

        alternatives = {name: (lambda ox, name=name, g=groupings: g(ox)[name])
                        for name in groupings(ME[0]) if name != "C"}
        found += [(name, ((ox, oy), (r1, r2)))
                  for name, ox in _disagree(apart, alternatives, edge(apart, ME[0], ME[0] + 2.0 * (r1 + r2)))]
    return found


# found by _first(_touch_search(300), 4) (float.hex: the exact inputs (other, radii))
TOUCH_CASES = {
    "r1^2 + 2 r1 r2 + r2^2": [
        (("0x1.2f6f5f112ba7ap+7", "0x1.942081af72577p+6"), ("0x1.711561b96ca43p+4", "0x1.ca8fbd1ca705ep+4")),
        (("0x1.0a4488bcee1aap+7", "0x1.14827c6e614d6p+7"), ("0x1.46299811ece84p+4", "0x1.e3957f2f90ccbp+4")),
        (("0x1.1a05e0b02d59bp+7", "0x1.6bb8e193ced75p+6"), ("0x1.ac46acf8ebd7fp+4", "0x1.e785ce404d334p+3")),
        (("0x1.1f3f08c8e3cc9p+7", "0x1.0625544981936p+7"), ("0x1.02d23697a0feep+5", "0x1.534ac2da91731p+4")),
    ],
    "(px - r)(px + r) + py^2 > 0": [
        (("0x1.0a4488bcee1aap+7", "0x1.14827c6e614d6p+7"), ("0x1.46299811ece84p+4", "0x1.e3957f2f90ccbp+4")),
        (("0x1.27db672fe7a37p+7", "0x1.838adc784e637p+6"), ("0x1.b45dd4d30fbfcp+4", "0x1.4c1b6ab8ce9bdp+4")),
        (("0x1.f199276b25c7ap+6", "0x1.8d39a3f3a932ep+5"), ("0x1.52df498e86716p+4", "0x1.16253c59d303ep+5")),
        (("0x1.0ab6bfe19bf78p+7", "0x1.8ab49e9b7e037p+6"), ("0x1.19713002665f0p+4", "0x1.f960a91d3cf74p+3")),
    ],
    "hypot(p) > r": [
        (("0x1.10f70c009e4f8p+7", "0x1.863bf20e5d923p+6"), ("0x1.00d39c8e20884p+4", "0x1.483300fa81323p+4")),
        (("0x1.3ffbb89b8f998p+7", "0x1.763dceaf6382fp+6"), ("0x1.f6fe40e98ac72p+4", "0x1.ce6321e8cc6aep+4")),
        (("0x1.204645427b995p+7", "0x1.93e78de2e6644p+5"), ("0x1.15015471f4344p+5", "0x1.fb40aee638041p+4")),
        (("0x1.f504d9c0b0b7bp+6", "0x1.f17c0614b2ec6p+6"), ("0x1.3869db198dcdap+4", "0x1.f241814fe88dcp+3")),
    ],
    "px^2 > r^2 - py^2": [
        (("0x1.f199276b25c7ap+6", "0x1.8d39a3f3a932ep+5"), ("0x1.52df498e86716p+4", "0x1.16253c59d303ep+5")),
        (("0x1.18fd03df78a85p+7", "0x1.1afa30c05bf92p+7"), ("0x1.a33e4b888a7c6p+4", "0x1.fc5acb4567d67p+4")),
        (("0x1.00a5a3ffc49c6p+7", "0x1.eb9dbd4d092f2p+6"), ("0x1.198c2b6ef233ap+4", "0x1.2d42a990ac6cdp+4")),
        (("0x1.e92aee1b9c53cp+6", "0x1.1252f320fc381p+6"), ("0x1.2a31ecfff4ccdp+4", "0x1.3e2f8df7a87e1p+4")),
    ],
}


@pytest.mark.parametrize("name", TOUCH_CASES)
def test_orca_touching_discs_where_a_regrouping_decides_otherwise(name):
    for case in TOUCH_CASES[name]:
        _touch_case(*(tuple(float.fromhex(c) for c in pair) for pair in case))


def test_orca_touching_discs_search():
    """The search finds inputs where each regrouping decides otherwise, and the two forms agree on all of them."""
    found = _first(_touch_search(300), 4)
    names = {name for name, _ in found}
    assert names == set(_touch_groupings((1.0, 0.0), 1.0, 1.0)) - {"C"}, names
    for _, case in found:
        _touch_case(*case)


# -- a static circle within reach (PedestrianOrcaModel._substep_python's ``close``): gap − r < reach ---------------

CIRCLE = (500.0, 500.0, 20.3)  # a static circle (x, y, radius; cm) far from the walls
CIRCLE_WORLD = SimpleNamespace(bounds=WORLD.bounds, polygons=(), circles=np.array([CIRCLE]))


def _circle_groupings(x: tuple[float, float], top: float, r: float) -> dict[str, bool]:
    """Whether the static circle CIRCLE is within reach of the pedestrian at ``x`` (cm) of radius ``r`` (cm) and top
    speed ``top`` (cm/s): ``"C"`` as both forms compute it (geometry.away_from_static's gap), then regroupings."""
    fx, fy = x[0] - CIRCLE[0], x[1] - CIRCLE[1]
    d = math.sqrt(fx * fx + fy * fy)
    gap = d - CIRCLE[2]
    tau = REACH_CONFIG.time_horizon_obst_s
    reach = tau * top + r
    return {
        "C": gap - r < reach,
        "gap < reach + r": gap < reach + r,
        "d - (R + r) < reach": d - (CIRCLE[2] + r) < reach,
        "gap - r - r < tau*top": gap - r - r < tau * top,
    }


def _circle_case(place: tuple[float, float], top: tuple[float]) -> None:
    """Both forms for the pedestrian at ``place`` walking past CIRCLE, preferring to walk at it: the circle's line (a
    leg's) binds."""
    to = (CIRCLE[0] - place[0], CIRCLE[1] - place[1])
    _substep(REACH_CONFIG, [place], [(-to[1], to[0])], [to], [25.0], [top[0]], world=CIRCLE_WORLD)


def _circle_search(n: int, seed: int = 36) -> list[tuple[str, tuple]]:
    """Circle-reach cases (grouping, (place, (top,))) from ``n`` seeded places 60-220 cm from CIRCLE's rim: the top
    speed bisected to the C form's edge (the gap checked against geometry.away_from_static's), the inputs 0-3 ulps
    from it kept where a regrouping decides otherwise."""
    rng = np.random.default_rng(seed)
    found = []
    for _ in range(n):
        angle, dist = float(rng.uniform(0.0, 2.0 * math.pi)), float(rng.uniform(80.0, 240.0))
        place = (CIRCLE[0] + dist * math.cos(angle), CIRCLE[1] + dist * math.sin(angle))
        gaps, _ = geo.away_from_static(np.array([place]), np.zeros((0, 4)), np.array([CIRCLE]))
        fx, fy = place[0] - CIRCLE[0], place[1] - CIRCLE[1]
        assert float(gaps[0, 0]) == math.sqrt(fx * fx + fy * fy) - CIRCLE[2]

        def within(top: float, place=place) -> bool:
            return _circle_groupings(place, top, 25.0)["C"]

        alternatives = {name: (lambda top, name=name, place=place: _circle_groupings(place, top, 25.0)[name])
                        for name in _circle_groupings(place, 1.0, 25.0) if name != "C"}
        found += [(name, (place, (top,))) for name, top in _disagree(within, alternatives, edge(within, 0.0, 1e4))]
    return found


# found by _first(_circle_search(300), 4) (float.hex: the exact inputs (place, (top,)))
CIRCLE_CASES = {
    "d - (R + r) < reach": [
        (("0x1.1d5f5515e8306p+8", "0x1.c36bb402ab1d9p+8"), ("0x1.df38b3098abf9p+4",)),
        (("0x1.1d5f5515e8306p+8", "0x1.c36bb402ab1d9p+8"), ("0x1.df38b3098abfap+4",)),
        (("0x1.131c5d31a0b81p+9", "0x1.44a0fca931e5dp+9"), ("0x1.16fa2c8ea7ccfp+4",)),
        (("0x1.dba4892afdd7dp+8", "0x1.5e288561dc41fp+9"), ("0x1.a4c63c23251e9p+4",)),
    ],
    "gap - r - r < tau*top": [
        (("0x1.06e80a8204e89p+9", "0x1.370586a1974a7p+9"), ("0x1.5c6f8d0a72927p+3",)),
        (("0x1.11c2e3e5f924fp+9", "0x1.2258fb9c4d9bfp+9"), ("0x1.2add847d75ef1p+2",)),
        (("0x1.cf35e2231ebd5p+8", "0x1.513d669c8c47cp+9"), ("0x1.59a6ca71c0d01p+4",)),
        (("0x1.fb2d19c365d8dp+8", "0x1.2235942278c3ep+9"), ("0x1.0b3757fdb8e94p+1",)),
    ],
    "gap < reach + r": [
        (("0x1.0afd774a6f9d9p+9", "0x1.2c193422dba5ap+9"), ("0x1.c66d1da53df28p+2",)),
        (("0x1.19f7ce16a502cp+9", "0x1.3e40a1b6588a3p+9"), ("0x1.016558dbbf377p+4",)),
        (("0x1.88152196f1808p+8", "0x1.e4ce5d8459be5p+8"), ("0x1.ef208101a8a9bp+2",)),
        (("0x1.9a7c4f74b6f0ap+8", "0x1.118cdda595fc9p+9"), ("0x1.8ae0baab3091bp+2",)),
    ],
}


@pytest.mark.parametrize("name", CIRCLE_CASES)
def test_orca_circle_within_reach_where_a_regrouping_decides_otherwise(name):
    for case in CIRCLE_CASES[name]:
        _circle_case(*(tuple(float.fromhex(c) for c in pair) for pair in case))


def test_orca_circle_within_reach_search():
    """The search finds inputs where each regrouping decides otherwise, and the two forms agree on all of them."""
    found = _first(_circle_search(300), 4)
    names = {name for name, _ in found}
    assert names == set(_circle_groupings((0.0, 0.0), 1.0, 25.0)) - {"C"}, names
    for _, case in found:
        _circle_case(*case)


# -- nearly parallel constraints in the linear program (orca_lp._lp1): |d × d_other| <= _PARALLEL ---------------

PARALLEL_CONFIG = PedestrianOrcaConfig()
AT_WALL = (500.0, 20.0)  # overlapping the bottom wall (radius 25 cm): its hard line is y >= 0, along +x exactly


def _parallel_den(eps: float, gap: float) -> float:
    """_lp1's ``denominator`` (the sine of the angle; no unit) of the neighbour's line against the bottom wall's: the
    pedestrian at AT_WALL, standing, the other (radius 25 cm) standing ``gap`` (cm) beyond touching straight above it
    but moving at (``eps``, 0) cm/s. The neighbour's line (the time horizon's arc) runs ~``gap``/τ from the origin at
    an angle ~``eps``/|w| to the wall's line, whose direction (1, -0) makes the denominator the neighbour direction's
    y exactly (any float near _PARALLEL, not a difference of rounded products). The lines by orca_lp itself."""
    p = (AT_WALL[0] - AT_WALL[0], (AT_WALL[1] + 50.0 + gap) - AT_WALL[1])
    line = orca_lp.orca_line(p, (0.0 - eps, 0.0 - 0.0), 25.0 + 25.0, PARALLEL_CONFIG.time_horizon_s, 0.25, 1.0,
                             (0.0, 0.0))
    return orca_lp._det(line.direction, (1.0, -0.0))


def _parallel_case(gap: tuple[float], eps: tuple[float]) -> None:
    """Both forms for the pedestrian at AT_WALL preferring (50, 100) cm/s: the neighbour's line binds, and where it
    meets the wall's line (non-parallel) or not (parallel) moves the velocity along it."""
    _substep(PARALLEL_CONFIG, [AT_WALL], [(0.0, 0.0)], [(50.0, 100.0)], [25.0], [60.0],
             [((AT_WALL[0], AT_WALL[1] + 50.0 + gap[0]), (eps[0], 0.0), 25.0)])


def test_orca_nearly_parallel_lines_meeting_in_the_speed_disc():
    """The neighbour's line at |sin| = _PARALLEL from a hard line, 0-3 ulps either side (parallel, or meeting it
    inside the speed disc, which moves the velocity), for seeded gaps of 0.5-2 · 1e-7 cm.
    Regroupings of the comparison itself cannot part the forms here: the determinant of a unit direction with an
    axis is one coordinate exactly (its two products are exact), and |d| <= P, d² <= P², |d|/P <= 1 and |d|·1e9 <= 1
    decide alike on every float near P (rounding is monotone, and adjacent floats keep distinct squares and
    quotients); the edge itself (<= against <) is what this pins."""
    rng = np.random.default_rng(36)
    for gap in rng.uniform(0.5e-7, 2e-7, 8).tolist():
        at = edge(lambda eps, gap=gap: abs(_parallel_den(eps, gap)) <= orca_lp._PARALLEL, 0.0, 1e-3)
        for eps in ulps(at, 3):
            _parallel_case((gap,), (eps,))
    # the regroupings of the comparison decide alike on the 2 · 4096 floats round _PARALLEL
    limit = orca_lp._PARALLEL
    below = above = limit
    for _ in range(4096):
        below, above = math.nextafter(below, 0.0), math.nextafter(above, 1.0)
        for den in (below, above):
            assert (den <= limit) == (den * den <= limit * limit) == (den / limit <= 1.0) == (den * 1e9 <= 1.0)


# -- an edge already covered by an earlier edge's line (orca_lp._covered): det(c − point, d) − r/τ >= −_COVERED ----

# a polygon's bottom: two oblique collinear edges A-B and B-C (cm; counter-clockwise, the obstacle above), one end
# bent: the later edge's discs then lie on either side of the earlier edge's line
BENT = ((300.0, 290.0), (500.0, 300.0), (700.0, 310.0))


def _bent_world(end_y: float, near: float) -> SimpleNamespace:
    """The polygon with C (``near`` = 0) or A (``near`` = 1) moved to y = ``end_y`` (cm)."""
    a, b, c = BENT
    a, c = ((a[0], end_y), c) if near else (a, (c[0], end_y))
    polygon = np.array([a, b, c, (700.0, 500.0), (300.0, 500.0)])
    return SimpleNamespace(bounds=WORLD.bounds, polygons=(polygon,), circles=np.zeros((0, 3)))


def _covered_groupings(place: tuple[float, float], end_y: float, near: float, v: tuple[float, float]
                       ) -> dict[str, bool]:
    """Whether the nearer edge's line covers the other edge, its bent end's disc ``c1`` (``near``: A bent, the
    pedestrian under B-C) or ``c2`` (C bent, under A-B), for the pedestrian (radius 25 cm) at ``place`` moving at
    ``v`` (cm/s); the earlier line by orca_lp.edge_lines itself. ``"C"`` as both forms compute _covered, then
    regroupings."""
    vertices = orca_lp.obstacle_vertices(orca_lp.world_chains(WORLD.bounds, _bent_world(end_y, near).polygons))
    kb = vertices.points.index(BENT[1])
    first, later = (kb, vertices.previous[kb]) if near else (vertices.previous[kb], kb)
    lines = orca_lp.edge_lines(vertices, [first], place, v, 25.0, REACH_CONFIG.time_horizon_obst_s)
    names = ("C", "det >= margin - COVERED", "det + COVERED >= margin")
    if not lines:
        return dict.fromkeys(names, False)  # the nearer edge adds no line (a foreign leg): nothing covers
    (line,) = lines
    inv_tau = 1.0 / REACH_CONFIG.time_horizon_obst_s
    margin = inv_tau * 25.0
    (px, py), (dx, dy) = line.point, line.direction
    ends = [(vertices.points[k][0] - place[0], vertices.points[k][1] - place[1])
            for k in (later, vertices.next[later])]

    def each(test: Callable[[float], bool]) -> bool:
        return all(test((inv_tau * rel[0] - px) * dy - (inv_tau * rel[1] - py) * dx) for rel in ends)

    cov = orca_lp._COVERED
    return dict(zip(names, (each(lambda det: det - margin >= -cov), each(lambda det: det >= margin - cov),
                            each(lambda det: det + cov >= margin)), strict=True))


def _covered_case(place: tuple[float, float], bent: tuple[float, float], v: tuple[float, float]) -> None:
    """Both forms for the pedestrian at ``place`` below the polygon bent as ``bent`` = (end_y, near), moving at ``v``
    (cm/s), preferring to walk at the bent end."""
    end_y, near = bent
    end = (300.0 if near else 700.0, end_y)
    _substep(REACH_CONFIG, [place], [v], [(end[0] - place[0], end[1] - place[1])], [25.0], [60.0],
             world=_bent_world(end_y, near))


def _covered_search(n: int, seed: int = 36) -> list[tuple[str, tuple]]:
    """Covered cases (grouping, (place, (end_y, near), v)) from ``n`` seeded places and velocities under either edge:
    the bent end's y bisected to the C form's edge (its disc 1e-9 cm/s past the nearer edge's line), the inputs 0-3
    ulps from it kept where a regrouping decides otherwise."""
    rng = np.random.default_rng(seed)
    found = []
    for i in range(n):
        near = float(i % 2)
        place = (float(rng.uniform(520.0, 680.0) if near else rng.uniform(320.0, 480.0)),
                 float(rng.uniform(230.0, 270.0)))
        v = (float(rng.uniform(-80.0, 80.0)), float(rng.uniform(0.0, 60.0)))
        straight = BENT[0][1] if near else BENT[2][1]

        def covered(end_y: float, place=place, near=near, v=v) -> bool:
            return _covered_groupings(place, end_y, near, v)["C"]

        if covered(straight - 1.0) == covered(straight + 1.0):
            continue  # the nearer edge's line is a leg's, or none: it covers the other edge however bent, or never
        alternatives = {name: (lambda end_y, name=name, place=place, near=near, v=v:
                               _covered_groupings(place, end_y, near, v)[name])
                        for name in _covered_groupings(place, straight, near, v) if name != "C"}
        at = edge(covered, straight - 1.0, straight + 1.0)
        found += [(f"{name}, {'A' if near else 'C'} bent", (place, (end_y, near), v))
                  for name, end_y in _disagree(covered, alternatives, at)]
    return found


# found by _first(_covered_search(300), 4) (float.hex: the exact inputs (place, (end_y, near), v))
COVERED_CASES = {
    "det >= margin - COVERED, A bent": [
        (("0x1.1139344410d9ep+9", "0x1.d2d30d934d01cp+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("-0x1.f5a2d3c93bd80p+1", "0x1.7cf4ef0909316p+5")),
        (("0x1.0e5c4c009997cp+9", "0x1.cf2c1523a79eep+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("-0x1.c31e6bfe82300p+1", "0x1.0e03ed09f68acp+5")),
        (("0x1.3f544e9f8d7bep+9", "0x1.d3fc8ffafad16p+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("-0x1.abeac853ccae8p+3", "0x1.b4d7146ecaab8p+5")),
        (("0x1.356bc182af6bep+9", "0x1.d196358219c55p+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("0x1.f9f12051bf600p-1", "0x1.8949e8b55e4eep+4")),
    ],
    "det + COVERED >= margin, A bent": [
        (("0x1.1139344410d9ep+9", "0x1.d2d30d934d01cp+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("-0x1.f5a2d3c93bd80p+1", "0x1.7cf4ef0909316p+5")),
        (("0x1.0e5c4c009997cp+9", "0x1.cf2c1523a79eep+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("-0x1.c31e6bfe82300p+1", "0x1.0e03ed09f68acp+5")),
        (("0x1.3f544e9f8d7bep+9", "0x1.d3fc8ffafad16p+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("-0x1.abeac853ccae8p+3", "0x1.b4d7146ecaab8p+5")),
        (("0x1.356bc182af6bep+9", "0x1.d196358219c55p+7"),
         ("0x1.21ffffffea7f9p+8", "0x1.0000000000000p+0"),
         ("0x1.f9f12051bf600p-1", "0x1.8949e8b55e4eep+4")),
    ],
    "det >= margin - COVERED, C bent": [
        (("0x1.9b93b8747ed17p+8", "0x1.ec5d6fd1ff218p+7"),
         ("0x1.35ffffffea7f9p+8", "0x0.0p+0"),
         ("0x1.e5039ca99cc38p+3", "0x1.9e4f1af6e67fap+5")),
        (("0x1.c3212c9991aa4p+8", "0x1.fd546db96e6fep+7"),
         ("0x1.35ffffffea7f9p+8", "0x0.0p+0"),
         ("-0x1.77e7213354542p+4", "0x1.7fce0ac89cc39p+5")),
        (("0x1.b91228ee392e0p+8", "0x1.e47f07cee1a89p+7"),
         ("0x1.35ffffffea7f9p+8", "0x0.0p+0"),
         ("-0x1.54f1f739488ccp+4", "0x1.bae8aba8ec05ep+5")),
    ],
    "det + COVERED >= margin, C bent": [
        (("0x1.9b93b8747ed17p+8", "0x1.ec5d6fd1ff218p+7"),
         ("0x1.35ffffffea7f9p+8", "0x0.0p+0"),
         ("0x1.e5039ca99cc38p+3", "0x1.9e4f1af6e67fap+5")),
        (("0x1.c3212c9991aa4p+8", "0x1.fd546db96e6fep+7"),
         ("0x1.35ffffffea7f9p+8", "0x0.0p+0"),
         ("-0x1.77e7213354542p+4", "0x1.7fce0ac89cc39p+5")),
        (("0x1.b91228ee392e0p+8", "0x1.e47f07cee1a89p+7"),
         ("0x1.35ffffffea7f9p+8", "0x0.0p+0"),
         ("-0x1.54f1f739488ccp+4", "0x1.bae8aba8ec05ep+5")),
    ],
}


@pytest.mark.parametrize("name", COVERED_CASES)
def test_orca_edge_covered_where_a_regrouping_decides_otherwise(name):
    for case in COVERED_CASES[name]:
        _covered_case(*(tuple(float.fromhex(c) for c in pair) for pair in case))


def test_orca_edge_covered_search():
    """The search finds inputs where each regrouping decides otherwise (for either end's disc), and the two forms
    agree on all of them."""
    found = _first(_covered_search(300), 4)
    assert {name for name, _ in found} == {f"{name}, {end} bent" for end in "AC"
                                           for name in ("det >= margin - COVERED", "det + COVERED >= margin")}
    for _, case in found:
        _covered_case(*case)


# -- the cut-off disc or a leg of an edge's velocity obstacle (orca_lp.edge_lines): t_left = (v − c_left)·left < 0 ---


def _left_groupings(place: tuple[float, float], v: tuple[float, float]) -> dict[str, bool]:
    """Whether the velocity ``v`` (cm/s) of the pedestrian (radius 25 cm) at ``place`` (cm) below OBLIQUE projects
    before the start of the left leg of OBLIQUE's velocity obstacle (t_left < 0; at 0 edge_lines takes the cut-off
    disc's line or the leg's): ``"C"`` as both forms compute it, then regroupings."""
    inv_tau = 1.0 / REACH_CONFIG.time_horizon_obst_s
    rel1 = (OBLIQUE[0][0] - place[0], OBLIQUE[0][1] - place[1])
    left = orca_lp._leg_left(rel1, rel1[0] * rel1[0] + rel1[1] * rel1[1], 25.0)
    left_cut = (inv_tau * rel1[0], inv_tau * rel1[1])
    from_left = (v[0] - left_cut[0], v[1] - left_cut[1])
    return {
        "C": from_left[0] * left[0] + from_left[1] * left[1] < 0.0,
        "v.left - c_left.left": (v[0] * left[0] + v[1] * left[1]) - (left_cut[0] * left[0] + left_cut[1] * left[1])
        < 0.0,
        "c_left = rel / tau": (v[0] - rel1[0] / REACH_CONFIG.time_horizon_obst_s) * left[0]
        + (v[1] - rel1[1] / REACH_CONFIG.time_horizon_obst_s) * left[1] < 0.0,
    }


def _left_case(place: tuple[float, float], v: tuple[float, float]) -> None:
    """Both forms for the pedestrian at ``place`` moving at ``v`` (cm/s) and preferring to walk at OBLIQUE's first
    end: the line at the velocity obstacle's left end binds."""
    to = (OBLIQUE[0][0] - place[0], OBLIQUE[0][1] - place[1])
    _substep(REACH_CONFIG, [place], [v], [to], [25.0], [60.0], world=OBLIQUE_WORLD)


def _left_search(n: int, seed: int = 36) -> list[tuple[str, tuple]]:
    """Left-end cases (grouping, (place, v)) from ``n`` seeded places 40-150 cm below OBLIQUE and velocities: the
    velocity's x bisected to the C form's edge, the inputs 0-3 ulps from it kept where a regrouping decides
    otherwise."""
    rng = np.random.default_rng(seed)
    (a0, a1), (b0, b1) = OBLIQUE
    normal = (b1 - a1, -(b0 - a0))
    scale = 1.0 / math.hypot(*normal)
    found = []
    for _ in range(n):
        t, dist = float(rng.uniform(0.05, 0.95)), float(rng.uniform(40.0, 150.0)) * scale
        place = (a0 + t * (b0 - a0) + dist * normal[0], a1 + t * (b1 - a1) + dist * normal[1])
        vy = float(rng.uniform(-40.0, 40.0))

        def before(vx: float, place=place, vy=vy) -> bool:
            return _left_groupings(place, (vx, vy))["C"]

        if before(-300.0) == before(300.0):
            continue
        alternatives = {name: (lambda vx, name=name, place=place, vy=vy: _left_groupings(place, (vx, vy))[name])
                        for name in _left_groupings(place, (0.0, vy)) if name != "C"}
        at = edge(before, -300.0, 300.0)
        found += [(name, (place, (vx, vy))) for name, vx in _disagree(before, alternatives, at)]
    return found


# found by _first(_left_search(300), 4) (float.hex: the exact inputs (place, v))
LEFT_CASES = {
    "v.left - c_left.left": [
        (("0x1.dd8c6ea5ac8cbp+8", "0x1.c7ece938ab6f4p+7"), ("-0x1.7c501e5549116p+2", "0x1.f81b008330414p+4")),
        (("0x1.dd8c6ea5ac8cbp+8", "0x1.c7ece938ab6f4p+7"), ("-0x1.7c501e5549115p+2", "0x1.f81b008330414p+4")),
        (("0x1.22fc47ce0ae31p+9", "0x1.8051b23e86be1p+7"), ("-0x1.b7634a0b2c39ep+5", "-0x1.450db2e3ddd12p+4")),
        (("0x1.22fc47ce0ae31p+9", "0x1.8051b23e86be1p+7"), ("-0x1.b7634a0b2c39dp+5", "-0x1.450db2e3ddd12p+4")),
    ],
    "c_left = rel / tau": [
        (("0x1.22fc47ce0ae31p+9", "0x1.8051b23e86be1p+7"), ("-0x1.b7634a0b2c39ep+5", "-0x1.450db2e3ddd12p+4")),
        (("0x1.f4aaadafe9203p+8", "0x1.fc37044ff2795p+7"), ("-0x1.63f42ba64d2afp+4", "-0x1.4282a34f619a0p+0")),
        (("0x1.fc0a7f3613169p+8", "0x1.8122dff1a442ap+7"), ("-0x1.a02822f5cf2bbp+3", "0x1.0cc29ce792a62p+5")),
        (("0x1.f0cafbd9c6f87p+8", "0x1.a896329b39014p+7"), ("-0x1.2712d17164280p+3", "0x1.1286e1b380ac6p+5")),
    ],
}


@pytest.mark.parametrize("name", LEFT_CASES)
def test_orca_edge_cut_off_or_leg_where_a_regrouping_decides_otherwise(name):
    for case in LEFT_CASES[name]:
        _left_case(*(tuple(float.fromhex(c) for c in pair) for pair in case))


def test_orca_edge_cut_off_or_leg_search():
    """The search finds inputs where each regrouping decides otherwise, and the two forms agree on all of them."""
    found = _first(_left_search(300), 4)
    assert {name for name, _ in found} == set(_left_groupings((500.0, 200.0), (0.0, 0.0))) - {"C"}
    for _, case in found:
        _left_case(*case)


# -- a static circle's rim touching (orca_lp.static_point_line): |rim − x|² > r², its ORCA line or the contact line --


def _rim_groupings(place: tuple[float, float]) -> dict[str, bool]:
    """Whether the pedestrian (radius 25 cm) at ``place`` (cm) is clear of CIRCLE's nearest rim point (rel =
    −away · gap, geometry.away_from_static's, as both forms compute it): ``"C"``, then regroupings. (hypot(p) > r
    is no regrouping here: for r = 25 the square root of the float after r² rounds above r.)"""
    fx, fy = place[0] - CIRCLE[0], place[1] - CIRCLE[1]
    d = math.sqrt(fx * fx + fy * fy)
    away, gap = (fx / d, fy / d), d - CIRCLE[2]
    px, py = -away[0] * gap, -away[1] * gap
    r = 25.0
    return {
        "C": px * px + py * py > r * r,
        "px^2 > r^2 - py^2": px * px > r * r - py * py,
        "(px - r)(px + r) + py^2 > 0": (px - r) * (px + r) + py * py > 0.0,
    }


def _rim_case(place: tuple[float, float]) -> None:
    """Both forms for the pedestrian at ``place`` walking at CIRCLE's centre."""
    to = (CIRCLE[0] - place[0], CIRCLE[1] - place[1])
    _substep(REACH_CONFIG, [place], [(0.5 * to[0], 0.5 * to[1])], [to], [25.0], [60.0], world=CIRCLE_WORLD)


def _rim_search(n: int, seed: int = 36) -> list[tuple[str, tuple]]:
    """Rim cases (grouping, (place,)) from ``n`` seeded directions from CIRCLE: the distance along each bisected
    (through the place's x) to the C form's edge, the inputs 0-3 ulps from it kept where a regrouping decides
    otherwise."""
    rng = np.random.default_rng(seed)
    found = []
    for _ in range(n):
        dy = float(rng.uniform(-40.0, 40.0))

        def clear(x: float, dy=dy) -> bool:
            return _rim_groupings((x, CIRCLE[1] + dy))["C"]

        alternatives = {name: (lambda x, name=name, dy=dy: _rim_groupings((x, CIRCLE[1] + dy))[name])
                        for name in _rim_groupings((CIRCLE[0] + 100.0, CIRCLE[1] + dy)) if name != "C"}
        at = edge(clear, CIRCLE[0] + 1.0, CIRCLE[0] + 100.0)
        found += [(name, ((x, CIRCLE[1] + dy),)) for name, x in _disagree(clear, alternatives, at)]
    return found


# found by _first(_rim_search(2000), 4) (float.hex: the exact inputs (place,))
RIM_CASES = {
    "px^2 > r^2 - py^2": [
        (("0x1.09181be509dfap+9", "0x1.d23996dcae4f2p+8"),),
        (("0x1.05eefe2f301e8p+9", "0x1.0d40551c7d0d1p+9"),),
        (("0x1.0857305bee476p+9", "0x1.d0efa0b5927f6p+8"),),
        (("0x1.082458f3014f3p+9", "0x1.0bb14be7d9443p+9"),),
    ],
    "(px - r)(px + r) + py^2 > 0": [
        (("0x1.0eddbc00beb1dp+9", "0x1.02cf820bd0a97p+9"),),
        (("0x1.0857305bee476p+9", "0x1.d0efa0b5927f6p+8"),),
        (("0x1.0b2b447675e1bp+9", "0x1.08c5f086514b0p+9"),),
        (("0x1.0bf6132646bf9p+9", "0x1.07cc9589d7edep+9"),),
    ],
}


@pytest.mark.parametrize("name", RIM_CASES)
def test_orca_circle_rim_touching_where_a_regrouping_decides_otherwise(name):
    for case in RIM_CASES[name]:
        _rim_case(*(tuple(float.fromhex(c) for c in pair) for pair in case))


def test_orca_circle_rim_touching_search():
    """The search finds inputs where each regrouping decides otherwise, and the two forms agree on all of them."""
    found = _first(_rim_search(2000), 4)
    assert {name for name, _ in found} == set(_rim_groupings((600.0, 500.0))) - {"C"}
    for _, case in found:
        _rim_case(*case)
