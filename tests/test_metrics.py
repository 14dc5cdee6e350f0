"""Metrics pinned on hand-made logs with known answers, and the interval statistics."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.episode_log import load_episode
from analysis.metrics import MetricOptions, episode_metrics, median_and_p99, metrics_table, turn_count
from analysis.stats import bootstrap_mean, excludes_zero, wilson
from tests.handmade import write_log


def square_poses():
    """A 100 cm square in 50 cm steps, turning left (+90°) at each corner, the last turn in place."""
    return [(0, 0, 0), (50, 0, 0), (100, 0, 0), (100, 50, 90), (100, 100, 90), (50, 100, 180), (0, 100, 180),
            (0, 50, 270), (0, 0, 270), (0, 0, 0)]


def test_square_path_has_known_length_and_four_turns(tmp_path):
    log = load_episode(write_log(tmp_path / "square.mcap", square_poses(), goal=(0.0, 0.0), outcome="timeout"))
    m = episode_metrics(log)
    assert m["path_length_cm"] == pytest.approx(400.0)
    assert m["turn_count"] == 4
    assert m["heading_change_deg_total"] == pytest.approx(360.0)
    assert m["collisions_static"] == 0 and m["collisions_dynamic"] == 0 and m["collision_check_agrees"]
    assert m["steps"] == 9 and m["outcome"] == "timeout" and not m["success"]
    assert m["min_clearance_static_cm"] == pytest.approx(200 - 20)  # walls at -200 and 800


def test_turn_count_merges_same_sign_runs_and_ignores_small_changes():
    assert turn_count(np.array([10, 10, 0, -10, -10, 10])) == 3
    assert turn_count(np.array([4.9, -4.9, 3.0])) == 0
    assert turn_count(np.array([30.0, 30.0, 30.0])) == 1
    assert turn_count(np.array([6.0, 6.0]), threshold_deg=7.0) == 0


def test_touching_a_static_obstacle_twice_counts_two_contacts(tmp_path):
    box = [(200, 30), (300, 30), (300, 100), (200, 100)]
    # along y = 0 (clear: 30 - 20 = 10 cm), dip to y = 15 (touching), back out, a clear step, dip again;
    # contact is swept over each step, so the steps into and out of a dip both touch
    poses = [(100, 0, 0), (150, 0, 0), (200, 15, 0), (230, 0, 0), (260, 0, 0), (290, 15, 0), (320, 0, 0),
             (400, 0, 0)]
    contacts = [False, True, True, False, True, True, False]
    log = load_episode(write_log(tmp_path / "touch.mcap", poses, statics=[box], contacts_static=contacts,
                                 outcome="goal", goal=(400.0, 0.0)))
    m = episode_metrics(log)
    assert m["collisions_static"] == 2
    assert m["collision_check_agrees"] and m["collisions_logged_static"] == 2
    assert m["min_clearance_static_cm"] < 0
    assert not m["success"]  # reached the goal, but with contacts


def test_disagreement_with_the_simulator_flags_is_reported(tmp_path):
    box = [(200, 30), (300, 30), (300, 100), (200, 100)]
    poses = [(100, 0, 0), (150, 0, 0), (200, 15, 0), (230, 0, 0)]
    log = load_episode(write_log(tmp_path / "lie.mcap", poses, statics=[box], contacts_static=[False] * 3))
    m = episode_metrics(log)
    assert m["collisions_static"] == 1 and m["collisions_logged_static"] == 0 and not m["collision_check_agrees"]


def test_a_wait_of_three_steps(tmp_path):
    poses = [(0, 0, 0), (25, 0, 0), (25, 0, 0), (25, 0, 0), (25, 0, 0), (50, 0, 0), (75, 0, 0)]
    modes = ["direct", "wait", "wait", "wait", "direct", "direct"]
    speeds = [25.0, 0.0, 0.0, 0.0, 25.0, 25.0]
    log = load_episode(write_log(tmp_path / "wait.mcap", poses, modes=modes, speeds=speeds, goal=(75.0, 0.0)))
    m = episode_metrics(log)
    assert m["wait_steps"] == 3
    assert m["time_to_goal_s"] == 6.0 and m["success"]
    assert m["path_efficiency"] == pytest.approx(1.0)
    assert m["compute_time_us_median"] == pytest.approx(12.5)


def test_dynamic_contact_and_clearance_from_truth(tmp_path):
    poses = [(0, 0, 0), (40, 0, 0), (80, 0, 0)]
    obstacles = [[("o", 100, 0, 60, 0, 20)], [("o", 60, 0, 20, 0, 20)]]  # head-on, passes through the robot
    log = load_episode(write_log(tmp_path / "hit.mcap", poses, obstacles=obstacles, outcome="collision"))
    m = episode_metrics(log)
    assert m["collisions_dynamic"] == 1
    assert m["min_clearance_dynamic_cm"] == pytest.approx(-40.0)


def test_bad_logs_are_left_out_with_a_reason(tmp_path):
    write_log(tmp_path / "good.mcap", square_poses(), goal=(0.0, 0.0))
    write_log(tmp_path / "err.mcap", square_poses(), outcome="error")
    write_log(tmp_path / "cut.mcap", square_poses(), truncate=True)
    (tmp_path / "junk.mcap").write_bytes(b"\x00not an mcap" * 10)
    (tmp_path / "empty.mcap").write_bytes(b"")
    rows, bad = metrics_table([tmp_path])
    assert len(rows) == 1 and rows.iloc[0]["log"].endswith("good.mcap")
    reasons = dict(zip([p.split("/")[-1] for p in bad["log"]], bad["reason"], strict=True))
    assert set(reasons) == {"err.mcap", "cut.mcap", "junk.mcap", "empty.mcap"}
    assert "raised" in reasons["err.mcap"] and "truncated" in reasons["cut.mcap"]
    assert "junk.mcap" in reasons["junk.mcap"]


@pytest.mark.parametrize("workers", ["forked", "joblib"])
def test_parallel_metrics_table_equals_the_serial_one(tmp_path, monkeypatch, workers, request):
    """In workers forked from this process (analysis.forked), or in joblib's pool where it cannot fork (a sweep's
    launcher runs threads): the same rows in the same order."""
    import analysis.forked
    import analysis.logs

    for k in range(6):
        write_log(tmp_path / f"good{k}.mcap", square_poses()[: 4 + k], goal=(0.0, 0.0))
    write_log(tmp_path / "err.mcap", square_poses(), outcome="error")
    write_log(tmp_path / "cut.mcap", square_poses(), truncate=True)
    (tmp_path / "junk.mcap").write_bytes(b"\x00not an mcap" * 10)
    serial_rows, serial_bad = metrics_table([tmp_path])
    if workers == "forked":
        request.getfixturevalue("forkable")  # tests/conftest.py
        monkeypatch.setattr(analysis.logs, "FORK_MIN_LOGS", 1)  # 9 logs in 5 chunks over 2 processes
    else:
        monkeypatch.setattr(analysis.forked, "can_fork", lambda: False)
        monkeypatch.setattr(analysis.logs, "PARALLEL_MIN_LOGS", 1)  # 9 logs in 5 chunks over 2 workers
    rows, bad = metrics_table([tmp_path], jobs=2)
    assert len(rows) == 6 and len(bad) == 3
    assert rows.equals(serial_rows) and bad.equals(serial_bad)  # same rows, same order


def test_wilson_interval_known_values():
    p, lo, hi = wilson(5, 5)
    assert p == 1.0 and lo == pytest.approx(0.5655, abs=1e-3) and hi == 1.0
    p, lo, hi = wilson(0, 10)
    assert p == 0.0 and lo == 0.0 and hi == pytest.approx(0.2775, abs=1e-3)
    assert all(math.isnan(v) for v in wilson(0, 0))
    for n in range(1, 200):  # the exact ends, not 5.6e-17 or 1 - 1.1e-16
        assert wilson(0, n)[1] == 0.0 and wilson(n, n)[2] == 1.0
        assert (wilson(1, n)[1] > 0.0 and wilson(n - 1, n)[2] < 1.0) or n == 1


def test_text_cells_cannot_break_a_markdown_table():
    import pandas as pd

    from analysis.report import _markdown_table

    text = _markdown_table(pd.DataFrame({"log": ["a|b.mcap", "x\ny.mcap"], "n": [1, 2]}))
    rows = text.splitlines()
    assert len(rows) == 4 and all(len(re.split(r"(?<!\\)\|", row)) == 4 for row in rows), text
    assert "a\\|b.mcap" in text and "x y.mcap" in text


def test_bootstrap_is_seeded_and_brackets_the_mean():
    x = np.arange(20.0)
    a, b = bootstrap_mean(x), bootstrap_mean(x)
    assert a == b and a[1] < a[0] < a[2]
    assert bootstrap_mean([3.0, 3.0, 3.0]) == (3.0, 3.0, 3.0)
    assert excludes_zero(0.1, 2.0) and not excludes_zero(-1.0, 2.0)


# -- the standard navigation metrics (issue #18), each on a hand-made log with values worked out by hand ----------
def with_true_velocities(src, dst, dt: float = 1.0):
    """Copy a hand-made log, setting each obstacle's logged velocity to its move over the step / dt (cm/s)."""
    from tests.handmade import rewrite_log

    def edit(topic, msg):
        if topic == "/obstacles/truth":
            for o in msg["obstacles"]:
                o["vx_cm_s"], o["vy_cm_s"] = (o["next_x_cm"] - o["x_cm"]) / dt, (o["next_y_cm"] - o["y_cm"]) / dt

    rewrite_log(src, dst, edit)
    return dst


