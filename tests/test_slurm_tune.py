"""A study's workers as a Slurm job array (``python -m runners.tune STUDY --launcher slurm``) on a real one-node
Slurm cluster started on this machine (the ``slurm`` fixture, :mod:`tests.slurm_cluster`).

- two Slurm workers share the study in its journal file: exactly the budget's trials, both tasks ran trials, the
  held-out evaluation and the report are written by the command;
- ``scancel`` of one task while its trial runs: that trial (only) is lost as interrupted, the command names the
  task and its Submitit log in one line; re-running resumes and completes the budget exactly;
- Ctrl-C of the command cancels the array: no task is left, the trials in flight are interrupted, re-run completes;
- a killed command leaves its array running: a re-run is refused in one line until the array has ended;
- a study stored in SQLite, and a partition the cluster does not have, are refused in one line; the SQLite study,
  moved to the journal file with ``--to-journal`` as that line says, then completes its budget on Slurm;
- a comparison (``--compare``) runs each study as a job array of its own and writes the comparison report.

Tiny studies: head_on (~42 steps an episode), the training seeds set how long a trial runs.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import optuna
import pytest

from runners.tuning.storage import open_storage
from runners.tuning.study import INTERRUPTED, SURPLUS, WORKER, counted
from tests.conftest import ROOT
from tests.slurm_cluster import PARTITION, Cluster, wait_for
from tests.test_tune import study_file, trials_of

pytestmark = [pytest.mark.slurm, pytest.mark.long]


def tune_args(out: Path, path: Path, *args: str) -> list[str]:
    return [sys.executable, "-m", "runners.tune", str(path), "--out", str(out), "--launcher", "slurm",
            f"hydra.launcher.partition={PARTITION}", *args]


def tune_on(cluster: Cluster, out: Path, path: Path, *args: str, timeout: float = 400) -> subprocess.CompletedProcess:
    return subprocess.run(tune_args(out, path, *args), cwd=ROOT, env=cluster.env, capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


def ran(trials: list[optuna.trial.FrozenTrial]) -> list[optuna.trial.FrozenTrial]:
    """The trials that ran (surplus trials, asked for beyond the budget, never run)."""
    return [t for t in trials if not t.user_attrs.get(SURPLUS)]


def running_task(out: Path) -> str | None:
    """The Slurm task (``<array>_<task>``) of task 0 while one of its trials runs and has written a log."""
    if not (out / "study.journal").exists():
        return None
    try:
        trials = trials_of(out, "journal")
    except KeyError:  # the journal is there, the study not yet in it (optuna: "Record does not exist.")
        return None
    for t in trials:
        task = (t.user_attrs.get(WORKER) or {}).get("slurm_task") or ""
        if t.state.name == "RUNNING" and task.endswith("_0") and list((out / "trials" / f"{t.number:05d}").glob("*")):
            return task
    return None


def long_trials(tmp_path: Path) -> Path:
    """Three trials of ~10 s (150 episodes): long enough to stop one mid-trial."""
    return study_file(tmp_path, trials=3, train_seeds={"start": 0, "count": 150},
                      heldout_seeds={"start": 1000, "count": 3})


def test_two_slurm_workers_share_one_study_and_keep_the_budget(slurm: Cluster, tmp_path: Path) -> None:
    out = tmp_path / "study"
    # ~3 s a trial (40 episodes): both tasks start before the other could run the whole budget
    path = study_file(tmp_path, trials=4, train_seeds={"start": 0, "count": 40})
    res = tune_on(slurm, out, path, "--workers", "2")
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    assert re.search(r"submitted 2 Slurm worker task\(s\) as job array \d+", res.stdout), res.stdout
    assert (out / "study.journal").exists() and not (out / "study.db").exists()  # the journal, chosen for Slurm
    trials = trials_of(out, "journal")
    assert sum(map(counted, trials)) == 4 and len(ran(trials)) == 4, [t.state for t in trials]  # the budget exactly
    workers = [t.user_attrs[WORKER] for t in ran(trials)]
    tasks = {w["slurm_task"] for w in workers}
    assert len(tasks) == 2 and all(re.fullmatch(r"\d+_[01]", task) for task in tasks), workers  # both ran trials
    assert len({w["pid"] for w in workers}) == 2 and {w["host"] for w in workers} == {slurm.node}
    assert len(re.findall(r"^trial \d+: score=", res.stdout, re.M)) == 4, res.stdout  # each trial, as it ended
    assert (out / "report" / "study.md").stat().st_size > 0 and (out / "tuned.yaml").exists()
    assert wait_for(slurm.idle, 30), slurm.jobs()
    print(f"2 Slurm workers: tasks {sorted(tasks)} ran {[w['slurm_task'] for w in workers]}")


def two_workers_with_a_trial_running(slurm: Cluster, tmp_path: Path) -> tuple[Path, Path, subprocess.Popen]:
    """A study of long trials started on two Slurm workers, returned once one of its trials is running (the
    command still running)."""
    out = tmp_path / "study"
    path = long_trials(tmp_path)
    proc = subprocess.Popen(tune_args(out, path, "--workers", "2", "--no-heldout"), cwd=ROOT, env=slurm.env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert wait_for(lambda: running_task(out) is not None or proc.poll() is not None, 180), "no trial ran"
        assert proc.poll() is None, proc.communicate()
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    return out, path, proc


def test_scancel_of_one_task_loses_only_its_trial_and_a_rerun_completes_the_budget(slurm: Cluster,
                                                                                    tmp_path: Path) -> None:
    out, path, proc = two_workers_with_a_trial_running(slurm, tmp_path)
    try:
        task = running_task(out)
        assert task is not None
        slurm.run("scancel", task)  # SIGTERM to the task, as Slurm ends a job
        _, stderr = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert proc.returncode == 1 and len(lines) == 1 and "Traceback" not in stderr, stderr[-3000:]
    failed = re.fullmatch(rf"error: 1 of 2 Slurm worker tasks failed: {task} CANCELLED[^(]*(?:\(exit 130\))? "
                          r"\(log (\S+)\); re-run the command to resume", lines[0])
    assert failed and Path(failed.group(1)).exists(), lines[0]
    trials = trials_of(out, "journal")
    lost = [t for t in ran(trials) if not counted(t)]
    assert len(lost) <= 1 and sum(map(counted, trials)) <= 3, [(t.number, t.state.name) for t in trials]
    assert all(t.user_attrs[WORKER]["slurm_task"] == task for t in lost)  # only the cancelled task's trial
    assert wait_for(slurm.idle, 60), slurm.jobs()

    res = tune_on(slurm, out, path, "--workers", "2")
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    trials = trials_of(out, "journal")
    lost = [t for t in ran(trials) if not counted(t)]
    assert sum(map(counted, trials)) == 3, [(t.number, t.state.name) for t in trials]  # the budget, exactly
    assert len(lost) == 1 and lost[0].state.name == "FAIL" and lost[0].user_attrs.get(INTERRUPTED), lost
    assert lost[0].user_attrs[WORKER]["slurm_task"] == task
    assert (out / "report" / "study.md").exists()
    print(f"scancel {task}: {lines[0]}; re-run: {sum(map(counted, trials))} trials counted, trial "
          f"{lost[0].number} interrupted")


def test_ctrl_c_cancels_the_array_and_a_rerun_completes(slurm: Cluster, tmp_path: Path) -> None:
    out, path, proc = two_workers_with_a_trial_running(slurm, tmp_path)
    try:
        tic = time.monotonic()
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=200)
        took = time.monotonic() - tic
    finally:
        if proc.poll() is None:
            proc.kill()
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert proc.returncode == 130 and len(lines) == 1 and "Traceback" not in stderr, stderr[-3000:]
    assert re.fullmatch(r"interrupted: the Slurm job array \d+ is cancelled; its trials in flight are marked "
                        r"interrupted; re-run the command to resume", lines[0]), lines
    # the command waited for the cancelled tasks to end: squeue lists none (not even completing)
    assert slurm.idle(), (slurm.run("squeue", "--noheader", "--format=%i %T").stdout, slurm.jobs())
    trials = trials_of(out, "journal")
    assert not [t for t in trials if t.state.name == "RUNNING"], [(t.number, t.state.name) for t in trials]
    interrupted = [t for t in trials if t.user_attrs.get(INTERRUPTED)]
    assert interrupted and all(t.state.name == "FAIL" for t in interrupted)

    res = tune_on(slurm, out, path, "--workers", "2", "--no-heldout")
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    assert sum(map(counted, trials_of(out, "journal"))) == 3
    print(f"Ctrl-C: array cancelled, {len(interrupted)} trial(s) interrupted, command ended {took:.1f} s later")


def test_a_killed_command_leaves_its_array_and_a_rerun_waits_for_it(slurm: Cluster, tmp_path: Path) -> None:
    """SIGKILL of the command cannot cancel its array: its workers run on. A re-run (which would mark their
    trials in flight interrupted) is refused in one line naming the array until it has ended."""
    out, path = tmp_path / "study", long_trials(tmp_path)
    proc = subprocess.Popen(tune_args(out, path, "--workers", "2", "--no-heldout"), cwd=ROOT, env=slurm.env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        assert wait_for(lambda: running_task(out) is not None or proc.poll() is not None, 180), "no trial ran"
    finally:
        proc.kill()
        proc.wait()
    array = running_task(out).split("_")[0]  # type: ignore[union-attr]
    res = tune_on(slurm, out, path, "--workers", "2", "--no-heldout")
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith(f"error: {out}: the Slurm job array {array} of an earlier command still runs this "
                               f"study's workers") and f"scancel {array}" in lines[0], lines[0]
    assert not [t for t in trials_of(out, "journal") if t.user_attrs.get(INTERRUPTED)]  # theirs left alone
    slurm.run("scancel", array)
    assert wait_for(slurm.idle, 90), slurm.jobs()
    res = tune_on(slurm, out, path, "--workers", "2", "--no-heldout")
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    assert sum(map(counted, trials_of(out, "journal"))) == 3


def test_a_sqlite_study_is_refused_for_slurm_workers(slurm: Cluster, tmp_path: Path) -> None:
    out, path = tmp_path / "study", study_file(tmp_path, trials=1)
    local = subprocess.run([sys.executable, "-m", "runners.tune", str(path), "--out", str(out), "--no-heldout"],
                           cwd=ROOT, env=slurm.env, capture_output=True, text=True, timeout=300)
    assert local.returncode == 0 and (out / "study.db").exists(), local.stderr
    before = (out / "study.db").read_bytes()
    res = tune_on(slurm, out, path, "--workers", "2", "--trials", "2")
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert res.returncode == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith(f"error: {out / 'study.db'}: a study stored in SQLite cannot be shared by Slurm "
                               "workers"), lines[0]
    convert = f"python -m runners.tune {path} --out {out} --to-journal"
    assert convert in lines[0], lines[0]  # the line names the conversion
    assert (out / "study.db").read_bytes() == before and not (out / ".submitit").exists() and slurm.idle()
    # converted as the line says, the study goes on on Slurm from its one trial to the budget of two
    res = subprocess.run([sys.executable, "-m", *convert.split()[2:]], cwd=ROOT, env=slurm.env, capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0 and (out / "study.journal").exists() and not (out / "study.db").exists(), res.stderr
    first = trials_of(out, "journal")[0]
    res = tune_on(slurm, out, path, "--workers", "2", "--trials", "2", "--no-heldout")
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    trials = trials_of(out, "journal")
    assert sum(map(counted, trials)) == 2 and trials[0] == first  # the converted trial is kept, not run again
    assert WORKER in trials[1].user_attrs and trials[1].user_attrs[WORKER].get("slurm_task")
    res = tune_on(slurm, tmp_path / "other", path, "--storage", "sqlite")  # asked for explicitly: refused too
    assert res.returncode == 2 and "--storage sqlite: Slurm workers share the study through the journal file" \
        in res.stderr and not (tmp_path / "other").exists(), res.stderr


def test_a_partition_the_cluster_does_not_have_is_one_line(slurm: Cluster, tmp_path: Path) -> None:
    out, path = tmp_path / "study", study_file(tmp_path, trials=1)
    res = subprocess.run([sys.executable, "-m", "runners.tune", str(path), "--out", str(out), "--launcher", "slurm",
                          "hydra.launcher.partition=nosuch"], cwd=ROOT, env=slurm.env, capture_output=True,
                         text=True, timeout=300)
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert res.returncode == 2 and len(lines) == 1 and "Traceback" not in res.stderr, res.stderr
    assert re.fullmatch(r"error: Slurm did not accept the workers' job array: sbatch: error: .*partition.*",
                        lines[0]), lines[0]
    assert {t.state.name for t in trials_of(out, "journal")} == {"WAITING"} and slurm.idle()  # the default, not run


def test_a_comparison_runs_its_studies_as_slurm_arrays_and_reports(slurm: Cluster, tmp_path: Path) -> None:
    """``--compare`` with ``--launcher slurm``: each study of a tiny comparison (two methods, two trials of two
    episodes) runs as a job array of its own, in the journal file; the held-out evaluation and the comparison
    report are written by the command."""
    from tests.test_tune_compare import write

    out = tmp_path / "out"
    res = subprocess.run([sys.executable, "-m", "runners.tune", "--compare", str(write(tmp_path)), "--out", str(out),
                          "--launcher", "slurm", f"hydra.launcher.partition={PARTITION}"], cwd=ROOT, env=slurm.env,
                         capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    assert res.returncode == 0, f"{res.stderr[-3000:]}\n{slurm.logs()}"
    assert len(re.findall(r"submitted 1 Slurm worker task\(s\) as job array \d+", res.stdout)) == 2, res.stdout
    for name in ("tiny", "tiny_dwa"):
        assert (out / name / "study.journal").exists() and not (out / name / "study.db").exists()
        trials = optuna.load_study(study_name=name, storage=open_storage(out / name, "journal")).get_trials()
        assert sum(map(counted, trials)) == 2
        assert all(re.fullmatch(r"\d+", t.user_attrs[WORKER]["slurm_task"] or "") for t in ran(trials))  # one job
        assert (out / name / "report" / "study.md").exists()
    report = out / "report"
    assert "## Held-out results per scenario" in (report / "comparison.md").read_text()
    assert (report / "comparison.csv").stat().st_size > 0 and (report / "comparison_overall.csv").stat().st_size > 0
    assert slurm.idle()
