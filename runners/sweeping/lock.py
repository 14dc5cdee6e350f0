"""One owner per sweep directory: an exclusive ``fcntl.flock`` on ``<sweep dir>/.fuzzynav/lock``.

Two sweeps writing into one directory corrupt each other's logs (both write the same file names) and both
believe they ran everything. The launching process of a sweep takes the lock before anything is written and keeps
it until it exits; the kernel releases it when the process dies, however it dies, so a stale lock file never
blocks anyone (its content is only the last holder's description). A second sweep fails at once with one line
naming the holder: process id, host and start time.

``flock`` locks are held by the open file: the descriptor is not inherited by the workers (Python opens files
non-inheritable), so a worker that outlives the launcher does not keep the directory locked. On network file
systems ``flock`` is only as good as the file system's support for it (NFSv4 and Lustre with ``flock`` mount
option: yes).
"""

from __future__ import annotations

import fcntl
import os
import socket
import time
from pathlib import Path

from runners.sweeping.paths import lock_file

_HELD: dict[Path, int] = {}  # sweep dir (resolved) -> open descriptor holding its lock, in this process


class SweepLockError(Exception):
    """The sweep directory is in use (the message names the holder) or the lock file cannot be created."""


def holder_text() -> str:
    """This process as the lock file describes it: ``pid <pid> on <host>, started <local time>``."""
    return f"pid {os.getpid()} on {socket.gethostname()}, started {time.strftime('%Y-%m-%d %H:%M:%S %z')}"


def acquire(sweep_dir: Path) -> Path:
    """Take the lock of ``sweep_dir`` (created if needed) for this process; a second call returns at once.
    Returns the lock file. Raises :class:`SweepLockError` if another process holds it, or an ``OSError`` (with
    the path) if the directory or the lock file cannot be created."""
    key = sweep_dir.resolve()
    path = lock_file(sweep_dir)
    if key in _HELD:
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = _read(fd) or "another process (no description in the lock file)"
        os.close(fd)
        raise SweepLockError(f"{sweep_dir} is in use by another sweep ({holder}; lock {path}): wait for it to "
                             "finish or choose another hydra.sweep.dir") from None
    except OSError:
        os.close(fd)
        raise
    try:  # describe the holder for the next one who tries (best effort: the lock itself is what counts)
        os.ftruncate(fd, 0)
        os.pwrite(fd, (holder_text() + "\n").encode(), 0)
    except OSError:
        pass
    _HELD[key] = fd
    return path


def release(sweep_dir: Path) -> None:
    """Give the lock up (it is also released when the process exits)."""
    fd = _HELD.pop(sweep_dir.resolve(), None)
    if fd is not None:
        os.close(fd)


def _read(fd: int) -> str:
    try:
        return os.pread(fd, 500, 0).decode(errors="replace").strip()
    except OSError:
        return ""
