"""A study file (``conf/tune/<name>.yaml`` or any path): what is searched, what is optimised, on which episodes.

::

    name: h_wait_margin                 # the study's name in its storage
    base: [planner=auto]                 # fixed overrides of every trial and of the held-out runs
    space:                               # Hydra's override grammar (runners.tuning.space)
      - planner.h_wait=int(range(1,6))
      - planner.safety_margin_cm=interval(0,30)
    objectives:                          # analysis.objectives
      - {name: score, direction: maximize, terms: {success: 1.0, time_to_goal_s: -0.005}, fill: {time_to_goal_s: 120}}
    scenarios: [head_on, crossing_right] # conf/scenario options (scenario=<name>)
    train_seeds: {start: 0, count: 4}    # each trial runs every scenario on these seeds
    heldout_seeds: {start: 1000, count: 20}  # the best trial and the default, after the study: never a training seed
    sampler: tpe                         # tpe | cmaes | random | nsga2 (two or more objectives: tpe, random, nsga2)
    sampler_seed: 0
    trials: 20
    controller_space: [[left, front, right], [dtheta], [v]]   # optional: membership functions (controller_space.py)
    controller_rules: [dtheta, v]        # optional: each rule's output terms (rule_space.py)

:func:`load_study_file` reads and checks it; each problem is one :class:`StudyFileError` naming the file and field.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from analysis.objectives import Objective, ObjectiveError, objectives_from_data
from fuzzynav.conf import CONF_DIR
from fuzzynav.params import limits
from runners.configuration.data_files import CONFIG_FILE, DataFileError, check_data_file
from runners.tuning.controller_space import ControllerSpaceError, check_entries
from runners.tuning.rule_space import RuleSpaceError
from runners.tuning.rule_space import check_entries as check_rule_entries
from runners.tuning.space import Parameter, SpaceError, parse_space

STUDY_DIR = CONF_DIR / "tune"
SAMPLERS = ("tpe", "cmaes", "random", "nsga2")
SINGLE_OBJECTIVE_SAMPLERS = ("cmaes",)
FIELDS = ("name", "base", "space", "controller_space", "controller_rules", "objectives", "scenarios", "train_seeds",
          "heldout_seeds", "sampler", "sampler_seed", "trials", "description")
MAX_TRIALS = 100_000
MAX_EPISODES_PER_TRIAL = 10_000


class StudyFileError(ValueError):
    """The study file is wrong; the message names the file and the field."""


@dataclass(frozen=True)
class Seeds:
    """Seeds ``start`` … ``start + count - 1``."""

    start: int
    count: int

    @property
    def seeds(self) -> range:
        return range(self.start, self.start + self.count)

    def text(self) -> str:
        return f"{self.start}..{self.start + self.count - 1}"


@dataclass(frozen=True)
class StudySpec:
    """A checked study file (``path``: where it was read)."""

    path: Path
    name: str
    base: tuple[str, ...]
    space: tuple[Parameter, ...]
    controller_space: tuple[tuple[str, ...], ...]
    objectives: tuple[Objective, ...]
    scenarios: tuple[str, ...]
    train: Seeds
    heldout: Seeds
    sampler: str
    sampler_seed: int
    trials: int
    description: str = ""
    controller_rules: tuple[str, ...] = ()

    @property
    def directions(self) -> list[str]:
        return [o.direction for o in self.objectives]


def find_study_file(name_or_path: str, folder: Path = STUDY_DIR) -> Path:
    """``<folder>/<name>.yaml`` (``conf/tune/`` by default) for a bare name, else the path as given."""
    if "/" not in name_or_path and not name_or_path.endswith((".yaml", ".yml")):
        return folder / f"{name_or_path}.yaml"
    return Path(name_or_path)


def _seeds(data: Any, where: str) -> Seeds:
    if not isinstance(data, Mapping) or set(data) != {"start", "count"}:
        raise StudyFileError(f"{where}: expected {{start: <first seed>, count: <number of seeds>}}")
    start, count = data["start"], data["count"]
    for key, value, low in (("start", start, 0), ("count", count, 1)):
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise StudyFileError(f"{where}.{key}: expected an integer >= {low}, got {str(value)[:40]!r}")
    if start + count - 1 > limits.MAX_SEED:
        raise StudyFileError(f"{where}: the last seed {start + count - 1} is above the limit {limits.MAX_SEED}")
    return Seeds(start, count)


def _strings(data: Any, where: str, what: str) -> tuple[str, ...]:
    if isinstance(data, str) or not isinstance(data, list):
        raise StudyFileError(f"{where}: expected a list of {what}")
    for i, item in enumerate(data):
        if not isinstance(item, str) or not item.strip():
            raise StudyFileError(f"{where}[{i}]: expected {what[:-1]} (a string), got {str(item)[:40]!r}")
    return tuple(data)


def study_from_data(data: Any, path: Path) -> StudySpec:
    """Check a study file's parsed content (``path`` names it in the messages)."""
    try:
        return _study_from_data(data, path)
    except StudyFileError as err:
        if str(err).startswith(f"{path}: "):
            raise
        raise StudyFileError(f"{path}: {err}") from None


