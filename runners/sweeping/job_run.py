"""One Hydra job (a sweep's, in a worker process, or ``runners.run``'s single run): what Hydra's
``hydra.core.utils.run_job`` does, without its two copies.

Hydra's ``run_job`` (Hydra 1.3) deep-copies the job's config to make the task's config and deep-copies Hydra's
node for the job's result, and sets ``HydraConfig`` twice; in a worker of :class:`FuzzynavLauncher` the config
was made for this job alone (:class:`~runners.configuration.job_configs.JobConfigs` returns a new
object), so Hydra's node needs no copy of its own, and the result goes back to the launching process without the
configs (the sweepers read only its status, its return value and ``hydra.job``). All a job can observe is Hydra's:

* ``hydra.runtime.output_dir`` set, the output directory made, the working directory changed to it when
  ``hydra.job.chdir`` is true (and changed back after the job);
* ``HydraConfig`` holds the job's Hydra node during the job (and the earlier one after it);
* job logging configured from ``hydra.job_logging``; the ``.hydra/`` snapshot (``config.yaml``, ``hydra.yaml``,
  ``overrides.yaml``) written where ``hydra.output_subdir`` says, with the same text as Hydra's;
* ``hydra.job.env_set`` applied during the task; the callbacks' ``on_job_start`` and ``on_job_end`` called with the
  job's config and result; an exception of the task is the result's (``FAILED``), as in Hydra.

``tests/test_launcher.py`` compares a job's outputs with those of Hydra's ``run_job`` on the same config.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import os
from collections.abc import Iterator
from pathlib import Path

from hydra.core.hydra_config import HydraConfig
from hydra.core.utils import JobReturn, JobRuntime, JobStatus, configure_log
from hydra.types import HydraContext, TaskFunction
from omegaconf import AnyNode, DictConfig, OmegaConf, open_dict, read_write

from runners.logs import yaml_text


def run_job(config: DictConfig, hydra_context: HydraContext, task_function: TaskFunction,
            job_dir_key: str = "hydra.sweep.dir", job_subdir_key: str | None = "hydra.sweep.subdir") -> JobReturn:
    """Run the job whose config is ``config`` (this job's own object: it becomes the task's config, without its
    ``hydra`` node) in the directory ``job_dir_key`` / ``job_subdir_key`` name, as Hydra's ``run_job`` takes them: a
    sweep job by default, ``("hydra.run.dir", None)`` for a single run (``runners.run``). Returns the job's full
    result (a sweep's launcher sends it back :func:`slim`)."""
    callbacks = hydra_context.callbacks
    old_cwd = os.getcwd()
    orig_hydra_cfg = HydraConfig.instance().cfg
    HydraConfig.instance().set_config(config)  # before the output directory: it may use ${hydra:...}
    output_dir = str(OmegaConf.select(config, job_dir_key))
    if job_subdir_key is not None:
        output_dir = os.path.join(output_dir, str(OmegaConf.select(config, job_subdir_key)))
    hydra_cfg = HydraConfig.instance().cfg  # the job's own copy of Hydra's node (set_config copies it)
    assert isinstance(hydra_cfg, DictConfig)
    for node in (config, hydra_cfg):
        with read_write(node.hydra.runtime), open_dict(node.hydra.runtime):
            node.hydra.runtime.output_dir = os.path.abspath(output_dir)
    chdir = False
    try:
        ret = JobReturn()
        overrides = OmegaConf.to_container(config.hydra.overrides.task)
        assert isinstance(overrides, list)
        ret.overrides = overrides
        task_cfg = _without_hydra(config)
        ret.cfg, ret.hydra_cfg = task_cfg, hydra_cfg
        Path(output_dir).mkdir(parents=True, exist_ok=True)
        chdir = bool(hydra_cfg.hydra.job.chdir)  # Hydra >= 1.2 with version_base 1.2+: None means no
        if chdir:
            os.chdir(output_dir)
            ret.working_dir = output_dir
        else:
            ret.working_dir = os.getcwd()
        try:
            configure_log(config.hydra.job_logging, config.hydra.verbose)
        except ValueError as err:  # logging's "Unable to configure handler 'file'": the file system's error names it
            cause = err.__cause__ or err.__context__
            if isinstance(cause, OSError):
                raise cause from None
            raise
        if config.hydra.output_subdir is not None:
            snapshot = Path(config.hydra.runtime.output_dir) / Path(config.hydra.output_subdir)
            _save(task_cfg, "config.yaml", snapshot)
            _save(hydra_cfg, "hydra.yaml", snapshot)
            _save(config.hydra.overrides.task, "overrides.yaml", snapshot)
        with _env(dict(hydra_cfg.hydra.job.env_set)):
            callbacks.on_job_start(config=config, task_function=task_function)
            try:
                ret.return_value = task_function(task_cfg)
                ret.status = JobStatus.COMPLETED
            except Exception as e:
                ret.return_value = e
                ret.status = JobStatus.FAILED
        ret.task_name = JobRuntime.instance().get("name")
        for handler in list(logging.getLogger().handlers):
            with contextlib.suppress(Exception):
                handler.flush()
        callbacks.on_job_end(config=config, job_return=ret)
        return ret
    finally:
        HydraConfig.instance().cfg = orig_hydra_cfg
        if chdir:
            os.chdir(old_cwd)


def slim(ret: JobReturn) -> JobReturn:
    """``ret`` as the launching process gets it: the configs stay in the worker (pickling them back cost as much as
    sending them); ``hydra_cfg`` keeps ``hydra.job`` (number, id, name: what the sweepers report)."""
    out = JobReturn(overrides=ret.overrides, working_dir=ret.working_dir, task_name=ret.task_name,
                    status=ret.status, _return_value=ret._return_value)
    if ret.hydra_cfg is not None:
        out.hydra_cfg = OmegaConf.create({"hydra": {"job": OmegaConf.to_container(ret.hydra_cfg.hydra.job)}})
    return out


def _without_hydra(config: DictConfig) -> DictConfig:
    """The task's config: a copy of ``config`` without Hydra's node (as Hydra makes it: struct flags kept). Hydra's
    node is not copied only to be deleted (about a third of a run's config: the copy took ~20 ms and takes ~13 ms
    without it): the copy gets a placeholder there (deep copy's memo), which is then deleted."""
    task_cfg = copy.deepcopy(config, {id(config["hydra"]): AnyNode(None)})
    with read_write(task_cfg), open_dict(task_cfg):
        del task_cfg["hydra"]
    return task_cfg


def _save(cfg: object, filename: str, output_dir: Path) -> None:
    """One file of the ``.hydra/`` snapshot, as Hydra writes it."""
    output_dir.mkdir(parents=True, exist_ok=True)
    with open(output_dir / filename, "w", encoding="utf-8") as f:
        f.write(yaml_text.config_text(cfg))


@contextlib.contextmanager
def _env(env: dict[str, str]) -> Iterator[None]:
    """``hydra.job.env_set`` during the task, the environment as it was after."""
    before = {key: os.environ.get(key) for key in env}
    os.environ.update({str(k): str(v) for k, v in env.items()})
    try:
        yield
    finally:
        for key, value in before.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
