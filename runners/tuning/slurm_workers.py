"""A study's workers as one Slurm job array: ``python -m runners.tune STUDY --launcher slurm --workers N``.

The array's resources come from the sweep's Submitit preset, ``conf/hydra/launcher/slurm.yaml``, composed by Hydra
(so an edited preset applies) with the command's ``hydra.launcher.*`` overrides (``hydra.launcher.partition=cpu``,
``+hydra.launcher.additional_parameters.constraint=skylake``) and submitted with Submitit's public API, as Hydra's
Submitit launcher submits a sweep. Each array task runs :func:`runners.tuning.worker.worker` against the study's
storage, which must be the journal file (:func:`storage_kind`): SQLite's locking over a shared file system is
unreliable.
The command waits for the tasks, prints each trial as it ends (read from the storage), and reports the tasks that
failed in one line with their Submitit logs. Ctrl-C or SIGTERM cancels the array (``scancel``); a task's SIGTERM
ends its trial in flight as interrupted (and a trial a task left running is marked interrupted on resume).
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

LAUNCHERS = ("local", "slurm")
PRESET = "slurm"  # conf/hydra/launcher/slurm.yaml
OVERRIDE_PREFIXES = ("hydra.launcher.", "+hydra.launcher.", "++hydra.launcher.", "~hydra.launcher.")
POLL_S = 2.0  # how often the command reads the storage for ended trials and looks at the tasks (s)
FORCE_EVERY = 5  # every FORCE_EVERY-th poll asks Slurm (squeue) for the tasks' states: a task dead without output
CANCEL_WAIT_S = 120.0  # after scancel, how long the command waits for the tasks to end (Slurm's KillWait is 30 s)
SHOWN_FAILURES = 3  # failed tasks named on the error line; the others are counted


class SlurmWorkersError(ValueError):
    """The Slurm workers cannot be submitted as asked (one line)."""


def override_problem(overrides: Sequence[str]) -> str | None:
    """Why the command line's launcher overrides are not ``hydra.launcher.*`` overrides, or None."""
    for text in overrides:
        if not text.startswith(OVERRIDE_PREFIXES) or "=" not in text.lstrip("~"):
            return (f"{text[:80]!r}: launcher options are hydra.launcher.<key>=<value> (e.g. "
                    "hydra.launcher.partition=cpu); the study's own options are in its study file")
    return None


def storage_kind(kind: str, study_dir: Path, study: str) -> None:
    """Refuse a study stored in SQLite for Slurm workers: they run on other nodes and share the study folder over
    the cluster's file system, where SQLite's locks (and its WAL's shared memory) do not hold. ``study``: the study
    as the command was given it, for the conversion's command line."""
    if kind == "sqlite":
        raise SlurmWorkersError(f"{study_dir / 'study.db'}: a study stored in SQLite cannot be shared by Slurm "
                                "workers (SQLite locks badly over a shared file system); move it to the journal "
                                f"file first with: python -m runners.tune {study} --out {study_dir} --to-journal "
                                "(or run it with --launcher local)")


def launcher_params(overrides: Sequence[str], study_dir: Path, job_name: str) -> dict[str, Any]:
    """The Slurm preset composed by Hydra with ``overrides``; Submitit's folder is the study's ``.submitit/%j``
    unless the preset names another (``${hydra.sweep.dir}`` is the study folder). A bad override is one line."""
    from hydra import compose
    from omegaconf import OmegaConf

    from runners.tuning.episodes import hydra_conf

    problem = override_problem(overrides)
    if problem:
        raise SlurmWorkersError(problem)
    with hydra_conf():
        try:
            cfg = compose("config", overrides=[f"hydra/launcher={PRESET}", f"hydra.sweep.dir={study_dir.resolve()}",
                                               f"hydra.job.name={job_name}", *overrides], return_hydra_config=True)
            params = OmegaConf.to_container(cfg.hydra.launcher, resolve=True)
        except Exception as err:  # Hydra's override and composition errors: the first words name the key
            raise SlurmWorkersError(f"launcher options: {' '.join(str(err).split())[:300]}") from None
    assert isinstance(params, dict)
    target = str(params.pop("_target_", ""))
    from runners.sweeping.slurm import is_slurm_launcher

    if not is_slurm_launcher(target):
        raise SlurmWorkersError(f"conf/hydra/launcher/{PRESET}.yaml: its _target_ {target!r} is not Submitit's "
                                "Slurm launcher")
    for key in ("nodes", "tasks_per_node"):  # Submitit would start the worker once per task: same seed, same index
        if params.get(key) != 1:
            raise SlurmWorkersError(f"hydra.launcher.{key}={params.get(key)}: a study's worker is one process on "
                                    "one node; ask for more workers with --workers")
    return params


