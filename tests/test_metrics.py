"""Metrics pinned on hand-made logs with known answers, and the interval statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from analysis.episode_log import load_episode
from analysis.metrics import episode_metrics, metrics_table, turn_count
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


def test_parallel_metrics_table_equals_the_serial_one(tmp_path, monkeypatch):
    import analysis.logs

    for k in range(6):
        write_log(tmp_path / f"good{k}.mcap", square_poses()[: 4 + k], goal=(0.0, 0.0))
    write_log(tmp_path / "err.mcap", square_poses(), outcome="error")
    write_log(tmp_path / "cut.mcap", square_poses(), truncate=True)
    (tmp_path / "junk.mcap").write_bytes(b"\x00not an mcap" * 10)
    serial_rows, serial_bad = metrics_table([tmp_path])
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


def test_bootstrap_is_seeded_and_brackets_the_mean():
    x = np.arange(20.0)
    a, b = bootstrap_mean(x), bootstrap_mean(x)
    assert a == b and a[1] < a[0] < a[2]
    assert bootstrap_mean([3.0, 3.0, 3.0]) == (3.0, 3.0, 3.0)
    assert excludes_zero(0.1, 2.0) and not excludes_zero(-1.0, 2.0)
