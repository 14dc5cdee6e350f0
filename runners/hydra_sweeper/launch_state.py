"""What every job of one ``launch`` shares, handed to each worker process once instead of with every job.

Hydra's joblib launcher sends each job its config, Hydra's context and Hydra's global state, pickled anew: about
175 kB and 25 ms of the launching process's time per job (the context ~50 kB, the global state ~55 kB, the config
~70 kB), which on many cores makes the launching process the sweep's bottleneck and on two cores takes a share of
the episodes' CPU. :class:`LaunchState` is written once per launch into a file in the system's temporary folder (the
workers are processes of this machine; ~0.7 MB that must not take the output disk's last bytes from the logs); a
job carries only its overrides and number, and each worker reads the file at its first job of the launch and keeps
it (:func:`worker_state`). The launch removes the file when it returns; one left by a launching process that was
killed is removed by the next launch. The job configs are then made in the
workers (:class:`~runners.configuration.job_configs.JobConfigs`, from the configs the launching process
composed when it checked each swept value), in parallel.
"""

# no ``from __future__ import annotations``: Hydra's plugin scan runs this module without putting it in
# sys.modules, where dataclasses cannot resolve annotations written as strings
import os
import pickle
import secrets
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hydra.core.singleton import Singleton
from hydra.core.utils import setup_globals
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig

from runners.configuration.job_configs import JobConfigs


@dataclass
class LaunchState:
    """One launch's shared part. ``job_configs`` is None where Hydra composes every job (``assemble: false``)."""

    master: DictConfig
    hydra_context: HydraContext
    task_function: TaskFunction
    singleton_state: dict[Any, Any]
    job_configs: JobConfigs | None


@dataclass(frozen=True)
class LaunchStateFile:
    """Where a launch's :class:`LaunchState` is (what each job carries instead of the state itself)."""

    path: str
    token: str  # a new one per launch: a reused worker never takes an earlier launch's state for this one


PREFIX = "fuzzynav-launch-"


def write(state: LaunchState, folder: Path | None = None) -> LaunchStateFile:
    """Pickle ``state`` (with cloudpickle: the task function and Hydra's context may hold closures) into a new file in
    ``folder`` (the system's temporary folder by default); the caller removes it once the launch has returned
    (:func:`remove`)."""
    import cloudpickle

    folder = Path(tempfile.gettempdir() if folder is None else folder).resolve()  # absolute: jobs may chdir
    remove_stale(folder)
    token = secrets.token_hex(8)
    fd, name = tempfile.mkstemp(prefix=f"{PREFIX}{os.getpid()}-{token}-", suffix=".pkl", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            cloudpickle.dump(state, f, protocol=pickle.HIGHEST_PROTOCOL)
    except BaseException:
        Path(name).unlink(missing_ok=True)
        raise
    return LaunchStateFile(name, token)


def remove_stale(folder: Path) -> None:
    """Remove the launch files in ``folder`` whose launching process is gone (killed before its launch returned)."""
    for path in folder.glob(f"{PREFIX}*.pkl"):
        pid = path.name[len(PREFIX):].split("-", 1)[0]
        if pid.isdigit() and not _alive(int(pid)):
            path.unlink(missing_ok=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process
        return True
    return True


def remove(ref: LaunchStateFile) -> None:
    Path(ref.path).unlink(missing_ok=True)


_CURRENT: dict[str, LaunchState] = {}  # this worker's state of the launch in progress, by token


def worker_state(ref: LaunchStateFile) -> LaunchState:
    """The launch's state in this worker process: read at its first job of the launch, with Hydra's global state
    (resolvers, singletons) set up as Hydra's joblib launcher sets it up for a job; kept for the next jobs."""
    state = _CURRENT.get(ref.token)
    if state is None:
        with open(ref.path, "rb") as f:
            state = pickle.load(f)  # this sweep's own file, in its control directory
        assert isinstance(state, LaunchState)
        setup_globals()
        Singleton.set_state(state.singleton_state)
        _CURRENT.clear()
        _CURRENT[ref.token] = state
    return state
