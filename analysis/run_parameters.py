"""Run parameters of logged episodes: what defines a group of episodes, how a group is labelled, what success is.

Every analysis that pools episodes (the report, the sweep's summary) groups them by **every run parameter whose
resolved value differs among the logs analysed**, so that two settings are never averaged together silently.
A log's parameters come from its ``fuzzynav.run`` metadata (:func:`parameters_of`): the always-shown ones
(:data:`SHOWN`: scenario, policy, strategy, h_wait, controller, perception) plus the resolved Hydra config flattened to
dotted keys (``planner.safety_margin_cm``), without bookkeeping (:data:`BOOKKEEPING`: which seeds, how many
episodes, resume; Hydra's own settings and output directories are not in the logged config).

Provenance (fuzzynav version, git commit, library versions) is recorded too. By default logs from different
code are pooled and the difference is reported as a warning (a sweep resumed after an unrelated commit should
still pool); ``split_provenance=True`` makes those keys group dimensions as well.

Parameters of a part that is off are none: ``h_wait`` of a strategy that does not read it (wait, detour, none) and
every ``planner.*`` key under ``planner=none`` (:mod:`fuzzynav.params.names`).

Labels: ``auto(h=2) · safety_margin_cm=5`` — the strategy (with h_wait where it is read, or where it differs),
then each differing parameter by its shortest unambiguous key suffix; where policies differ the policy leads
(``dwa · none``) and groups are ordered by policy (the paper's ``fuzzy`` first, ``direct`` last). Differing
``scenario.*`` keys (a generated scenario's ``scenario.params.*``, an edited scenario file under the same name)
belong to the scenario's label instead (``random_mixed · n_dynamic=5``): those episodes are different worlds and
are never paired. ``scenario.*`` and ``controller.*`` keys that only differ together with the scenario or
controller name are implied by the name and not repeated. A key missing from some logs (added to the config
later) differs and shows as ``unset``; a log with no readable config differs only in ``config=none`` (its keys
are unknown).
"""

from __future__ import annotations

import hashlib
import json
import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import yaml

from fuzzynav.episode_identity import POLICY_SOURCE, RECORDING
from fuzzynav.params.names import PLANNER_OFF, reads_h_wait

EPISODE_PARAMETERS = ("scenario", "policy", "strategy", "h_wait", "seed", "controller", "perception")
"""Columns of every per-episode table, in this order (from the metadata; ``seed`` says which episode)."""
SHOWN = ("scenario", "policy", "strategy", "h_wait", "controller", "perception")
"""Run parameters every table shows, whether they differ or not."""
BOOKKEEPING = frozenset({"seed", "episodes", "resume"})
"""Top-level config keys that choose which episodes run, not how: never group dimensions."""
ALIASES = {"scenario.name": "scenario", "planner.strategy": "strategy", "planner.h_wait": "h_wait",
           "controller.name": "controller", "perception.mode": "perception", "navigator.policy": "policy",
           "navigator._target_": "policy"}
"""Config keys that repeat a shown parameter (the metadata's value is used)."""
NAMED_SUBTREES = {"scenario.": "scenario", "controller.": "controller", "navigator.": "policy"}
"""Config subtrees described by a name: their keys are dimensions only where they differ under one name (DWA's
weights are not a dimension of a comparison of DWA with APF, but are of two DWA runs that differ in them)."""

STRATEGY_ORDER = ("auto", "wait", "detour", "none")
#: the policy of logs written before policies could be chosen: the paper's fuzzy controller
LEGACY_POLICY = "fuzzy"
#: the order of policies in tables and figures: the paper's first, the floor (straight to the goal) last, the rest
#: by name; the names come from the logs, so a new policy needs no entry here
POLICY_FIRST, POLICY_LAST = "fuzzy", "direct"
CONFIG = "config"  # "logged", or "none" for a log without a readable config: its config keys are unknown, not unset
UNSET = "unset"  # label of a parameter a log does not have (e.g. a key added to the config later)
NULL = "null"  # label of a parameter whose value is null in the log's config
OFF = "off (planner=none)"  # the value of a planner parameter that nothing reads: never a difference, never a label
SEP = " · "
RECORDING_PARAMETER = f"scenario.{RECORDING}"  # a scenario parameter: the world it was read from
RECORDING_PATH = "scenario.params.recording"  # ... which names it by its path: a dimension where one path has two
_MISSING = object()
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)  # libyaml when PyYAML has it: ~10x faster


