"""The episodes of one configuration of a study (a trial, or a held-out run): composed by Hydra from ``conf/``
as ``runners.run`` composes them, validated by :func:`runners.configuration.run_inputs.load_run`, run by
:func:`runners.run.run_episode` with their logs in one folder; the metrics come from those logs
(:func:`analysis.metrics.metrics_table`), as a report computes them.
"""

from __future__ import annotations

import contextlib
import copy
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from omegaconf import DictConfig, OmegaConf

from analysis.metrics import metrics_table
from fuzzynav.conf import CONF_DIR
from runners.configuration import schema
from runners.configuration.run_inputs import load_run
from runners.logs import yaml_text
from runners.run import config_hash, log_path, run_episode, scenario_generator
from runners.tuning.study_file import Seeds


class ConfigurationError(ValueError):
    """A trial's configuration does not compose or does not validate (the message is one line)."""


@contextlib.contextmanager
def hydra_conf() -> Iterator[None]:
    """Hydra's global state for composing fuzzynav's configs in this process (nothing if already set)."""
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    if GlobalHydra.instance().is_initialized():
        yield
        return
    schema.register()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        yield


def compose(overrides: Sequence[str]) -> DictConfig:
    """The run config of ``overrides`` (inside :func:`hydra_conf`); Hydra's error as one line."""
    from hydra import compose as hydra_compose

    try:
        return hydra_compose("config", overrides=list(overrides))
    except Exception as err:  # Hydra's composition and grammar errors: the first line names the key
        raise ConfigurationError(" ".join(str(err).split())[:300]) from None


def is_group(key: str) -> bool:
    """Whether an override's key names a config group of ``conf/`` (``planner``), not a value (``planner.h_wait``)."""
    return "." not in key and (CONF_DIR / key).is_dir()


_COMPOSED: dict[tuple[str, ...], DictConfig] = {}  # composed configs by their group overrides, in this process
_MAX_COMPOSED = 256


def run_config(overrides: Sequence[str], scenario: str, seeds: Seeds) -> DictConfig:
    """The composed config of one scenario's episodes of a configuration. Hydra composes the config groups
    (``planner=auto``, the scenario) once per process; the values (``planner.h_wait=3``, the seeds) are then
    set as Hydra sets a value override after composing (``OmegaConf.update``, merge; the schema checks keys and
    types). Composing was ~0.1-0.3 s per trial and scenario, more than a short trial's episodes. An override
    that is not a plain ``key=value`` (``+key=``, ``~key``) goes through Hydra's composition whole."""
    from hydra.core.override_parser.overrides_parser import OverridesParser
    from hydra.core.override_parser.types import OverrideType

    everything = [*overrides, f"scenario={scenario}", f"seed={seeds.start}", f"episodes={seeds.count}"]
    try:
        parsed = OverridesParser.create().parse_overrides(everything)
    except Exception as err:
        raise ConfigurationError(" ".join(str(err).split())[:300]) from None
    if any(o.type != OverrideType.CHANGE or o.package or o.is_sweep_override() for o in parsed):
        return compose(everything)
    groups = tuple(text for text, o in zip(everything, parsed, strict=True) if is_group(o.get_key_element()))
    if groups not in _COMPOSED:
        if len(_COMPOSED) >= _MAX_COMPOSED:
            _COMPOSED.clear()
        _COMPOSED[groups] = compose(groups)
    cfg = copy.deepcopy(_COMPOSED[groups])
    for o in parsed:
        key = o.get_key_element()
        if is_group(key):
            continue
        try:
            OmegaConf.update(cfg, key, o.value(), merge=True)
        except Exception as err:  # an unknown key, a value of the wrong type: the schema's message
            raise ConfigurationError(f"Could not override '{key}': {' '.join(str(err).split())[:250]}") from None
    return cfg


def check_configuration(overrides: Sequence[str], scenario: str, seeds: Seeds) -> None:
    """Compose and validate (as a run does, first seed's scenario only) without running anything."""
    cfg = run_config(overrides, scenario, Seeds(seeds.start, 1))
    try:
        load_run(cfg, all_seeds=False)
    except Exception as err:  # ValueError and ConfigFileError: one line naming the field
        raise ConfigurationError(" ".join(str(err).split())[:300]) from None


@dataclass
class EpisodeResults:
    """The usable episodes' metrics and the logs left out (with the reason), as :func:`metrics_table` gives them."""

    episodes: pd.DataFrame
    excluded: pd.DataFrame
    logs: list[Path]


def run_configuration(overrides: Sequence[str], scenarios: Sequence[str], seeds: Seeds, out_dir: Path
                      ) -> EpisodeResults:
    """Run every scenario on every seed with ``overrides``, one log per episode in ``out_dir``; the metrics are
    read back from the logs. A configuration that does not validate raises :class:`ConfigurationError` before
    any log is written; an episode that fails is a log with outcome ``error`` (left out, with its reason)."""
    inputs = []
    for scenario in scenarios:
        cfg = run_config(overrides, scenario, seeds)
        try:
            inputs.append((cfg, load_run(cfg)))
        except Exception as err:  # ValueError and ConfigFileError: one line naming the field
            raise ConfigurationError(" ".join(str(err).split())[:300]) from None
    out_dir.mkdir(parents=True, exist_ok=True)
    logs: list[Path] = []
    for cfg, run in inputs:
        text = yaml_text.config_text(cfg, resolve=True)
        generator = scenario_generator(run.plain)
        for seed in run.seeds:
            world = run.scenarios[seed]
            path = log_path(out_dir, world.name, run.plain, seed)
            run_episode(world, run.evaluator, run.episode_config, seed, path, text, config_hash(text, seed), generator)
            logs.append(path)
    episodes, excluded = metrics_table(logs)
    return EpisodeResults(episodes, excluded, logs)
