"""Where a run came from: fuzzynav version, git commit and library versions (strings, computed once)."""

from __future__ import annotations

import subprocess
import threading
from functools import cache
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
LIBRARIES = ("numpy", "scikit-fuzzy", "shapely", "mcap", "foxglove-sdk", "scipy", "hydra-core")


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


_PREFETCH: list[threading.Thread] = []


def prefetch() -> None:
    """Start :func:`git_commit` in a background thread: its two git commands (~7 ms, mostly waiting for them) run
    while the caller goes on (a single run's start, composing and checking its config); :func:`git_commit` waits
    for them. Once per process."""
    if not _PREFETCH:
        _PREFETCH.append(threading.Thread(target=_git_commit, name="fuzzynav-git-commit", daemon=True))
        _PREFETCH[0].start()


def git_commit() -> str:
    """The checkout's commit (with ``-dirty`` when it has uncommitted changes), or ``unknown``."""
    if _PREFETCH and _PREFETCH[0] is not threading.current_thread():
        _PREFETCH[0].join()
    return _git_commit()


@cache
def _git_commit() -> str:
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=10)
        if head.returncode != 0:
            return "unknown"
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT,
                               capture_output=True, text=True, timeout=10)
        return head.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


@cache
def provenance() -> dict[str, str]:
    """``fuzzynav_version``, ``git_commit`` and ``<library>_version`` entries."""
    out = {"fuzzynav_version": _version("fuzzynav"), "git_commit": git_commit()}
    for lib in LIBRARIES:
        out[f"{lib}_version"] = _version(lib)
    return out
