"""fuzzynav's Hydra sweeper: Hydra's basic sweeper, checking each swept value once instead of every job.

Installed as ``hydra_plugins.fuzzynav_sweeper`` (Hydra loads sweepers only from the ``hydra_plugins``
package; ``pyproject.toml`` maps this directory there) and selected in ``conf/config.yaml``
(``hydra/sweeper: fuzzynav``). Before launching, Hydra's basic sweeper composes the config of every job in
the launching process, one after the other (about 0.1 s each), and the launcher composes each job again where
it runs. This sweeper composes, before launching, only the jobs needed to try every swept value at least
once: every distinct value of a text setting or config group option (``scenario=head_on``), and one value of
each type for numbers and booleans (``seed=range(0,1000,50)`` composes like ``seed=0``). A bad value is
still reported before anything runs; the default sweep of 21 jobs composes 9 configs up front instead of 21.
Everything else (batches, ``params``, ``max_batch_size``) is the basic sweeper's.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence

from hydra._internal.core_plugins.basic_sweeper import BasicSweeper

from runners.precheck import representative_jobs

__all__ = ["FuzzynavSweeper", "representative_jobs"]

log = logging.getLogger(__name__)


class FuzzynavSweeper(BasicSweeper):
    """Hydra's ``BasicSweeper``, validating only :func:`representative_jobs` of each batch before launching."""

    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        tic = time.perf_counter()
        jobs = representative_jobs(batch)
        for overrides in jobs:
            self.hydra_context.config_loader.load_sweep_config(self.config, list(overrides))
        log.debug(f"Validated {len(jobs)} of {len(batch)} job configs in {time.perf_counter() - tic:.2f} s")
