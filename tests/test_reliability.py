"""Faults: SIGINT/SIGTERM finish the log as interrupted; SIGKILL leaves a partial log (never one that looks
complete) readable up to its last chunk; a killed sweep resumes without losing or recomputing anything."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from analysis.episode_log import load_episode
from analysis.log_inputs import find_logs
from analysis.logs import episode_summary, is_complete
from analysis.metrics import metrics_table
from tests.conftest import ROOT

# a 20 km corridor (tests/scenarios/scenario/endless_corridor.yaml): an episode that only a signal ends
LONG = [f"hydra.searchpath=[file://{ROOT / 'tests' / 'scenarios'}]", "scenario=endless_corridor"]


def start(args, **kw):
    return subprocess.Popen([sys.executable, "-m", *args], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, **kw)


def wait_for(predicate, timeout=120.0):
    end = time.time() + timeout
    while time.time() < end:
        if predicate():
            return True
        time.sleep(0.1)
    return False


def log_size(run_dir: Path) -> int:
    """Size of the log being written (``.<name>.mcap.partial`` until finished) or written."""
    logs = list(run_dir.glob(".*.mcap.partial")) + list(run_dir.glob("*.mcap"))
    return logs[0].stat().st_size if logs else 0


@pytest.mark.parametrize("sig, code, reason", [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")])
def test_signal_finishes_the_log_as_interrupted(tmp_path, sig, code, reason):
    proc = start(["runners.run", *LONG, f"hydra.run.dir={tmp_path}"])
    assert wait_for(lambda: log_size(tmp_path) > 40_000), "the episode did not start"
    proc.send_signal(sig)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "interrupted" in err and "Traceback" not in err
    log = next(tmp_path.glob("*.mcap"))
    assert is_complete(log)
    row = episode_summary(log)
    assert row["outcome"] == "interrupted" and row["steps"] > 10
    rows, bad = metrics_table([tmp_path])
    assert rows.empty and "interrupted" in bad.iloc[0]["reason"]  # never counted as success or failure


def test_sigkill_leaves_a_log_readable_up_to_its_last_chunk(tmp_path):
    proc = start(["runners.run", *LONG, f"hydra.run.dir={tmp_path}"])
    assert wait_for(lambda: log_size(tmp_path) > 150_000)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    assert not list(tmp_path.glob("*.mcap"))  # nothing that looks like a finished log
    log = next(tmp_path.glob(".*.mcap.partial"))
    assert not is_complete(log)
    episode = load_episode(log)
    assert episode.outcome == "incomplete" and episode.steps > 20 and not episode.complete
    rows, bad = metrics_table([log])  # named explicitly, a partial log is read for what it has
    assert rows.empty and "truncated" in bad.iloc[0]["reason"]
    res = subprocess.run([sys.executable, "-m", "runners.replay", str(log), "--out", str(tmp_path / "r")], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "outcome: incomplete" in res.stdout


def _comparable(sweep_dir: Path) -> pd.DataFrame:
    rows, bad = metrics_table([sweep_dir])
    assert bad.empty
    drop = [c for c in rows.columns if c.startswith("compute_time") or c == "log"]
    return rows.drop(columns=drop).sort_values(["scenario", "strategy", "h_wait", "seed"]).reset_index(drop=True)


def test_killed_sweep_resumes_without_loss_or_recomputation(tmp_path):
    args = ["runners.sweep", "sweep=quick", "hydra.launcher.n_jobs=2"]
    killed = tmp_path / "killed"
    proc = start([*args, f"hydra.sweep.dir={killed}"])
    assert wait_for(lambda: sum(is_complete(p) for p in killed.rglob("*.mcap")) >= 3)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    before = {p: p.stat().st_mtime_ns for p in killed.rglob("*.mcap") if is_complete(p)}
    assert 3 <= len(before) < 12
    res = subprocess.run([sys.executable, "-m", *args, f"hydra.sweep.dir={killed}", "resume=true"], cwd=ROOT,
                         capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-2000:]
    assert f"resume: {len(before)} complete episode(s) kept, {12 - len(before)} run" in res.stdout
    logs = find_logs([killed])
    assert len(logs) == 12 and len({p.name for p in logs}) == 12 and all(is_complete(p) for p in logs)
    assert all(p.stat().st_mtime_ns == t for p, t in before.items())  # completed ones were not re-run
    fresh = tmp_path / "fresh"
    res = subprocess.run([sys.executable, "-m", *args, f"hydra.sweep.dir={fresh}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=900)
    assert res.returncode == 0
    pd.testing.assert_frame_equal(_comparable(killed), _comparable(fresh))


def test_sweep_with_submitit_local_launcher(tmp_path):
    """The cluster code path, rehearsed locally: every job in its own process through Submitit."""
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "sweep=quick", "hydra/launcher=local_processes",
                          f"hydra.sweep.dir={tmp_path}", "scenario=head_on", "planner=auto,none", "episodes=2"],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    logs = find_logs([tmp_path])
    assert len(logs) == 4 and all(is_complete(p) for p in logs)
    assert len({p.parent for p in logs}) == 2  # two jobs, each writing only its own directory
    outcomes = {(episode_summary(p)["strategy"], episode_summary(p)["outcome"]) for p in logs}
    assert outcomes == {("auto", "goal"), ("none", "collision")}
    assert (tmp_path / "report" / "report.md").exists() and (tmp_path / ".submitit").is_dir()


def test_a_single_run_resumes_and_reruns_its_own_episode(tmp_path):
    """``runners.run X resume=true`` over X's complete log keeps it (it raised KeyError: 'policy'); a run with or
    without ``resume`` over the log the other wrote is the same episode, not "the log of another episode"."""
    def run(*extra: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "runners.run", "scenario=head_on", f"hydra.run.dir={tmp_path}",
                               *extra], cwd=ROOT, capture_output=True, text=True, timeout=300)

    first = run("resume=true")
    assert first.returncode == 0 and "(complete: kept)" not in first.stdout, first.stderr
    log = next(tmp_path.glob("*.mcap"))
    kept = run("resume=true")
    assert kept.returncode == 0 and "Traceback" not in kept.stderr, kept.stderr
    assert "policy=fuzzy" in kept.stdout and kept.stdout.rstrip().endswith("(complete: kept)"), kept.stdout
    again = run()
    assert again.returncode == 0 and "another episode" not in again.stderr, again.stderr
    assert episode_summary(log)["outcome"] == "goal"
