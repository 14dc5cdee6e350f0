"""The Slurm launcher (``hydra/launcher=slurm``) against a real one-node Slurm cluster on this machine.

The ``slurm`` fixture (``tests/conftest.py``, :mod:`tests.slurm_cluster`) starts the cluster for the module: one
node, this host; every Slurm command, and the sweep, is pointed at it by ``SLURM_CONF``.

- a sweep submitted as a job array gives the same logs (message content), ``summary.csv`` and report tables as
  the same sweep on ``all_cores`` (compute times excluded);
- ``scancel`` of one array task mid-run (SIGTERM, as Slurm sends it, and SIGKILL, as a dead node or the
  out-of-memory killer ends a job) ends the sweep with one line, the summary and the resume command; ``resume=true``
  completes it with every episode exactly once;
- a job over its time limit (``timeout_min``) is reported with the episode it interrupted, the seeds it did not
  run and the resume command.

Needs root and Debian's ``slurm-wlm`` and ``munge`` (``.ci/run`` installs them). Without them the tests skip with
the reason, except in CI (``CI=true``), where that is a failure: CI must show that they ran.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from analysis.logs import LogFile, episode_summary, is_complete, read_metadata
from fuzzynav.episode_identity import episode_key_of
from runners.dataset import content_digests
from runners.logs.diff import diff_logs
from runners.sweeping import stop
from tests.conftest import ROOT
from tests.slurm_cluster import PARTITION, Cluster, array_tasks, job_processes, wait_for

pytestmark = [pytest.mark.slurm, pytest.mark.long]

# a 20 km corridor (tests/scenarios/scenario/endless_corridor.yaml): an episode that max_steps or a signal ends
SEARCH = f"hydra.searchpath=[file://{ROOT / 'tests' / 'scenarios'}]"


# -- helpers -----------------------------------------------------------------------------------------------------
def sweep_args(cluster: Cluster | None, args: list[str], sweep_dir: Path) -> list[str]:
    launcher = ["hydra/launcher=slurm", f"hydra.launcher.partition={PARTITION}"] if cluster else []
    return [sys.executable, "-m", "runners.sweep", *args, *launcher, f"hydra.sweep.dir={sweep_dir}"]


def run_sweep(cluster: Cluster | None, args: list[str], sweep_dir: Path, timeout: float = 300
              ) -> subprocess.CompletedProcess:
    env = cluster.env if cluster else {k: v for k, v in os.environ.items() if k != "SLURM_CONF"}
    return subprocess.run(sweep_args(cluster, args, sweep_dir), cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=timeout)


def logs(sweep_dir: Path) -> list[Path]:
    return sorted(p for p in sweep_dir.rglob("*.mcap") if ".fuzzynav" not in p.parts)


def partials(sweep_dir: Path) -> list[Path]:
    return sorted(sweep_dir.glob("*/.*.mcap.partial"))


def problem_lines(stderr: str) -> list[str]:
    """stderr without Hydra's and Submitit's own log lines and the sweep's progress lines."""
    from runners.progress import is_progress_line

    return [line for line in stderr.splitlines()
            if line.strip() and "[HYDRA]" not in line and not is_progress_line(line)]


def comparable_csv(path: Path, sweep_dir: Path) -> pd.DataFrame:
    """A CSV of the summary or the report without compute times, with log paths relative to the sweep."""
    frame = pd.read_csv(path)
    frame = frame.drop(columns=[c for c in frame.columns if c.startswith("compute_time")])
    if "metric" in frame.columns:
        frame = frame[~frame["metric"].astype(str).str.startswith("compute_time")]
    if "log" in frame.columns:
        # a table's log paths are relative to its own folder
        frame["log"] = [str((path.parent / p).resolve().relative_to(sweep_dir.resolve())) for p in frame["log"]]
    return frame.sort_values(list(frame.columns)).reset_index(drop=True)


