"""``runners.benchmarks.sweep_rss``: the memory of a long sweep, sampled from outside (the real command, small)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from runners.benchmarks.sweep_rss import Sample, summary
from tests.conftest import ROOT


def test_the_summary_reads_workers_and_the_sweep_apart_by_episodes_logged():
    # pid 1: the sweep; 2: a worker; 3: multiprocessing's resource tracker (small: not a worker)
    samples = [Sample(0, 0, {1: 60}), Sample(1, 5, {1: 61, 2: 50, 3: 15}), Sample(2, 10, {1: 62, 2: 55, 3: 15}),
               Sample(3, 50, {1: 63, 2: 80, 3: 15}), Sample(4, 100, {1: 64, 2: 88, 3: 15}),
               Sample(5, 100, {1: 150, 2: 88}), Sample(6, 100, {1: 160, 2: 88})]
    out = summary(samples, 1, 100, jobs=1)
    assert [(m["fraction"], m["sweep_rss_mb"], m["workers_rss_mb"]) for m in out["marks"]] == [
        (0.1, 62, [55]), (0.5, 63, [80]), (1.0, 64, [88])]
    assert out["worker_growth_10_to_100"] == [pytest.approx(88 / 55 - 1)]
    assert out["sweep_rss_mb_peak_after"] == 160


def test_a_worker_that_exited_before_a_mark_counts_with_its_last_rss():
    # two workers (2, 3); worker 3 ends its job and exits before all the episodes have their logs
    samples = [Sample(0, 0, {1: 60}), Sample(1, 2, {1: 61, 2: 50, 3: 52}), Sample(2, 10, {1: 62, 2: 55, 3: 57}),
               Sample(3, 12, {1: 62, 2: 60}), Sample(4, 20, {1: 63, 2: 61})]
    out = summary(samples, 1, 20, jobs=2)
    assert out["marks"][-1]["workers_rss_mb"] == [61, 57]
    assert out["worker_growth_10_to_100"] == [pytest.approx(61 / 50 - 1), pytest.approx(57 / 52 - 1)]


def test_the_command_runs_a_small_sweep_and_reports_every_worker(tmp_path):
    out = tmp_path / "rss.json"
    res = subprocess.run([sys.executable, "-m", "runners.benchmarks.sweep_rss", "--episodes", "20", "--jobs", "2",
                          "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    result = json.loads(out.read_text())
    assert result["episodes"] == 20 and [m["fraction"] for m in result["marks"]] == [0.1, 0.5, 1.0]
    assert len(result["marks"][-1]["workers_rss_mb"]) == 2 and all(mb for mb in result["marks"][-1]["workers_rss_mb"])
    assert "20 episodes of head_on" in res.stdout


def test_bad_arguments_are_one_line_errors():
    res = subprocess.run([sys.executable, "-m", "runners.benchmarks.sweep_rss", "--episodes", "5", "--jobs", "2"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "--episodes: at least 10 per job" in res.stderr
    res = subprocess.run([sys.executable, "-m", "runners.benchmarks.sweep_rss", "--jobs", "0"], cwd=ROOT,
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "--jobs: must be in [1, 7], got 0" in res.stderr
