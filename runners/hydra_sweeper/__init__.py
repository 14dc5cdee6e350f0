"""fuzzynav's Hydra sweeper: Hydra's basic sweeper, checking each swept value once, and surviving its jobs' faults.

Installed as ``hydra_plugins.fuzzynav_sweeper`` (Hydra loads sweepers only from the ``hydra_plugins``
package; ``pyproject.toml`` maps this directory there) and selected in ``conf/config.yaml``
(``hydra/sweeper: fuzzynav``). Two differences from Hydra's ``BasicSweeper``:

1. Before launching, the basic sweeper composes the config of every job in the launching process, one after the
   other (about 0.1 s each), and the launcher composes each job again where it runs. This sweeper composes only
   the jobs needed to try every swept value at least once: every distinct value of a text setting or config group
   option (``scenario=head_on``), and one value of each type for numbers and booleans (``seed=range(0,1000,50)``
   composes like ``seed=0``). A bad value is still reported before anything runs; the default sweep of 21 jobs
   composes 9 configs up front instead of 21.
2. A launcher that raises (a worker process killed: loky's ``TerminatedWorkerError``, a Submitit job that
   vanished) or a job that fails (a log that cannot be written) does not end the sweep with a traceback: the
   failure is noted as one line (:mod:`runners.sweeping.control`) and the sweep ends normally, so that its end
   writes the summary of the episodes that completed and says how to resume. After a stop request (a signal, or a
   job's stop file) no new job or batch is handed out.

Everything else (batches, ``params``, ``max_batch_size``) is the basic sweeper's. :class:`FaultTolerantSweeper` is
Hydra's ``BasicSweeper`` with difference 2 only: ``runners.sweep`` uses it when ``hydra/sweeper=basic`` is chosen
(:func:`runners.sweep.fault_tolerant_sweeper`), so that every job's config is composed up front as Hydra does,
and a lost worker is still one line, the summary and the resume command, never a traceback.
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.utils import JobStatus
from omegaconf import OmegaConf

from runners.configuration.plugins import PluginConfigSearchPath  # found here by Hydra's scan of hydra_plugins
from runners.configuration.precheck import check_composed, representative_jobs
from runners.configuration.sweep_size import sweep_problem
from runners.sweeping import control as sweep_control
from runners.sweeping import resume as sweep_resume

from .launcher import RefusedJob  # (relative: installed, this package is hydra_plugins.fuzzynav_sweeper)

__all__ = ["FaultTolerantSweeper", "FuzzynavSweeper", "PluginConfigSearchPath", "representative_jobs"]

log = logging.getLogger(__name__)


class FaultTolerantSweeper(BasicSweeper):
    """Hydra's ``BasicSweeper`` (every job's config composed before launching), noting launcher and job failures
    instead of raising them (difference 2 of the module docstring)."""

    def sweep(self, arguments: list[str]) -> Any:
        assert self.config is not None and self.launcher is not None and self.hydra_context is not None
        sweep_dir = Path(self.config.hydra.sweep.dir)
        parser = OverridesParser.create(config_loader=self.hydra_context.config_loader)
        parsed = parser.parse_overrides([*self._parse_config(), *arguments])
        problem = sweep_problem(parsed)  # (a preset's params: the command line's were checked before Hydra started)
        if problem:
            print(f"error: config: {problem}", file=sys.stderr)
            sys.exit(2)
        run = sweep_control.begin_or_exit(sweep_dir)
        self.overrides = self.split_arguments(parsed, self.max_batch_size)
        returns: list[Sequence[Any]] = []
        try:  # the sweep's own config, as Hydra saves it
            sweep_dir.mkdir(parents=True, exist_ok=True)
            OmegaConf.save(self.config, sweep_dir / "multirun.yaml")
        except OSError as err:
            run.fail(sweep_control.io_line(err, sweep_dir / "multirun.yaml"))
            return _finish(run, self.config, returns)
        initial_job_idx = 0
        while not self.is_done() and not run.stop_requested():
            batch = self.get_job_batch()
            try:
                self.validate_batch_is_legal(batch)
            except BaseException:  # Hydra reports the bad config; a resume's set-aside logs go back first
                sweep_resume.restore(sweep_dir)
                raise
            try:
                results = self.launcher.launch(sweep_control.StoppableJobs(batch, run), initial_job_idx=initial_job_idx)
            except Exception as err:
                if sweep_control.debug_requested():
                    raise
                sweep_control.launcher_failed(run, err)
                break
            for result in results:
                if result.status == JobStatus.FAILED:
                    job = result.hydra_cfg.hydra.job.num if result.hydra_cfg is not None else "?"
                    sweep_control.job_failed(run, job, result._return_value)
            initial_job_idx += len(batch)
            returns.append(results)
        return _finish(run, self.config, returns)


class FuzzynavSweeper(FaultTolerantSweeper):
    """:class:`FaultTolerantSweeper`, validating only :func:`representative_jobs` of each batch before launching
    (difference 1 of the module docstring)."""

    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        tic = time.perf_counter()
        jobs = representative_jobs(batch)
        configs = getattr(self.launcher, "job_configs", None)  # fuzzynav's launcher makes jobs' configs from these
        compose_in_workers = getattr(self.launcher, "compose_in_workers", None)
        try:
            composed = compose_in_workers(jobs) if compose_in_workers is not None else None
        except Exception as err:  # a composed config a run would refuse (a preset's episodes=0): the launcher's
            if not hasattr(err, "problem"):  # RefusedJob, of whichever name its package was loaded under
                raise
            refuse_job(getattr(err, "overrides", []), err)
        for i, overrides in enumerate(jobs):
            try:
                if composed is not None:
                    config = composed[i]
                else:
                    config = self.hydra_context.config_loader.load_sweep_config(self.config, list(overrides))
                    problem = check_composed(config)
                    if problem is not None:
                        raise RefusedJob(overrides, problem)
            except Exception as err:  # a swept value of hydra.sweeper.params (a preset's) that does not compose
                if sweep_control.debug_requested() and not isinstance(err, RefusedJob):
                    raise
                refuse_job(overrides, err)
            if configs is not None:
                configs.add_composed(overrides, config)
        log.debug(f"Validated {len(jobs)} of {len(batch)} job configs in {time.perf_counter() - tic:.2f} s")


def refuse_job(overrides: Sequence[str], err: Exception) -> None:
    """One line naming the job's overrides and what Hydra found wrong in them, exit 2 (before any job ran: the
    sweeper's :meth:`~FaultTolerantSweeper.sweep` puts a resume's set-aside logs back on the way out). Hydra printed
    its error over a dozen lines (the options of the group, the search path)."""
    import sys

    from analysis.interrupts import interrupt_in_chain
    from runners.configuration.precheck import one_line

    interrupt = interrupt_in_chain(err)
    if interrupt is not None:  # a signal inside OmegaConf's clean-up: not a config problem
        raise interrupt from None
    problem = getattr(err, "problem", None) or one_line(err)  # (a RefusedJob says it in one line)
    print(f"error: {problem} (the sweep's job {' '.join(overrides)[:200]})", file=sys.stderr)
    sys.exit(2)


def _finish(run: sweep_control.SweepRun, config: Any, returns: list[Sequence[Any]]) -> list[Sequence[Any]]:
    """Without ``runners.sweep``'s callback (a plain ``runners.run --multirun``) nobody else reports failures and
    stops: report them here, one line each, and exit non-zero (128 + the signal after a stop)."""
    callbacks = OmegaConf.to_container(config.hydra.get("callbacks") or {}, resolve=False)
    if "runners.sweep.SweepProgress" in str(callbacks):
        return returns
    sweep_control.finish(run)
    return returns
