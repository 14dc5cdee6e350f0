"""The launching process of a sweep: owning the directory, stopping on a signal, noting what went wrong.

:func:`begin` (called when the sweep starts, by its callback or else by fuzzynav's sweeper) takes the directory's
lock (:mod:`runners.sweeping.lock`), removes what a killed earlier sweep left (partial logs, a stop file) and routes
SIGINT/SIGTERM to :func:`_on_signal`:

- the first signal asks every job to stop through the sweep's stop file (:mod:`runners.sweeping.stop`): episodes in
flight
  end their current step and are logged ``interrupted``, jobs not started yet do nothing, the launcher stops
  handing out jobs (:class:`StoppableJobs`), and the end of the sweep writes the summary of what completed and
  exits 130 (SIGINT) or 143 (SIGTERM);
- a second signal, or a signal before the sweep has started, stops at once: every descendant process is killed
  (their unfinished logs stay ``.*.mcap.partial``, never mistaken for complete logs) and the process exits.

Failures that are not episode outcomes — a log that cannot be written (disk full, read-only), a job that failed,
a worker process that died — are noted as one line each (:meth:`SweepRun.fail`) and reported at the end of the
sweep, after the summary of the completed episodes, with a non-zero exit.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis import interrupts
from runners.sweeping import lock as sweep_lock
from runners.sweeping import process_tree, stop
from runners.sweeping.paths import partial_logs, stop_file


@dataclass
class SweepRun:
    """One sweep, in its launching process. ``started``: wall-clock time (s since the epoch) when it began, to tell
    the logs it wrote from older ones; ``signum``: the stop signal received, if any; ``errors``: one line per
    failure; ``removed_partials``: partial logs of killed episodes of an earlier sweep, removed at the start;
    ``found``: the logs the directory held when a sweep without resume began (path -> :func:`log_fingerprint`),
    which are not this sweep's unless it writes them again."""

    sweep_dir: Path
    started: float
    signum: int | None = None
    errors: list[str] = field(default_factory=list)
    removed_partials: int = 0
    found: dict[str, tuple[int, int]] = field(default_factory=dict)

    def fail(self, line: str) -> None:
        """Note a failure (once per distinct line) and ask the jobs still running to stop."""
        if line not in self.errors:
            self.errors.append(line)
        stop.request_sweep_stop(self.sweep_dir, 0, f"sweep stopped: {line}")

    def stop_requested(self) -> bool:
        return self.signum is not None or stop_file(self.sweep_dir).exists()

    def stop_signal(self) -> int | None:
        """The signal that stopped the sweep: received here, or by one of its jobs (recorded in the stop file)."""
        if self.signum is not None:
            return self.signum
        request = stop.read_sweep_stop(stop_file(self.sweep_dir))
        return request[0] if request and request[0] in interrupts.SIGNAL_NAMES else None


