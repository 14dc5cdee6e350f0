"""A comparison file (``conf/tune/compare/<name>.yaml`` or any path): methods tuned on the same budget, compared
on the same held-out seeds.

::

    name: suite_v2                      # the comparison's name (default: the file's stem)
    description: Table 1 as published vs tuned Table 1 vs each baseline tuned with the same budget
    reference: suite_v2_table1           # whose default (as published) is every method's common reference
    studies:                             # study files (runners.tuning.study_file): a method is one line
      - suite_v2_table1                  #   a name: conf/tune/<name>.yaml
      - suite_v2_dwa
      - ../my_study.yaml                 #   a path: relative to this file's folder

:func:`load_comparison` reads it, loads every study file and checks, before any trial, that the studies can be
compared: the same scenarios, training seeds, held-out seeds, trials (so the same budget of episodes: trials x
scenarios x training seeds) and objectives, and no training seed of one study among the held-out seeds of
another. Each problem is one :class:`ComparisonFileError` naming the file and the field.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from runners.configuration.data_files import CONFIG_FILE, DataFileError, check_data_file
from runners.tuning.study_file import STUDY_DIR, StudyFileError, StudySpec, find_study_file, load_study_file

COMPARISON_DIR = STUDY_DIR / "compare"
FIELDS = ("name", "description", "reference", "studies")
MAX_STUDIES = 64


class ComparisonFileError(ValueError):
    """The comparison file, or one of its studies, is wrong; the message names the file and the field."""


@dataclass(frozen=True)
class Comparison:
    """A checked comparison: ``studies`` in the file's order, ``reference`` one of them."""

    path: Path
    name: str
    description: str
    studies: tuple[StudySpec, ...]
    reference: StudySpec

    @property
    def budget(self) -> int:
        """Episodes each method is tuned on: trials x scenarios x training seeds (the same for every study)."""
        spec = self.reference
        return spec.trials * len(spec.scenarios) * spec.train.count


def find_comparison_file(name_or_path: str) -> Path:
    """``conf/tune/compare/<name>.yaml`` for a bare name, else the path as given."""
    return find_study_file(name_or_path, COMPARISON_DIR)


def study_path(entry: str, comparison_path: Path) -> Path:
    """A ``studies`` entry's study file: ``conf/tune/<name>.yaml`` for a bare name, else a path relative to the
    comparison file's folder."""
    path = find_study_file(entry)
    return path if path.is_absolute() else comparison_path.parent / path


def _objectives_text(spec: StudySpec) -> str:
    return "; ".join(f"{o.name} {o.direction} {dict(o.terms)} fill {dict(o.fill)}" for o in spec.objectives)


def _same_setup(spec: StudySpec, ref: StudySpec, comparison: str) -> None:
    """That ``spec`` is tuned and evaluated as ``ref`` is (one line naming ``spec``'s file and field if not)."""
    budget = f"every study of comparison {comparison} needs the same"
    if set(spec.scenarios) != set(ref.scenarios):
        names = [", ".join(map(repr, s.scenarios))[:150] for s in (spec, ref)]  # repr: a name may hold a newline
        raise ComparisonFileError(f"{spec.path}: scenarios: {names[0]} differ from {ref.path}'s {names[1]}: {budget} "
                                  "scenarios")
    for field, words, mine, theirs in (("train_seeds", "training seeds", spec.train, ref.train),
                                       ("heldout_seeds", "held-out seeds", spec.heldout, ref.heldout)):
        if mine != theirs:
            raise ComparisonFileError(f"{spec.path}: {field}: {mine.text()} differ from {ref.path}'s {theirs.text()}: "
                                      f"{budget} {words}")
    if spec.trials != ref.trials:
        episodes = len(spec.scenarios) * spec.train.count
        raise ComparisonFileError(
            f"{spec.path}: trials: {spec.trials} x {episodes} episodes = {spec.trials * episodes} episodes differ "
            f"from {ref.path}'s {ref.trials} x {episodes} = {ref.trials * episodes}: {budget} budget of episodes")
    if spec.objectives != ref.objectives:
        raise ComparisonFileError(f"{spec.path}: objectives: {_objectives_text(spec)[:150]} differ from {ref.path}'s "
                                  f"{_objectives_text(ref)[:150]}: {budget} objectives")