# -- tests ---------------------------------------------------------------------------------------------------------
def test_job_array_equals_the_same_sweep_on_all_cores(slurm: Cluster, tmp_path: Path) -> None:
    """Two jobs of two episodes as one job array on the cluster, and on all_cores: the same logs (every message,
    compute times excepted), summary.csv and report tables."""
    args = ["sweep=quick", "scenario=head_on", "planner=auto,wait", "episodes=2", "scenario.max_steps=40"]
    on_slurm, local = tmp_path / "slurm", tmp_path / "all_cores"
    res = run_sweep(slurm, args, on_slurm)
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    assert not problem_lines(res.stderr), res.stderr[-3000:]  # no sacct warnings: squeue answers instead
    tasks = array_tasks(on_slurm)
    assert len(tasks) == 2 and len({t.split("_")[0] for t in tasks}) == 1, tasks  # one array of two tasks
    states = slurm.jobs()
    assert all(states.get(t) == "COMPLETED" for t in tasks), states
    res = run_sweep(None, args, local)
    assert res.returncode == 0, res.stderr[-3000:]

    names = [str(p.relative_to(on_slurm)) for p in logs(on_slurm)]
    assert len(names) == 4 and names == [str(p.relative_to(local)) for p in logs(local)]
    for name in names:
        a, b = on_slurm / name, local / name
        if content_digests(a)["sha256"] != content_digests(b)["sha256"]:
            diff = diff_logs(b, a)
            pytest.fail(f"{name}: the log on Slurm differs from all_cores': {diff.kind}, first {diff.first}, "
                        f"floats {list(diff.floats)[:3]}")
    pd.testing.assert_frame_equal(comparable_csv(on_slurm / "summary.csv", on_slurm),
                                  comparable_csv(local / "summary.csv", local))
    for table in ("episodes.csv", "groups.csv", "paired.csv"):
        pd.testing.assert_frame_equal(comparable_csv(on_slurm / "report" / table, on_slurm),
                                      comparable_csv(local / "report" / table, local), obj=table)
    # the sweeps' directories differ in length, and a Markdown table pads its columns to the longest log path
    report = [re.sub(r"-{3,}", "---", re.sub(r" {2,}", " ", (d / "report" / "report.md").read_text().replace(
        str(d), "<sweep>"))) for d in (on_slurm, local)]
    assert report[0] == report[1]