def check_slurm() -> None:
    """One line when this machine cannot submit to Slurm (Slurm's commands missing, no controller answers)."""
    from runners.sweeping.slurm import slurm_problem

    problem = slurm_problem(what="--launcher slurm", instead="run the workers on this machine with --launcher "
                            "local (the default), or run the command on a node of the cluster")
    if problem:
        raise SlurmWorkersError(problem)


def prepare(overrides: Sequence[str], study_dir: Path, study_name: str) -> dict[str, Any]:
    """The array's parameters, composed and checked before anything is written; raises :class:`SlurmWorkersError`."""
    params = launcher_params(overrides, study_dir, f"tune_{study_name}")
    check_slurm()
    return params


@dataclass(frozen=True)
class TaskEnd:
    """How one array task's worker ended: its exit status (0: the budget is reached) and where it ran."""

    index: int
    host: str
    pid: int
    code: int


def run_task(study_file: str, study_dir: str, kind: str, budget: int, index: int) -> TaskEnd:
    """One array task (on a node of the cluster): a worker of the study until the budget is reached. The worker's
    exit status is returned, so that Submitit stores it as the task's result."""
    from runners.tuning.worker import worker

    try:
        worker(study_file, study_dir, kind, budget, index)
        code = 0
    except SystemExit as end:
        code = end.code if isinstance(end.code, int) else 1
    return TaskEnd(index, socket.gethostname(), os.getpid(), code)


def submit(params: dict[str, Any], spec: Any, study_dir: Path, kind: str, budget: int, workers: int) -> list[Any]:
    """Submit ``workers`` tasks as one job array, with the parameters as Hydra's Submitit launcher passes them."""
    import submitit
    from hydra_plugins.hydra_submitit_launcher.config import BaseQueueConf
    from omegaconf import OmegaConf

    from runners.sweeping.slurm import use_squeue_without_sacct

    use_squeue_without_sacct()  # else a task that died unnoticed by sacct-less Slurm is waited for forever
    params = dict(params)
    folder = params.pop("submitit_folder")
    executor = submitit.AutoExecutor(folder=folder, cluster="slurm",
                                     slurm_max_num_timeout=params.pop("max_num_timeout", 0))
    generic = set(OmegaConf.structured(BaseQueueConf).keys())
    executor.update_parameters(**{k if k in generic else f"slurm_{k}": v for k, v in params.items()})
    n = range(workers)
    return executor.map_array(run_task, [str(spec.path.resolve())] * workers, [str(study_dir.resolve())] * workers,
                              [kind] * workers, [budget] * workers, list(n))


def array_file(study_dir: Path) -> Path:
    """Where the command notes the job array that runs the study's workers, until its tasks have ended."""
    from runners.sweeping.paths import lock_file

    return lock_file(study_dir).parent / "slurm_array"


def refuse_live_array(study_dir: Path) -> None:
    """Refuse a study whose workers of an earlier command (killed before it could cancel them) still run on Slurm:
    this command would mark their trials in flight interrupted while they run, and add workers of its own. Asked
    only where the study folder notes an array and ``squeue`` answers (any launcher: a local run too)."""
    path = array_file(study_dir)
    try:
        array = path.read_text().strip()
    except OSError:
        return
    if not array.isdigit():
        return
    tasks = listed_tasks(array)
    if tasks:
        raise SlurmWorkersError(f"{study_dir}: the Slurm job array {array} of an earlier command still runs this "
                                f"study's workers ({len(tasks)} task(s) pending or running): wait for "
                                f"it to end or cancel it (scancel {array}), then re-run")
    path.unlink(missing_ok=True)


