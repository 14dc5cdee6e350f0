"""fuzzynav's local launcher: the sweep's jobs on every core, in joblib's pool of long-lived worker processes.

Selected by ``hydra/launcher=all_cores`` (the sweep presets' default). It runs jobs as Hydra's joblib launcher does
(each job in a loky worker process that is reused for the next jobs, through joblib's public ``Parallel``), with
three differences, each there because a job of a few episodes cost more than its episodes:

1. What all jobs share (Hydra's context and global state, the configs composed when each swept value was checked)
   goes to each worker once, through a temporary file (:mod:`.launch_state`); a job carries
   its overrides and number only. Hydra's launcher pickles ~175 kB per job in the launching process.
2. Each job's config is made in its worker by :class:`~runners.configuration.job_configs.JobConfigs`
   (assembled from the configs composed once per swept value; the same config), not composed again (~0.1 s).
3. The job runs through :func:`runners.sweeping.job_run.run_job`: Hydra's ``run_job`` without its second copy of
   the config, and the result comes back without the configs.
"""

from __future__ import annotations

import logging
import os
import pickle
from collections.abc import Iterable, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, JobStatus, configure_log, filter_overrides, setup_globals
from hydra.plugins.launcher import Launcher
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, OmegaConf, open_dict

from runners.configuration import hydra_paths
from runners.configuration.job_configs import JobConfigs
from runners.sweeping import job_run

from . import launch_state

log = logging.getLogger(__name__)


def parallel_settings(n_jobs: int) -> dict[str, Any]:
    """joblib ``Parallel`` settings of the sweep's pool, used inside :func:`worker_pool`. With the same settings
    loky hands back the pool it already has (``runners.sweep.prewarm_workers`` starts it early)."""
    return {"n_jobs": int(n_jobs), "max_nbytes": None}


def worker_pool() -> AbstractContextManager:
    """joblib's ``parallel_config`` of the sweep's pool: loky's processes, each starting with
    :func:`runners.sweeping.process_tree.worker_started` (it ends with this launching process, even one killed
    before the worker had a job)."""
    from joblib import parallel_config

    from runners.sweeping.process_tree import worker_started

    return parallel_config(backend="loky", initializer=worker_started, initargs=(os.getpid(),))


class FuzzynavLauncher(Launcher):
    """``n_jobs``: worker processes (-1: one per core). ``assemble``: make jobs' configs from the composed ones
    (false: Hydra composes every job, as its joblib launcher does)."""

    def __init__(self, n_jobs: int = -1, assemble: bool = True) -> None:
        self.n_jobs = n_jobs
        self.assemble = assemble
        self.config: DictConfig | None = None
        self.task_function: TaskFunction | None = None
        self.hydra_context: HydraContext | None = None
        self.job_configs: JobConfigs | None = None

    def setup(self, *, hydra_context: HydraContext, task_function: TaskFunction, config: DictConfig) -> None:
        self.config, self.task_function, self.hydra_context = config, task_function, hydra_context
        loader = hydra_context.config_loader
        self.job_configs = JobConfigs(config, lambda overrides: loader.load_sweep_config(config, overrides))

    def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[JobReturn]:
        from joblib import Parallel, delayed

        setup_globals()
        assert self.config is not None and self.hydra_context is not None and self.task_function is not None
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        sweep_dir.mkdir(parents=True, exist_ok=True)
        log.info(f"Launching jobs on {self.n_jobs} worker(s), sweep output dir : {sweep_dir}")
        overrides_list = [list(o) for o in job_overrides]  # StoppableJobs: iterating it ends early after a stop
        if self.assemble and self.job_configs is not None and overrides_list:
            self.job_configs.config(overrides_list[0])  # the reference: the same in every worker
        state = launch_state.LaunchState(self.config, self.hydra_context, self.task_function, Singleton.get_state(),
                                         self.job_configs if self.assemble else None)
        ref = launch_state.write(state)

        def jobs() -> Iterable[Any]:
            for idx, overrides in enumerate(overrides_list, start=initial_job_idx):
                log.info(f"\t#{idx} : {' '.join(filter_overrides(overrides))}")
                yield delayed(execute_job)(ref, overrides, idx)

        try:
            with worker_pool():
                runs = Parallel(**parallel_settings(self.n_jobs))(jobs())
        finally:
            launch_state.remove(ref)
        assert isinstance(runs, list) and all(isinstance(r, JobReturn) for r in runs)
        return runs


    def compose_in_workers(self, jobs: Sequence[Sequence[str]]) -> list[bytes] | None:
        """Hydra's configs of ``jobs`` (the sweeper's check of each swept value), composed in the worker pool, in
        parallel (each ~0.1 s; the workers are idle then), pickled (:meth:`JobConfigs.add_composed` takes them as
        they are). None where that did not work out (a bad value among them, a worker lost): the caller composes
        them itself and Hydra says what is wrong in its own words."""
        from joblib import Parallel, delayed

        assert self.config is not None and self.hydra_context is not None and self.task_function is not None
        if len(jobs) < 2 or self.n_jobs == 1:
            return None
        state = launch_state.LaunchState(self.config, self.hydra_context, self.task_function, Singleton.get_state(),
                                         None)
        try:
            ref = launch_state.write(state)
        except OSError:
            return None
        try:
            with worker_pool():
                configs = Parallel(**parallel_settings(self.n_jobs))(delayed(compose_job)(ref, list(o))
                                                                      for o in jobs)
        except RefusedJob:
            raise
        except Exception:
            return None
        finally:
            launch_state.remove(ref)
        return configs if isinstance(configs, list) and len(configs) == len(jobs) else None


