"""The artificial potential field baseline (fuzzynav/policies/apf.py, Khatib 1986): its forces on hand-made inputs,
the speed mapping, determinism, the registry, one closed-loop drive past an obstacle and the method's known
local minimum."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzynav.kinematics import RobotState
from fuzzynav.planning.layer import Observation
from fuzzynav.policies.apf import ApfConfig, ApfPolicy, apf_command, attractive_force, obstacle_discs, repulsive_force
from fuzzynav.policies.base import Policy, make_policy
from fuzzynav.sensing.tracking import Track
from tests import policy_scenes as scenes
from tests.policy_scenes import CTX, drive, in_laser_range, wall

CFG = ApfConfig()
NO_DISCS = (np.zeros((0, 2)), np.zeros(0))


def observe(state: RobotState, goal: tuple[float, float], points: np.ndarray,
            tracks: tuple[Track, ...] = ()) -> Observation:
    """What the robot senses: the obstacle points within laser range."""
    return scenes.observe(state, goal, in_laser_range(state, points), tracks)


def test_in_free_space_the_force_points_at_the_goal_conic_far_quadratic_near():
    # 500 cm away (beyond d* = 100): the constant far-field pull ξ·d* = 100 along (3, 4)/5
    assert attractive_force(0.0, 0.0, (300.0, 400.0), 1.0, 100.0) == pytest.approx((60.0, 80.0), rel=1e-15)
    # 50 cm away: ξ·(goal − x)
    assert attractive_force(10.0, 10.0, (40.0, 50.0), 1.0, 100.0) == (30.0, 40.0)
    dtheta, v, attraction, repulsion = apf_command(0.0, 0.0, 90.0, (300.0, 400.0), *NO_DISCS, CFG, 20.0,
                                                   10.0, 40.0, 1.0)
    assert dtheta == pytest.approx(math.degrees(math.atan2(400.0, 300.0)) - 90.0, abs=1e-12)
    assert (attraction, repulsion) == (pytest.approx(100.0, rel=1e-15), 0.0)
    # turning by -36.87°: full strength, slowed by cos(36.87°) = 0.8 -> 10 + 30 * 0.8
    assert v == pytest.approx(34.0, rel=1e-12)


def test_a_single_point_pushes_with_khatibs_magnitude_measured_from_the_robot_surface():
    # point 70 cm from the centre of a robot of radius 20: gap ρ = 50, ρ0 = 80, η = 1e6
    # η (1/ρ − 1/ρ0) / ρ² = 1e6 * (0.02 − 0.0125) / 2500 = 3.0, pointing away from the point (−x)
    fx, fy = repulsive_force(0.0, 0.0, np.array([[70.0, 0.0]]), np.zeros(1), 20.0, 1e6, 80.0, 1.0)
    assert fx == pytest.approx(-3.0, rel=1e-12) and fy == 0.0
    # a moving obstacle of radius 30 whose centre is 100 cm away has the same gap, hence the same push
    fx_disc, _ = repulsive_force(0.0, 0.0, np.array([[100.0, 0.0]]), np.array([30.0]), 20.0, 1e6, 80.0, 1.0)
    assert fx_disc == pytest.approx(-3.0, rel=1e-12)
    # the push is along the line from the point to the robot: a point at 45° pushes equally in x and y
    gx, gy = repulsive_force(0.0, 0.0, np.array([[-49.5, -49.5]]), np.zeros(1), 20.0, 1e6, 80.0, 1.0)
    assert gx == pytest.approx(gy, rel=1e-12) and gx > 0.0


def test_outside_the_influence_distance_nothing_pushes_and_contact_stays_finite():
    for x in (100.0, 101.0, 250.0):  # gaps 80 (= ρ0: potential and force both reach 0 there), 81, 230
        assert repulsive_force(0.0, 0.0, np.array([[x, 0.0]]), np.zeros(1), 20.0, 1e6, 80.0, 1.0) == (0.0, 0.0)
    # overlapping (centre distance 10 < robot radius): the gap is floored at 1 cm, η (1 − 1/80) away from it
    fx, fy = repulsive_force(0.0, 0.0, np.array([[10.0, 0.0]]), np.zeros(1), 20.0, 1e6, 80.0, 1.0)
    assert fx == pytest.approx(-1e6 * (1.0 - 1.0 / 80.0), rel=1e-12) and fy == 0.0


def test_symmetric_obstacles_cancel_sideways_and_the_order_of_points_does_not_matter():
    pts = np.array([[70.0, 30.0], [70.0, -30.0], [60.0, 45.5], [60.0, -45.5]])
    fx, fy = repulsive_force(0.0, 0.0, pts, np.zeros(4), 20.0, 1e6, 80.0, 1.0)
    assert fy == 0.0 and fx < 0.0
    # sums are correctly rounded (math.fsum), so any order of the returns gives the same bits
    assert repulsive_force(0.0, 0.0, pts[::-1], np.zeros(4), 20.0, 1e6, 80.0, 1.0) == (fx, fy)


def test_moving_obstacles_repel_from_their_predicted_position():
    track = Track(id=1, x=130.0, y=0.0, vx=-30.0, vy=0.0, radius=30.0)
    centres, radii = obstacle_discs(np.array([[0.0, 200.0]]), (track,), lookahead_s=1.0)
    assert centres.tolist() == [[0.0, 200.0], [100.0, 0.0]] and radii.tolist() == [0.0, 30.0]
    assert obstacle_discs(np.zeros((0, 2)), (track,), lookahead_s=0.0)[0].tolist() == [[130.0, 0.0]]
    # through the policy: the track 1 s ahead is 50 cm from the robot's surface (push 3.0), now it is 80 (0)
    obs = Observation(RobotState(0.0, 0.0, 0.0), (1000.0, 0.0), (130.0, 130.0, 130.0), (track,), np.zeros((0, 2)))
    assert make_policy("apf", {}, CTX).act(obs).fields["repulsive"] == pytest.approx(3.0, rel=1e-12)
    assert make_policy("apf", {"lookahead_s": 0}, CTX).act(obs).fields["repulsive"] == 0.0


def test_speed_slows_when_the_force_points_away_and_lands_on_the_goal():
    # force straight behind: turn 180 (the robot clamps it), v_min
    dtheta, v, _, _ = apf_command(0.0, 0.0, 0.0, (-500.0, 0.0), *NO_DISCS, CFG, 20.0, 10.0, 40.0, 1.0)
    assert abs(dtheta) == 180.0 and v == 10.0
    # 50 cm ahead (quadratic zone): strength 50/100 -> 10 + 30 * 0.5 = 25 cm/s
    assert apf_command(0.0, 0.0, 0.0, (50.0, 0.0), *NO_DISCS, CFG, 20.0, 10.0, 40.0, 1.0)[:2] == (0.0, 25.0)
    # 15 cm ahead: 10 + 30 * 0.15 = 14.5 cm/s, short of the 15 that would land on it in one step
    assert apf_command(0.0, 0.0, 0.0, (15.0, 0.0), *NO_DISCS, CFG, 20.0, 10.0, 40.0, 1.0)[1] == 14.5
    # 30 cm ahead with a strong push from behind: at most what lands on the goal
    behind = (np.array([[-30.0, 0.0]]), np.zeros(1))
    assert apf_command(0.0, 0.0, 0.0, (30.0, 0.0), *behind, CFG, 20.0, 10.0, 40.0, 1.0)[1] == 30.0
    # on the goal with nothing around: no force, no direction: stand still
    assert apf_command(5.0, 5.0, 0.0, (5.0, 5.0), *NO_DISCS, CFG, 20.0, 10.0, 40.0, 1.0)[:2] == (0.0, 0.0)


def test_same_input_gives_the_same_bits():
    rng = np.random.default_rng(7)
    pts = rng.uniform(-200.0, 200.0, size=(300, 2))
    tracks = (Track(1, 50.0, 60.0, -10.0, 5.0, 25.0), Track(2, -80.0, 10.0, 20.0, 0.0, 30.0))
    obs = Observation(RobotState(3.0, -4.0, 33.0, 20.0), (400.0, 300.0), (130.0, 130.0, 130.0), tracks, pts)
    first, second = make_policy("apf", {}, CTX).act(obs), make_policy("apf", {}, CTX).act(obs)
    assert first == second and first.mode == "apf"
    assert np.array([first.dtheta_deg, first.v_cm_s]).tobytes() == np.array([second.dtheta_deg,
                                                                              second.v_cm_s]).tobytes()


def test_registry_builds_apf_and_names_a_bad_parameter():
    policy = make_policy("apf", {"repulsive_gain": 5e5, "influence_cm": 60}, CTX)
    assert isinstance(policy, ApfPolicy) and isinstance(policy, Policy)
    assert policy.config.repulsive_gain == 5e5 and policy.config.influence_cm == 60.0
    for params, problem in (({"influence_cm": 0}, r"navigator\.influence_cm: must be in \(0, 10,000\] cm"),
                            ({"lookahead_s": -1}, r"navigator\.lookahead_s: must be in \[0, 60\] s"),
                            ({"attractive_gain": -2}, r"navigator\.attractive_gain: must be"),
                            ({"min_gap_cm": 90}, r"navigator\.min_gap_cm: must be below influence_cm"),
                            ({"eta": 1}, r"navigator\.eta: unknown key")):
        with pytest.raises(ValueError, match=problem):
            make_policy("apf", params, CTX)


def test_closed_loop_reaches_the_goal_around_an_obstacle_without_contact():
    # an 80 cm wall across the straight line, centred 25 cm to the left of it: the repulsion has a sideways
    # part from the start, so the robot is not on the symmetric local minimum (next test) and passes right
    points = wall(300.0, -15.0, 65.0)
    states, closest = drive(make_policy("apf", {}, CTX), (600.0, 0.0), points, steps=60)
    end = states[-1]
    assert math.hypot(end.x - 600.0, end.y) <= 20.0, end
    assert closest > CTX.robot_radius, closest  # never touched the wall
    assert min(s.y for s in states) < -15.0 - CTX.robot_radius  # went round the wall's right-hand end
    assert len(states) - 1 < 40


def test_known_local_minimum_a_wide_symmetric_wall_ahead_traps_the_robot():
    """Documented property of potential fields (Khatib 1986; Koren & Borenstein 1991), not a failure: a
    300 cm wall straight across the line to the goal, symmetric about it. Where the repulsion balances the
    attraction the robot turns back and forth (the 180° turn is taken clockwise, which breaks the symmetry
    for a moment, but the pull of the goal brings it back to the line) and never gets round."""
    points = wall(300.0, -150.0, 150.0)
    states, closest = drive(make_policy("apf", {}, CTX), (600.0, 0.0), points, steps=80)
    assert len(states) == 81  # no arrival in 80 steps
    late = states[20:]
    # stuck in a small region in front of the wall, close to the line, without touching the wall
    assert all(200.0 < s.x < 300.0 - CTX.robot_radius and abs(s.y) < 20.0 for s in late)
    assert closest > CTX.robot_radius
    # it oscillates rather than stands: every 4 steps it turns away (heading near 240°) and back
    assert sum(1 for s in late if 90.0 < s.heading < 270.0) >= len(late) // 4