def test_spl_acceleration_jerk_and_stalled_time(tmp_path):
    # along +x to a goal at 100 cm (tolerance 20 cm), standing still for one step half-way; dt = 1 s
    poses = [(0, 0, 0), (25, 0, 0), (50, 0, 0), (50, 0, 0), (75, 0, 0), (100, 0, 0)]
    path = write_log(tmp_path / "line.mcap", poses, goal=(100.0, 0.0), speeds=[25.0, 25.0, 0.0, 25.0, 25.0])
    m = episode_metrics(load_episode(path))
    assert m["success"] and m["path_length_cm"] == pytest.approx(100.0)
    assert m["spl"] == pytest.approx(80.0 / 100.0)  # shortest = 100 − 20 (tolerance); path 100
    # move velocities 25, 25, 0, 25, 25 cm/s: |Δv| = 0, 25, 25, 0; |Δ²v| = 25, 50, 25
    assert m["accel_mean_cm_s2"] == pytest.approx(12.5) and m["accel_max_cm_s2"] == pytest.approx(25.0)
    assert m["jerk_mean_cm_s3"] == pytest.approx(100.0 / 3) and m["jerk_max_cm_s3"] == pytest.approx(50.0)
    assert m["stalled_time_s"] == pytest.approx(1.0)  # step 2: speed 0 at 50 cm from the goal
    assert m["path_irregularity_deg_per_m"] == 0.0  # facing the goal all the way
    assert math.isnan(m["min_ttc_s"])  # no moving obstacle: nothing to measure
    assert m["near_miss_steps"] == 0 and m["personal_space_intrusion_s"] == 0
    slow = episode_metrics(load_episode(path), MetricOptions(stall_speed_cm_s=30.0))
    assert slow["stalled_time_s"] == pytest.approx(5.0)  # every step is slower than 30 cm/s and away from the goal


