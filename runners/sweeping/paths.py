"""Where a sweep keeps its control files: ``<sweep dir>/.fuzzynav/``.

``lock``: the owner of the sweep directory (:mod:`runners.sweeping.lock`); ``stop``: present while the sweep is asked
to stop (:mod:`runners.sweeping.stop`); ``resume/``: complete logs set aside by a resume until a job of the sweep takes
them
back (:mod:`runners.sweeping.resume`). Everything lives in the sweep directory itself, so that the jobs see it wherever
they run (worker processes, Submitit processes, cluster nodes on a shared file system).
"""

from __future__ import annotations

import os
import re
import time
from collections.abc import Callable
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


def job_logs(sweep_dir: Path) -> list[Path]:
    """The logs the sweep's jobs wrote (``*.mcap`` under the job directories, at any depth: ``hydra.sweep.subdir``
    may nest), in order; not the logs set aside in the control directory, nor those of another command's folder
    inside this one (:func:`is_other_output`)."""
    return _logs_below(sweep_dir, lambda name: name.endswith(".mcap"))


def partial_logs(sweep_dir: Path) -> list[Path]:
    """Logs whose writing never finished (their process died): ``.<name>.mcap.partial`` next to where the log
    would be (not in another command's folder inside this one)."""
    return _logs_below(sweep_dir, lambda name: name.startswith(".") and name.endswith(f".mcap{PARTIAL_SUFFIX}"))


def is_other_output(directory: Path) -> bool:
    """Whether ``directory``, inside a sweep's folder, holds another command's output: another sweep's (its control
    folder, or Hydra's ``multirun.yaml``) or a single run's (its ``.hydra/hydra.yaml`` says ``mode: RUN``). A resume
    into ``multirun/`` took the logs of every earlier sweep there (as the same episodes), and their summaries and
    reports then named files that had moved."""
    if (directory / CONTROL_DIR).is_dir() or (directory / "multirun.yaml").is_file():
        return True
    try:
        with open(directory / ".hydra" / "hydra.yaml", encoding="utf-8", errors="replace") as f:
            text = f.read(1_000_000)
    except OSError:
        return False
    return _SINGLE_RUN.search(text) is not None


_SINGLE_RUN = re.compile(r"^  mode: RUN\s*$", re.MULTILINE)  # Hydra's snapshot of a single run's hydra node


def _logs_below(sweep_dir: Path, wanted: Callable[[str], bool], others: list[Path] | None = None) -> list[Path]:
    """The files ``wanted`` names below ``sweep_dir``, sorted, outside its control folder and other commands'
    folders (appended to ``others``; symbolic links to folders are not followed)."""
    found: list[Path] = []
    for root, dirs, files in os.walk(sweep_dir):
        here = Path(root)
        kept = []
        for d in dirs:
            if d != CONTROL_DIR and is_other_output(here / d):
                if others is not None:
                    others.append(here / d)
            elif d != CONTROL_DIR:
                kept.append(d)
        dirs[:] = kept
        found += [here / name for name in files if wanted(name)]
    return sorted(found)


def other_outputs(sweep_dir: Path) -> list[Path]:
    """The folders inside ``sweep_dir`` that hold another command's output (:func:`is_other_output`)."""
    others: list[Path] = []
    _logs_below(sweep_dir, lambda name: False, others)
    return sorted(others)


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
