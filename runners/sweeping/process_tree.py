"""The processes below this one (a sweep's workers, Submitit's job processes and their children), to end them all.

Python's standard library has no portable way to list child processes; this reads ``/proc`` on Linux and asks
``ps`` elsewhere (macOS), so that no extra dependency is needed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from pathlib import Path


def descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children first), from /proc on Linux, else from ``ps``."""
    parents: dict[int, list[int]] = {}
    proc = Path("/proc")
    if proc.is_dir():
        for entry in proc.iterdir():
            if entry.name.isdigit():
                with contextlib.suppress(OSError, ValueError, IndexError):
                    stat = (entry / "stat").read_text()
                    ppid = int(stat[stat.rindex(")") + 2:].split()[1])  # the name in (...) may hold spaces
                    parents.setdefault(ppid, []).append(int(entry.name))
    else:
        with contextlib.suppress(OSError, subprocess.SubprocessError, ValueError):
            out = subprocess.run(["ps", "-A", "-o", "pid=,ppid="], capture_output=True, text=True, timeout=10).stdout
            for line in out.splitlines():
                child, ppid = (int(x) for x in line.split())
                parents.setdefault(ppid, []).append(child)
    found, queue = [], [pid]
    while queue:
        for child in parents.get(queue.pop(0), []):
            if child not in found:
                found.append(child)
                queue.append(child)
    return found


def kill_descendants() -> int:
    """SIGKILL every descendant of this process; returns how many were signalled."""
    count = 0
    for pid in descendants(os.getpid()):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.kill(pid, signal.SIGKILL)
            count += 1
    return count


_WATCHDOG: list[threading.Thread] = []
PARENT_POLL_S = 0.5  # how often a worker looks for its launcher (s): it is gone at most this long after it died


def exit_with_parent(poll_s: float = PARENT_POLL_S, expected_parent: int | None = None) -> None:
    """End this process (SIGKILL) as soon as its parent has died; started once per process, in a sweep's worker.

    A launcher killed with SIGKILL cannot stop its workers, and loky's idle workers ignore SIGINT/SIGTERM (see
    ``runners.sweep._import_runner``): they lived on for ever, holding the caller's stdout and stderr open. A
    daemon thread compares ``os.getppid()`` with the parent it had at the start: a process whose parent dies is
    re-parented (to init or a subreaper), so the pid changes. Linux's ``prctl(PR_SET_PDEATHSIG)`` is not used:
    it fires when the *thread* that started the worker ends, and loky starts workers from short-lived threads
    (``runners.sweep.prewarm_workers``, its executor manager), so workers would die with them. The same test works
    on macOS and other POSIX systems; not on Windows, where a process keeps its parent's pid. The episode in flight
    is killed like by a second signal to the launcher: its log stays ``.*.mcap.partial`` and the next sweep into
    the directory removes it (``resume=true`` runs it again). ``expected_parent``: the pid the parent had when it
    started this process (a worker whose launcher died before this runs has init's pid for a parent: it ends at
    once)."""
    if _WATCHDOG or os.name != "posix":
        return
    parent = os.getppid() if expected_parent is None else expected_parent

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll_s)
        os.kill(os.getpid(), signal.SIGKILL)

    thread = threading.Thread(target=watch, name="fuzzynav-exit-with-parent", daemon=True)
    _WATCHDOG.append(thread)
    thread.start()


def worker_started(launcher_pid: int) -> None:
    """The sweep's worker processes run this first (loky's initializer: before they wait for a job), so that a
    launcher killed while they start leaves none behind: an idle worker that never got a job used to wait for
    loky's idle timeout, five minutes, holding the caller's stdout and stderr."""
    exit_with_parent(expected_parent=launcher_pid)
