"""The size of a sweep before it runs: its jobs (the product of the sizes of its sweeps, the preset's and the
command line's) and its episodes (jobs × ``episodes``); :mod:`runners.sweep` shows the progress against it and
:mod:`runners.sweeping.end` counts the episodes that were not run."""

from __future__ import annotations

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import ValueType
from omegaconf import DictConfig

from fuzzynav.conf import CONF_DIR
from runners.configuration.plugins import plugin_config_dirs
from runners.configuration.sweep_size import sweep_size


def count_episodes(config: DictConfig) -> int | None:
    """Episodes the sweep will run: product of the sweep sizes times ``episodes`` (None if unknown)."""
    jobs = count_jobs(config, list(config.hydra.overrides.task))
    return None if jobs is None else jobs * int(config.get("episodes", 1))


def count_jobs(config: DictConfig, task: list[str]) -> int | None:
    """Jobs of the sweep: the product of the sweep sizes of the preset's ``hydra.sweeper.params`` and the
    command-line overrides ``task`` (None if unknown)."""
    params = dict(config.hydra.sweeper.get("params") or {})
    overrides = [f"{k}={v}" for k, v in params.items()]
    overrides += task
    total = 1
    try:
        parsed = OverridesParser.create().parse_overrides(overrides)
    except Exception:
        return None
    sizes: dict[str, int] = {}
    for o in parsed:
        key = o.get_key_element()
        if not o.is_sweep_override():
            sizes[key] = 1  # a plain command-line value replaces the preset's sweep over that key
            continue
        if o.value_type == ValueType.GLOB_CHOICE_SWEEP:
            dirs = [CONF_DIR / key, *(folder / key for _, folder in plugin_config_dirs())]  # as Hydra searches
            names = sorted({p.stem for d in dirs if d.is_dir() for p in d.glob("*.yaml")})
            sizes[key] = len(o.value().filter(names))
        else:
            size = sweep_size(o)
            if size is None:
                return None
            sizes[key] = size
    for n in sizes.values():
        total *= max(n, 1)
    return total

