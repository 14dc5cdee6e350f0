"""Command-line argument checks shared by ``analysis.report`` and ``runners.replay``: every bad argument ends
with one line ``error: <argument>: <problem>`` and exit status 2, never a traceback or argparse's usage block."""

from __future__ import annotations

import argparse
import errno
import math
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

MAX_JOBS = 1024


class OneLineParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line on stderr (``error: ...``), exit status 2."""

    def error(self, message: str) -> NoReturn:
        # an argument holding a line break (quoted on a shell command line) stays on the one line, escaped
        message = "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)
        sys.stderr.write(f"error: {message} (see --help)\n")
        raise SystemExit(2)


def number_in(lo: float, hi: float, unit: str = "", lo_open: bool = False) -> Callable[[str], float]:
    """An argparse ``type``: a finite number in [lo, hi] (``(lo, hi]`` with ``lo_open``); NaN and infinities are
    refused (NaN passes every ``<`` test, so an unchecked NaN threshold silently changes a metric)."""
    interval = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]{' ' + unit if unit else ''}"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text[:40]!r} is not a number") from None
        if not math.isfinite(value) or value < lo or value > hi or (lo_open and value == lo):
            raise argparse.ArgumentTypeError(f"{text[:40]!r} is not a finite number in {interval}")
        return value
    return parse


def jobs(text: str) -> int:
    """An argparse ``type`` for ``--jobs``: -1 (every core) or 1 to ``MAX_JOBS`` worker processes."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text[:40]!r} is not an integer") from None
    if value != -1 and not 1 <= value <= MAX_JOBS:
        raise argparse.ArgumentTypeError(f"{value}: expected -1 (every core) or 1 to {MAX_JOBS}")
    return value


def unwritable_dir(path: Path) -> str | None:
    """Why files cannot be written into directory ``path`` (created if missing), or None: tried by creating
    and removing a file, so that a long analysis does not end with a traceback on its first write."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".write-test-", dir=path)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        return f"{err.filename or path}: cannot write: {err.strerror or err}"
    return None


def path_problem(path: str) -> str | None:
    """Why a path given on the command line cannot be read, as one line naming it, or None: a symlink loop or a
    dangling link is said as such (``Path.exists`` is False for both, which was reported as "no such file")."""
    try:
        os.stat(path)
    except OSError as err:
        if err.errno == errno.ELOOP:
            return f"{path}: symlink loop (too many levels of symbolic links)"
        if err.errno == errno.ENOENT and os.path.islink(path):
            return f"{path}: dangling symlink (to {os.readlink(path)!r}, which does not exist)"
        if err.errno == errno.ENOENT:
            return f"{path}: no such file or directory"
        return f"{path}: cannot read: {err.strerror or err}"
    return None