def log_fingerprint(path: Path) -> tuple[int, int] | None:
    """(inode, modification time in ns) of a log, or None where it cannot be read: a log written again (a new file
    put in its place) has another, whatever the file system's clock resolution."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns


_CURRENT: list[SweepRun] = []


def current() -> SweepRun | None:
    return _CURRENT[0] if _CURRENT else None


def begin(sweep_dir: Path) -> SweepRun:
    """Start (once per process) the sweep into ``sweep_dir``: lock, clean up, route the signals. Raises
    :class:`runners.sweeping.lock.SweepLockError` or ``OSError`` (see :func:`io_line`)."""
    run = current()
    if run is not None:
        return run
    install_handlers()
    sweep_lock.acquire(sweep_dir)
    stop.clear_sweep_stop(sweep_dir)
    removed = 0
    for partial in partial_logs(sweep_dir):  # left by killed episodes of an earlier sweep: nobody writes them now
        with contextlib.suppress(FileNotFoundError):
            partial.unlink()
            removed += 1
    run = SweepRun(sweep_dir, time.time(), removed_partials=removed)
    _CURRENT.append(run)
    stop.mark_launcher()
    return run


def begin_or_exit(sweep_dir: Path) -> SweepRun:
    """:func:`begin`, or one line and exit 1 if the directory is in use or cannot be written (an exception would
    not do: Hydra turns an exception raised in a callback into a warning)."""
    try:
        return begin(sweep_dir)
    except sweep_lock.SweepLockError as err:
        print(f"error: {err}", file=sys.stderr)
    except OSError as err:
        print(f"error: {io_line(err, sweep_dir)}", file=sys.stderr)
    sys.exit(1)


def end(run: SweepRun) -> None:
    """After the summary: give the lock up. The stop file stays after a stop or a failure, so that a job the
    launcher lost track of (a Submitit job still running when its launcher gave up on it) stops too; the next sweep
    into the directory removes it."""
    if run.signum is None and not run.errors:
        stop.clear_sweep_stop(run.sweep_dir)
    sweep_lock.release(run.sweep_dir)


# -- signals -------------------------------------------------------------------------------------------------------
_INSTALLED: list[bool] = []


def install_handlers() -> None:
    """Route SIGINT and SIGTERM of this (launching) process to :func:`_on_signal`; once."""
    if not _INSTALLED:
        signal.signal(signal.SIGINT, _on_signal)
        signal.signal(signal.SIGTERM, _on_signal)
        _INSTALLED.append(True)


def _on_signal(signum: int, frame: Any) -> None:
    run = current()
    name = interrupts.SIGNAL_NAMES.get(signum, str(signum))
    if run is None or run.signum is not None:
        stop_now(signum, "before the sweep started" if run is None else f"second {name}")
    run.signum = signum
    if not stop.request_sweep_stop(run.sweep_dir, signum, f"sweep stopped ({name} to the launching process)"):
        stop_now(signum, "the stop file could not be written")
    _say(f"{name}: stopping the sweep: episodes in flight end after their current step, logged as interrupted; "
         f"{name} again stops at once")


def stop_now(signum: int, why: str) -> None:
    """Kill every descendant process and exit 128 + ``signum`` (no summary: nothing waits any more)."""
    killed = process_tree.kill_descendants()
    if current() is None:
        _say(f"stopped before the sweep started ({killed} worker process(es) ended)")
    else:
        _say(f"stopped at once ({why}): {killed} worker process(es) killed; their unfinished logs are left as "
             ".*.mcap.partial; run the sweep again with resume=true to complete it")
    os._exit(128 + signum)


def _say(line: str) -> None:
    """One line on stderr, safe inside a signal handler (no reentrant buffered write)."""
    with contextlib.suppress(OSError):
        os.write(2, (line + "\n").encode())


# -- launching ------------------------------------------------------------------------------------------------------
class StoppableJobs(list):
    """A launcher's job list that stops yielding jobs once the sweep is asked to stop: launchers that hand jobs
    out lazily (joblib's ``Parallel`` over a generator, Hydra's basic launcher) start no new job after a signal.
    Indexing and ``len`` see every job."""

    def __init__(self, jobs: Sequence[Sequence[str]], run: SweepRun | None) -> None:
        super().__init__(jobs)
        self.run = run

    def __iter__(self) -> Iterator[Sequence[str]]:
        for job in list.__iter__(self):
            if self.run is not None and self.run.stop_requested():
                return
            yield job


def io_line(err: OSError, default_path: Path | str | None = None) -> str:
    """One line for an I/O error: the path (the error's own, else ``default_path``) and what is wrong."""
    from runners.logs.mcap_log import LogWriteError

    if isinstance(err, LogWriteError):
        return str(err)
    path = err.filename or default_path
    text = err.strerror or str(err) or type(err).__name__
    return f"{path}: {text}" if path else text


def launcher_failed(run: SweepRun, err: Exception) -> None:
    """The launcher raised instead of returning the jobs' results: a job's process died (a SIGKILL, the kernel's
    out-of-memory killer, a lost cluster node) or could not write its files; the episodes it was running are
    lost, those not started were not run."""
    if isinstance(err, OSError) and not _is_lost_worker(err):
        # Hydra's own writes in a job (its .hydra/ snapshot) fail without naming the file; a job whose log could
        # not be written named it in the stop file, and it is usually the same cause
        request = stop.read_sweep_stop(stop_file(run.sweep_dir)) if not err.filename else None
        named = request[1].removeprefix("sweep stopped: ") if request and request[0] == 0 else ""
        run.fail(named if named.startswith(str(run.sweep_dir)) else io_line(err, run.sweep_dir))
        return
    text = str(err)
    codes = re.search(r"exit codes of the workers are (\{[^}]*\})", text)  # loky names the signal: SIGKILL(-9)
    # Submitit puts the job and the result file's path on its first line, its Slurm state on the second
    job = re.match(r"Job (\S+) .*\n(has not produced any output \(state: [^)]*\))", text)
    first = (text.strip().splitlines() or [""])[0][:200]
    detail = f"exit codes {codes.group(1)}" if codes else f"job {job.group(1)} {job.group(2)}" if job else first
    run.fail(f"a worker process was lost ({type(err).__name__}{': ' + detail if detail else ''})")


def _is_lost_worker(err: BaseException) -> bool:
    from concurrent.futures.process import BrokenProcessPool

    return isinstance(err, BrokenProcessPool) or type(err).__name__ in ("TerminatedWorkerError",
                                                                         "UncompletedJobError")


def job_failed(run: SweepRun, job_num: Any, err: BaseException) -> None:
    """A job ended with an exception (its episodes' own exceptions are outcomes, so this is not one of them)."""
    if isinstance(err, OSError):
        run.fail(io_line(err))
        return
    text = (str(err).strip().splitlines() or [""])[0][:300]
    if type(err).__name__ == "ConfigFileError":  # (a file named, as runners.run says it)
        run.fail(f"job {job_num} failed: {text}")
    elif isinstance(err, ValueError):  # the job's config did not pass the checks a run makes (runners.run.task)
        run.fail(f"job {job_num} failed: config: {text.removeprefix('config: ')}")
    else:
        run.fail(f"job {job_num} failed: {type(err).__name__}: {text}")


def print_errors(run: SweepRun) -> None:
    """The failures on at most two lines: the first is the cause, the others usually follow from it."""
    if run.errors:
        print(f"error: {run.errors[0]}", file=sys.stderr)
    if len(run.errors) > 1:
        more = f" (and {len(run.errors) - 2} more)" if len(run.errors) > 2 else ""
        print(f"error: also: {run.errors[1][:200]}{more}", file=sys.stderr)


def finish(run: SweepRun) -> None:
    """The last act of a sweep's launching process, whoever ends the sweep (``runners.sweep``'s callback, or
    fuzzynav's sweeper when there is no callback): the failures on stderr (:func:`print_errors`), the directory
    given up (:func:`end`), and exit 128 + the signal after a stop, 1 after a failure; returns only when the
    sweep completed."""
    print_errors(run)
    signum = run.stop_signal()
    end(run)
    if signum is not None:
        sys.exit(128 + signum)
    if run.errors:
        sys.exit(1)


def debug_requested() -> bool:
    return os.environ.get("HYDRA_FULL_ERROR") == "1"
