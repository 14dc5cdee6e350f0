"""The Dynamic Window Approach policy (fuzzynav/policies/dwa.py): its core math on hand-made observations, its
registry entry, and one closed-loop run in a small in-test simulation. Units: cm, s, degrees, cm/s."""

from __future__ import annotations

import numpy as np
import pytest

from fuzzynav.kinematics import RobotLimits, RobotState, step_unicycle
from fuzzynav.numerics.geometry import segment_point_distance, swept_distance
from fuzzynav.numerics.portable_math import dist
from fuzzynav.planning.layer import Observation
from fuzzynav.policies.base import Policy, PolicyContext, make_policy
from fuzzynav.policies.dwa import DWAConfig, DWAPolicy, _segment_distances, evaluate, speed_window
from fuzzynav.sensing.tracking import Track
from tests.policy_scenes import NO_POINTS, observe, random_observation, wall

LIMITS = RobotLimits()
RADIUS = 20.0
CTX = PolicyContext(LIMITS, RADIUS)
CFG = DWAConfig()


def rollout_gaps(state: RobotState, dtheta: float, v: float, points: np.ndarray, tracks: tuple[Track, ...],
                 steps: int) -> list[float]:
    """Smallest gap (cm) in each step when the robot executes (dtheta, v) and then holds v straight, as the
    kinematics does it, against static points and tracks moving at constant velocity."""
    gaps = []
    s = state
    for k in range(steps):
        nxt = step_unicycle(s, dtheta if k == 0 else 0.0, v, 1.0, LIMITS)
        p0, p1 = np.array([s.x, s.y]), np.array([nxt.x, nxt.y])
        gap = np.inf
        if len(points):
            gap = float(np.min(segment_point_distance(p0, p1, points))) - RADIUS
        for t in tracks:
            o0 = np.array([t.x + k * t.vx, t.y + k * t.vy])
            o1 = o0 + np.array([t.vx, t.vy])
            gap = min(gap, float(swept_distance(p0, p1, o0, o1)) - RADIUS - t.radius)
        gaps.append(gap)
        s = nxt
    return gaps


def act(obs: Observation, params: dict | None = None):
    return make_policy("dwa", params or {}, CTX).act(obs)


def test_empty_world_turns_to_the_goal_at_the_top_speed_of_the_window():
    a = act(observe(RobotState(0.0, 0.0, 0.0, 40.0), (300.0, 300.0)))
    assert a.mode == "dwa"
    assert a.dtheta_deg == pytest.approx(45.0, abs=1e-9)
    assert a.v_cm_s == 40.0
    assert a.fields["heading"] == 1.0 and a.fields["admissible"] == a.fields["candidates"]
    # from 25 cm/s the window's top is 25 + 15 = 40; from rest it is 15
    assert act(observe(RobotState(0.0, 0.0, 0.0, 25.0), (300.0, 300.0))).v_cm_s == 40.0
    assert act(observe(RobotState(0.0, 0.0, 0.0, 0.0), (300.0, 300.0))).v_cm_s == 15.0


def test_goal_approach_lands_on_the_goal_instead_of_passing_it():
    a = act(observe(RobotState(0.0, 0.0, 90.0, 40.0), (0.0, 30.0)))
    assert (a.dtheta_deg, a.v_cm_s) == (0.0, 30.0)
    nxt = step_unicycle(RobotState(0.0, 0.0, 90.0, 40.0), a.dtheta_deg, a.v_cm_s, 1.0, LIMITS)
    assert dist(nxt.position, (0.0, 30.0)) < 1e-9
    # nearer than one step at v_min: the slowest move
    assert act(observe(RobotState(0.0, 0.0, 90.0, 40.0), (0.0, 4.0))).v_cm_s == LIMITS.v_min


