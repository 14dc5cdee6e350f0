"""Property tests (hypothesis): bounds, sonar range, reaching the goal alone, determinism."""

from __future__ import annotations

import math

import numpy as np
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode import Episode
from fuzzynav.kinematics import RobotLimits, RobotState, step_unicycle
from fuzzynav.numerics.portable_math import sin_cos_deg_array
from fuzzynav.scenarios.scenario import Circle, StaticObstacle, scenario_from_dict
from fuzzynav.scenarios.world import World
from fuzzynav.sensing.raycast import cast_rays
from fuzzynav.sensing.sonar import Sonar, SonarConfig
from tests.conftest import load_controller

TABLE1 = FastEvaluator(load_controller("table1"))
LISTING = FastEvaluator(load_controller("listing"))
finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@given(finite, finite, finite, finite)
@settings(max_examples=300)
def test_controller_outputs_within_bounds(left, front, right, angle):
    d, v = TABLE1.evaluate({"left": left, "front": front, "right": right, "angle": angle})
    assert -120 <= d <= 120 and 10 <= v <= 40
    d, v = LISTING.evaluate({"SL": left, "SS": front, "SR": right})
    assert -120 <= d <= 120 and 10 <= v <= 40


@st.composite
def worlds(draw):
    w, h = draw(st.floats(300, 2000)), draw(st.floats(300, 2000))
    obstacles = []
    for _ in range(draw(st.integers(0, 5))):
        cx, cy = draw(st.floats(0, w)), draw(st.floats(0, h))
        if draw(st.booleans()):
            obstacles.append(StaticObstacle(circle=Circle((cx, cy), draw(st.floats(5, 100)))))
        else:
            sx, sy = draw(st.floats(5, 200)), draw(st.floats(5, 200))
            obstacles.append(StaticObstacle(polygon=((cx, cy), (cx + sx, cy), (cx + sx, cy + sy), (cx, cy + sy))))
    return World((0, 0, w, h), obstacles)


@given(worlds(), st.floats(0, 1), st.floats(0, 1), st.floats(-720, 720))
@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow])
def test_sonar_readings_in_range(world, fx, fy, heading):
    xmin, ymin, xmax, ymax = world.bounds
    x, y = xmin + fx * (xmax - xmin), ymin + fy * (ymax - ymin)
    readings = Sonar(SonarConfig(), 20.0).read(x, y, heading, world.solid)
    assert all(0.0 <= r <= 130.0 for r in readings)


def _sonar_unclipped(sonar: Sonar, x: float, y: float, heading: float, solid) -> np.ndarray:
    """The sonar without its rectangle pre-clip: each wedge intersected with the whole world."""
    dist = shapely.distance(shapely.intersection(sonar.wedges(x, y, heading), solid), shapely.Point(x, y))
    return np.where(np.isnan(dist), 130.0, np.clip(dist - 20.0, 0.0, 130.0))


@given(worlds(), st.floats(-0.1, 1.1), st.floats(-0.1, 1.1), st.floats(-720, 720))
@settings(max_examples=60, suppress_health_check=[HealthCheck.too_slow])
def test_sonar_preclip_changes_nothing(world, fx, fy, heading):
    xmin, ymin, xmax, ymax = world.bounds
    x, y = xmin + fx * (xmax - xmin), ymin + fy * (ymax - ymin)
    sonar = Sonar(SonarConfig(), 20.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        expected = _sonar_unclipped(sonar, x, y, heading, world.solid)
    np.testing.assert_allclose(sonar.read(x, y, heading, world.solid), expected, rtol=0, atol=1e-9)


@given(worlds(), st.floats(-0.1, 1.1), st.floats(-0.1, 1.1), st.floats(20, 400))
@settings(max_examples=80, suppress_health_check=[HealthCheck.too_slow])
def test_ray_cast_culling_changes_nothing(world, fx, fy, max_range):
    xmin, ymin, xmax, ymax = world.bounds
    origin = np.array([xmin + fx * (xmax - xmin), ymin + fy * (ymax - ymin)])
    sin, cos = sin_cos_deg_array(np.arange(360.0))
    directions = np.stack([cos, sin], axis=1)
    ranges, hit = cast_rays(origin, directions, world.segments, world.circles, max_range)
    # brute force: every segment and circle on its own, the nearest wins (ties to the lowest index)
    best, best_hit = np.full(360, float(max_range)), np.full(360, -1)
    items = [(world.segments[i:i + 1], np.zeros((0, 3))) for i in range(len(world.segments))]
    items += [(np.zeros((0, 4)), world.circles[i:i + 1]) for i in range(len(world.circles))]
    for k, (seg, circ) in enumerate(items):
        r, h = cast_rays(origin, directions, seg, circ, 1e12)
        closer = (h >= 0) & (r < best)
        best, best_hit = np.where(closer, r, best), np.where(closer, k, best_hit)
    np.testing.assert_array_equal(ranges, best)
    np.testing.assert_array_equal(hit, best_hit)


@given(st.floats(-200, 200), st.floats(-100, 100), st.floats(0, 360), st.floats(0, 360))
@settings(max_examples=200)
def test_unicycle_respects_limits(dtheta, v, heading, _):
    lim = RobotLimits()
    s = step_unicycle(RobotState(0.0, 0.0, heading), dtheta, v, 1.0, lim)
    moved = math.hypot(s.x, s.y)
    assert moved == 0.0 if v <= 0 else 10.0 - 1e-9 <= moved <= 40.0 + 1e-9
    turn = (s.heading - heading + 180) % 360 - 180
    assert abs(turn) <= 120 + 1e-9


@given(st.floats(100, 1900), st.floats(100, 1900), st.floats(100, 1900), st.floats(100, 1900),
       st.floats(0, 360))
@settings(max_examples=40, deadline=None)
def test_robot_alone_reaches_goal(sx, sy, gx, gy, heading):
    if math.hypot(gx - sx, gy - sy) <= 25:
        return
    s = scenario_from_dict({"bounds": [0, 0, 2000, 2000], "max_steps": 200,
                            "robot": {"start": [sx, sy], "goal": [gx, gy], "heading": heading}})
    ep = Episode(s, TABLE1)
    list(ep.run())
    assert ep.outcome == "goal"


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=10, deadline=None)
def test_same_seed_same_records(seed):
    s = scenario_from_dict({
        "bounds": [0, 0, 1000, 600], "max_steps": 60,
        "robot": {"start": [100, 300], "goal": [900, 300]},
        "static_obstacles": [{"circle": {"center": [500, 200], "radius": 40}}],
        "dynamic_obstacles": [{"id": "a", "radius": 20, "start": [800, 320], "velocity": [-25, 0]}]})
    from fuzzynav.config import episode_config_from_dict
    cfg = episode_config_from_dict({"laser": {"noise_std_cm": 1.0}})
    a = [(r.next_state, r.decision.mode) for r in Episode(s, TABLE1, cfg, seed=seed).run()]
    b = [(r.next_state, r.decision.mode) for r in Episode(s, TABLE1, cfg, seed=seed).run()]
    assert a == b
    assert np.isfinite([st_.x for st_, _ in a]).all()
