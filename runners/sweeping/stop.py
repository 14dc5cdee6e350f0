"""Stopping episodes cleanly: SIGINT/SIGTERM, and a sweep's stop file, acted on between two steps.

A stop never cuts a log inside a message: a signal handler only notes the request, and the episode loop calls
:func:`check` after every step, which raises :class:`analysis.interrupts.Interrupted`; the episode's log is then
finished with outcome ``interrupted``. A second signal raises at once.

In a sweep the launching process cannot signal its jobs reliably (Submitit processes, cluster nodes, loky workers
that a signal between two jobs would kill, breaking the pool), so it asks them to stop through the file system:
it creates the sweep's stop file (:func:`request_sweep_stop`), which every job looks for at most every
``STOP_POLL_S`` seconds while it runs and before each episode. A job that cannot write its logs creates it too,
so that the other jobs do not go on into a full disk.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from analysis.interrupts import Interrupted, describe
from runners.sweeping.paths import stop_file

STOP_POLL_S = 0.25  # how often (at most) a running job looks for the stop file: a stat per 0.25 s, not per step


# -- in the process running episodes -------------------------------------------------------------------------------
_LAUNCHER: list[bool] = []  # this process launches a sweep (its jobs may run here too: Hydra's basic launcher)


def mark_launcher() -> None:
    _LAUNCHER.append(True)


def is_launcher() -> bool:
    return bool(_LAUNCHER)


_PENDING: list[int] = []  # signals received while a job runs, acted on between two steps
_GRACE: list[bool] = []  # [True] while the grace timer of a stop signal runs
_TIME_LIMIT: list[bool] = []  # Submitit's warning that this Slurm job nears its time limit (SIGUSR2), see install
TIME_LIMIT_REASON = "the Slurm job reached its time limit (hydra.launcher.timeout_min)"
_WATCHED: list[Path] = []  # the sweep directory whose stop file this job looks for (none outside a sweep)
_next_look = 0.0  # time.monotonic() of the next look at the stop file


STEP_GRACE_S = 10.0  # after a stop signal, how long the step in flight may take before it is cut


def _on_signal(signum: int, frame: Any) -> None:
    """SIGINT/SIGTERM during a job: noted, and raised between two steps by :func:`check`; a second one raises
    at once, and so does the first when the step in flight does not end within ``STEP_GRACE_S`` (a policy whose
    ``act()`` never returns held the run forever: the signal waited for a step that never ended)."""
    if _PENDING:
        raise Interrupted(signum)
    _PENDING.append(signum)
    with contextlib.suppress(ValueError, OSError, AttributeError):  # no SIGALRM (Windows) or not the main thread
        signal.signal(signal.SIGALRM, _step_overdue)
        signal.setitimer(signal.ITIMER_REAL, STEP_GRACE_S)
        _GRACE.append(True)


def _step_overdue(signum: int, frame: Any) -> None:
    if _OVERDUE:  # the stop file's request, which the step in flight kept this job from reading (_StopFileWatch)
        stop_signum, why = _OVERDUE.pop()
        raise Interrupted(stop_signum, f"{why}; the step in flight had not ended {STEP_GRACE_S:g} s later")
    pending = _PENDING[0] if _PENDING else signal.SIGTERM
    if _WATCHED:  # as check() does at a step boundary: a signal to one job of a sweep stops the sweep
        request_sweep_stop(_WATCHED[0], pending, describe(pending))
    raise Interrupted(pending, f"{describe(pending)}; the step in flight had not ended {STEP_GRACE_S:g} s later")


_WATCHING: list[bool] = []  # [True] while a _StopFileWatch runs in this process
_OVERDUE: list[tuple[int, str]] = []  # a sweep stop the step in flight did not let the job act on in time
_CHECKS = [0]  # how many times check() ran: the job's heartbeat, read by _StopFileWatch


class _StopFileWatch(threading.Thread):
    """A sweep job's step can hang (a policy whose ``act()`` never returns), and the job reads the stop file only
    between steps: the sweep, asked to stop, then waited for it forever. This thread looks at the stop file too;
    once it appears, the step in flight has ``STEP_GRACE_S`` to end (the job then stops at the step boundary as
    usual), after which the thread interrupts the job's main thread (SIGALRM, :func:`_step_overdue`): the episode
    ends as interrupted with the stop's reason, its log finished."""

    def __init__(self, sweep_dir: Path) -> None:
        super().__init__(name="fuzzynav-stop-file-watch", daemon=True)
        self.path = stop_file(sweep_dir)
        self.main = threading.main_thread().ident
        self.done = threading.Event()

    def run(self) -> None:
        while not self.done.wait(STOP_POLL_S):
            request = read_sweep_stop(self.path)
            if request is None:
                continue
            beat = _CHECKS[0]
            if self.done.wait(STEP_GRACE_S) or _CHECKS[0] != beat:
                return  # the job ended, or reached a step boundary (where it stops by itself)
            _OVERDUE[:] = [request]
            with contextlib.suppress(ValueError, OSError, AttributeError, ProcessLookupError):
                signal.pthread_kill(self.main, signal.SIGALRM)
            return


