"""fuzzynav's local launcher: the sweep's jobs on every core, in joblib's pool of long-lived worker processes.

Selected by ``hydra/launcher=all_cores`` (the sweep presets' default). It runs jobs as Hydra's joblib launcher does
(one ``hydra.core.utils.run_job`` per job in a loky worker process that is reused for the next jobs, through
joblib's public ``Parallel``), with one difference: each job's config is made in the launching process by
:class:`~hydra_plugins.fuzzynav_sweeper.job_configs.JobConfigs` (Hydra composes one config per swept value; the
other jobs are assembled from those, the same config), instead of Hydra composing it again in the worker (about
0.1 s of a worker's time per job, more than the default sweep's five episodes take).
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from hydra.core.hydra_config import HydraConfig
from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, configure_log, filter_overrides, run_job, setup_globals
from hydra.plugins.launcher import Launcher
from hydra.types import HydraContext, TaskFunction
from omegaconf import DictConfig, open_dict

from .job_configs import JobConfigs

log = logging.getLogger(__name__)


def parallel_settings(n_jobs: int) -> dict[str, Any]:
    """joblib ``Parallel`` settings of the sweep's pool. With the same settings loky hands back the pool it already
    has (``runners.sweep.prewarm_workers`` starts it early; the end of the sweep reads the logs in it)."""
    return {"n_jobs": int(n_jobs), "backend": "loky", "max_nbytes": None}


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
        assert self.job_configs is not None
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        sweep_dir = Path(str(self.config.hydra.sweep.dir))
        sweep_dir.mkdir(parents=True, exist_ok=True)
        log.info(f"Launching jobs on {self.n_jobs} worker(s), sweep output dir : {sweep_dir}")
        singleton_state = Singleton.get_state()

        def jobs() -> Iterable[Any]:  # lazily: a stop request ends the overrides' iteration (StoppableJobs)
            for idx, overrides in enumerate(job_overrides, start=initial_job_idx):
                log.info(f"\t#{idx} : {' '.join(filter_overrides(overrides))}")
                config = self._job_config(overrides)
                with open_dict(config):
                    config.hydra.job.id = f"{config.hydra.job.name}_{idx}"
                    config.hydra.job.num = idx
                yield delayed(execute_job)(config, self.hydra_context, self.task_function, singleton_state)

        runs = Parallel(**parallel_settings(self.n_jobs))(jobs())
        assert isinstance(runs, list) and all(isinstance(r, JobReturn) for r in runs)
        log.debug(f"job configs: {self.job_configs.composed} composed, {self.job_configs.assembled} assembled")
        return runs

    def _job_config(self, overrides: Sequence[str]) -> DictConfig:
        assert self.job_configs is not None and self.hydra_context is not None and self.config is not None
        if not self.assemble:
            return self.hydra_context.config_loader.load_sweep_config(self.config, list(overrides))
        return self.job_configs.config(overrides)


def execute_job(config: DictConfig, hydra_context: HydraContext, task_function: TaskFunction,
                singleton_state: dict[Any, Any]) -> JobReturn:
    """One job in a worker process (as Hydra's joblib launcher runs it, from a config made by the launcher)."""
    setup_globals()
    Singleton.set_state(singleton_state)
    HydraConfig.instance().set_config(config)
    return run_job(hydra_context=hydra_context, config=config, task_function=task_function,
                   job_dir_key="hydra.sweep.dir", job_subdir_key="hydra.sweep.subdir")