def check_studies(studies: tuple[StudySpec, ...], comparison: str) -> None:
    """Before any trial: no study's training seed among any study's held-out seeds, and every study with the
    first one's setup (scenarios, seeds, trials, objectives)."""
    for spec in studies:
        for other in studies:
            overlap = set(spec.train.seeds).intersection(other.heldout.seeds)
            if overlap:
                raise ComparisonFileError(
                    f"{spec.path}: train_seeds: {spec.train.text()} overlap the held-out seeds {other.heldout.text()} "
                    f"of {other.path} (seed {min(overlap)}): held-out results must come from seeds no study saw")
    for spec in studies[1:]:
        _same_setup(spec, studies[0], comparison)


def comparison_from_data(data: Any, path: Path, trials: int | None = None) -> Comparison:
    """Check a comparison file's parsed content and load its studies (``trials``: the command's ``--trials``,
    which replaces every study's)."""
    if not isinstance(data, Mapping):
        raise ComparisonFileError(f"{path}: expected a mapping of {', '.join(FIELDS)}")
    unknown = [str(k) for k in data if k not in FIELDS]
    if unknown:
        raise ComparisonFileError(f"{path}: {unknown[0][:60]!r}: unknown field (known: {', '.join(FIELDS)})")
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name.replace("-", "_").isidentifier():
        raise ComparisonFileError(f"{path}: name: expected a name (letters, digits, _ and -), got {str(name)[:40]!r}")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise ComparisonFileError(f"{path}: description: expected text")
    entries = data.get("studies")
    if entries is None:
        raise ComparisonFileError(f"{path}: studies: missing (a list of study names or files)")
    if isinstance(entries, str) or not isinstance(entries, list) or not entries:
        raise ComparisonFileError(f"{path}: studies: expected a non-empty list of study names or files")
    if len(entries) > MAX_STUDIES:
        raise ComparisonFileError(f"{path}: studies: {len(entries)} studies, above the limit {MAX_STUDIES}")
    studies: list[StudySpec] = []
    for i, entry in enumerate(entries):
        if not isinstance(entry, str) or not entry.strip() or not entry.isprintable():
            raise ComparisonFileError(f"{path}: studies[{i}]: expected a study name or file, got {str(entry)[:40]!r}")
        try:
            spec = load_study_file(study_path(entry, path))
        except StudyFileError as err:
            raise ComparisonFileError(f"{path}: studies[{i}]: {' '.join(str(err).split())}") from None
        if trials is not None:
            spec = replace(spec, trials=trials)
        for j, seen in enumerate(studies):
            if seen.name == spec.name:
                raise ComparisonFileError(f"{path}: studies[{i}]: study {spec.name!r} ({spec.path}) is also "
                                          f"studies[{j}] ({seen.path}): each study once, each with its own name")
        studies.append(spec)
    reference = data.get("reference", studies[0].name)
    chosen = [s for s in studies if s.name == reference]
    if not isinstance(reference, str) or not chosen:
        raise ComparisonFileError(f"{path}: reference: expected the name of one of its studies "
                                  f"({', '.join(s.name for s in studies)[:200]}), got {str(reference)[:40]!r}")
    ordered = (chosen[0], *[s for s in studies if s is not chosen[0]])  # checked against the reference
    try:
        check_studies(ordered, name)
    except ComparisonFileError as err:
        raise ComparisonFileError(f"{err} (comparison {path})") from None
    return Comparison(path, name, description, tuple(studies), chosen[0])


def load_comparison(path: Path, trials: int | None = None) -> Comparison:
    """Read and check a comparison file and its studies (size, YAML safety, every field)."""
    try:
        raw = check_data_file(path, CONFIG_FILE)
    except DataFileError as err:
        raise ComparisonFileError(" ".join(str(err).split())) from None
    try:
        data = yaml.safe_load(raw)
    except yaml.YAMLError as err:
        raise ComparisonFileError(f"{path}: YAML error: {str(err).splitlines()[0]}") from None
    return comparison_from_data(data, path, trials)
