"""Cases of the hostile corpus hostile14c (issue 14) that end to end need a real run: a step length other
than 1 s, and a report in which no log could be analysed."""

from __future__ import annotations

import subprocess
import sys

from tests.conftest import ROOT


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True, timeout=300)


def test_a_run_with_dt_07_is_a_log_every_tool_reads(tmp_path):
    """``dt=0.7`` was in range and ran, but the obstacles' positions after step k (at k·dt + dt) were not those step
    k + 1 started from (at (k + 1)·dt) in the last bit: the report, replay --verify, dataset build and the sweep
    summary all refused the log (hostile14c run_dt_0p7_report, rpl_verify_dt_0p7, swp_dt_0p7)."""
    res = run("runners.run", f"hydra.run.dir={tmp_path}", "dt=0.7", "scenario.max_steps=40")
    assert res.returncode == 0, res.stderr
    (log,) = tmp_path.glob("*.mcap")
    res = run("runners.replay", str(log), "--verify", "--quiet")
    assert res.returncode == 0 and "all 40 decisions reproduced" in res.stdout, res.stderr
    res = run("analysis.report", str(log), "--out", str(tmp_path / "report"), "--jobs", "1")
    assert res.returncode == 0 and "left out" not in res.stdout, res.stdout + res.stderr


def test_a_step_length_the_analysis_cannot_read_is_refused_by_the_run(tmp_path):
    """``dt=1e-300`` ran, and the analysis then refused its metadata: one range now serves both."""
    res = run("runners.run", f"hydra.run.dir={tmp_path / 'o'}", "dt=1e-300")
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2 and lines == ["error: config: dt: must be in [0.001, 60] s, got 1e-300"], res.stderr
    assert not (tmp_path / "o").exists()


def test_a_report_of_no_analysable_log_exits_non_zero(tmp_path):
    """A damaged log, two logs concatenated or a text file as the only input gave exit 0 and an empty report
    (hostile14c rep_appended_garbage, rep_two_logs_concat, rep_args_file_not_mcap): the report still lists why each
    was left out, and the exit status says there is no result."""
    notes = tmp_path / "notes.txt"
    notes.write_text("not a log\n")
    res = run("analysis.report", str(notes), "--out", str(tmp_path / "report"), "--jobs", "1")
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 1 and len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert lines[0].startswith(f"error: none of the 1 log(s) could be analysed (1 not-mcap): {notes}: not an MCAP "
                               "file (no MCAP magic at the start) (all in 'Logs left out' of ")
    assert "Logs left out" in (tmp_path / "report" / "report.md").read_text()