def test_dynamic_window_bounds_the_speeds():
    assert speed_window(10.0, 1000.0, CFG, LIMITS, 1.0) == (10.0, 25.0)
    assert speed_window(0.0, 1000.0, CFG, LIMITS, 1.0) == (10.0, 15.0)
    assert speed_window(40.0, 1000.0, CFG, LIMITS, 1.0) == (10.0, 40.0)
    slow = DWAConfig(accel_cm_s2=10.0, decel_cm_s2=5.0)
    assert speed_window(40.0, 1000.0, slow, LIMITS, 1.0) == (35.0, 40.0)
    # landing on the goal beats the braking limit (the robot can change speed at once)
    assert speed_window(40.0, 20.0, slow, LIMITS, 1.0) == (20.0, 20.0)

    a = act(observe(RobotState(0.0, 0.0, 0.0, 10.0), (1000.0, 0.0)))
    assert a.v_cm_s == 25.0  # not 40: 10 + 15 cm/s² · 1 s
    ev = evaluate(RobotState(0.0, 0.0, 0.0, 40.0), (1000.0, 0.0), (), NO_POINTS, slow, LIMITS, RADIUS, 1.0)
    speeds = sorted(set(ev.candidates.v_cm_s.tolist()))
    assert speeds == pytest.approx([0.0, 35.0, 35.0 + 5.0 / 3.0, 35.0 + 10.0 / 3.0, 40.0], abs=1e-12)


def test_wall_far_ahead_slows_the_robot_down_without_turning():
    points = wall(150.0, -150.0, 150.0)
    state = RobotState(0.0, 0.0, 0.0, 40.0)
    a = act(observe(state, (400.0, 0.0), points))
    assert a.mode == "dwa" and a.dtheta_deg == 0.0
    assert LIMITS.v_min <= a.v_cm_s < 40.0  # at 40 cm/s the rollout would end 10 cm from the wall: no room to brake
    assert min(rollout_gaps(state, a.dtheta_deg, a.v_cm_s, points, (), CFG.horizon_steps)) >= CFG.margin_cm


def test_wall_close_ahead_turns_away():
    points = wall(60.0, -150.0, 150.0)
    state = RobotState(0.0, 0.0, 0.0, 40.0)
    ev = evaluate(state, (400.0, 0.0), (), points, CFG, LIMITS, RADIUS, 1.0)
    straight = (ev.candidates.dtheta_deg == 0.0) & (ev.candidates.v_cm_s > 0)
    assert straight.any() and not ev.admissible[straight].any()
    a = act(observe(state, (400.0, 0.0), points))
    assert a.mode == "dwa" and a.dtheta_deg != 0.0 and a.v_cm_s > 0
    assert min(rollout_gaps(state, a.dtheta_deg, a.v_cm_s, points, (), CFG.horizon_steps)) >= CFG.margin_cm


def test_crossing_obstacle_keeps_the_margin_at_the_predicted_times():
    crossing = (Track(1, 150.0, -100.0, 0.0, 40.0, 20.0),)
    state = RobotState(0.0, 0.0, 0.0, 40.0)
    # straight on at full speed meets it in the third second
    assert min(rollout_gaps(state, 0.0, 40.0, NO_POINTS, crossing, 3)) < 0.0
    ev = evaluate(state, (500.0, 0.0), crossing, NO_POINTS, CFG, LIMITS, RADIUS, 1.0)
    full = (ev.candidates.dtheta_deg == 0.0) & (ev.candidates.v_cm_s == 40.0)
    assert not ev.admissible[full].any()
    a = act(observe(state, (500.0, 0.0), tracks=crossing))
    assert a.mode == "dwa"
    assert min(rollout_gaps(state, a.dtheta_deg, a.v_cm_s, NO_POINTS, crossing, CFG.horizon_steps)) \
        >= CFG.margin_cm
    assert a.fields["clearance_cm"] >= CFG.margin_cm


@pytest.mark.parametrize("points, tracks", [
    (np.array([[15.0, 0.0]]), ()),  # a laser return inside the robot's disc
    (NO_POINTS, (Track(1, 35.0, 0.0, 0.0, 0.0, 20.0),)),  # an obstacle overlapping it
])
def test_obstacle_touching_the_robot_leaves_nothing_admissible(points, tracks):
    a = act(observe(RobotState(0.0, 0.0, 0.0, 25.0), (400.0, 0.0), points, tracks))
    assert (a.mode, a.dtheta_deg, a.v_cm_s) == ("dwa_stop", 0.0, 0.0)
    assert a.fields["admissible"] == 0


