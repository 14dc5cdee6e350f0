"""A sweep's output files are written whole or not at all: ``summary.csv`` and the report.

Each is written under a temporary name (a file) or into a temporary directory (the report) and renamed into place
when every byte is written. A full disk or a read-only directory is an ``OSError`` that names the file the user
expects (``summary.csv``, ``report/``), never a half-written report that looks finished.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

if TYPE_CHECKING:
    from analysis.metrics import Analysis


def write_whole(path: Path, write: Callable[[TextIO], object]) -> None:
    """Write a file through ``write(open text file)`` under a temporary name and rename it into place: the file is
    complete or absent. An ``OSError`` names ``path``."""
    tmp = path.with_name(f".{path.name}.partial")
    try:
        with open(tmp, "w", newline="") as f:
            write(f)
        os.replace(tmp, path)
    except OSError as err:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise OSError(err.errno, err.strerror or str(err), str(path)) from None


def write_report(sweep_dir: Path, analysis: Analysis) -> Path:
    """Build the report in ``<sweep dir>/.report.partial/`` and move it to ``<sweep dir>/report/`` when every file
    is written: a report is complete or absent. An ``OSError`` names the report directory."""
    from analysis.report import build_report

    final, tmp, old = sweep_dir / "report", sweep_dir / ".report.partial", sweep_dir / ".report.old"
    for leftover in (tmp, old):
        shutil.rmtree(leftover, ignore_errors=True)
    try:
        build_report([sweep_dir], tmp, analysis=analysis, final_dir=final)
        if final.exists():
            os.replace(final, old)
        os.replace(tmp, final)
    except Exception as err:  # (a figure that raised too: no half-built report stays behind)
        shutil.rmtree(tmp, ignore_errors=True)
        if old.exists() and not final.exists():  # the earlier report stays where it was
            os.replace(old, final)
        if isinstance(err, OSError):
            raise OSError(err.errno, f"the report could not be written: {err.strerror or err}", str(final)) from None
        raise
    shutil.rmtree(old, ignore_errors=True)
    return final