def compose_job(ref: launch_state.LaunchStateFile, overrides: list[str]) -> bytes:
    """Hydra's config of one job, composed in a worker process (``load_sweep_config``, as the sweeper would),
    pickled with cloudpickle (the schema's dataclasses are made at run time)."""
    import cloudpickle

    from runners.configuration.precheck import check_composed

    state = launch_state.worker_state(ref)
    config = state.hydra_context.config_loader.load_sweep_config(state.master, overrides)
    problem = check_composed(config)  # as a job loads it: a preset's swept value out of range (episodes=0)
    if problem is not None:
        raise RefusedJob(overrides, problem)
    return cloudpickle.dumps(config, protocol=pickle.HIGHEST_PROTOCOL)


class RefusedJob(ValueError):
    """A job whose composed config a run would refuse: its overrides and the one-line problem."""

    def __init__(self, overrides: Sequence[str], problem: str) -> None:
        super().__init__(problem)
        self.overrides, self.problem = list(overrides), problem

    def __reduce__(self) -> tuple[type, tuple[list[str], str]]:  # back from a worker process whole
        return RefusedJob, (self.overrides, self.problem)


def execute_job(ref: launch_state.LaunchStateFile, overrides: list[str], idx: int) -> JobReturn:
    """One job in a worker process: its config made here (from the launch's shared state), run as Hydra runs a
    job (:func:`runners.sweeping.job_run.run_job`)."""
    state = launch_state.worker_state(ref)
    if state.job_configs is not None:
        config = state.job_configs.config(overrides)
    else:
        config = state.hydra_context.config_loader.load_sweep_config(state.master, overrides)
    with open_dict(config):
        config.hydra.job.id = f"{config.hydra.job.name}_{idx}"
        config.hydra.job.num = idx
    # a job whose folder is not in the sweep's (a subdir or sweep dir resolved from its values): nothing written
    problem = hydra_paths.job_dir_problem(config, str(state.master.hydra.sweep.dir))
    if problem is not None:
        return JobReturn(overrides=list(overrides), status=JobStatus.FAILED, _return_value=ValueError(problem),
                         hydra_cfg=OmegaConf.create({"hydra": {"job": {"num": idx}}}))
    return job_run.slim(job_run.run_job(config, state.hydra_context, state.task_function))
