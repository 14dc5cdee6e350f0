"""Where a sweep keeps its control files: ``<sweep dir>/.fuzzynav/``.

``lock``: the owner of the sweep directory (:mod:`runners.sweeping.lock`); ``stop``: present while the sweep is asked
to stop (:mod:`runners.sweeping.stop`); ``resume/``: complete logs set aside by a resume until a job of the sweep takes
them
back (:mod:`runners.sweeping.resume`). Everything lives in the sweep directory itself, so that the jobs see it wherever
they run (worker processes, Submitit processes, cluster nodes on a shared file system).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

CONTROL_DIR = ".fuzzynav"
PARTIAL_SUFFIX = ".partial"  # logs being written: runners.logs.mcap_log.partial_path


def control_dir(sweep_dir: Path) -> Path:
    return sweep_dir / CONTROL_DIR


def lock_file(sweep_dir: Path) -> Path:
    return control_dir(sweep_dir) / "lock"


def stop_file(sweep_dir: Path) -> Path:
    return control_dir(sweep_dir) / "stop"


def holding_dir(sweep_dir: Path) -> Path:
    return control_dir(sweep_dir) / "resume"


def _outside_control(sweep_dir: Path, paths) -> list[Path]:
    return sorted(p for p in paths if CONTROL_DIR not in p.relative_to(sweep_dir).parts[:-1])


def job_logs(sweep_dir: Path) -> list[Path]:
    """The logs the sweep's jobs wrote (``*.mcap`` under the job directories, at any depth: ``hydra.sweep.subdir``
    may nest), in order; not the logs set aside in the control directory."""
    return _outside_control(sweep_dir, sweep_dir.rglob("*.mcap")) if sweep_dir.is_dir() else []


def partial_logs(sweep_dir: Path) -> list[Path]:
    """Logs whose writing never finished (their process died): ``.<name>.mcap.partial`` next to where the log
    would be."""
    return _outside_control(sweep_dir, sweep_dir.rglob(f".*.mcap{PARTIAL_SUFFIX}")) if sweep_dir.is_dir() else []


class LogScan:
    """The sweep's job logs, looked at again and again while the sweep runs (its progress): each :meth:`scan` lists
    the ``*.mcap`` files of the directories that changed since the previous scan (every directory the first time),
    not the control directory's. A directory whose modification time is unchanged is not listed again, unless that
    time is recent (within :data:`RECENT_S`: a file system with coarse timestamps may add a file without changing
    it): rescanning the whole tree every half second cost the sweep's process ~2 s of CPU in a 1,000-episode sweep,
    growing with the square of the episodes."""

    RECENT_S = 5.0

    def __init__(self, sweep_dir: Path) -> None:
        self.root = str(sweep_dir)
        self._dirs: dict[str, tuple[int, list[str]]] = {}  # directory -> (mtime ns when listed, its subdirectories)

    def scan(self) -> list[str]:
        """Paths of the logs in the directories that changed since the previous scan."""
        recent = time.time_ns() - int(self.RECENT_S * 1e9)
        found: list[str] = []
        todo, listed = [self.root], {}
        while todo:
            directory = todo.pop()
            try:
                mtime = os.stat(directory).st_mtime_ns
            except OSError:
                continue
            cached = self._dirs.get(directory)
            if cached is not None and cached[0] == mtime and mtime < recent:
                listed[directory] = cached
                todo.extend(cached[1])
                continue
            subdirs: list[str] = []
            try:
                with os.scandir(directory) as entries:
                    for entry in entries:
                        if entry.is_dir(follow_symlinks=False):
                            if entry.name != CONTROL_DIR:
                                subdirs.append(entry.path)
                        elif entry.name.endswith(".mcap"):
                            found.append(entry.path)
            except OSError:
                continue
            listed[directory] = (mtime, subdirs)
            todo.extend(subdirs)
        self._dirs = listed
        return found