def _study_from_data(data: Any, path: Path) -> StudySpec:
    if not isinstance(data, Mapping):
        raise StudyFileError(f"{path}: expected a mapping of {', '.join(FIELDS[:6])} ...")
    unknown = [str(k) for k in data if k not in FIELDS]
    if unknown:
        raise StudyFileError(f"{path}: {unknown[0][:60]}: unknown field (known: {', '.join(FIELDS)})")
    for key in ("objectives", "scenarios", "train_seeds", "heldout_seeds"):
        if key not in data:
            raise StudyFileError(f"{path}: {key}: missing")
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name.replace("-", "_").isidentifier():
        raise StudyFileError(f"{path}: name: expected a name (letters, digits, _ and -), got {str(name)[:40]!r}")
    if "space" not in data and "controller_space" not in data and "controller_rules" not in data:
        raise StudyFileError(f"{path}: space: missing (or controller_space: the controller's membership functions, "
                             "controller_rules: its rule outputs)")
    try:
        controller_space = check_entries(data.get("controller_space"))
        controller_rules = check_rule_entries(data.get("controller_rules"))
        space = tuple(parse_space(data["space"])) \
            if "space" in data or not (controller_space or controller_rules) else ()
        objectives = tuple(objectives_from_data(data["objectives"]))
    except (SpaceError, ObjectiveError, ControllerSpaceError, RuleSpaceError) as err:
        raise StudyFileError(f"{path}: {err}") from None
    base = _strings(data.get("base", []), "base", "overrides")
    for i, text in enumerate(base):
        key = text.lstrip("+~").partition("=")[0].strip()
        if key in {p.key for p in space}:
            raise StudyFileError(f"{path}: base[{i}]: {key} is also searched (space): one or the other")
        if key in ("scenario", "seed", "episodes", "resume") or key.startswith("hydra"):
            raise StudyFileError(f"{path}: base[{i}]: {key} is set by the study (scenarios, train_seeds, "
                                 "heldout_seeds), not by an override")
    for p in space:
        if p.key in ("scenario", "seed", "episodes", "resume"):
            raise StudyFileError(f"{path}: space: {p.key} is set by the study, not searched")
    scenarios = _strings(data["scenarios"], "scenarios", "scenario names")
    if not scenarios:
        raise StudyFileError(f"{path}: scenarios: is empty: name at least one")
    if len(set(scenarios)) != len(scenarios):
        raise StudyFileError(f"{path}: scenarios: a scenario is named twice")
    try:
        train = _seeds(data["train_seeds"], "train_seeds")
        heldout = _seeds(data["heldout_seeds"], "heldout_seeds")
    except StudyFileError as err:
        raise StudyFileError(f"{path}: {err}") from None
    overlap = set(train.seeds).intersection(heldout.seeds) if train.start < heldout.start + heldout.count and \
        heldout.start < train.start + train.count else set()
    if overlap:
        raise StudyFileError(f"{path}: heldout_seeds: {heldout.text()} overlap train_seeds {train.text()} (seed "
                             f"{min(overlap)}): held-out results must come from seeds the study never saw")
    if train.count * len(scenarios) > MAX_EPISODES_PER_TRIAL:
        raise StudyFileError(f"{path}: train_seeds: {train.count * len(scenarios)} episodes per trial, above the "
                             f"limit {MAX_EPISODES_PER_TRIAL}")
    sampler = data.get("sampler", "tpe")
    if sampler not in SAMPLERS:
        raise StudyFileError(f"{path}: sampler: expected one of {', '.join(SAMPLERS)}, got {str(sampler)[:40]!r}")
    if len(objectives) > 1 and sampler in SINGLE_OBJECTIVE_SAMPLERS:
        raise StudyFileError(f"{path}: sampler: {sampler} optimises one objective; with {len(objectives)} "
                             "objectives use tpe, nsga2 or random")
    seed, trials = data.get("sampler_seed", 0), data.get("trials", 20)
    for key, value, low, high in (("sampler_seed", seed, 0, 2**32 - 1), ("trials", trials, 1, MAX_TRIALS)):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise StudyFileError(f"{path}: {key}: expected an integer in [{low}, {high}], got {str(value)[:40]!r}")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise StudyFileError(f"{path}: description: expected text")
    return StudySpec(path, name, base, space, controller_space, objectives, scenarios, train, heldout, sampler, seed,
                     trials, description, controller_rules)


def load_study_file(path: Path) -> StudySpec:
    """Read and check a study file (size, YAML safety, every field)."""
    try:
        raw = check_data_file(path, CONFIG_FILE)
    except DataFileError as err:
        raise StudyFileError(str(err)) from None
    try:
        data = yaml.safe_load(raw)
    except yaml.YAMLError as err:
        raise StudyFileError(f"{path}: YAML error: {str(err).splitlines()[0]}") from None
    return study_from_data(data, path)
