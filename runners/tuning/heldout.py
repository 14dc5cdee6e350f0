"""The honest result of a study: the best trial and the default, run on the held-out seeds (never a training
seed: :mod:`runners.tuning.study_file` refuses an overlap), with 95 % intervals.

Logs go to ``<study>/heldout/<label>/`` (``default``, ``tuned``; for two objectives ``trial_<n>`` for each evaluated
Pareto trial), so that ``python -m analysis.report <study>/heldout`` compares them like any sweep. Each evaluated
trial is also written as ``<study>/<label>.yaml``, a config that ``python -m runners.run --config-dir <study>
--config-name <label>`` runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import optuna
import pandas as pd
from omegaconf import OmegaConf

from analysis.objectives import objective_value
from analysis.stats import bootstrap_mean, wilson
from runners.logs import yaml_text
from runners.tuning.episodes import EpisodeResults, hydra_conf, is_group, run_config, run_configuration
from runners.tuning.study import OVERRIDES
from runners.tuning.study_file import StudySpec

HELDOUT_DIR = "heldout"
MAX_PARETO = 3  # Pareto trials evaluated on the held-out seeds (the two ends of the front and its middle)


@dataclass
class Evaluated:
    """One configuration run on the held-out seeds."""

    label: str
    overrides: list[str]
    trial: int | None
    results: EpisodeResults
    objectives: dict[str, float] = field(default_factory=dict)
    same_as_default: bool = False  # the trial's configuration is the default's: its episodes are the default's


def chosen_trials(study: optuna.Study) -> list[optuna.trial.FrozenTrial]:
    """The best trial (one objective), or up to :data:`MAX_PARETO` Pareto trials spread along the first
    objective (two or more)."""
    if len(study.directions) == 1:
        return [study.best_trial]
    front = sorted(study.best_trials, key=lambda t: (t.values[0], t.number))
    if len(front) <= MAX_PARETO:
        return front
    return [front[0], front[len(front) // 2], front[-1]]


def config_yaml(overrides: list[str], note: str) -> str:
    """A primary config that composes fuzzynav's ``config`` with ``overrides``: config groups as ``override``
    entries of its defaults list, values as nested keys."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    groups: list[dict[str, Any]] = []
    values: dict[str, Any] = {}
    for override in OverridesParser.create().parse_overrides(overrides):
        key, value = override.get_key_element(), override.value()
        if is_group(key):
            groups.append({f"override {key}": value})
            continue
        node = values
        *parents, last = key.split(".")
        for part in parents:
            node = node.setdefault(part, {})
        node[last] = value
    lines = [f"# {line}" for line in note.splitlines()]
    body = {"defaults": ["config", "_self_", *groups], **values}
    return "\n".join(lines) + "\n" + yaml_text.dump(body)


def evaluate(study: optuna.Study, spec: StudySpec, study_dir: Path) -> list[Evaluated]:
    """Run the default and the chosen trials on the held-out seeds; write each trial's config file."""
    chosen = chosen_trials(study)
    runs: list[tuple[str, list[str], int | None]] = [("default", list(spec.base), None)]
    for t in chosen:
        label = "tuned" if len(chosen) == 1 else f"trial_{t.number}"
        overrides = list(t.user_attrs[OVERRIDES])
        if spec.controller_space or spec.controller_rules:  # a tuned controller: its own name in logs and reports
            with hydra_conf():
                base_name = run_config(spec.base, spec.scenarios[0], spec.heldout).controller.name
            overrides.append(f"controller.name={base_name}_{label}")
        runs.append((label, overrides, t.number))
    evaluated: list[Evaluated] = []
    with hydra_conf():
        # compared as data: Table 1's 30 and a partition's 30.0 are the same breakpoint
        default_config = OmegaConf.to_container(run_config(spec.base, spec.scenarios[0], spec.heldout), resolve=True)
        for label, overrides, number in runs:
            if number is not None:
                note = (f"study {spec.name}, trial {number} ({spec.path.name}); run it with\n"
                        f"  python -m runners.run --config-dir {study_dir.absolute()} --config-name {label} "
                        f"scenario={spec.scenarios[0]}")
                (study_dir / f"{label}.yaml").write_text(config_yaml(overrides, note))
                if spec.controller_space or spec.controller_rules:
                    write_controller(study_dir, spec, label, number, overrides)
            out = study_dir / HELDOUT_DIR / label
            for old in out.glob("*.mcap"):  # a re-run evaluates again from nothing
                old.unlink()
            unnamed = [o for o in overrides if not o.startswith("controller.name=")]  # the name alone changes nothing
            # the default won: the same episodes, not run (nor counted) twice
            if number is not None and OmegaConf.to_container(
                    run_config(unnamed, spec.scenarios[0], spec.heldout), resolve=True) == default_config:
                print(f"held-out: {label} (trial {number}) is the default configuration", flush=True)
                evaluated.append(Evaluated(label, overrides, number, evaluated[0].results, evaluated[0].objectives,
                                           same_as_default=True))
                continue
            print(f"held-out: {label} on {len(spec.scenarios)} scenarios x seeds {spec.heldout.text()}", flush=True)
            results = run_configuration(overrides, spec.scenarios, spec.heldout, out)
            values = {o.name: objective_value(results.episodes, o) for o in spec.objectives}
            evaluated.append(Evaluated(label, overrides, number, results, values))
    return evaluated