def test_spl_is_zero_on_failure_and_acceleration_counts_turns(tmp_path):
    log = load_episode(write_log(tmp_path / "square.mcap", square_poses(), goal=(0.0, 0.0), outcome="timeout"))
    m = episode_metrics(log)
    assert m["spl"] == 0.0
    # moves of 50 cm/s along x, then y, ...: a corner turns the velocity by 90° at constant speed, |Δv| = 50√2
    assert m["accel_max_cm_s2"] == pytest.approx(50 * math.sqrt(2))
    assert m["stalled_time_s"] == 0.0  # the last step turns in place at the goal: at the goal, not stalled


def test_path_irregularity_discounts_the_turn_to_face_the_goal(tmp_path):
    # facing +y, the goal along +x: the 90° turn in place is needed, the rest is straight -> 0
    turn = [(0, 0, 90), (0, 0, 0), (50, 0, 0), (100, 0, 0)]
    m = episode_metrics(load_episode(write_log(tmp_path / "turn.mcap", turn, goal=(100.0, 0.0))))
    assert m["heading_change_deg_total"] == pytest.approx(90.0) and m["path_irregularity_deg_per_m"] == 0.0
    # facing the goal, weaving by 30° and back over 1 m: 60° of unneeded rotation per metre
    weave = [(0, 0, 0), (50, 0, 30), (100, 0, 0)]
    m = episode_metrics(load_episode(write_log(tmp_path / "weave.mcap", weave, goal=(100.0, 0.0))))
    assert m["path_irregularity_deg_per_m"] == pytest.approx(60.0)


def test_min_time_to_collision_head_on(tmp_path):
    # robot +x at 40 cm/s, obstacle from x = 300 at −60 cm/s, radii 20 + 20: closing at 100 cm/s
    poses = [(0, 0, 0), (40, 0, 0), (80, 0, 0)]
    obstacles = [[("o", 300, 0, 240, 0, 20)], [("o", 240, 0, 180, 0, 20)]]
    raw = write_log(tmp_path / "raw.mcap", poses, obstacles=obstacles, goal=(80.0, 0.0))
    m = episode_metrics(load_episode(with_true_velocities(raw, tmp_path / "ttc.mcap")))
    assert m["min_ttc_s"] == pytest.approx((200 - 40) / 100)  # step 1: 200 cm apart, 40 cm of radii: 1.6 s
    # the same obstacle moving away at +60 cm/s: never on a collision course -> inf
    away = [[("o", 300, 0, 360, 0, 20)], [("o", 360, 0, 420, 0, 20)]]
    raw = write_log(tmp_path / "raw2.mcap", poses, obstacles=away, goal=(80.0, 0.0))
    assert episode_metrics(load_episode(with_true_velocities(raw, tmp_path / "away.mcap")))["min_ttc_s"] == math.inf