def _cancel_grace() -> None:
    """Stop the step's grace timer (the step ended, or the job's handlers are undone)."""
    if _GRACE:
        _GRACE.clear()
        with contextlib.suppress(ValueError, OSError, AttributeError):
            signal.setitimer(signal.ITIMER_REAL, 0)
            # while the stop-file watch runs, its SIGALRM must still raise, never kill the job (SIG_DFL would)
            signal.signal(signal.SIGALRM, _step_overdue if _WATCHING else signal.SIG_DFL)


def _on_time_limit(signum: int, frame: Any) -> None:
    """Submitit's time-limit warning (SIGUSR2): noted, and raised between two steps by :func:`check`."""
    _TIME_LIMIT.append(True)


def install(sweep_dir: Path | None, idle: Any = None) -> Callable[[], None]:
    """Route SIGINT and SIGTERM to the step-boundary stop and watch the stop file of ``sweep_dir`` (None: not in
    a sweep) for the duration of a job. Returns the function that undoes it; ``idle`` (e.g. ``signal.SIG_IGN``)
    is then the handler instead of the previous one. In a thread other than the main one Python cannot install
    handlers: there the signals act as before, and only the stop file is watched."""
    global _next_look
    _PENDING.clear()
    _TIME_LIMIT.clear()
    _WATCHED[:] = [sweep_dir] if sweep_dir is not None else []
    _next_look = 0.0  # look at once: a job that starts after the sweep was asked to stop does nothing
    previous: dict[int, Any] = {}
    handlers = {signal.SIGINT: _on_signal, signal.SIGTERM: _on_signal}
    if os.environ.get("SUBMITIT_EXECUTOR") == "slurm":
        # Submitit asks Slurm for SIGUSR2 signal_delay_s before the time limit and, on it, raises its own
        # exception inside whatever runs (the episode: logged as an error, and the sweep went on as if complete).
        # Instead the episode in flight ends as interrupted at the next step, the job's later seeds are not run,
        # and the sweep reports them with the resume command. Only this job stops: the others have their own
        # time limits.
        handlers[signal.SIGUSR2] = _on_time_limit
    for signum, handler in handlers.items():
        try:
            previous[signum] = signal.signal(signum, handler)
        except ValueError:  # not the main thread
            break
    _ROUTED[:] = [signal.SIGINT in previous]
    watch = None
    _OVERDUE.clear()
    if sweep_dir is not None and _ROUTED[0] and hasattr(signal, "pthread_kill"):
        with contextlib.suppress(ValueError, OSError, AttributeError):
            previous.setdefault(signal.SIGALRM, signal.signal(signal.SIGALRM, _step_overdue))
            watch = _StopFileWatch(sweep_dir)
            watch.start()
            _WATCHING.append(True)

    def restore() -> None:
        if watch is not None:
            watch.done.set()
            watch.join()
        _WATCHING.clear()
        _OVERDUE.clear()
        _cancel_grace()
        _WATCHED.clear()
        _ROUTED.clear()
        for signum, handler in previous.items():  # SIGALRM back to what it was: only the watch needed it
            signal.signal(signum, handler if idle is None or signum == signal.SIGALRM else idle)

    return restore