def is_success(outcome: str | None, contacts: float | None, time_to_goal_s: float | None) -> bool:
    """THE definition of a successful episode: outcome ``goal`` (reached within the step limit), zero contacts
    and a finite time-to-goal (s). ``contacts``: contact events, as :mod:`analysis.metrics` recomputes them from
    the logged geometry (cross-checked against the simulator's flags in the report); unknown (None, NaN) is not
    zero. The sweep's summary reads this same per-episode value, so the two cannot disagree.

    A NaN time-to-goal means the logged positions never come within the goal tolerance; a log whose outcome
    says ``goal`` anyway contradicts itself, and an episode we cannot show reached the goal is not counted as a
    success."""
    if outcome != "goal" or contacts is None or time_to_goal_s is None:
        return False
    if math.isnan(float(contacts)) or math.isnan(float(time_to_goal_s)):
        return False
    return float(contacts) == 0


def is_provenance(key: str) -> bool:
    """Metadata keys that say which code wrote the log (versions, git commit, the digest of a plug-in's source):
    logs that differ in one are never pooled."""
    return key in ("fuzzynav_version", "git_commit", POLICY_SOURCE) or key.endswith("_version")


def _flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Dotted keys to leaf values; a list is one value (its compact JSON text), as it is one setting."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, Mapping) and value:
            out.update(_flatten(value, dotted + "."))
        elif isinstance(value, list | tuple | Mapping):
            out[dotted] = json.dumps(value, separators=(",", ":"), sort_keys=True, default=str)
        else:
            out[dotted] = value
    return out


def _int(value: Any) -> int | None:
    try:
        return None if value in (None, "") else int(value)
    except (TypeError, ValueError):
        return None


def parameters_of(meta: Mapping[str, str], config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """One log's run parameters from its ``fuzzynav.run`` metadata: the shown ones, the flattened resolved
    config minus bookkeeping and aliases, and provenance. ``config``: the metadata's config already parsed
    (else it is parsed here). A log without a readable config (hand-written, or from a tool that logs none) has
    the shown parameters, provenance and ``config=none``."""
    params: dict[str, Any] = {key: meta.get(key) for key in SHOWN}
    params["h_wait"] = _int(params["h_wait"])
    params["policy"] = params["policy"] or LEGACY_POLICY  # logs written before policies could be chosen
    if config is None:
        try:
            config = yaml.load(meta.get("config") or "", Loader=_YAML_LOADER)
        except yaml.YAMLError:
            config = None
    params[CONFIG] = "logged" if isinstance(config, Mapping) and config else "none"
    if isinstance(config, Mapping):
        for key, value in _flatten(config).items():
            if key in ALIASES or key.split(".")[0] in BOOKKEEPING or key.startswith("hydra."):
                continue
            params[key] = value
    params.update({key: value for key, value in meta.items() if is_provenance(key)})
    if RECORDING in meta:  # the recording's content: two recordings of one file name are two worlds, never pooled
        params[RECORDING_PARAMETER] = meta[RECORDING]
    # a parameter of a part that is off is no dimension: h_wait where the strategy does not read it, every
    # planner parameter under planner=none (tests/test_parameters_off.py: the episodes are the same bits)
    if not reads_h_wait(params["strategy"]):
        params["h_wait"] = None
    if params["strategy"] == PLANNER_OFF:
        for key in [k for k in params if k.startswith("planner.")]:
            params[key] = OFF
    return params


def _implied_by_name(key: str, runs: Sequence[Mapping[str, Any]]) -> bool:
    """Whether ``key`` lies in a named subtree and has one value per name among ``runs`` (the recording's digest: one
    value per recording path)."""
    owner = RECORDING_PATH if key == RECORDING_PARAMETER else next(
        (name for prefix, name in NAMED_SUBTREES.items() if key.startswith(prefix)), None)
    if owner is None:
        return False
    seen: dict[Any, Any] = {}
    for run in runs:
        value = _hashable(run.get(key, _MISSING))
        if seen.setdefault(run.get(owner), value) != value:
            return False
    return True


def _hashable(value: Any) -> Any:
    """A value as logs are compared by it: its kind, then the value. 10 and 10.0 are one value (their label is
    ``10``); 10 and '10', true and 1, null and a missing key are two (as their labels are: :func:`format_value`),
    which Python's ``==`` would partly pool (``True == 1``). NaN is one value (NaN != NaN would split)."""
    if value is _MISSING:
        return ("missing",)
    if value is None:
        return ("null",)
    if isinstance(value, bool):
        return ("bool", value)
    if isinstance(value, int | float):
        return ("number", "nan") if isinstance(value, float) and math.isnan(value) else ("number", value)
    if isinstance(value, str):
        return ("text", value)
    return ("other", repr(value))


def differing_parameters(runs: Sequence[Mapping[str, Any]]) -> list[str]:
    """Keys whose value differs among ``runs`` (parameter dicts from :func:`parameters_of`; a key missing from
    some runs differs), except ``scenario.*``/``controller.*`` keys implied by the scenario/controller name.
    Order: the shown parameters, then config keys in config order, then provenance."""
    keys: dict[str, None] = {}
    for run in runs:
        keys.update(dict.fromkeys(run))
    # config keys are compared among the logs that have a config (the others differ in "config" itself)
    configured = [run for run in runs if run.get(CONFIG, "logged") == "logged"]

    def differs(key: str) -> bool:
        among = runs if key in SHOWN or key == CONFIG or is_provenance(key) else configured
        among = [run for run in among if run.get(key, _MISSING) != OFF]  # where the part is on
        return len({_hashable(run.get(key, _MISSING)) for run in among}) > 1 and not _implied_by_name(key, among)

    differing = [key for key in keys if differs(key)]
    shown = [k for k in SHOWN if k in differing]
    provenance = [k for k in differing if is_provenance(k)]
    return shown + [k for k in differing if k not in SHOWN and not is_provenance(k)] + provenance


def short_names(keys: Iterable[str]) -> dict[str, str]:
    """Shortest dotted suffix of each key that no other key ends with (and that is no shown parameter's
    name), at least 3 characters: ``planner.safety_margin_cm`` -> ``safety_margin_cm``; ``sensors.sonar.range_cm``
    and ``sensors.laser.range_cm`` -> ``sonar.range_cm``, ``laser.range_cm``."""
    keys = list(keys)
    out = {}
    for key in keys:
        parts = key.split(".")
        for n in range(1, len(parts) + 1):
            suffix = ".".join(parts[-n:])
            clash = any(other != key and (other == suffix or other.endswith("." + suffix)) for other in keys)
            if not clash and suffix not in (*SHOWN, "seed") and len(suffix) >= 3:
                break
        out[key] = suffix
    return out


def format_value(value: Any) -> str:
    """A value as it appears in a label: ``5`` for 5.0, ``true``, ``null``, ``unset`` for a missing key; text
    that would read as one of those or as a number in quotes (``'10'``), so that two values that differ never
    share a label (the groups are made by label); long text (controller rules, git commits) as its first 10
    characters and a 6-character hash, still unique."""
    if value is _MISSING:
        return UNSET
    if value is None:
        return NULL
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, float):
        return str(int(value)) if value.is_integer() else repr(value)
    text = str(value)
    if isinstance(value, str) and _reads_as_another_kind(text):
        text = f"'{text}'"
    if len(text) > 24:
        return f"{text[:10]}…{hashlib.sha1(text.encode()).hexdigest()[:6]}"
    return text


