"""A single run's output directory is checked before Hydra writes into it.

Hydra creates ``hydra.run.dir`` and writes its ``.hydra/`` snapshot before the run starts; on a read-only or full
file system that is a Python traceback. :class:`OutputDirCheck` (a Hydra callback, ``conf/config.yaml``) creates the
directory first and writes a small probe file in it, so that the problem is one line naming the directory and exit
status 1. Sweeps check their directory when they take its lock (:mod:`runners.sweeping.control`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path
from typing import Any

from hydra.experimental.callback import Callback
from omegaconf import DictConfig

PROBE_BYTES = 64 * 1024  # about what Hydra's snapshot and the first chunks of a log need


def check_writable(directory: Path) -> str | None:
    """None if ``directory`` can be created and ``PROBE_BYTES`` written in it; else one line naming the path."""
    probe = directory / ".fuzzynav-probe"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with open(probe, "wb") as f:
            f.write(b"\0" * PROBE_BYTES)
            f.flush()
            os.fsync(f.fileno())  # a full disk may only say so when the data is written out
    except OSError as err:
        return f"{err.filename or directory}: cannot write the output directory: {err.strerror or err}"
    finally:
        with contextlib.suppress(OSError):
            probe.unlink()
    return None


class OutputDirCheck(Callback):
    """``on_run_start``: :func:`check_writable` on ``hydra.run.dir``; a problem is one line and exit 1."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        problem = check_writable(Path(config.hydra.run.dir))
        if problem:
            print(f"error: {problem}", file=sys.stderr)
            sys.exit(1)  # SystemExit: Hydra turns an exception raised in a callback into a warning
