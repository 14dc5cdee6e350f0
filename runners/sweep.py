"""Config sweeps: a Hydra multirun of ``runners.run``, in parallel, with a progress bar and a summary.

    python -m runners.sweep                       # the default experiment (conf/sweep/default.yaml)
    python -m runners.sweep sweep=quick           # any preset in conf/sweep/
    python -m runners.sweep navigator=fuzzy_tpt,dwa,orca   # a sweep over policies: preset sweep=policies
    python -m runners.sweep sweep=quick planner.safety_margin_cm=5,15    # plus any Hydra override

Logs: ``multirun/<date>/<time>/<job>/<scenario>__<strategy>[__h<h_wait>]__...__s<seed>.mcap`` with Hydra's
``.hydra/`` snapshots per job. At the end it reads the logs back once (:func:`analysis.metrics.analyse_logs`),
writes ``summary.csv``, prints a table of outcomes per group — scenario, strategy, h_wait and every other run
parameter the sweep varied (:mod:`analysis.run_parameters`) — and writes the analysis report from the same
numbers into ``<sweep dir>/report/``.

Faults (:mod:`runners.sweeping.control`): the sweep owns its directory (a lock: a second sweep into it exits at once);
``resume=true`` verifies and keeps each completed episode once (:mod:`runners.sweeping.resume`); SIGINT/SIGTERM stop
the jobs cleanly, write the summary of what completed and exit 130/143; a lost worker, a full disk or a job that
failed ends the sweep with the summary, one line per failure and a non-zero exit. ``summary.csv`` and the report
are written whole or not at all.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import threading
from pathlib import Path
from typing import Any

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from analysis.drawing import FigureError
from analysis.logs import is_complete
from fuzzynav.params.limits import MAX_SWEEP_JOBS
from runners.progress import EpisodeProgress
from runners.sweeping import control as sweep_control
from runners.sweeping import end as sweep_end
from runners.sweeping import resume as sweep_resume
from runners.sweeping import shm_leftovers
from runners.sweeping.paths import LogScan, job_logs
from runners.sweeping.size import count_episodes, count_jobs

# a job's own directory: Hydra's job number or id, or the overrides that make the job (``${hydra.job.num}``,
# ``${hydra:job.id}``, ``${hydra.job.override_dirname}``)
_PER_JOB = re.compile(r"\$\{\s*hydra[.:]\s*job\.(num|id|override_dirname)\s*\}")


def shared_job_dir(config: DictConfig, task: list[str]) -> str | None:
    """One line when ``hydra.sweep.subdir`` is the same directory for every job of a sweep of more than one job
    (``hydra.sweep.subdir=same``: every job wrote its logs into one directory and the logs of one job replaced
    the logs of the same name of another, e.g. the same planner at another safety margin; the sweep said it
    succeeded). None when it names each job's own directory or the sweep is one job."""
    sweep = config.hydra.get("sweep") if "hydra" in config else None
    if sweep is None:
        return None
    raw = OmegaConf.to_container(sweep, resolve=False).get("subdir")
    excluded = _swept_but_excluded(config, task) if raw is not None and "override_dirname" in str(raw) else None
    if excluded:
        return (f"config: hydra.job.config.override_dirname.exclude_keys: {excluded[:60]} is swept but left out "
                f"of hydra.sweep.subdir {str(raw)[:60]!r}, so jobs that differ only in it share one directory "
                "(logs of the same name would replace each other); keep it in the name or include ${hydra.job.num}")
    if raw is None or _PER_JOB.search(str(raw)):
        return None
    jobs = count_jobs(config, task)
    if jobs is not None and jobs <= 1:
        return None
    return (f"config: hydra.sweep.subdir: {str(raw)[:60]!r} is the same directory for each of the "
            f"{jobs if jobs is not None else 'several'} jobs (logs of the same name would replace each other); "
            "include ${hydra.job.num}")