def write_controller(study_dir: Path, spec: StudySpec, label: str, number: int, overrides: list[str]) -> Path:
    """The tuned controller as a controller file, ``<study>/controller/<name>.yaml``: run it with
    ``python -m runners.run hydra.searchpath=[file://<study>] controller=<name>``."""
    with hydra_conf():
        section = OmegaConf.to_container(run_config(overrides, spec.scenarios[0], spec.heldout).controller,
                                         resolve=True)
    searched = [what for what, on in (("membership functions", spec.controller_space),
                                      ("rule outputs", spec.controller_rules)) if on]
    section["description"] = f"tuned by study {spec.name}, trial {number} ({' and '.join(searched)} searched)"
    path = study_dir / "controller" / f"{section['name']}.yaml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(f"# run with: python -m runners.run hydra.searchpath=[file://{study_dir.absolute()}] "
                    f"controller={section['name']}\n" + yaml_text.dump(section))
    return path


def metric_interval(metric: str, values: list[float]) -> tuple[float, float, float, int]:
    """(mean, low, high, n) of a metric's values (NaNs dropped): the success rate with its Wilson interval, any
    other metric's mean with its percentile bootstrap interval (95 %)."""
    finite = [v for v in values if not math.isnan(v)]
    if not finite:
        return math.nan, math.nan, math.nan, 0
    if metric == "success":
        return (*wilson(int(sum(finite)), len(finite)), len(finite))
    return (*bootstrap_mean(finite), len(finite))


def interval_table(evaluated: list[Evaluated], spec: StudySpec) -> pd.DataFrame:
    """One row per scenario, objective metric and configuration: mean and 95 % interval on the held-out seeds
    (Wilson for success, percentile bootstrap otherwise); and, for each tuned configuration, the paired
    difference from the default (same seed, same world) with its bootstrap interval."""
    metrics = list(dict.fromkeys(m for o in spec.objectives for m in o.metrics))
    default = evaluated[0]
    rows = []
    for scenario in spec.scenarios:
        for metric in metrics:
            base = default.results.episodes
            base = base[base["scenario"] == scenario].set_index("seed")[metric].astype(float) if not base.empty \
                else pd.Series(dtype=float)
            for ev in evaluated:
                if ev.same_as_default:
                    continue
                eps = ev.results.episodes
                sub = eps[eps["scenario"] == scenario].set_index("seed")[metric].astype(float) if not eps.empty \
                    else pd.Series(dtype=float)
                mean, lo, hi, n = metric_interval(metric, sub.tolist())
                row = {"scenario": scenario, "metric": metric, "configuration": ev.label, "n": n, "mean": mean,
                       "ci_low": mean if n == 0 else lo, "ci_high": hi}
                if ev is not default and not ev.same_as_default:
                    common = sub.index.intersection(base.index)
                    diffs = [d for d in (sub[common] - base[common]).tolist() if not math.isnan(d)]
                    d_mean, d_lo, d_hi = bootstrap_mean(diffs) if diffs else (math.nan,) * 3
                    row.update(diff_vs_default=d_mean, diff_ci_low=d_lo, diff_ci_high=d_hi, pairs=len(diffs))
                rows.append(row)
    return pd.DataFrame(rows)
