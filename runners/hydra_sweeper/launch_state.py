"""What every job of one ``launch`` shares, handed to each worker process once instead of with every job.

Hydra's joblib launcher sends each job its config, Hydra's context and Hydra's global state, pickled anew: about
175 kB and 25 ms of the launching process's time per job (the context ~50 kB, the global state ~55 kB, the config
~70 kB), which on many cores makes the launching process the sweep's bottleneck and on two cores takes a share of
the episodes' CPU. :class:`LaunchState` is written once per launch into the sweep's control directory
(:func:`runners.sweeping.paths.control_dir`); a job carries only its overrides and number, and each worker reads
the file at its first job of the launch and keeps it (:func:`worker_state`). The job configs are then made in the
workers (:class:`~hydra_plugins.fuzzynav_sweeper.job_configs.JobConfigs`, from the configs the launching process
composed when it checked each swept value), in parallel.
"""

# no ``from __future__ import annotations``: Hydra's plugin scan runs this module without putting it in
# sys.modules, where dataclasses cannot resolve annotations written as strings
import os
import pickle
import secrets
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hydra.core.singleton import Singleton
from hydra.core.utils import setup_globals
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig

from .job_configs import JobConfigs


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


def write(state: LaunchState, control_dir: Path) -> LaunchStateFile:
    """Pickle ``state`` (with cloudpickle: the task function and Hydra's context may hold closures) into
    ``control_dir``; the caller removes the file once the launch has returned (:func:`remove`), and the next launch
    removes one that a killed launch left."""
    import cloudpickle

    token = secrets.token_hex(8)
    control_dir.mkdir(parents=True, exist_ok=True)
    for stale in control_dir.glob("launch-*"):  # an earlier launch of this (locked) sweep folder that was killed
        stale.unlink(missing_ok=True)
    path = control_dir.resolve() / f"launch-{token}.pkl"  # absolute: a job may change the working directory
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        cloudpickle.dump(state, f, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)
    return LaunchStateFile(str(path), token)


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
