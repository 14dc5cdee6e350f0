"""Where a sweep keeps its control files: ``<sweep dir>/.fuzzynav/``.

``lock``: the owner of the sweep directory (:mod:`runners.sweeping.lock`); ``stop``: present while the sweep is asked
to stop (:mod:`runners.sweeping.stop`); ``resume/``: complete logs set aside by a resume until a job of the sweep takes
them
back (:mod:`runners.sweeping.resume`). Everything lives in the sweep directory itself, so that the jobs see it wherever
they run (worker processes, Submitit processes, cluster nodes on a shared file system).
"""

from __future__ import annotations

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
