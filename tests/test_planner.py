"""Dynamic path planning: the paper's worked example (Table 2 / Fig. 5), GetSuccessors, edge cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzynav.planning.planner import (
    PlannerConfig,
    find_collision_window,
    find_new_path,
    get_successors,
    path_collides,
    phi_low,
)
from fuzzynav.planning.tpt import build_tpt
from fuzzynav.sensing.tracking import Track


def paper_table():
    """Robot moving +y at 25 cm/s from (0, 0); obstacle 1 crossing at 20 cm/s along +x (φ = 0°) so that the
    discs (radius 20, margin 0) overlap at steps 6, 7 and 8 only; obstacle 2 far away never collides."""
    tracks = [Track(1, -140.0, 175.0, 20.0, 0.0, 20.0), Track(2, 400.0, 400.0, 0.0, -5.0, 20.0)]
    return build_tpt((0.0, 0.0), (0.0, 1000.0), 25.0, tracks, robot_radius=20.0, n_traj=9, dt=1.0,
                     safety_margin=0.0, swept=False)  # the paper samples the table at the steps


def test_table_collisions_at_steps_6_7_8():
    tpt = paper_table()
    assert tpt.collide.shape == (10, 2)
    assert [k for k in range(1, 10) if tpt.collide[k, 0]] == [6, 7, 8]
    assert not tpt.collide[:, 1].any()


def test_swept_table_catches_a_pass_between_samples():
    # robot +x at 40 cm/s, obstacle -x at 30 cm/s, 45 cm off the line: they pass between steps 1 and 2
    tracks = [Track(1, 100.0, 45.0, -30.0, 0.0, 18.0)]
    sampled = build_tpt((0.0, 0.0), (1000.0, 0.0), 40.0, tracks, 20.0, 9, 1.0, 10.0, swept=False)
    swept = build_tpt((0.0, 0.0), (1000.0, 0.0), 40.0, tracks, 20.0, 9, 1.0, 10.0, swept=True)
    assert not sampled.collide[:, 0].any()
    assert swept.collide[1:3, 0].any()


def test_paper_example_detours_with_h_wait_2():
    tpt = paper_table()
    assert find_collision_window(tpt) == (6, 5, 9, 0)
    plan = find_new_path(tpt, PlannerConfig(h_wait=2, safety_margin_cm=0.0), heading_deg=90.0)
    assert (plan.tc, plan.tS, plan.tG, plan.wait_time) == (6, 5, 9, 3)
    assert plan.strategy == "detour" and plan.detour_start == 4
    # rTraj(1 -> tS') is kept, then the detour; it ends within tolerance of rG = rTraj(9)
    np.testing.assert_allclose(plan.path[:4], tpt.robot[1:5])
    assert math.dist(plan.path[-1], tpt.robot_at(9)) <= 10.0
    assert not path_collides(tpt, plan.path, tpt.robot[0], None, 0.0)


def test_paper_example_waits_with_h_wait_4():
    tpt = paper_table()
    plan = find_new_path(tpt, PlannerConfig(h_wait=4, safety_margin_cm=0.0), heading_deg=90.0)
    assert plan.strategy == "wait" and plan.wait_time == 3
    # rTraj(1 -> tS-1) then rTraj(tS) repeated until step tG - 1 = 8
    np.testing.assert_allclose(plan.path[:4], tpt.robot[1:5])
    np.testing.assert_allclose(plan.path[4:], np.repeat(tpt.robot[5][None], 4, axis=0))
    assert len(plan.path) == 8


def test_get_successors_returns_57_positions():
    pos, speeds, headings, low = get_successors((0.0, 0.0), (0.0, 100.0), 0.0, (10.0, 25.0, 40.0), rule="paper")
    assert pos.shape == (57, 2) and low == 0.0
    np.testing.assert_allclose(headings[:19], np.arange(0, 181, 10))
    np.testing.assert_allclose(np.hypot(pos[:, 0], pos[:, 1]), speeds)
    np.testing.assert_allclose(pos[18 + 19], [-25.0, 0.0], atol=1e-9)  # 25 cm/s at 180°


@pytest.mark.parametrize("theta, phi, expected", [
    (90.0, 0.0, 0.0),      # line 42: φ < 180, θ < φ + 180 -> φLow = φ
    (300.0, 60.0, 240.0),  # line 43: φ < 180, θ >= φ + 180 -> φ + 180
    (100.0, 270.0, 90.0),  # line 46: φ >= 180, θ < φ -> φ - 180
    (300.0, 270.0, 270.0),  # line 47: φ >= 180, θ >= φ -> φ
])
def test_phi_low_branches_of_the_listing(theta, phi, expected):
    assert phi_low(theta, phi, "paper") == expected
    r_goal = (100 * math.cos(math.radians(theta)), 100 * math.sin(math.radians(theta)))
    _, _, headings, low = get_successors((0.0, 0.0), r_goal, phi, (10, 25, 40), rule="paper")
    assert low == pytest.approx(expected)
    np.testing.assert_allclose(headings[:19], (expected + np.arange(19) * 10.0) % 360.0)


def test_phi_low_target_side_and_toward_goal_contain_the_target():
    for theta in range(0, 360, 15):
        for phi in range(0, 360, 15):
            low = phi_low(theta, phi, "target_side")
            assert (theta - low) % 360 <= 180
            assert phi_low(theta, phi, "toward_goal") == pytest.approx((theta - 90) % 360)


def test_collision_at_step_1_waits_in_place():
    # obstacle about to cross just in front: tc = 1, tS = 0 (the present position)
    tracks = [Track(1, -45.0, 60.0, 30.0, 0.0, 20.0)]
    tpt = build_tpt((0.0, 0.0), (0.0, 500.0), 25.0, tracks, 20.0, 9, 1.0, 0.0)
    tc, t_s, t_g, _ = find_collision_window(tpt)
    assert (tc, t_s) == (1, 0)
    plan = find_new_path(tpt, PlannerConfig(strategy="wait", safety_margin_cm=0.0), heading_deg=90.0)
    assert plan.strategy == "wait"
    np.testing.assert_allclose(plan.path, np.zeros((t_g - 1, 2)))


def test_boxed_in_robot_stops():
    # static points all around at 25 cm and an obstacle coming straight at it: no wait, no detour
    ang = np.radians(np.arange(0, 360, 5))
    ring = np.stack([26 * np.cos(ang), 26 * np.sin(ang)], 1)
    tracks = [Track(1, 0.0, 120.0, 0.0, -30.0, 20.0)]
    tpt = build_tpt((0.0, 0.0), (0.0, 500.0), 25.0, tracks, 20.0, 9, 1.0, 10.0)
    for strategy in ("auto", "detour", "wait"):
        plan = find_new_path(tpt, PlannerConfig(strategy=strategy), 90.0, static_points=ring)
        assert plan.strategy == "stop" and len(plan.path) == 1


def test_detour_bound_is_respected():
    tpt = paper_table()
    cfg = PlannerConfig(h_wait=0, safety_margin_cm=0.0, detour_max_steps=1, strategy="detour")
    plan = find_new_path(tpt, cfg, heading_deg=90.0)
    # the detour fails; standing still is safe here, so the fallback waits in place
    assert plan.strategy == "wait" and "not reached" in plan.reason
    np.testing.assert_allclose(plan.path, np.zeros((plan.tG - 1, 2)))


def test_evade_when_standing_still_collides():
    # an obstacle coming straight at a robot that cannot detour (detour_max_steps=1): it side-steps
    tracks = [Track(1, 0.0, 150.0, 0.0, -40.0, 20.0)]
    tpt = build_tpt((0.0, 0.0), (0.0, 500.0), 25.0, tracks, 20.0, 9, 1.0, 10.0)
    plan = find_new_path(tpt, PlannerConfig(strategy="detour", detour_max_steps=1), heading_deg=90.0)
    assert plan.strategy == "evade" and len(plan.path) == 1
    assert abs(plan.path[0][0]) > 20  # moved sideways, off the obstacle's line
    no_evade = find_new_path(tpt, PlannerConfig(strategy="detour", detour_max_steps=1, evade_when_blocked=False),
                             heading_deg=90.0)
    assert no_evade.strategy == "stop"


def test_astar_search_also_reaches_rg():
    tpt = paper_table()
    plan = find_new_path(tpt, PlannerConfig(h_wait=2, safety_margin_cm=0.0, detour_search="astar"), 90.0)
    assert plan.strategy == "detour"
    assert math.dist(plan.path[-1], tpt.robot_at(9)) <= 10.0
    assert not path_collides(tpt, plan.path, tpt.robot[0], None, 0.0)


@pytest.mark.parametrize("kw, field", [({"h_wait": -1}, "planner.h_wait"), ({"n_traj": 0}, "planner.n_traj"),
                                       ({"strategy": "fly"}, "planner.strategy")])
def test_bad_planner_config_names_the_field(kw, field):
    with pytest.raises(ValueError, match=field):
        PlannerConfig(**kw)


def _wall_beside_rtraj() -> np.ndarray:
    """Laser returns of a wall whose end is 22 cm right of rTraj (x = 0, +y) at y = 62 cm, between steps 2 and 3:
    closer than the robot radius + static margin."""
    return np.array([[x, 62.0] for x in np.arange(22.0, 81.0, 2.0)])


def test_detour_prefix_backs_up_before_a_static_point():
    """The listing follows rTraj unchecked to rS' = rTraj(4); the end of a wall 22 cm off rTraj between steps 2
    and 3 (within the robot radius + static margin) moves the detour's start back to step 2, the last one
    reached clear of it."""
    tpt = paper_table()
    wall = _wall_beside_rtraj()
    plan = find_new_path(tpt, PlannerConfig(h_wait=2, safety_margin_cm=0.0, detour_search="astar"), heading_deg=90.0,
                         static_points=wall)
    assert plan.strategy == "detour" and plan.detour_start == 2
    assert "(tS' 4 -> 2: rTraj to step 3 passes a static point)" in plan.reason
    np.testing.assert_allclose(plan.path[:2], tpt.robot[1:3])
    clearance = tpt.robot_radius + PlannerConfig().static_margin_cm
    assert not path_collides(tpt, plan.path, tpt.robot[0], wall, clearance)
    # the listing's greedy search finds no way past the wall's end from there; its failure says where it started
    greedy = find_new_path(tpt, PlannerConfig(h_wait=2, safety_margin_cm=0.0), heading_deg=90.0, static_points=wall)
    assert greedy.strategy == "wait" and "(tS' 4 -> 2: rTraj to step 3 passes a static point)" in greedy.reason


def test_detour_prefix_unchecked_without_avoid_static_points():
    """``avoid_static_points: false`` (paper_literal) keeps the listing's rS' = rTraj(tS - 1)."""
    tpt = paper_table()
    plan = find_new_path(tpt, PlannerConfig(h_wait=2, safety_margin_cm=0.0, avoid_static_points=False),
                         heading_deg=90.0, static_points=_wall_beside_rtraj())
    assert plan.strategy == "detour" and plan.detour_start == 4 and "tS' 4 ->" not in plan.reason


def test_detour_prefix_clear_of_static_points_is_the_listings():
    tpt = paper_table()
    far = np.array([[300.0, y] for y in range(0, 200, 5)], dtype=float)
    plan = find_new_path(tpt, PlannerConfig(h_wait=2, safety_margin_cm=0.0), heading_deg=90.0, static_points=far)
    assert plan.detour_start == 4 and "->" not in plan.reason