def _reads_as_another_kind(text: str) -> bool:
    """Whether a text's label would be that of a number, a boolean, null or a missing key."""
    if text.strip().lower() in (UNSET, NULL, "true", "false", "none", ""):
        return True
    try:
        float(text)
    except ValueError:
        return text.startswith("'")  # (a text already in quotes: quoted again, never the label of another)
    return True


def _order(value: Any) -> tuple:
    """Natural sort key of a parameter value: numbers by value (5 before 10), then text, missing last."""
    if value is _MISSING or value is None or value == OFF:
        return (3, "")
    if isinstance(value, bool):
        return (1, str(value))
    if isinstance(value, int | float):
        return (0, float(value))
    return (2, str(value))


@dataclass(frozen=True)
class Grouping:
    """How a set of logs is grouped and labelled (see the module docstring)."""

    scenario_keys: tuple[str, ...] = ()
    """Differing ``scenario.*`` keys: part of the scenario's label."""
    variant_keys: tuple[str, ...] = ()
    """Other differing keys (controller, perception, config keys, provenance when split): part of the variant."""
    h_wait_shown: frozenset[str] = frozenset({"auto"})
    """Strategies whose label shows h_wait: auto (which reads it) and any whose h_wait differs among the logs."""
    short: Mapping[str, str] = field(default_factory=dict)
    pooled_provenance: tuple[str, ...] = ()
    """Provenance keys that differ but do not split groups (reported as a warning)."""

    @property
    def dimensions(self) -> tuple[str, ...]:
        """Every key that splits groups beyond scenario, strategy and h_wait."""
        return self.scenario_keys + self.variant_keys

    def _parts(self, run: Mapping[str, Any], keys: Iterable[str]) -> list[str]:
        return [f"{self.short.get(k, k)}={self.value_label(run, k)}" for k in keys if run.get(k, _MISSING) != OFF]

    def value_label(self, run: Mapping[str, Any], key: str) -> str:
        """``key``'s value in ``run`` as labels show it (:func:`format_value`; a shown parameter the metadata lacks,
        None in ``run``, is ``unset``)."""
        value = run.get(key, _MISSING)
        return format_value(_MISSING if value is None and key in SHOWN else value)

    def strategy_label(self, run: Mapping[str, Any]) -> str:
        """``auto(h=2)``, ``wait``; ``wait(h=1)`` when wait episodes with different h_wait are analysed."""
        strategy, h_wait = str(run.get("strategy")), run.get("h_wait")
        return f"{strategy}(h={h_wait})" if strategy in self.h_wait_shown and h_wait is not None else strategy

    def setting_label(self, run: Mapping[str, Any]) -> str:
        """The differing parameters besides scenario and strategy (``safety_margin_cm=5``), '' if none."""
        return SEP.join(self._parts(run, self.variant_keys))

    def variant_label(self, run: Mapping[str, Any]) -> str:
        """The group's label within its scenario: ``auto(h=2) · safety_margin_cm=5``; led by the policy where
        policies differ (``dwa · auto(h=2)``)."""
        if "policy" in self.variant_keys:
            rest = [k for k in self.variant_keys if k != "policy"]
            return SEP.join([self.value_label(run, "policy"), self.strategy_label(run), *self._parts(run, rest)])
        return SEP.join([self.strategy_label(run), *self._parts(run, self.variant_keys)])

    def scenario_label(self, run: Mapping[str, Any]) -> str:
        """``head_on``; ``random_mixed · n_dynamic=5`` when that scenario's parameters differ among the logs."""
        return SEP.join([str(run.get("scenario")), *self._parts(run, self.scenario_keys)])

    def sort_key(self, run: Mapping[str, Any]) -> tuple:
        """Natural order of groups: scenario, its parameters, strategy (auto, wait, detour, none), h_wait, the
        other parameters (numbers by value)."""
        strategy = str(run.get("strategy"))
        rank = STRATEGY_ORDER.index(strategy) if strategy in STRATEGY_ORDER else len(STRATEGY_ORDER)
        policy = str(run.get("policy"))
        policy_rank = ((0 if policy == POLICY_FIRST else 2 if policy == POLICY_LAST else 1, policy)
                       if "policy" in self.variant_keys else ())
        return (str(run.get("scenario")), *(_order(run.get(k, _MISSING)) for k in self.scenario_keys), *policy_rank,
                rank, strategy, _order(run.get("h_wait")), *(_order(run.get(k, _MISSING)) for k in self.variant_keys))

    def columns(self, run: Mapping[str, Any]) -> dict[str, Any]:
        """Per-episode columns: each dimension's value (full key; ``unset`` if missing), ``scenario_label``,
        ``variant`` and ``setting``."""
        out = {k: run.get(k, UNSET) for k in self.dimensions if k not in SHOWN}
        out.update(scenario_label=self.scenario_label(run), variant=self.variant_label(run),
                   setting=self.setting_label(run))
        return out


