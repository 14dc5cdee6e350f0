"""The fuzzy controller's membership functions as a search space (``controller_space:`` in a study file).

Each entry names variables that share one partition of their universe, e.g. Table 1's three distance inputs
(whose terms are one YAML anchor) and each output::

    controller_space: [[left, front, right], [dtheta], [v]]

The partition is searched in the coordinates of :mod:`fuzzynav.controller.partition` (gaps between the terms'
cores, and where the feet between neighbours lie), in which every point keeps the terms ordered, overlapping and
covering the universe; the base configuration's controller (Table 1 by default) is the study's first trial. A
trial's terms become ordinary overrides (``controller.inputs.front.terms.near.params=[0.0,0.0,31.2,58.7]``), so
its logs and its config record them as any other run parameter.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from optuna.distributions import FloatDistribution

from fuzzynav.controller.partition import MIN_OVERLAP, PartitionError, coordinates_of, partition_terms
from runners.tuning.space import Parameter

PREFIX = "controller~"  # Optuna parameter names of the partition coordinates (not Hydra keys)


class ControllerSpaceError(ValueError):
    """An entry of ``controller_space`` is wrong (the message names it)."""


@dataclass(frozen=True)
class PartitionGroup:
    """Variables (``inputs.left`` …) sharing one partition: their terms, universe and starting coordinates."""

    label: str
    paths: tuple[str, ...]
    terms: tuple[tuple[str, str, tuple[float, ...]], ...]
    universe: tuple[float, float]
    start: tuple[tuple[str, float], ...]

    def term_data(self) -> dict[str, dict[str, Any]]:
        return {name: {"mf": mf, "params": list(params)} for name, mf, params in self.terms}


def check_entries(data: Any, field: str = "controller_space") -> tuple[tuple[str, ...], ...]:
    """The study file's ``controller_space`` as groups of variable names (checked for form only)."""
    if data is None:
        return ()
    if not isinstance(data, list) or not data:
        raise ControllerSpaceError(f"{field}: expected a list of variable groups such as [[left, front, right], [v]]")
    groups, seen = [], set()
    for i, group in enumerate(data):
        names = [group] if isinstance(group, str) else group
        if not isinstance(names, list) or not names or not all(isinstance(n, str) and n for n in names):
            raise ControllerSpaceError(f"{field}[{i}]: expected a variable name or a list of them")
        for name in names:
            if name in seen:
                raise ControllerSpaceError(f"{field}[{i}]: {name[:40]} is named twice")
            seen.add(name)
        groups.append(tuple(names))
    return tuple(groups)


def resolve(entries: Sequence[Sequence[str]], controller: Mapping[str, Any], field: str = "controller_space"
            ) -> list[PartitionGroup]:
    """The groups of the composed config's ``controller`` section; the variables of a group must have the same
    terms and universe (one partition is applied to all)."""
    groups = []
    for i, names in enumerate(entries):
        found = []
        for name in names:
            section = next((s for s in ("inputs", "outputs") if name in (controller.get(s) or {})), None)
            if section is None:
                known = [*controller.get("inputs", {}), *controller.get("outputs", {})]
                raise ControllerSpaceError(f"{field}[{i}]: {name[:40]!r} is not a variable of controller "
                                           f"{controller.get('name')} (known: {', '.join(known)})")
            found.append((f"{section}.{name}", controller[section][name]))
        first = found[0][1]
        for path, var in found[1:]:
            if var.get("terms") != first.get("terms") or list(var.get("universe")) != list(first.get("universe")):
                raise ControllerSpaceError(f"{field}[{i}]: {path} has other terms or another universe than "
                                           f"{found[0][0]}: one partition cannot be applied to both")
        try:
            start = coordinates_of(first["terms"], first["universe"], f"{field}[{i}] ({found[0][0]}.terms)")
        except PartitionError as err:
            raise ControllerSpaceError(str(err)) from None
        terms = tuple((n, t["mf"], tuple(float(p) for p in t["params"])) for n, t in first["terms"].items())
        groups.append(PartitionGroup(names[0], tuple(p for p, _ in found), terms,
                                     (float(first["universe"][0]), float(first["universe"][1])),
                                     tuple(start.items())))
    return groups


def parameters(groups: Sequence[PartitionGroup]) -> list[Parameter]:
    """One Optuna parameter per coordinate of each group: gaps in [0, 1], rises in [0, 1], overlaps in
    [:data:`MIN_OVERLAP`, 1] (each group's starting point lies inside)."""
    out = []
    for g in groups:
        for coord, _ in g.start:
            low = MIN_OVERLAP if coord.startswith("overlap") else 0.0
            out.append(Parameter(f"{PREFIX}{g.label}.{coord}", FloatDistribution(low, 1.0),
                                 f"{g.label} ({', '.join(g.paths)}): {coord}"))
    return out


def start_values(groups: Sequence[PartitionGroup]) -> dict[str, float]:
    """The coordinates of the base controller (Table 1), as parameter values."""
    return {f"{PREFIX}{g.label}.{coord}": value for g in groups for coord, value in g.start}


def overrides(groups: Sequence[PartitionGroup], values: Mapping[str, Any]) -> list[str]:
    """The overrides that set every grouped variable's terms to the partition at ``values``."""
    out = []
    for g in groups:
        coords = {coord: float(values[f"{PREFIX}{g.label}.{coord}"]) for coord, _ in g.start}
        terms = partition_terms(g.term_data(), g.universe, coords, g.label)
        for path in g.paths:
            for name, term in terms.items():
                numbers = ",".join(repr(float(p)) for p in term["params"])
                out.append(f"controller.{path}.terms.{name}.params=[{numbers}]")
    return out