@pytest.mark.parametrize("signal_name", ["TERM", "KILL"])
def test_scancel_of_one_array_task_then_resume_runs_every_episode_once(slurm: Cluster, tmp_path: Path,
                                                                       signal_name: str) -> None:
    """``scancel`` one task of the array while its first episode runs. SIGTERM (plain ``scancel``): the task ends
    its episode as interrupted and asks the whole sweep to stop; exit 143. SIGKILL (a dead node, the OOM killer):
    the task's episode is lost; exit 1. Either way one line on stderr, no traceback, the summary of what completed
    and the resume command; the resume completes the sweep with every episode exactly once."""
    sweep_dir = tmp_path / "s"
    args = ["sweep=quick", SEARCH, "scenario=endless_corridor", "scenario.max_steps=1500", "planner=auto,wait",
            "episodes=2"]
    proc = subprocess.Popen(sweep_args(slurm, args, sweep_dir), cwd=ROOT, env=slurm.env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        # task 0 (job 0, directory 0/) is in its first episode; the other runs alongside if there is a free CPU
        assert wait_for(lambda: bool(list((sweep_dir / "0").glob(".*.mcap.partial"))), 180), "task 0 did not start"
        task = next(name for name in array_tasks(sweep_dir) if name.endswith("_0"))
        if signal_name == "TERM":  # what Slurm does to a job it ends: SIGTERM, then SIGKILL after KillWait
            slurm.run("scancel", task)
        else:  # the job's process dies at once, as on a lost node or by the out-of-memory killer (scancel
            # --signal=KILL would not do: Slurm treats it as a plain scancel)
            pids = job_processes(task)
            assert pids, f"no process of {task} found"
            for pid in pids:
                os.kill(pid, signal.SIGKILL)
        out, err = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    lines = problem_lines(err)
    assert "Traceback" not in err and "Error executing job" not in err and len(lines) <= 2, err[-3000:]
    if signal_name == "TERM":
        assert proc.returncode == 143, err[-3000:]
        assert re.search(r"stopped by SIGTERM: \d+ episode\(s\) finished, [12] interrupted", out), out[-3000:]
    else:
        assert proc.returncode == 1, err[-3000:]
        assert re.fullmatch(r"error: a worker process was lost \(UncompletedJobError: job \d+_0 has not produced any "
                            r"output \(state: FAILED\)\)", lines[0]), lines
        assert re.search(r"incomplete: \d+ episode\(s\) finished, \d+ interrupted, [12] lost", out), out[-3000:]
    hint = [line for line in out.splitlines() if line.startswith("to complete the sweep: python -m runners.sweep")]
    assert len(hint) == 1 and "resume=true" in hint[0] and "hydra/launcher=slurm" in hint[0], out[-3000:]
    assert wait_for(slurm.idle, 60), slurm.jobs()  # the other task ends too (the sweep's stop file)
    before = {p: p.stat().st_mtime_ns for p in logs(sweep_dir) if episode_summary(p)["outcome"] == "timeout"}

    res = run_sweep(slurm, [*args, "resume=true"], sweep_dir)
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    assert f"resume: {len(before)} complete episode(s) kept, {4 - len(before)} run" in res.stdout, res.stdout[-2000:]
    final = logs(sweep_dir)
    keys = [episode_key_of(read_metadata(p)) for p in final]
    assert len(final) == 4 and len(set(keys)) == 4 and not partials(sweep_dir), final
    assert all(is_complete(p) and episode_summary(p)["outcome"] == "timeout" for p in final)
    assert all(p.stat().st_mtime_ns == t for p, t in before.items())  # kept, not run again
    summary = pd.read_csv(sweep_dir / "summary.csv")
    assert len(summary) == 4 and summary["log"].is_unique and set(summary["outcome"]) == {"timeout"}
    assert (sweep_dir / "report" / "report.html").exists()
    what = "scancel" if signal_name == "TERM" else "SIGKILL to the job's process"
    ended = next(line for line in out.splitlines() if line.startswith(("stopped by", "incomplete:")))
    print(f"{what}: {' | '.join([*lines, ended])}; resume: {len(before)} episode(s) kept, {4 - len(before)} run")


# the time-limit test: Submitit asks Slurm for its warning (SIGUSR2) SIGNAL_DELAY_S before the limit (sbatch
# --signal=USR2@<signal_delay_s>), and Slurm "may send it up to 60 seconds earlier than specified" (man sbatch,
# --signal). With a 1-minute limit and the warning 40 s before it, it came 0.1 s after the job started, before
# Python had installed a handler: the job died by signal 12 and left no log. Here it comes 60 to 120 s into the job,
# long after the job's Python started, and 60 s before the limit, long before Slurm would end the job itself.
TIME_LIMIT_MIN, SIGNAL_DELAY_S, SLURM_SIGNAL_SLACK_S = 3, 60, 60
# an episode of the corridor with planner=auto reaches the goal after about 80,000 steps (80 s on a 2-CPU CI
# machine once, 7 to 13 s on CI's machine since): episodes may end before the warning, so the job has far more
# seeds than it can run in the time limit even on a machine a hundred times faster; whichever episode is in
# flight is the one interrupted
TIME_LIMIT_EPISODES = 1000


def test_a_job_over_its_time_limit_is_reported_with_the_resume_command(slurm: Cluster, tmp_path: Path) -> None:
    """``timeout_min=3`` with Submitit's warning 60 s before it (SIGUSR2; Slurm sends it 60 to 120 s into the job):
    the episode in flight ends as interrupted with the reason, the episodes before it are complete, the job's later
    seeds are not run, and the sweep says so in one line, prints the summary of what completed and the resume
    command, and exits 1. (Submitit used to raise its own exception inside the episode: the log said ``error`` and
    the sweep exited 0 as if complete.)"""
    assert SIGNAL_DELAY_S + SLURM_SIGNAL_SLACK_S + 30 <= TIME_LIMIT_MIN * 60  # >= 30 s for the job to start Python
    sweep_dir = tmp_path / "s"
    n = TIME_LIMIT_EPISODES
    args = ["sweep=quick", SEARCH, "scenario=endless_corridor", "scenario.max_steps=100000", "planner=auto",
            f"episodes={n}", f"hydra.launcher.timeout_min={TIME_LIMIT_MIN}",
            f"hydra.launcher.signal_delay_s={SIGNAL_DELAY_S}"]
    tic = time.monotonic()
    res = run_sweep(slurm, args, sweep_dir)
    took = time.monotonic() - tic
    lines = problem_lines(res.stderr)
    assert res.returncode == 1 and "Traceback" not in res.stderr and len(lines) == 1, \
        f"{res.stderr[-3000:]}\n{slurm.logs()}"
    stopped = re.fullmatch(r"error: 1 episode\(s\) stopped before they finished \(the Slurm job reached its time "
                           r"limit \(hydra\.launcher\.timeout_min\)\), e\.g\. (\S+__s(\d+)\.mcap); their jobs did not "
                           r"run their later seeds", lines[0])
    assert stopped, lines
    seed = int(stopped.group(2))  # the episode in flight at the warning: seeds 0 .. seed-1 ran to their end
    assert seed < n - 1, f"the job ran out of seeds before the warning: {lines[0]}"  # later seeds were left
    assert f"incomplete: {seed} episode(s) finished, 1 interrupted, 0 lost, {n - 1 - seed} not run (of {n})" \
        in res.stdout, res.stdout[-3000:]
    hint = [line for line in res.stdout.splitlines() if line.startswith("to complete the sweep: ")]
    assert len(hint) == 1 and "resume=true" in hint[0] and "hydra/launcher=slurm" in hint[0], res.stdout[-3000:]
    found = sorted(logs(sweep_dir), key=lambda p: int(episode_summary(p)["seed"]))
    assert [episode_summary(p)["seed"] for p in found] == list(range(seed + 1)) and not partials(sweep_dir), found
    *finished, log = found
    assert log.resolve() == Path(stopped.group(1)).resolve(), (log, lines[0])
    assert all(is_complete(p) and episode_summary(p)["outcome"] == "goal" for p in finished), finished
    ((_topic, _t, ended),) = LogFile(log, ["/episode"]).messages(["/episode"])
    assert ended["outcome"] == "interrupted" and ended["reason"] == stop.TIME_LIMIT_REASON, ended
    assert not (sweep_dir / "report" / "report.html").exists()  # the report is for the complete sweep
    print(f"time limit: {lines[0]} ({took:.0f} s)")


# -- without a cluster: the launcher's watcher where sacct does not work ----------------------------------------
def fake_commands(bin_dir: Path, sacct: str, squeue: str) -> None:
    """``sacct`` and ``squeue`` scripts in ``bin_dir`` that print the given text (a leading ``!`` fails instead)."""
    bin_dir.mkdir()
    for name, text in (("sacct", sacct), ("squeue", squeue)):
        body = f"echo '{text[1:]}' >&2; exit 1" if text.startswith("!") else f"printf '{text}'"
        (bin_dir / name).write_text(f"#!/bin/sh\n{body}\n")
        (bin_dir / name).chmod(0o755)


@pytest.mark.parametrize("accounting", [False, True])
def test_job_states_come_from_squeue_when_sacct_does_not_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             accounting: bool) -> None:
    """Submitit's watcher with sacct (accounting) as it was; without, the same states from squeue (a cancelled task
    is done: the launcher reports it instead of waiting forever) and a poll at least once a minute."""
    from runners.sweeping.slurm import SQUEUE_DELAY_S, SqueueFallbackWatcher

    sacct = "JobID|State|NodeList\\n12_0|CANCELLED by 0|vm\\n12_[1-2]|PENDING|\\n" if accounting else \
        "!Slurm accounting storage is disabled"
    fake_commands(tmp_path / "bin", sacct, "12_0|CANCELLED|vm\\n12_[1-2]|PENDING|\\n")
    monkeypatch.setenv("PATH", f"{tmp_path / 'bin'}:{os.environ['PATH']}")
    watcher = SqueueFallbackWatcher(delay_s=600)
    for job in ("12_0", "12_1", "12_2"):
        watcher.register_job(job)
    assert watcher.get_state("12_0", mode="force").startswith("CANCELLED")
    assert watcher.is_done("12_0", mode="cache") and not watcher.is_done("12_2", mode="cache")
    assert watcher.get_state("12_2", mode="cache") == "PENDING"
    assert watcher.sacct_works is accounting
    assert watcher._delay_s == (600 if accounting else SQUEUE_DELAY_S)