def find_grouping(runs: Sequence[Mapping[str, Any]], split_provenance: bool = False) -> Grouping:
    """The grouping of ``runs`` (parameter dicts, one per log or one per distinct configuration)."""
    differing = differing_parameters(runs)
    provenance = tuple(k for k in differing if is_provenance(k))
    splitting = [k for k in differing if k not in ("scenario", "strategy", "h_wait")
                 and (split_provenance or not is_provenance(k))]
    scenario_keys = tuple(k for k in splitting if k.startswith("scenario."))
    variant_keys = tuple(k for k in splitting if not k.startswith("scenario."))
    by_strategy: dict[str, set] = {}
    for run in runs:
        by_strategy.setdefault(str(run.get("strategy")), set()).add(run.get("h_wait"))
    h_wait_shown = frozenset({"auto"} | {s for s, hs in by_strategy.items() if len(hs) > 1})
    return Grouping(scenario_keys=scenario_keys, variant_keys=variant_keys, h_wait_shown=h_wait_shown,
                    short=short_names([k for k in differing if k not in SHOWN]),
                    pooled_provenance=() if split_provenance else provenance)


def provenance_warning(grouping: Grouping, runs: Sequence[Mapping[str, Any]]) -> str | None:
    """One sentence when logs from different code are pooled: each differing provenance key with its values
    and episode counts (``runs``: one parameter dict per episode)."""
    # a key whose values each stay in groups of their own is not pooled (a _target_ policy's source digest beside
    # fuzzynav's own policies, in groups of their own: the warning said they were pooled)
    groups: dict[tuple[str, str], dict[str, set]] = {}
    for run in runs:
        seen = groups.setdefault((grouping.scenario_label(run), grouping.variant_label(run)), {})
        for key in grouping.pooled_provenance:
            seen.setdefault(key, set()).add(grouping.value_label(run, key))
    pooled = [key for key in grouping.pooled_provenance if any(len(seen.get(key, ())) > 1 for seen in groups.values())]
    if not pooled:
        return None
    parts = []
    for key in pooled:
        counts = Counter(grouping.value_label(run, key) for run in runs)
        parts.append(f"{key} " + ", ".join(f"{value} ({n} episodes)" for value, n in sorted(counts.items())))
    return ("warning: these logs were written by different code — " + "; ".join(parts) + ". They are pooled in "
            "the groups; results may differ between versions (split them with --split-provenance).")
