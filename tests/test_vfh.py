"""The vector field histogram baseline (fuzzynav/policies/vfh.py, Borenstein & Koren 1991 with the VFH+ enlargement):
histogram, smoothing, valleys, steering and speed on hand-made inputs, determinism, the registry and one
closed-loop drive past an obstacle (the drive helpers are test_apf's, so both baselines face the same
obstacle)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzynav.kinematics import RobotState
from fuzzynav.planning.layer import Observation
from fuzzynav.policies.base import Policy, make_policy
from fuzzynav.policies.vfh import (
    VfhConfig,
    VfhPolicy,
    occupied_cells,
    perimeter_points,
    polar_histogram,
    smooth_histogram,
    steering_direction,
    valleys,
    vfh_command,
    vfh_speed,
)
from fuzzynav.sensing.tracking import Track
from tests.policy_scenes import CTX, drive, wall

CFG = VfhConfig()
NO_POINTS = np.zeros((0, 2))


def histogram_with_valleys(free: list[range], n: int = 72) -> np.ndarray:
    """A smoothed histogram (n sectors) at 200 (above the default threshold of 100) except 0 in ``free``."""
    h = np.full(n, 200.0)
    for sectors in free:
        h[list(sectors)] = 0.0
    return h


def test_points_are_binned_into_distinct_cells():
    pts = np.array([[101.0, 12.0], [109.0, 19.0], [111.0, 12.0], [-0.5, -0.5]])
    assert occupied_cells(pts, 10.0).tolist() == [[-5.0, -5.0], [105.0, 15.0], [115.0, 15.0]]
    assert occupied_cells(pts[::-1], 10.0).tolist() == occupied_cells(pts, 10.0).tolist()
    assert occupied_cells(NO_POINTS, 10.0).shape == (0, 2)


def test_a_single_cell_lands_in_its_sector_with_the_hand_computed_magnitude():
    # robot at (5, 5); the cell centred at (105, 15): d = sqrt(100² + 10²), β = atan(10/100) = 5.71° ->
    # sector 1 of 5°; magnitude a − b·d = 160 − d (a = b·window = 160, b = 1, certainty 1)
    cell = occupied_cells(np.array([[101.0, 12.0]]), 10.0)
    expected = 160.0 - math.sqrt(10100.0)
    h = polar_histogram(5.0, 5.0, cell, CFG, enlarge_cm=0.0)
    assert h[1] == pytest.approx(expected, rel=1e-12) and np.count_nonzero(h) == 1
    # enlarged by r = 30 cm: γ = asin(30/d) = 17.37°, so [β − γ, β + γ] = [−11.66°, 23.08°] meets the
    # sectors 69, 70, 71 (wrapping round 0°), 0, 1, 2, 3 and 4, each with the same magnitude
    h = polar_histogram(5.0, 5.0, cell, CFG, enlarge_cm=30.0)
    assert np.flatnonzero(h).tolist() == [0, 1, 2, 3, 4, 69, 70, 71]
    assert h[np.flatnonzero(h)] == pytest.approx([expected] * 8, rel=1e-12)
    # at or beyond the window's edge (160 cm) a cell counts for nothing
    assert not polar_histogram(0.0, 0.0, np.array([[160.0, 0.0], [0.0, 170.0]]), CFG, 30.0).any()
    # a cell closer than the enlargement blocks the whole half plane towards it: 180° of 5° sectors, +1
    # because the interval [−90°, 90°] ends exactly on sector borders
    assert np.count_nonzero(polar_histogram(0.0, 0.0, np.array([[15.0, 5.0]]), CFG, 30.0)) == 37


def test_smoothing_by_hand_wraps_round():
    # l = 3: weights 1 2 3 2 1 over sectors k−2 .. k+2, divided by 2l + 1 = 7
    h = np.zeros(12)
    h[5], h[0] = 7.0, 14.0
    assert smooth_histogram(h, 3).tolist() == [6.0, 4.0, 2.0, 1.0, 2.0, 3.0, 2.0, 1.0, 0.0, 0.0, 2.0, 4.0]
    # l = 5 (the paper's): one sector's density spreads over 9 sectors, at most 5/11 of it
    h = np.zeros(72)
    h[40] = 11.0
    assert np.flatnonzero(smooth_histogram(h, 5)).tolist() == list(range(36, 45))
    assert smooth_histogram(h, 5)[40] == 5.0
    # l = 1 leaves the histogram as it is, divided by 3
    assert smooth_histogram(np.array([3.0, 6.0, 9.0]), 1).tolist() == [1.0, 2.0, 3.0]


def test_valleys_are_circular_runs_of_free_sectors():
    free = np.array([True, True, False, False, True, True, True, False, True, True])
    assert valleys(free) == [(4, 3), (8, 4)]  # the second wraps round: sectors 8, 9, 0, 1
    assert valleys(np.ones(6, bool)) == [(0, 6)] and valleys(np.zeros(6, bool)) == []


def test_valley_selection_picks_the_valley_nearest_the_target():
    # two narrow valleys: sectors 10..14 (centre 62.5°) and 30..33 (centre 160°)
    h = histogram_with_valleys([range(10, 15), range(30, 34)])
    assert steering_direction(h, 100.0, CFG) == (62.5, 2)  # sector 20: 6 sectors from 14, 10 from 30
    assert steering_direction(h, 125.0, CFG) == (160.0, 2)  # sector 25: 11 from 14, 5 from 30
    assert steering_direction(h, 110.0, CFG) == (160.0, 2)  # sector 22: 8 and 8, the tie goes counter-clockwise
    assert steering_direction(h, 61.0, CFG) == (62.5, 2)  # inside a narrow valley: its centre


def test_wide_valley_steers_half_s_max_from_the_near_border_or_at_a_clear_target():
    h = histogram_with_valleys([range(0, 36)])  # 36 free sectors > s_max = 18: wide
    assert steering_direction(h, 90.0, CFG) == (90.0, 1)  # sector 18: 18 and 17 sectors from the borders
    # near the first border (sector 0) or counter-clockwise outside it: 9 sectors in from it, (0.5 + 9)·5°
    assert steering_direction(h, 20.0, CFG) == (47.5, 1)
    assert steering_direction(h, 350.0, CFG) == (47.5, 1)
    # near the last border (sector 35) or clockwise outside it: (35.5 − 9)·5°
    assert steering_direction(h, 170.0, CFG) == (132.5, 1)
    assert steering_direction(h, 200.0, CFG) == (132.5, 1)
    # nothing above the threshold: straight at the target; everything above it: no direction
    assert steering_direction(np.zeros(72), 123.4, CFG) == (123.4, 1)
    assert steering_direction(np.full(72, 100.0), 123.4, CFG) == (None, 0)


def test_blocked_ahead_steers_into_the_free_valley():
    # a wall 100 cm ahead from 150 cm right to 40 cm left of the line to the goal: free only round its left end
    mode, dtheta, v, fields = vfh_command(0.0, 0.0, 0.0, (500.0, 0.0), wall(100.0, -150.0, 40.0), (), CFG,
                                          20.0, 10.0, 40.0, 1.0)
    assert mode == "vfh" and fields["valleys"] == 1
    # beyond the wall's left end enlarged by robot radius + safety (atan(70/100) = 35°), turning left
    assert math.degrees(math.atan2(70.0, 100.0)) < fields["direction_deg"] < 90.0 and dtheta == fields["direction_deg"]
    assert fields["density_heading"] > CFG.h_m and v == 10.0  # the heading's sector is blocked: v_min


def test_no_valley_means_stand_still():
    ring = np.array([[50.0 * math.cos(math.radians(a)), 50.0 * math.sin(math.radians(a))] for a in range(0, 360, 3)])
    mode, dtheta, v, fields = vfh_command(0.0, 0.0, 30.0, (500.0, 0.0), ring, (), CFG, 20.0, 10.0, 40.0, 1.0)
    assert (mode, dtheta, v) == ("vfh_stop", 0.0, 0.0)
    assert fields["valleys"] == 0 and fields["direction_deg"] == 30.0


def test_speed_reduction_follows_the_paper_within_the_robot_limits():
    assert vfh_speed(50.0, 200.0, 10.0, 40.0, 1000.0, 1.0) == 30.0  # 40 · (1 − 50/200)
    assert vfh_speed(0.0, 200.0, 10.0, 40.0, 1000.0, 1.0) == 40.0
    assert vfh_speed(190.0, 200.0, 10.0, 40.0, 1000.0, 1.0) == 10.0  # 2 cm/s is below v_min
    assert vfh_speed(500.0, 200.0, 10.0, 40.0, 1000.0, 1.0) == 10.0  # h''_c = min(h'_c, h_m)
    assert vfh_speed(0.0, 200.0, 10.0, 40.0, 25.0, 1.0) == 25.0  # lands on the goal
    assert vfh_speed(0.0, 200.0, 10.0, 40.0, 4.0, 1.0) == 10.0


def test_moving_obstacles_are_discs_sampled_on_their_perimeter_at_their_present_position():
    track = Track(id=3, x=90.0, y=0.0, vx=-30.0, vy=0.0, radius=30.0)
    pts = perimeter_points((track,), 10.0)
    assert len(pts) == math.ceil(2.0 * math.pi * 30.0 / 10.0)  # 19: no two more than 10 cm apart
    assert np.hypot(pts[:, 0] - 90.0, pts[:, 1]) == pytest.approx(np.full(len(pts), 30.0), rel=1e-12)
    assert len(perimeter_points((Track(4, 0.0, 0.0, 0.0, 0.0, 5.0),), 10.0)) == 8  # at least 8 per disc
    # the same disc as static returns or as a track: the same command
    as_track = vfh_command(0.0, 0.0, 0.0, (500.0, 0.0), NO_POINTS, (track,), CFG, 20.0, 10.0, 40.0, 1.0)
    as_points = vfh_command(0.0, 0.0, 0.0, (500.0, 0.0), pts, (), CFG, 20.0, 10.0, 40.0, 1.0)
    assert as_track == as_points and as_track[1] != 0.0


def test_same_input_gives_the_same_bits_in_any_order_of_the_returns():
    rng = np.random.default_rng(11)
    pts = rng.uniform(-200.0, 200.0, size=(300, 2))
    tracks = (Track(1, 50.0, 60.0, -10.0, 5.0, 25.0),)
    state = RobotState(3.0, -4.0, 33.0, 20.0)
    first = make_policy("vfh", {}, CTX).act(Observation(state, (400.0, 300.0), (130.0,) * 3, tracks, pts))
    again = make_policy("vfh", {}, CTX).act(Observation(state, (400.0, 300.0), (130.0,) * 3, tracks, pts[::-1]))
    assert first == again and first.mode in ("vfh", "vfh_stop")
    assert np.array([first.dtheta_deg, first.v_cm_s, first.fields["density_heading"]]).tobytes() == np.array(
        [again.dtheta_deg, again.v_cm_s, again.fields["density_heading"]]).tobytes()


def test_registry_builds_vfh_and_names_a_bad_parameter():
    policy = make_policy("vfh", {"sector_deg": 10, "threshold": 150}, CTX)
    assert isinstance(policy, VfhPolicy) and isinstance(policy, Policy)
    assert policy.config.sectors == 36 and policy.config.threshold == 150.0
    for params, problem in (({"sector_deg": 7}, r"navigator\.sector_deg: must divide 360"),
                            ({"smoothing_l": 0}, r"navigator\.smoothing_l: must be in \[1, 180\] sectors"),
                            ({"smoothing_l": 37}, r"navigator\.smoothing_l: must be in \[1, 36\]"),
                            ({"threshold": -1}, r"navigator\.threshold: must be in \(0, "),
                            ({"wide_valley_sectors": 72}, r"navigator\.wide_valley_sectors: must be in \[1, 71\]"),
                            ({"safety_cm": -5}, r"navigator\.safety_cm: must be in \[0, 1,000\] cm"),
                            ({"window_cm": 5}, r"navigator\.window_cm: must exceed cell_cm"),
                            ({"alpha": 5}, r"navigator\.alpha: unknown key")):
        with pytest.raises(ValueError, match=problem):
            make_policy("vfh", params, CTX)


def test_closed_loop_reaches_the_goal_around_an_obstacle_without_contact():
    # the APF test's obstacle: an 80 cm wall across the straight line, centred 25 cm to its left
    points = wall(300.0, -15.0, 65.0)
    states, closest = drive(make_policy("vfh", {}, CTX), (600.0, 0.0), points, steps=60)
    end = states[-1]
    assert math.hypot(end.x - 600.0, end.y) <= 20.0, end
    assert closest > CTX.robot_radius + CFG.safety_cm, closest  # kept the enlargement's margin
    assert min(s.y for s in states) < -15.0 - CTX.robot_radius  # went round the wall's right-hand end
    assert len(states) - 1 < 30
