"""A tuning study's objectives, computed from the per-episode metrics of its logs (:mod:`analysis.metrics`).

An objective is a weighted sum of metric means: ``success`` (THE success of :func:`analysis.run_parameters.is_success`,
1 or 0 per episode, so that its mean is the success rate), ``spl``, ``time_to_goal_s`` … any numeric column of
:data:`analysis.metrics.COLUMN_UNITS`. Each metric is averaged over the episodes of each scenario, then the scenarios'
means are averaged (every scenario weighs the same, however many of its episodes are usable). A metric that is
undefined for some episodes (``time_to_goal_s`` of an episode that never reached the goal is NaN) is averaged
over the episodes where it is defined, unless the objective gives it a ``fill`` value for those (e.g. the step
limit in seconds, so that failing is not cheaper than arriving late).

Written in a study file as::

    objectives:
      - {name: score, direction: maximize, terms: {success: 1.0, time_to_goal_s: -0.005}, fill: {time_to_goal_s: 120}}
      - {metric: spl, direction: maximize}        # one metric: its name is the objective's name
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import pandas as pd

from analysis.metrics import COLUMN_UNITS

#: the per-episode columns an objective may use: every metric with a number per episode
OBJECTIVE_METRICS = tuple(sorted(k for k in COLUMN_UNITS if k not in ("log", "outcome", "h_wait")))
DIRECTIONS = ("maximize", "minimize")
MAX_OBJECTIVES = 4


class ObjectiveError(ValueError):
    """An objective's definition is wrong (the message names the field)."""


@dataclass(frozen=True)
class Objective:
    """``name``; ``direction`` ``maximize`` or ``minimize``; ``terms`` (metric, weight) pairs summed;
    ``fill`` (metric, value) for the episodes where the metric is undefined (NaN)."""

    name: str
    direction: str
    terms: tuple[tuple[str, float], ...]
    fill: tuple[tuple[str, float], ...] = ()

    @property
    def metrics(self) -> tuple[str, ...]:
        return tuple(m for m, _ in self.terms)


