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
from hydra.core.override_parser.overrides_parser import OverridesParser

log = logging.getLogger(__name__)


def _value_kind(value: object) -> object:
    """What composing a value depends on: the type for numbers, booleans and null; the value otherwise."""
    if value is None or isinstance(value, bool | int | float):
        return type(value).__name__
    return repr(value)


def representative_jobs(batch: Sequence[Sequence[str]]) -> list[Sequence[str]]:
    """The jobs of ``batch`` (each a list of ``key=value`` overrides), in order, that first bring a new
    (key, value kind) pair: composing them tries every swept value (see :func:`_value_kind`)."""
    parser = OverridesParser.create()
    seen: set[tuple[str, object]] = set()
    picked = []
    for job in batch:
        pairs = {(o.get_key_element(), _value_kind(o.value())) for o in parser.parse_overrides(list(job))}
        if not pairs <= seen:
            seen |= pairs
            picked.append(job)
    return picked


class FuzzynavSweeper(BasicSweeper):
    """Hydra's ``BasicSweeper``, validating only :func:`representative_jobs` of each batch before launching."""

    def validate_batch_is_legal(self, batch: Sequence[Sequence[str]]) -> None:
        tic = time.perf_counter()
        jobs = representative_jobs(batch)
        for overrides in jobs:
            self.hydra_context.config_loader.load_sweep_config(self.config, list(overrides))
        log.debug(f"Validated {len(jobs)} of {len(batch)} job configs in {time.perf_counter() - tic:.2f} s")