def test_mirror_symmetric_tie_goes_to_the_right_turn():
    # goal straight behind: ±120° are mirror images with the same score to the last bit
    a = act(observe(RobotState(0.0, 0.0, 0.0, 40.0), (-300.0, 0.0)))
    assert a.dtheta_deg == -120.0


def test_same_observation_gives_the_same_action_bits():
    obs = random_observation(7)
    first, second = act(obs), make_policy("dwa", {}, CTX).act(obs)

    def bits(a):
        return (a.mode, a.dtheta_deg.hex(), a.v_cm_s.hex(),
                {k: v.hex() if isinstance(v, float) else v for k, v in a.fields.items()})

    assert bits(first) == bits(second)


def test_segment_distances_equal_the_geometry_helper_to_the_bit():
    rng = np.random.default_rng(3)
    start, ends, points = rng.uniform(-50, 50, 2), rng.uniform(-150, 150, (40, 2)), rng.uniform(-250, 250, (90, 2))
    ends[0] = start  # a candidate that does not move
    expected = segment_point_distance(start, ends[:, None, :], points)
    assert np.array_equal(_segment_distances(start, ends, points), expected)


def test_registry_builds_the_policy_and_names_bad_parameters():
    policy = make_policy("dwa", {"horizon_steps": 2}, CTX)
    assert isinstance(policy, DWAPolicy) and isinstance(policy, Policy) and policy.name == "dwa"
    assert policy.config.horizon_steps == 2
    for params, field in [({"turn_samples": 4}, "turn_samples"), ({"speed_samples": 0}, "speed_samples"),
                          ({"margin_cm": -1.0}, "margin_cm"), ({"clearance_cap_cm": 5.0}, "clearance_cap_cm"),
                          ({"decel_cm_s2": 0.0}, "decel_cm_s2"), ({"horizon_steps": 0}, "horizon_steps"),
                          ({"accel_cm_s2": 5.0}, "accel_cm_s2"), ({"alpha_heading": "x"}, "alpha_heading"),
                          ({"bogus": 1}, "bogus")]:
        with pytest.raises(ValueError, match=rf"^navigator\.{field}:"):
            make_policy("dwa", params, CTX)


def test_closed_loop_reaches_the_goal_past_a_post_and_a_crossing_obstacle():
    """Tiny simulation: the robot (unicycle kinematics) from rest at (0, 0) to (600, 0) past a post of laser
    returns on its line and a disc crossing its path at constant velocity (perceived exactly); the gaps are
    checked over every step, swept."""
    angles = np.radians(np.arange(0.0, 360.0, 10.0))
    post = np.column_stack([200.0 + 15.0 * np.cos(angles), 10.0 + 15.0 * np.sin(angles)])
    disc_radius = 20.0
    disc = np.array([320.0, -480.0])  # crosses y = 0 at t = 19 s, when the robot comes by
    disc_v = np.array([0.0, 25.0])
    goal = (600.0, 0.0)
    policy = make_policy("dwa", {}, CTX)
    policy.reset(0)
    state = RobotState(0.0, 0.0, 0.0, 0.0)
    static_gaps, moving_gaps = [], []
    for _ in range(60):
        seen = post[np.hypot(post[:, 0] - state.x, post[:, 1] - state.y) <= 250.0]
        tracks = (Track(1, float(disc[0]), float(disc[1]), float(disc_v[0]), float(disc_v[1]), disc_radius),)
        a = policy.act(observe(state, goal, seen, tracks))
        nxt = step_unicycle(state, a.dtheta_deg, a.v_cm_s, 1.0, LIMITS)
        p0, p1 = np.array(state.position), np.array(nxt.position)
        static_gaps.append(float(np.min(segment_point_distance(p0, p1, post))) - RADIUS)
        moving_gaps.append(float(swept_distance(p0, p1, disc, disc + disc_v)) - RADIUS - disc_radius)
        state, disc = nxt, disc + disc_v
        if dist(state.position, goal) <= RADIUS:
            break
    assert dist(state.position, goal) <= RADIUS
    # the margin holds against both, and both were in the way (not passed at a distance)
    assert CFG.margin_cm <= min(static_gaps) < 30.0
    assert CFG.margin_cm <= min(moving_gaps) < 50.0