def _finite(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ObjectiveError(f"{where}: expected a finite number, got {str(value)[:40]!r}")
    return float(value)


def _metric(name: Any, where: str) -> str:
    if name not in OBJECTIVE_METRICS:
        known = ", ".join(m for m in OBJECTIVE_METRICS if m in ("success", "spl", "time_to_goal_s",
                                                                  "path_length_cm", "min_clearance_dynamic_cm"))
        raise ObjectiveError(f"{where}: unknown metric {str(name)[:60]!r} (for instance {known}; all: "
                             "analysis.objectives.OBJECTIVE_METRICS)")
    return name


def objectives_from_data(data: Any, field: str = "objectives") -> list[Objective]:
    """The objectives of a study file's ``objectives`` list, validated (one-line :class:`ObjectiveError`)."""
    if isinstance(data, Mapping):
        data = [data]
    if not isinstance(data, Sequence) or isinstance(data, str) or not data:
        raise ObjectiveError(f"{field}: expected a list of objectives such as {{metric: spl, direction: maximize}}")
    if len(data) > MAX_OBJECTIVES:
        raise ObjectiveError(f"{field}: {len(data)} objectives, above the limit {MAX_OBJECTIVES}")
    objectives: list[Objective] = []
    for i, item in enumerate(data):
        where = f"{field}[{i}]"
        if not isinstance(item, Mapping):
            raise ObjectiveError(f"{where}: expected a mapping with metric (or terms) and direction")
        unknown = set(item) - {"name", "metric", "terms", "fill", "direction"}
        if unknown:
            raise ObjectiveError(f"{where}.{sorted(map(str, unknown))[0]}: unknown field (name, metric, terms, fill, "
                                 "direction)")
        if ("metric" in item) == ("terms" in item):
            raise ObjectiveError(f"{where}: give either metric (one metric) or terms (metric: weight, ...)")
        if "metric" in item:
            terms = ((_metric(item["metric"], f"{where}.metric"), 1.0),)
        else:
            raw = item["terms"]
            if not isinstance(raw, Mapping) or not raw:
                raise ObjectiveError(f"{where}.terms: expected a mapping metric: weight")
            terms = tuple((_metric(m, f"{where}.terms"), _finite(w, f"{where}.terms.{m}")) for m, w in raw.items())
        fill_raw = item.get("fill") or {}
        if not isinstance(fill_raw, Mapping):
            raise ObjectiveError(f"{where}.fill: expected a mapping metric: value")
        fill = tuple((_metric(m, f"{where}.fill"), _finite(v, f"{where}.fill.{m}")) for m, v in fill_raw.items())
        for m, _ in fill:
            if m not in dict(terms):
                raise ObjectiveError(f"{where}.fill.{m}: not one of the objective's metrics")
        direction = item.get("direction")
        if direction not in DIRECTIONS:
            raise ObjectiveError(f"{where}.direction: expected maximize or minimize, got {str(direction)[:40]!r}")
        name = item.get("name", terms[0][0] if "metric" in item else None)
        if not isinstance(name, str) or not name.isidentifier():
            raise ObjectiveError(f"{where}.name: expected a name (letters, digits, _), got {str(name)[:40]!r}")
        if any(o.name == name for o in objectives):
            raise ObjectiveError(f"{where}.name: {name!r} is used twice")
        objectives.append(Objective(name, direction, terms, fill))
    return objectives


def metric_means(episodes: pd.DataFrame, objective: Objective) -> dict[str, dict[str, float]]:
    """{metric: {scenario: mean}} of the objective's metrics (fill applied; NaN where no episode defines it)."""
    fill = dict(objective.fill)
    means: dict[str, dict[str, float]] = {}
    for metric in objective.metrics:
        per: dict[str, float] = {}
        for scenario, sub in episodes.groupby("scenario", sort=True):
            column = sub[metric].astype(float) if metric in sub else pd.Series(dtype=float)
            if metric in fill:
                column = column.fillna(fill[metric])
            finite = [v for v in column.tolist() if math.isfinite(v)]
            per[str(scenario)] = math.fsum(finite) / len(finite) if finite else math.nan
        means[metric] = per
    return means


def objective_value(episodes: pd.DataFrame, objective: Objective) -> float:
    """The objective over the episodes: sum of weight × (mean over scenarios of each scenario's metric mean);
    NaN when a metric has no defined value in some scenario (the caller reports which, :func:`undefined`)."""
    if episodes.empty:
        return math.nan
    means = metric_means(episodes, objective)
    total = 0.0
    for metric, weight in objective.terms:
        values = list(means[metric].values())
        if not values or any(math.isnan(v) for v in values):
            return math.nan
        total += weight * math.fsum(values) / len(values)
    return total


def undefined(episodes: pd.DataFrame, objective: Objective) -> str:
    """Why :func:`objective_value` is NaN, in a few words (``time_to_goal_s undefined in head_on: no episode
    defines it; give it a fill value``); '' if it is not."""
    if episodes.empty:
        return "no usable episode"
    for metric, per in metric_means(episodes, objective).items():
        for scenario, value in per.items():
            if math.isnan(value):
                return (f"{metric} undefined in {scenario} (no episode there defines it; give the objective a fill "
                        f"value for {metric})")
    return ""


def episode_values(episodes: pd.DataFrame, objective: Objective) -> pd.Series:
    """Each episode's objective: sum of weight x metric (fill applied), NaN where a term is undefined. Where no
    value of a scenario is NaN their mean is that scenario's term of :func:`objective_value` (the mean of a sum is
    the sum of the means), so that intervals and paired differences of the objective are those of a mean."""
    fill = dict(objective.fill)
    total = pd.Series(0.0, index=episodes.index)
    for metric, weight in objective.terms:
        column = episodes[metric].astype(float) if metric in episodes else pd.Series(math.nan, index=episodes.index)
        if metric in fill:
            column = column.fillna(fill[metric])
        total = total + weight * column.where(column.map(math.isfinite))
    return total