_ROUTED: list[bool] = []  # [True] while install's handlers are in charge of SIGINT and SIGTERM


def signals_routed() -> bool:
    """Whether SIGINT and SIGTERM reach the episodes only as :class:`Interrupted` (between :func:`install` and its
    undo, in the main thread): a plain ``KeyboardInterrupt`` is then raised by code (a policy's), not by a
    signal."""
    return bool(_ROUTED and _ROUTED[0])


def from_signal(err: KeyboardInterrupt) -> bool:
    """Whether ``err`` stands for a stop request (a signal, the stop file) rather than code that raised
    ``KeyboardInterrupt`` itself: always, unless the job's handlers route the signals (:func:`signals_routed`)."""
    return isinstance(err, Interrupted) or not signals_routed()


def check(time_limit: bool = True) -> None:
    """Raise :class:`Interrupted` if a stop was requested: a signal, the Slurm time-limit warning (unless
    ``time_limit`` is False), or (looked at every ``STOP_POLL_S``) the sweep's stop file. Called after every step
    and, through :func:`check_between_episodes`, before every episode."""
    global _next_look
    _CHECKS[0] += 1
    if _TIME_LIMIT and time_limit:
        raise Interrupted(signal.SIGUSR2, TIME_LIMIT_REASON)
    if _PENDING:
        _cancel_grace()  # the step ended in time
        if _WATCHED:  # a signal to one job of a sweep stops the sweep (a terminal's Ctrl-C reaches them all)
            request_sweep_stop(_WATCHED[0], _PENDING[0], describe(_PENDING[0]))
        raise Interrupted(_PENDING[0])
    if _WATCHED and time.monotonic() >= _next_look:
        _next_look = time.monotonic() + STOP_POLL_S
        request = read_sweep_stop(stop_file(_WATCHED[0]))
        if request is not None:
            raise Interrupted(*request)


def check_between_episodes() -> None:
    """:func:`check` before a job's next episode. The Slurm time-limit warning is left to the episode's first
    step, which ends it as interrupted with the reason: a job that returned early without a log would leave the
    sweep looking complete, its later seeds silently missing (the sweep names the time limit from that log)."""
    check(time_limit=False)


# -- the sweep's stop file -----------------------------------------------------------------------------------------
def request_sweep_stop(sweep_dir: Path, signum: int, why: str) -> bool:
    """Ask every job of the sweep to stop: create the stop file holding the signal number (0: a failure, not a
    signal) and the reason the interrupted logs will record. Returns False if it could not be created (then the
    caller must stop the jobs otherwise). An empty file (a full disk can refuse the content but not the name)
    still stops the jobs."""
    path = stop_file(sweep_dir)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    except OSError:
        return False
    with contextlib.suppress(OSError):
        os.write(fd, f"{int(signum)}\n{why}\n".encode())
    os.close(fd)
    return True


def read_sweep_stop(path: Path) -> tuple[int, str] | None:
    """(signal number, reason) of the stop file at ``path``, or None when there is none."""
    try:
        text = path.read_text(errors="replace")
    except FileNotFoundError:
        return None
    except OSError:
        text = ""
    first, _, rest = text.partition("\n")
    signum = int(first) if first.strip().isdigit() else 0  # empty (a full disk took no content): not a signal
    return signum, rest.strip() or "sweep stopped"


def clear_sweep_stop(sweep_dir: Path) -> None:
    """Remove a stop file left by an earlier sweep (whose launcher died before removing it)."""
    with contextlib.suppress(FileNotFoundError):
        stop_file(sweep_dir).unlink()