def test_min_time_to_collision_is_zero_in_contact(tmp_path):
    poses = [(0, 0, 0), (40, 0, 0), (80, 0, 0)]
    obstacles = [[("o", 100, 0, 60, 0, 20)], [("o", 60, 0, 20, 0, 20)]]  # overlapping at step 1 (20 cm apart)
    raw = write_log(tmp_path / "raw.mcap", poses, obstacles=obstacles, outcome="collision")
    assert episode_metrics(load_episode(with_true_velocities(raw, tmp_path / "hit.mcap")))["min_ttc_s"] == 0.0


def test_near_misses_and_personal_space(tmp_path):
    # along y = 0 past a box whose lower edge is at y = 35 (x 90..110): steps 1 and 2 pass 35 − 20 = 15 cm from it;
    # a standing pedestrian (radius 20) at (0, −80): step 0 passes 80 − 40 = 40 cm from its surface
    box = [(90, 35), (110, 35), (110, 60), (90, 60)]
    poses = [(0, 0, 0), (50, 0, 0), (100, 0, 0), (150, 0, 0)]
    obstacles = [[("p", 0, -80, 0, -80, 20)]] * 3
    path = write_log(tmp_path / "pass.mcap", poses, statics=[box], obstacles=obstacles, goal=(150.0, 0.0))
    m = episode_metrics(load_episode(path))
    assert m["near_miss_steps"] == 2  # 15 cm < 20 cm on steps 1 and 2; step 0: 40 cm and √(40² + 35²) − 20
    assert m["personal_space_intrusion_s"] == pytest.approx(1.0)  # 40 cm < 45 cm on step 0 only
    assert m["min_ttc_s"] == math.inf  # passes 80 cm from the centre: the 40 cm of radii are never reached
    wide = episode_metrics(load_episode(path), MetricOptions(near_miss_cm=50.0, personal_space_cm=60.0))
    assert wide["near_miss_steps"] == 3  # step 0: min(33.2, 40) < 50
    assert wide["personal_space_intrusion_s"] == pytest.approx(2.0)  # step 1: √(50² + 80²) − 40 = 54.3 < 60


def test_collisions_are_split_into_walls_and_static_obstacles(tmp_path):
    # the wall at x = 800: the move to x = 790 and the move back touch it (radius 20): one contact
    poses = [(700, 0, 0), (750, 0, 0), (790, 0, 0), (750, 0, 0), (700, 0, 0)]
    path = write_log(tmp_path / "wall.mcap", poses, contacts_static=[False, True, True, False], outcome="timeout")
    m = episode_metrics(load_episode(path))
    assert (m["collisions_wall"], m["collisions_static_obstacle"], m["collisions_static"]) == (1, 0, 1)
    box = [(200, 30), (300, 30), (300, 100), (200, 100)]
    poses = [(100, 0, 0), (150, 0, 0), (200, 15, 0), (230, 0, 0), (260, 0, 0), (290, 15, 0), (320, 0, 0),
             (400, 0, 0)]
    m = episode_metrics(load_episode(write_log(tmp_path / "box.mcap", poses, statics=[box], goal=(400.0, 0.0))))
    assert (m["collisions_wall"], m["collisions_static_obstacle"], m["collisions_static"]) == (0, 2, 2)
    # near misses: step 3 (30 − 20 = 10 cm) and step 6 (√(20² + 30²) − 20 = 16.1 cm); step 0: 38.3 cm; the rest touch
    assert m["near_miss_steps"] == 2


_compute_times = st.lists(st.one_of(st.floats(0.0, 1e12), st.integers(0, 10**12),
                                    st.sampled_from([0.0, 0.5, 1.0, 2.0, 1e12, 3])), min_size=1, max_size=300)


@given(_compute_times)
@settings(max_examples=500, deadline=None)
def test_median_and_p99_are_numpys_to_the_bit(values):
    """The compute-time columns are numpy's median and 99th percentile of the logged times, bit for bit (ints,
    floats and both mixed, ties, one value, lengths on both sides of each interpolation branch)."""
    arr = np.array(values)
    assert median_and_p99(values) == (float(np.median(arr)), float(np.percentile(arr, 99)))


def test_median_and_p99_of_nothing_or_nan_is_nan():
    assert all(math.isnan(x) for x in median_and_p99([]))
    assert all(math.isnan(x) for x in median_and_p99([1.0, math.nan, 2.0]))