def listed_tasks(array: str) -> list[str]:
    """The array's tasks ``squeue`` lists as not ended (pending, running, or completing: a cancelled task whose
    processes have not exited yet, which ``sacct`` and Submitit already call CANCELLED); empty where ``squeue``
    does not answer or no longer knows the array."""
    try:
        done = subprocess.run(["squeue", "--noheader", f"--jobs={array}", "--format=%i"], capture_output=True,
                              text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return []
    return done.stdout.split() if done.returncode == 0 else []


def pending(jobs: list[Any], force: bool) -> list[Any]:
    """The tasks not ended yet; ``force``: ask Slurm (one ``squeue`` for the whole array) rather than its cache."""
    left = [job for job in jobs if not job.done()]
    if left and force and left[0].done(force_check=True):
        left = [job for job in left[1:] if not job.done()]
    return left


EXIT_SUBMIT = 2  # the array was refused: the launcher options (partition, account ...) are bad input


def submission_error(err: BaseException) -> str:
    """sbatch's first error line (it names the value it refused) out of Submitit's exception, which holds the
    command's whole output."""
    lines = [line.strip() for line in str(err).splitlines() if line.strip()]
    said = [line for line in lines if "sbatch: error" in line] or lines[-1:] or [type(err).__name__]
    return " ".join(said[0].split())[:300]


class _Stop(Exception):
    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_stop(signum: int, frame: Any) -> None:
    raise _Stop(signum)


def task_failure(job: Any) -> str | None:
    """Why an ended array task failed (its Slurm state, its worker's exit status or exception), or None."""
    try:
        end = job.result()
    except Exception as err:  # no result (killed, cancelled, over its time limit, lost node) or the task raised
        lines = [line.strip() for line in str(err).splitlines() if line.strip()]
        last = lines[-1] if lines and "has not produced any output" not in lines[0] else ""
        return f"{job.state}{': ' + last[:120] if last else ''}"
    if isinstance(end, TaskEnd) and end.code == 0:
        return None
    code = end.code if isinstance(end, TaskEnd) else end
    what = "interrupted" if code in (130, 143) else "failed"
    return f"{job.state}, worker {what} (exit {code})"


def run_on_slurm(params: dict[str, Any], spec: Any, study: Any, study_dir: Path, kind: str, budget: int,
                 workers: int, show: Callable[[Any], None]) -> int:
    """Submit the workers, wait for them while printing the trials that end, and report the failed tasks.
    Returns the command's exit status: 0, 1 (a task failed), 130/143 (stopped: the array is cancelled)."""
    from optuna.trial import TrialState

    from runners.tuning.study import SURPLUS

    ended = (TrialState.COMPLETE, TrialState.FAIL)
    seen = {t.number for t in study.get_trials(deepcopy=False) if t.state in ended}
    previous = {s: signal.signal(s, _raise_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    jobs: list[Any] = []
    try:
        try:
            stops = {signal.SIGINT, signal.SIGTERM}
            signal.pthread_sigmask(signal.SIG_BLOCK, stops)  # a stop while sbatch runs would leave an array unknown
            try:
                with contextlib.redirect_stderr(io.StringIO()):  # Submitit prints sbatch's refusal, then raises it
                    jobs = submit(params, spec, study_dir, kind, budget, workers)
                array = jobs[0].job_id.split("_")[0]
                array_file(study_dir).write_text(array)
            except OSError:
                raise  # writing into the study folder: the command's line for a disk problem
            except Exception as err:  # sbatch refused the array (a partition, account or QOS it does not know)
                print(f"error: Slurm did not accept the workers' job array: {submission_error(err)}",
                      file=sys.stderr)
                return EXIT_SUBMIT
            finally:
                signal.pthread_sigmask(signal.SIG_UNBLOCK, stops)  # a stop asked for meanwhile cancels the array now
            print(f"submitted {workers} Slurm worker task(s) as job array {array} (logs: "
                  f"{jobs[0].paths.folder.parent / array}_*)", flush=True)
            polls = 0
            while True:
                for t in study.get_trials(deepcopy=False):
                    if t.number not in seen and t.state in ended:
                        seen.add(t.number)
                        if not t.user_attrs.get(SURPLUS):
                            show(t)
                polls += 1
                if not pending(jobs, force=polls % FORCE_EVERY == 0):
                    break
                time.sleep(POLL_S)
        except _Stop as stop:
            return cancel(jobs, stop.signum, study_dir)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    array_file(study_dir).unlink(missing_ok=True)
    failures = [(job, why) for job in jobs if (why := task_failure(job)) is not None]
    if failures:
        named = "; ".join(f"{job.job_id} {why} (log {job.paths.stderr})" for job, why in failures[:SHOWN_FAILURES])
        more = f"; and {len(failures) - SHOWN_FAILURES} more" if len(failures) > SHOWN_FAILURES else ""
        print(f"error: {len(failures)} of {len(jobs)} Slurm worker tasks failed: {named}{more}; re-run the "
              "command to resume", file=sys.stderr)
        return 1
    return 0


def cancel(jobs: list[Any], signum: int, study_dir: Path) -> int:
    """Cancel the array (its tasks end their trials in flight as interrupted) and wait for its tasks to end."""
    code = 128 + signum
    if not jobs:  # stopped while submitting: Submitit had not returned the array
        print("interrupted before the Slurm workers were submitted", file=sys.stderr)
        return code
    array = jobs[0].job_id.split("_")[0]
    subprocess.run(["scancel", array], capture_output=True, timeout=60, check=False)
    end = time.monotonic() + CANCEL_WAIT_S
    previous = {s: signal.signal(s, _raise_stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        # a task is ended when Slurm no longer lists it: one still completing may be writing its trial's end
        while pending(jobs, force=True) or listed_tasks(array):
            if time.monotonic() > end:
                break
            time.sleep(POLL_S)
        else:
            array_file(study_dir).unlink(missing_ok=True)
    except _Stop:  # a second Ctrl-C: do not wait for the tasks to end
        pass
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    print(f"interrupted: the Slurm job array {array} is cancelled; its trials in flight are marked interrupted; "
          "re-run the command to resume", file=sys.stderr)
    return code
