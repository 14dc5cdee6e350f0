"""Hypothesis fuzzing of resume after faults (issue #37 item 16): a finished sweep's folder is damaged at random —
logs deleted, truncated, overwritten with junk, emptied, duplicated into another job's folder, a stray file or
folder added — and ``resume=true`` must end with every episode exactly once, complete and checked, the undamaged
ones kept as they were, and the metrics equal to a fresh sweep's: no episode lost, none counted twice, nothing
pooled from a damaged copy."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.log_inputs import find_logs
from analysis.metrics import metrics_table
from tests.conftest import ROOT

ARGS = ["runners.sweep", "scenario=head_on,crossing_right", "planner=none", "episodes=3", "hydra.launcher.n_jobs=2"]
EPISODES = 6


def _sweep(where: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", *ARGS, f"hydra.sweep.dir={where}", *extra], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


def _table(sweep: Path) -> pd.DataFrame:
    rows, bad = metrics_table([sweep])
    assert bad.empty, bad.to_dict("records")
    drop = [c for c in rows.columns if c.startswith("compute_time") or c == "log"]
    return rows.drop(columns=drop).sort_values(["scenario", "seed"]).reset_index(drop=True)


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> tuple[Path, pd.DataFrame]:
    where = tmp_path_factory.mktemp("finished") / "sweep"
    res = _sweep(where)
    assert res.returncode == 0, res.stderr[-2000:]
    return where, _table(where)


_FAULTS = st.lists(st.tuples(st.sampled_from(["delete", "truncate", "junk", "empty", "duplicate", "stray_file",
                                               "stray_dir"]),
                             st.integers(0, EPISODES - 1), st.integers(1, 10_000)), min_size=1, max_size=4)


@settings(max_examples=6, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(faults=_FAULTS)
def test_resume_after_random_damage_completes_the_sweep_exactly(finished, tmp_path_factory, faults):
    original, fresh_table = finished
    sweep = tmp_path_factory.mktemp("damaged") / "sweep"
    shutil.copytree(original, sweep)
    logs = sorted(find_logs([sweep]))
    assert len(logs) == EPISODES
    damaged: set[str] = set()
    for kind, index, size in faults:
        log = logs[index]
        if kind in ("delete", "truncate", "junk", "empty") and not log.exists():
            continue
        if kind == "delete":
            log.unlink()
        elif kind == "truncate":
            data = log.read_bytes()
            log.write_bytes(data[: size % max(len(data) - 1, 1)])
        elif kind == "junk":
            log.write_bytes(os.urandom(size % 4096 + 1))
        elif kind == "empty":
            log.write_bytes(b"")
        elif kind == "duplicate":  # another job's folder holds a copy of this log
            other = next(p.parent for p in logs if p.parent != log.parent)
            if log.exists():
                shutil.copy2(log, other / log.name)
        elif kind == "stray_file":
            (log.parent / f"notes-{size}.txt").write_text("not a log")
        else:
            (log.parent / f"folder-{size}.mcap").mkdir(exist_ok=True)
        damaged.add(log.name)
    kept = {p.name: p.stat().st_mtime_ns for p in logs if p.exists() and p.name not in damaged}
    res = _sweep(sweep, "resume=true")
    assert res.returncode == 0, (faults, res.stdout[-1500:], res.stderr[-2000:])
    after = find_logs([sweep])
    names = [p.name for p in after]
    assert len(after) == EPISODES and len(set(names)) == EPISODES, (faults, names)
    for path in after:
        if path.name in kept:
            assert path.stat().st_mtime_ns == kept[path.name], (faults, path)  # an undamaged log was not re-run
    pd.testing.assert_frame_equal(_table(sweep), fresh_table)
