"""The processes below this one (a sweep's workers, Submitit's job processes and their children), to end them all.

Python's standard library has no portable way to list child processes; this reads ``/proc`` on Linux and asks
``ps`` elsewhere (macOS), so that no extra dependency is needed.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
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
