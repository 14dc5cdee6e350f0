"""runners.benchmarks.tuning (issue #39): the study's trials/minute and overhead are measured on the trials it ran
(no timing is asserted: speed is measured by runners.bench)."""

from __future__ import annotations

from runners.benchmarks.page import render
from runners.benchmarks.tuning import bench_tuning, tuning_line


def test_tuning_bench_measures_its_own_trials_and_renders():
    r = bench_tuning(trials=3, seeds=2)
    assert r["trials"] == 3 and r["episodes"] == 6 and r["episodes_per_trial"] == 2
    assert r["study_s"] > r["episodes_in_study_s"] > 0 and r["plain_episodes_s"] > 0
    assert r["trials_per_minute"] == 60 * 3 / r["study_s"]
    assert abs(r["episodes_in_study_s"] + r["metrics_s"] + r["sampler_storage_compose_s"] - r["study_s"]) < 1e-9
    assert "trials/min" in tuning_line(r)
    assert "## Tuning studies" in render({"tuning": r}) and "trials/min" in render({"tuning": r})
