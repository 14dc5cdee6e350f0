"""The ORCA policy (fuzzynav/policies/orca.py; van den Berg, Guy, Lin & Manocha 2011): its half-planes and linear
programs on hand-computed cases, the command conversion, determinism, the registry, and closed-loop drives in
a small in-test simulation. Units: cm, s, degrees, cm/s."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzynav.kinematics import RobotLimits, RobotState, step_unicycle
from fuzzynav.numerics.geometry import segment_point_distance, swept_distance
from fuzzynav.numerics.orca_lp import (
    Line,
    choose_velocity,
    orca_line,
    solve_lp2,
    solve_lp3,
    static_point_line,
    violation,
)
from fuzzynav.numerics.portable_math import dist
from fuzzynav.planning.layer import Observation
from fuzzynav.policies.base import Policy, PolicyContext, make_policy
from fuzzynav.policies.orca import OrcaConfig, OrcaPolicy, nearest_static_points, orca_lines, velocity_command
from fuzzynav.sensing.tracking import Track
from tests.policy_scenes import NO_POINTS, observe, random_observation

LIMITS = RobotLimits()
RADIUS = 20.0
CTX = PolicyContext(LIMITS, RADIUS)
CFG = OrcaConfig()
LASER_RANGE_CM = 250.0
SQRT21 = math.sqrt(21.0)

# half-planes by hand: y >= 10, y <= -10, x <= 20, x <= 0 (permitted = left of the direction)
ABOVE_10 = Line((0.0, 10.0), (1.0, 0.0))
BELOW_MINUS_10 = Line((0.0, -10.0), (-1.0, 0.0))
LEFT_OF_20 = Line((20.0, 0.0), (0.0, 1.0))
LEFT_OF_0 = Line((0.0, 0.0), (0.0, 1.0))


def act(obs: Observation, params: dict | None = None):
    return make_policy("orca", params or {}, CTX).act(obs)


def test_head_on_obstacle_line_by_hand():
    """Robot at 20 cm/s along +x, a disc 100 cm ahead coming at 20 cm/s: relative position (100, 0),
    relative velocity (40, 0), combined radius 40, τ = 5 s. w = (40, 0) − (100, 0)/5 = (20, 0) points away
    from the apex's side (w·p > 0), so the nearest boundary is a leg; on the line of centres det(p, w) = 0
    picks the right leg, whose direction is −(p_x·leg, −p_x·r)/|p|² = (−0.2√21, 0.4) with leg = √8400.
    u = (v_rel·d)d − v_rel = (−6.4, −3.2√21) (|u| = 16 = 40·sin(asin 0.4)); point = v + ρ·u."""
    full = orca_line((100.0, 0.0), (40.0, 0.0), 40.0, 5.0, 1.0, 1.0, (20.0, 0.0))
    assert full.direction == pytest.approx((-0.2 * SQRT21, 0.4), abs=1e-12)
    assert full.point == pytest.approx((13.6, -3.2 * SQRT21), abs=1e-12)
    half = orca_line((100.0, 0.0), (40.0, 0.0), 40.0, 5.0, 1.0, 0.5, (20.0, 0.0))
    assert half.direction == full.direction
    assert half.point == pytest.approx((16.8, -1.6 * SQRT21), abs=1e-12)
    # the current velocity is inside the VO: it violates the line by |u|·ρ, and the permitted side is
    # to the right (−y) of the obstacle
    assert violation(full, (20.0, 0.0)) == pytest.approx(16.0, abs=1e-12)
    assert violation(half, (20.0, 0.0)) == pytest.approx(8.0, abs=1e-12)
    assert violation(full, (20.0, -30.0)) < 0.0 < violation(full, (20.0, 30.0))


def test_cut_off_line_by_hand():
    """τ = 1 s: the VO's cut-off circle is centred at (100, 0) with radius 40, so relative speeds up to 60
    along +x are safe; the obstacle comes at 20 cm/s, so the robot may go at most 40 cm/s along +x:
    w = (40, 0) − (100, 0) = (−60, 0), (w·p)² = 3.6e7 > r²|w|² = 5.76e6, n = (−1, 0), u = (40 − 60)·n."""
    line = orca_line((100.0, 0.0), (40.0, 0.0), 40.0, 1.0, 1.0, 1.0, (20.0, 0.0))
    assert line.direction == (-0.0, 1.0)
    assert line.point == (40.0, 0.0)
    assert violation(line, (39.0, 25.0)) < 0.0 < violation(line, (41.0, -25.0))


def test_velocity_outside_every_vo_is_kept():
    """The robot already passes a track and a post to the side: its current velocity is the preferred one
    and outside both VOs, so every half-plane contains it and it is chosen unchanged."""
    state = RobotState(0.0, 0.0, 0.0, 25.0)
    tracks = (Track(1, 150.0, 90.0, -20.0, 0.0, 20.0),)
    post = np.array([[60.0, -45.0], [65.0, -45.0]])
    lines, hard = orca_lines(0.0, 0.0, (25.0, 0.0), tracks, post, CFG, RADIUS, LIMITS.v_max, 1.0)
    assert (len(lines), hard) == (3, 2)
    assert all(violation(line, (25.0, 0.0)) <= 0.0 for line in lines)
    result = choose_velocity(lines, hard, LIMITS.v_max, (25.0, 0.0))
    assert result.velocity == (25.0, 0.0) and not result.fallback
    a = act(observe(state, (1000.0, 0.0), post, tracks))
    assert (a.mode, a.dtheta_deg, a.v_cm_s) == ("orca", 0.0, 25.0)
    assert a.fields["lines"] == 3 and a.fields["fallback"] == 0.0


def test_lp_one_line_projects_the_preferred_velocity():
    failed, v = solve_lp2([ABOVE_10], 40.0, (30.0, 0.0))
    assert failed == 1 and v == (30.0, 10.0)
    # the projection (40, 30) is beyond the speed disc: the nearest point of the line inside it
    failed, v = solve_lp2([Line((0.0, 30.0), (1.0, 0.0))], 40.0, (40.0, 0.0))
    assert failed == 1 and v == pytest.approx((math.sqrt(700.0), 30.0), abs=1e-12)
    # a preferred velocity beyond the disc, no line: scaled onto the disc
    assert solve_lp2([], 40.0, (60.0, 80.0)) == (0, (24.0, 32.0))


def test_lp_two_lines_gives_the_corner_closest_to_the_preferred_velocity():
    for lines in ([ABOVE_10, LEFT_OF_20], [LEFT_OF_20, ABOVE_10]):
        failed, v = solve_lp2(lines, 40.0, (30.0, 0.0))
        assert failed == 2 and v == (20.0, 10.0)
    # brute force: no permitted velocity of a fine grid inside the disc is nearer to (30, 0)
    grid = np.arange(-40.0, 40.25, 0.25)
    best = min(math.hypot(x - 30.0, y) for x in grid for y in grid
               if x * x + y * y <= 1600.0 and y >= 10.0 and x <= 20.0)
    assert math.hypot(20.0 - 30.0, 10.0) <= best + 1e-12
    # when the projection on one line satisfies the other, that projection is the answer
    failed, v = solve_lp2([ABOVE_10, LEFT_OF_20], 40.0, (15.0, 0.0))
    assert v == (15.0, 10.0)


def test_infeasible_lines_fall_back_to_the_least_penetrating_velocity():
    """y >= 10 and y <= −10 cannot both hold: every velocity penetrates one of them by at least 10 cm/s
    (on y = 0 both by exactly 10), and of those the nearest to the preferred (30, 0) is (30, 0) itself."""
    failed, partial = solve_lp2([ABOVE_10, BELOW_MINUS_10], 40.0, (30.0, 0.0))
    assert failed == 1
    least = solve_lp3([ABOVE_10, BELOW_MINUS_10], 0, failed, 40.0, partial)
    assert max(violation(ABOVE_10, least), violation(BELOW_MINUS_10, least)) == pytest.approx(10.0, abs=1e-12)
    result = choose_velocity([ABOVE_10, BELOW_MINUS_10], 0, 40.0, (30.0, 0.0))
    assert result.fallback and result.velocity == pytest.approx((30.0, 0.0), abs=1e-6)
    assert result.penetration_cm_s == pytest.approx(10.0, abs=1e-6)
    # a hard (static) line x <= 0 is never given up: the fallback keeps it and stays on y = 0
    result = choose_velocity([LEFT_OF_0, ABOVE_10, BELOW_MINUS_10], 1, 40.0, (30.0, 0.0))
    assert result.fallback and result.velocity == pytest.approx((0.0, 0.0), abs=1e-6)
    assert violation(LEFT_OF_0, result.velocity) <= 1e-9
    assert result.penetration_cm_s == pytest.approx(10.0, abs=1e-6)


def test_static_point_behind_does_not_constrain_and_one_ahead_does():
    velocity = (25.0, 0.0)
    behind = static_point_line((-35.0, 0.0), 30.0, CFG.time_horizon_obst_s, 1.0, velocity)
    assert behind is not None and violation(behind, velocity) < 0.0
    result = choose_velocity([behind], 1, LIMITS.v_max, velocity)
    assert result.velocity == velocity and not result.fallback
    # 60 cm ahead, gap 30 cm to the inflated disc: within τ_obst = 2 s at most 15 cm/s towards it
    ahead = static_point_line((60.0, 0.0), 30.0, CFG.time_horizon_obst_s, 1.0, velocity)
    assert ahead is not None and violation(ahead, velocity) > 0.0
    result = choose_velocity([ahead], 1, LIMITS.v_max, velocity)
    assert violation(ahead, result.velocity) <= 1e-12 and result.velocity != velocity
    assert violation(ahead, (15.0, 0.0)) > -1e-9 and violation(ahead, (16.0, 0.0)) > 0.0


def test_overlap_forbids_approaching():
    """A return inside the inflated disc: no velocity towards it (RVO2's contact rule); a track overlapping:
    the half-plane demands leaving the overlap within one step."""
    line = static_point_line((25.0, 0.0), 30.0, 2.0, 1.0, (25.0, 0.0))
    assert line is not None and line.point == (0.0, 0.0)
    assert violation(line, (1.0, 30.0)) > 0.0 and violation(line, (-1.0, 30.0)) < 0.0
    assert static_point_line((0.0, 0.0), 30.0, 2.0, 1.0, (25.0, 0.0)) is None
    # track 35 cm ahead, combined radius 50, both still: the robot must back off by 15 cm within dt = 1 s
    track_line = orca_line((35.0, 0.0), (0.0, 0.0), 50.0, 5.0, 1.0, 1.0, (0.0, 0.0))
    assert violation(track_line, (-15.0, 0.0)) == pytest.approx(0.0, abs=1e-12)
    assert violation(track_line, (-14.0, 0.0)) > 0.0


def test_static_returns_are_bounded_nearest_first_and_every_track_kept():
    wall = np.column_stack([np.full(100, 50.0), np.arange(-250.0, 250.0, 5.0)])
    picked = nearest_static_points(wall, 0.0, 0.0, 110.0, CFG.max_static_points)
    assert len(picked) == CFG.max_static_points
    d = np.hypot(picked[:, 0], picked[:, 1])
    assert np.all(np.diff(d) >= 0.0) and tuple(picked[0]) == (50.0, 0.0)
    # reach = τ_obst·v_max + r = 2·40 + 30 = 110 cm: a return at 111 cm cannot matter
    assert len(nearest_static_points(np.array([[111.0, 0.0]]), 0.0, 0.0, 110.0, 32)) == 0
    # every track adds its line, nearest first, however far (its VO need not meet the speed disc)
    far = Track(1, 2_000.0, 0.0, -20.0, 0.0, 20.0)
    near = Track(2, 300.0, 0.0, -20.0, 0.0, 20.0)
    lines, hard = orca_lines(0.0, 0.0, (25.0, 0.0), (far, near), NO_POINTS, CFG, RADIUS, 40.0, 1.0)
    assert hard == 0
    assert lines == tuple(orca_line((t.x, t.y), (25.0 - t.vx, 0.0), 50.0, 5.0, 1.0, 1.0, (25.0, 0.0))
                          for t in (near, far))


def test_far_head_on_track_binds_at_half_reciprocity():
    """#37 item 10: the robot at rest, a walker 401 cm ahead closing at 30 cm/s, ρ = 0.5. Its VO cannot meet
    the speed disc ((401 − 50)/5 = 70.2 > 40 + 30, the rule that used to drop it), but the line is placed at
    ρ·u from the current velocity. By hand: relative velocity (30, 0), cut-off centre p/τ = (80.2, 0),
    w = (−50.2, 0) with w·p < 0 and (w·p)² > r²|w|², so the cut-off arc is nearest: n = (−1, 0),
    u = (r/τ − |w|)·n = (40.2, 0), point = 0.5·u = (20.1, 0), direction (0, 1): v_x ≤ 20.1 cm/s, below the
    preferred 25. RVO2 (pyrvo 0.4.3, single precision) chooses (20.1000, 0) too; the robot used to take 25.
    At ρ = 1 the same line is v_x ≤ 40.2 and does not bind."""
    walker = (Track(1, 401.0, 0.0, -30.0, 0.0, 20.0),)
    half = OrcaConfig(reciprocity=0.5)
    lines, _ = orca_lines(0.0, 0.0, (0.0, 0.0), walker, NO_POINTS, half, RADIUS, 40.0, 1.0)
    assert lines[0].point == pytest.approx((20.1, 0.0), abs=1e-12)
    assert lines[0].direction == pytest.approx((0.0, 1.0), abs=1e-15)
    a = act(observe(RobotState(0.0, 0.0, 0.0, 0.0), (1_000.0, 0.0), tracks=walker), {"reciprocity": 0.5})
    assert (a.mode, a.dtheta_deg) == ("orca", 0.0)
    assert a.v_cm_s == pytest.approx(20.1, abs=1e-12)
    assert a.fields["vx_cm_s"] == pytest.approx(20.1, abs=1e-12) and a.fields["lines"] == 1
    assert act(observe(RobotState(0.0, 0.0, 0.0, 0.0), (1_000.0, 0.0), tracks=walker)).v_cm_s == 25.0


tracks_st = st.lists(st.tuples(st.floats(60.0, 1_500.0), st.floats(-180.0, 180.0), st.floats(0.0, 60.0),
                               st.floats(-180.0, 180.0)), min_size=1, max_size=6)


@settings(max_examples=300, deadline=None)
@given(tracks=tracks_st, speed=st.floats(0.0, 40.0), heading=st.floats(-180.0, 180.0),
       goal_bearing=st.floats(-180.0, 180.0), reciprocity=st.sampled_from([0.5, 0.75, 1.0]))
def test_chosen_velocity_respects_every_tracks_line(tracks, speed, heading, goal_bearing, reciprocity):
    """RVO2's rule: the line of every neighbour constrains the choice. For tracks anywhere (60–1500 cm away,
    any direction, 0–60 cm/s), each track's half-plane, computed on its own, contains the chosen velocity
    whenever the 2-D program was feasible; the old rule (drop a track whose VO cannot meet the speed disc)
    broke this at ρ < 1."""
    def polar(r, deg):
        return r * math.cos(math.radians(deg)), r * math.sin(math.radians(deg))

    obs_tracks = tuple(Track(i, *polar(d, a), *polar(s, b), 20.0) for i, (d, a, s, b) in enumerate(tracks))
    velocity = polar(speed, heading)
    config = OrcaConfig(reciprocity=reciprocity)
    lines, hard = orca_lines(0.0, 0.0, velocity, obs_tracks, NO_POINTS, config, RADIUS, 40.0, 1.0)
    assert hard == 0 and len(lines) == len(obs_tracks)
    result = choose_velocity(lines, hard, 40.0, polar(25.0, goal_bearing))
    if result.fallback:
        return
    for t in obs_tracks:
        line = orca_line((t.x, t.y), (velocity[0] - t.vx, velocity[1] - t.vy), 50.0, 5.0, 1.0, reciprocity,
                         velocity)
        assert violation(line, result.velocity) <= 1e-9, (t, result.velocity)


def test_velocity_command_conversion():
    goal_bearing = 0.0
    assert velocity_command((0.0, 20.0), 0.0, goal_bearing, LIMITS) == (90.0, 20.0)
    assert velocity_command((30.0, 0.0), 90.0, goal_bearing, LIMITS) == (-90.0, 30.0)
    # beyond the 120° turn limit: full turn, the component along the new heading (30·cos 30°)
    sin150, cos150 = 0.5, -math.sqrt(3.0) / 2.0
    dtheta, v = velocity_command((30.0 * cos150, 30.0 * sin150), 0.0, goal_bearing, LIMITS)
    assert dtheta == 120.0 and v == pytest.approx(15.0 * math.sqrt(3.0), abs=1e-9)
    # slower than v_min: v_min from v_min/2 = 5 cm/s up, stand still below
    assert velocity_command((5.0, 0.0), 0.0, goal_bearing, LIMITS) == (0.0, LIMITS.v_min)
    assert velocity_command((4.9, 0.0), 0.0, goal_bearing, LIMITS) == (0.0, 0.0)
    assert velocity_command((0.0, -4.0), 0.0, goal_bearing, LIMITS) == (-90.0, 0.0)
    # exactly zero: stand still facing the goal
    assert velocity_command((0.0, 0.0), 10.0, 100.0, LIMITS) == (90.0, 0.0)


def test_goal_is_approached_and_landed_on():
    a = act(observe(RobotState(0.0, 0.0, 0.0, 25.0), (0.0, 300.0)))
    assert (a.mode, a.dtheta_deg, a.v_cm_s) == ("orca", 90.0, 25.0)
    a = act(observe(RobotState(0.0, 0.0, 90.0, 25.0), (0.0, 18.0)))
    assert (a.dtheta_deg, a.v_cm_s) == (0.0, 18.0)


def test_same_observation_gives_the_same_action_bits():
    obs = random_observation(11)
    policy = make_policy("orca", {}, CTX)
    policy.reset(1)
    first = policy.act(obs)
    policy.reset(2)

    def bits(a):
        return (a.mode, a.dtheta_deg.hex(), a.v_cm_s.hex(),
                {k: v.hex() if isinstance(v, float) else v for k, v in a.fields.items()})

    assert bits(first) == bits(policy.act(obs)) == bits(make_policy("orca", {}, CTX).act(obs))
    assert first.fields["lines"] > 5


def test_registry_builds_the_policy_and_names_bad_parameters():
    policy = make_policy("orca", {"reciprocity": 0.5, "time_horizon_s": 3.0}, CTX)
    assert isinstance(policy, OrcaPolicy) and isinstance(policy, Policy) and policy.name == "orca"
    assert (policy.config.reciprocity, policy.config.time_horizon_s) == (0.5, 3.0)
    for params, field in [({"reciprocity": 0.3}, "reciprocity"), ({"reciprocity": 1.5}, "reciprocity"),
                          ({"time_horizon_s": 0.0}, "time_horizon_s"),
                          ({"time_horizon_obst_s": -1.0}, "time_horizon_obst_s"),
                          ({"pref_speed_cm_s": "fast"}, "pref_speed_cm_s"), ({"margin_cm": -1.0}, "margin_cm"),
                          ({"max_static_points": -1}, "max_static_points"), ({"bogus": 1}, "bogus")]:
        with pytest.raises(ValueError, match=rf"^navigator\.{field}:"):
            make_policy("orca", params, CTX)


def drive(disc: tuple[float, float], disc_v: tuple[float, float], points: np.ndarray,
          goal: tuple[float, float], params: dict | None = None, steps: int = 60):
    """Tiny simulation: the robot (unicycle kinematics) from rest at (0, 0) to ``goal`` past static ``points``
    (seen within laser range) and a disc of radius 20 cm moving at constant velocity (perceived exactly).
    Returns (final state, smallest swept gap to the points, to the disc, number of fallback steps)."""
    policy = make_policy("orca", params or {}, CTX)
    policy.reset(0)
    state = RobotState(0.0, 0.0, 0.0, 0.0)
    pos, vel = np.array(disc), np.array(disc_v)
    static_gap, moving_gap, fallbacks = math.inf, math.inf, 0
    for _ in range(steps):
        seen = points[np.hypot(points[:, 0] - state.x, points[:, 1] - state.y) <= LASER_RANGE_CM]
        tracks = (Track(1, float(pos[0]), float(pos[1]), float(vel[0]), float(vel[1]), 20.0),)
        a = policy.act(observe(state, goal, seen, tracks))
        fallbacks += a.mode == "orca_fallback"
        nxt = step_unicycle(state, a.dtheta_deg, a.v_cm_s, 1.0, LIMITS)
        p0, p1 = np.array(state.position), np.array(nxt.position)
        if len(points):
            static_gap = min(static_gap, float(np.min(segment_point_distance(p0, p1, points))) - RADIUS)
        moving_gap = min(moving_gap, float(swept_distance(p0, p1, pos, pos + vel)) - RADIUS - 20.0)
        state, pos = nxt, pos + vel
        if dist(state.position, goal) <= RADIUS:
            break
    return state, static_gap, moving_gap, fallbacks


POST = np.column_stack([200.0 + 15.0 * np.cos(np.radians(np.arange(0.0, 360.0, 10.0))),
                        10.0 + 15.0 * np.sin(np.radians(np.arange(0.0, 360.0, 10.0)))])


@pytest.mark.parametrize("disc, disc_v", [
    ((320.0, -480.0), (0.0, 25.0)),  # crosses y = 0 from the right when the robot comes by
    ((300.0, 300.0), (0.0, -25.0)),  # from the left
    ((700.0, 5.0), (-30.0, 0.0)),  # head-on, nearly on the robot's line
])
def test_closed_loop_reaches_the_goal_with_the_margin(disc, disc_v):
    """ORCA keeps every obstacle outside the robot's disc inflated by ``margin_cm`` (10 cm) for the chosen
    velocity; the executed step is that velocity when the turn is within the limit, so the swept gaps stay at
    or above the margin (to rounding), and the post and the disc were both close (the test has teeth)."""
    state, static_gap, moving_gap, _ = drive(disc, disc_v, POST, (600.0, 0.0))
    assert dist(state.position, (600.0, 0.0)) <= RADIUS
    assert CFG.margin_cm - 1e-6 <= static_gap < 30.0
    assert CFG.margin_cm - 1e-6 <= moving_gap < 60.0


def test_closed_loop_head_on_shows_why_full_responsibility():
    """Against a scripted disc head-on, the paper's reciprocal share (0.5) leaves half of the avoidance to
    an obstacle that never takes it, and the margin is broken; full responsibility keeps it."""
    _, _, full, _ = drive((600.0, 0.0), (-30.0, 0.0), NO_POINTS, (600.0, 0.0))
    _, _, half, _ = drive((600.0, 0.0), (-30.0, 0.0), NO_POINTS, (600.0, 0.0), {"reciprocity": 0.5})
    assert full >= CFG.margin_cm - 1e-6
    assert 0.0 < half < CFG.margin_cm - 1.0


def test_goal_behind_a_wall_is_a_local_minimum():
    """The method's known limitation: heading for a goal straight behind a wall, the robot slows down and
    stands in front of it for good, at its margin from the wall (no contact, no detour)."""
    xs = np.arange(-300.0, 300.0, 5.0)
    wall = np.column_stack([xs, np.full(len(xs), 50.0)])
    policy = make_policy("orca", {}, CTX)
    state = RobotState(0.0, -100.0, 90.0, 25.0)
    for _ in range(30):
        a = policy.act(observe(state, (0.0, 400.0), wall))
        state = step_unicycle(state, a.dtheta_deg, a.v_cm_s, 1.0, LIMITS)
    assert a.v_cm_s == 0.0 and state.v == 0.0
    gap = 50.0 - state.y - RADIUS
    assert CFG.margin_cm <= gap < CFG.margin_cm + LIMITS.v_min


def test_closed_loop_in_a_blocked_corridor_falls_back_without_contact():
    """A 90 cm corridor and a disc coming head-on: robot and disc (80 cm together, 100 cm with the margins)
    cannot pass, the half-planes become infeasible, and the fallback still never lets them touch: the robot
    turns and retreats down the corridor ahead of the disc (the walls reach far behind it, so it cannot
    leave around their ends)."""
    xs = np.arange(-1500.0, 700.0, 5.0)
    corridor = np.vstack([np.column_stack([xs, np.full(len(xs), 45.0)]),
                          np.column_stack([xs, np.full(len(xs), -45.0)])])
    state, static_gap, moving_gap, fallbacks = drive((650.0, 0.0), (-20.0, 0.0), corridor, (600.0, 0.0))
    assert fallbacks > 0
    assert static_gap > 0.0 and moving_gap > 0.0
    assert state.x < 0.0 and abs(state.y) < 45.0 - RADIUS