def _swept_but_excluded(config: DictConfig, task: list[str]) -> str | None:
    """The first swept key of ``task`` that ``override_dirname`` leaves out (its ``exclude_keys``), if any and
    the subdir names no ``hydra.job.num`` or ``id`` besides."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    raw = str(OmegaConf.to_container(config.hydra.sweep, resolve=False).get("subdir"))
    if re.search(r"\$\{\s*hydra[.:]\s*job\.(num|id)\s*\}", raw):
        return None
    keys = OmegaConf.select(config, "hydra.job.config.override_dirname.exclude_keys", default=None) or []
    try:
        parsed = OverridesParser.create().parse_overrides(list(task))
    except Exception:  # the precheck has reported an override that does not parse
        return None
    for o in parsed:
        # the seed is in every log's name: jobs that differ only in it never write the same file
        if o.is_sweep_override() and o.get_key_element() != "seed" and o.get_key_element() in set(map(str, keys)):
            return o.get_key_element()
    return None


def refuse_shared_job_dir(config: DictConfig, task: list[str]) -> None:
    problem = shared_job_dir(config, task)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)


_SLURM_CHECKED: list[bool] = []  # asked once per process (sinfo may take a moment on a busy controller)


def refuse_unreachable_slurm(config: DictConfig) -> None:
    """With ``hydra/launcher=slurm``, one line and exit 2 when this machine cannot submit to Slurm
    (:func:`runners.sweeping.slurm.slurm_problem`), before any job is composed or written."""
    if _SLURM_CHECKED or "hydra" not in config:
        return
    from runners.sweeping.slurm import is_slurm_launcher, slurm_problem

    if not is_slurm_launcher(str((config.hydra.get("launcher") or {}).get("_target_", ""))):
        return
    _SLURM_CHECKED.append(True)
    problem = slurm_problem()
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)


SHORT_JOBS = 50  # from this many jobs of fewer than SHORT_JOB_EPISODES episodes, the sweep suggests batching
SHORT_JOB_EPISODES = 10


def short_jobs_tip(total_episodes: int | None, episodes_per_job: int) -> str | None:
    """A one-line tip when the sweep is many jobs of a few episodes: each Hydra job costs about 0.15-0.2 s of
    CPU (its config is composed and snapshotted where it runs), often more than a short episode itself."""
    if total_episodes is None or episodes_per_job >= SHORT_JOB_EPISODES:
        return None
    jobs = total_episodes // max(episodes_per_job, 1)
    if jobs < SHORT_JOBS or jobs > MAX_SWEEP_JOBS:  # (more: the sweeper refuses it, saying how to batch)
        return None
    return (f"tip: {jobs} jobs of {episodes_per_job} episode(s) each; every job costs about 0.15-0.2 s of CPU "
            "besides its episodes. Batch seeds into longer jobs, e.g. seed='range(0,1000,250)' episodes=250")


# watcher threads live here, not on the callback: the launcher pickles callbacks to send them to workers
_WATCHERS: dict[str, tuple[threading.Thread, threading.Event]] = {}
_PLANS: dict[str, sweep_resume.ResumePlan] = {}  # what a resume set aside, per sweep directory


def _watch(sweep_dir: Path, total: int | None, stop: threading.Event) -> None:
    """Count the logs the jobs finish (a log appears under its name only when complete; a kept one is moved back
    into its job's directory) until ``stop`` is set. Logs already there at the start count when replaced."""
    logs = LogScan(sweep_dir)
    before = {}
    for path in logs.scan():
        with contextlib.suppress(OSError):
            before[path] = os.stat(path).st_mtime_ns
    with EpisodeProgress(total, "sweep") as progress:
        done: set[str] = set()
        while True:
            stopping = stop.wait(0.5)
            for path in logs.scan():
                if path in done:
                    continue
                with contextlib.suppress(OSError):
                    if before.get(path) != os.stat(path).st_mtime_ns and is_complete(Path(path)):
                        done.add(path)
                        progress.update(1)
            progress.tick()
            if stopping:
                break


def _import_runner() -> int:
    """Run in a launcher worker: import what every job needs (the worker keeps it for the next jobs). Not
    scipy.optimize (~0.25 s): the tracker imports it only for a frame whose gated pairs conflict, which none of the
    default sweep's episodes has."""
    import signal

    import runners.run  # noqa: F401
    from runners.sweeping.process_tree import exit_with_parent

    exit_with_parent()  # a launcher killed with SIGKILL leaves no idle worker behind

    # idle workers ignore SIGINT/SIGTERM (each job handles them while it runs, see runners.run.run_job): a
    # terminal's Ctrl-C reaches every process of the sweep, and a worker that died of it would break the pool
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    return os.getpid()


_PREWARMED: list[bool] = []  # prewarm_workers has started the workers in this process


def prewarm_workers(config: DictConfig) -> None:
    """Start the launcher's worker processes (joblib's loky pool) now, in the background, so their start-up and imports
    (about a second) overlap with Hydra starting and validating every job's config in this process. loky keeps
    a pool of workers and reuses it for the next ``Parallel`` call with the same settings, which are the
    launcher's. Called as soon as the first config is composed, and again (doing nothing) when the sweep
    starts."""
    if _PREWARMED or "hydra" not in config:
        return
    launcher = config.hydra.get("launcher") or {}
    if "FuzzynavLauncher" not in str(launcher.get("_target_", "")):
        return
    try:  # only an optimisation: without it the launcher starts its workers itself
        from hydra_plugins.fuzzynav_sweeper.launcher import parallel_settings, worker_pool
        from joblib import Parallel, cpu_count, delayed
    except ImportError:
        return

    settings = parallel_settings(int(launcher.get("n_jobs") or 1))
    n_jobs = settings["n_jobs"]
    workers = cpu_count() if n_jobs < 0 else n_jobs

    def warm() -> None:
        with contextlib.suppress(Exception), worker_pool():
            Parallel(**settings)(delayed(_import_runner)() for _ in range(workers))

    _PREWARMED.append(True)
    threading.Thread(target=warm, daemon=True).start()


HYDRA_BASIC_SWEEPER = "hydra._internal.core_plugins.basic_sweeper.BasicSweeper"
FAULT_TOLERANT_SWEEPER = "hydra_plugins.fuzzynav_sweeper.FaultTolerantSweeper"


def fault_tolerant_sweeper(config: DictConfig) -> None:
    """With ``hydra/sweeper=basic``, sweep with :class:`hydra_plugins.fuzzynav_sweeper.FaultTolerantSweeper`:
    Hydra's basic sweeper, every job's config composed up front as the user chose, but a lost worker or a failed
    job noted as one line (the summary and the resume command follow) instead of a traceback from inside Hydra,
    where nothing of the sweep could report it. Called before Hydra instantiates the sweeper from this config."""
    if config.hydra.sweeper.get("_target_") != HYDRA_BASIC_SWEEPER:
        return
    from hydra.core.plugins import Plugins
    from omegaconf import open_dict, read_write

    try:
        from hydra_plugins.fuzzynav_sweeper import FaultTolerantSweeper
    except ImportError:  # fuzzynav not installed as a package: Hydra's sweeper as it is
        return
    Plugins.instance().register(FaultTolerantSweeper)
    with read_write(config.hydra), open_dict(config.hydra):
        config.hydra.sweeper._target_ = FAULT_TOLERANT_SWEEPER


class SweepProgress(Callback):
    """Owns the sweep directory for the sweep (:mod:`runners.sweeping.control`), prepares a resume, shows a progress
    bar over episodes, and at the end writes the summary and the report and reports what went wrong. Hydra turns
    an exception raised in a callback into a warning: every failure here is one line on stderr and an exit
    status instead."""

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        refuse_shared_job_dir(config, list(config.hydra.overrides.task))  # before anything runs or is written
        refuse_unreachable_slurm(config)
        fault_tolerant_sweeper(config)
        run = sweep_control.begin_or_exit(sweep_dir)
        shm_leftovers.remove_stale()  # pools of hard-stopped earlier sweeps (hostile14c flt_sigterm_twice_resume)
        if run.removed_partials:
            print(f"{run.removed_partials} partial log(s) of episodes killed in an earlier sweep removed (their "
                  "episodes run again)")
        try:
            if config.get("resume", False):
                plan = _PLANS[str(sweep_dir)] = sweep_resume.prepare(sweep_dir, jobs=-1)
                for line in plan.skipped:  # e.g. a FIFO named x.mcap: left alone, never opened
                    print(f"resume: skipped {line}")
            else:
                sweep_resume.restore(sweep_dir)
                found = {str(p): sweep_control.log_fingerprint(p) for p in job_logs(sweep_dir)}
                run.found = {path: mark for path, mark in found.items() if mark is not None}
                existing = sum(1 for p in found if is_complete(Path(p)))
                if existing:
                    print(f"warning: {sweep_dir} already holds {existing} complete logs; without resume=true those "
                          "of this sweep's episodes are run again and overwritten, and the others are left out of "
                          "its summary and report", file=sys.stderr)
        except Exception as err:  # Hydra would turn it into a warning and run the sweep anyway
            if sweep_control.debug_requested():
                raise
            line = sweep_control.io_line(err, sweep_dir) if isinstance(err, OSError) else \
                f"preparing the sweep failed: {type(err).__name__}: {err}"
            print(f"error: {line}", file=sys.stderr)
            sys.exit(1)
        prewarm_workers(config)
        if "SlurmLauncher" in str(config.hydra.launcher.get("_target_", "")):
            from runners.sweeping.slurm import use_squeue_without_sacct

            use_squeue_without_sacct()  # else a job that died unnoticed by sacct-less Slurm is waited for forever
        total = count_episodes(config)
        tip = short_jobs_tip(total, int(config.get("episodes", 1)))
        if tip:
            print(tip, file=sys.stderr)
        stop = threading.Event()
        thread = threading.Thread(target=_watch, args=(sweep_dir, total, stop), daemon=True)
        _WATCHERS[str(sweep_dir)] = (thread, stop)
        thread.start()

    def on_multirun_end(self, config: DictConfig, **kwargs: Any) -> None:
        sweep_dir = Path(config.hydra.sweep.dir)
        thread, stop = _WATCHERS.pop(str(sweep_dir), (None, None))
        if stop is not None and thread is not None:
            stop.set()
            thread.join()
        run = sweep_control.current() or sweep_control.begin(sweep_dir)
        try:
            sweep_end.end_of_sweep(config, run, _PLANS.pop(str(sweep_dir), None))
        except Exception as err:  # Hydra would turn it into a warning and exit 0
            if sweep_control.debug_requested():
                raise
            run.errors.append(sweep_control.io_line(err) if isinstance(err, OSError) else
                              f"{sweep_dir / 'report'}: the report could not be written: {err}"
                              if isinstance(err, FigureError) else
                              f"writing the summary failed: {type(err).__name__}: {err}")
        sweep_control.finish(run)


def default_preset(args: list[str]) -> str:
    """The preset of a command line that names none: ``policies`` when it sweeps the navigator (each policy with
    its own planner default: the default preset's sweep over planners would override them all), else
    ``default``."""
    for arg in args:
        if arg.startswith("-"):
            continue
        try:
            (parsed,) = OverridesParser.create().parse_overrides([arg])
        except Exception:  # Hydra itself reports a malformed override, with its own message
            continue
        if parsed.get_key_element() in ("navigator", "navigator.policy", "navigator._target_") \
                and parsed.is_sweep_override():
            return "policies"
    return "default"


SHOW_OPTIONS = ("--cfg", "-c", "--info", "-i")  # Hydra's options that print the config instead of running it


def preset_problem(args: list[str]) -> str | None:
    """One line when the command line sweeps, deletes or globs the ``sweep`` preset (``sweep=quick,policies``,
    ``~sweep``): a sweep is run by its preset (conf/sweep/), and without one Hydra's basic sweeper and launcher ran
    the jobs with no summary or report, exit 0."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parser = OverridesParser.create()
    for arg in args:
        if arg.startswith("-") or arg.lstrip("+~").partition("=")[0].strip() != "sweep":
            continue
        try:
            (override,) = parser.parse_overrides([arg])
        except Exception:  # the precheck names a malformed override
            continue
        if override.is_delete() or override.is_sweep_override():
            return (f"{arg[:80]}: a sweep runs one preset of conf/sweep/ (sweep=<name>): run one command per preset "
                    "(python -m runners.sweep sweep=quick, then sweep=policies)")
    return None


def with_preset(args: list[str], preset: str) -> list[str]:
    """``args`` with the ``preset`` override where Hydra's command-line parser reads it as one of the overrides:
    just before the first override, or first where there is none. Overrides are one group of positional arguments
    for that parser; in front of options followed by overrides (``--cfg job planner=wait``), the preset made a
    second group, and Hydra refused the command ("unrecognized arguments")."""
    from runners.run import hydra_arguments

    parsed = hydra_arguments(args)
    if parsed is None:  # a malformed option: Hydra's own message follows
        return [preset, *args]
    overrides = list(parsed[0].overrides)
    for i in range(len(args)):
        if overrides and args[i:i + len(overrides)] == overrides:
            return [*args[:i], preset, *args[i:]]
    return [preset, *args]


def main() -> None:
    sweep_control.install_handlers()  # from the start: a signal before the sweep begins kills its prewarmed workers
    from runners.configuration.command_line import canonical_arguments

    args, problem = canonical_arguments(sys.argv[1:])  # (--ru is --run, -cjob is --cfg job)
    problem = problem or preset_problem(args)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)
    if not any(a.startswith("sweep=") for a in args):
        args = with_preset(args, f"sweep={default_preset(args)}")
    if "--run" in args or "-r" in args:
        print("error: --run: runners.sweep runs a sweep; one configuration is python -m runners.run with the same "
              "overrides", file=sys.stderr)
        sys.exit(2)
    # Hydra's --cfg and --info show the sweep's config (one configuration) instead of running it: not a multirun
    shows = any(a in SHOW_OPTIONS or a.startswith(("--cfg=", "--info=")) for a in args)
    sys.argv = [sys.argv[0], *([] if shows else ["--multirun"]), *args]
    from runners import run

    task = [a for a in args if not a.startswith("-")]

    def on_config(config: DictConfig) -> None:
        refuse_shared_job_dir(config, task)  # with the command line's sweeps, not the one job composed to check
        refuse_unreachable_slurm(config)
        prewarm_workers(config)

    run.cli(on_config=on_config, sweep=True)


if __name__ == "__main__":
    main()
