"""``runners.bench_sweep_rss``: the memory of a long sweep, sampled from outside (the real command, small)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from runners.bench_sweep_rss import Series, _summary
from tests.conftest import ROOT


def test_the_summary_reads_workers_and_the_sweep_apart():
    root = Series(1, [0, 2, 4, 6, 8, 10, 12], [60, 61, 62, 63, 64, 150, 160])
    worker = Series(2, list(range(10)), [50, 55, 80, 80, 80, 80, 80, 80, 80, 88])
    helper = Series(3, list(range(10)), [15.0] * 10)  # multiprocessing's resource tracker: not a worker
    out = _summary({1: root, 2: worker, 3: helper}, 1, episodes=10)
    assert [w["pid"] for w in out["workers"]] == [2]
    assert out["workers"][0]["rss_mb_at_10pct"] == 55 and out["workers"][0]["rss_mb_at_end"] == 88
    assert out["workers"][0]["growth"] == pytest.approx(88 / 55 - 1)
    assert out["sweep_rss_mb_at_run_end"] == 64 and out["sweep_rss_mb_peak_in_summary"] == 160  # workers: t <= 9


def test_the_command_runs_a_small_sweep_and_reports_every_worker(tmp_path):
    out = tmp_path / "rss.json"
    res = subprocess.run([sys.executable, "-m", "runners.bench_sweep_rss", "--episodes", "20", "--jobs", "2",
                          "--out", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    result = json.loads(out.read_text())
    assert result["episodes"] == 20 and len(result["workers"]) == 2
    assert all(w["rss_mb_at_end"] > 0 for w in result["workers"])
    assert "20 episodes of head_on" in res.stdout


def test_bad_arguments_are_one_line_errors():
    res = subprocess.run([sys.executable, "-m", "runners.bench_sweep_rss", "--episodes", "5", "--jobs", "2"],
                         cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "--episodes: at least 10 per job" in res.stderr
