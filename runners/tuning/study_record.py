"""What a study is: the study file's fields that its trials' scores depend on, recorded in the study's storage
(the Optuna study's ``definition`` user attribute) when the study is created, and compared with the study file
each time the study is opened again.

A resumed study adds trials to the ones stored; the trials are only comparable (and the best one only the best)
if every trial ran the same scenarios on the same training seeds with the same fixed overrides and search space,
scored by the same objectives. A study file changed in any of those since the study began is refused in one
line naming the file, each field that differs (stored value → file's value) and the fix; otherwise the stored
trials would be reported under the new file's scenarios while their scores come from the old ones.

What may change on resume: ``trials`` (a larger budget extends the study; ``--trials`` does it from the command
line), ``description``, ``sampler`` and ``sampler_seed`` (they choose the points of the trials still to come, not
the scores of the ones stored), and ``heldout_seeds`` (the held-out evaluation runs again from nothing after the
trials, on the file's seeds: it never mixes with the trials). The command's own options (``--workers``,
``--launcher``, ``--no-heldout``) are not part of the study either.

A study created before the record existed has its space, base, objective names and directions stored, but not
its scenarios, training seeds nor objective terms. Such a study is resumed if it is consistent with the file: the
logs of its last completed trial must be the file's scenarios on its training seeds, and scoring them with the
file's objectives must give the stored values; then the record is written, and the study is checked as any other
from then on. If that cannot be confirmed (logs missing) it is refused: a study resumed on a guess would be the
silently wrong result the check exists to prevent.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from optuna.trial import TrialState

from runners.tuning.storage import trial_dir
from runners.tuning.study_file import StudySpec

DEFINITION = "definition"  # the Optuna study's user attribute holding the record
#: the recorded fields, in the study file's order (the error names them in this order)
FIELDS = ("base", "space", "controller_space", "controller_rules", "objectives", "scenarios", "train_seeds")
SHOWN = 80  # characters of a value in the error line


class StudyChangedError(ValueError):
    """The study file no longer describes the study stored in the folder (the message names file and fields)."""


def definition(spec: StudySpec) -> dict[str, Any]:
    """The record of a study file: plain JSON data, as the storage gives it back (lists, not tuples), so that a
    stored record and a fresh one compare equal exactly when the fields are the same."""
    return {
        "base": list(spec.base),
        "space": [p.text for p in spec.space],
        "controller_space": [list(group) for group in spec.controller_space],
        "controller_rules": list(spec.controller_rules),
        "objectives": [{"name": o.name, "direction": o.direction, "terms": [[m, w] for m, w in o.terms],
                        "fill": [[m, v] for m, v in o.fill]} for o in spec.objectives],
        "scenarios": list(spec.scenarios),
        "train_seeds": {"start": spec.train.start, "count": spec.train.count},
    }


def _text(field: str, value: Any) -> str:
    """A field's value as the study file would say it, trimmed for one line."""
    if field == "train_seeds" and isinstance(value, dict) and {"start", "count"} <= set(value):
        text = f"{value['start']}..{value['start'] + value['count'] - 1}"
    elif field == "objectives" and isinstance(value, list):
        text = "; ".join(_objective_text(o) for o in value) if value else "[]"
    elif isinstance(value, list) and all(isinstance(v, str) for v in value):
        text = ", ".join(value) if value else "[]"
    elif isinstance(value, str):
        text = value
    else:
        text = json.dumps(value, separators=(",", ":"))
    return text if len(text) <= SHOWN else text[:SHOWN - 1] + "…"


def _objective_text(objective: Any) -> str:
    if not isinstance(objective, dict):
        return str(objective)
    terms = " ".join(f"{w:+g}*{m}" for m, w in objective.get("terms", []))
    fill = ", ".join(f"{m}={v:g}" for m, v in objective.get("fill", []))
    return f"{objective.get('name')} {objective.get('direction')} {terms}" + (f" fill {fill}" if fill else "")


def differences(stored: dict[str, Any], current: dict[str, Any]) -> list[str]:
    """``field: old → new`` for each field of ``stored`` that ``current`` gives another value (a field the
    stored record lacks is not compared: the legacy check records only what the logs show)."""
    return [f"{field}: {_text(field, stored[field])} → {_text(field, current.get(field))}"
            for field in FIELDS if field in stored and stored[field] != current.get(field)]


def refusal(spec: StudySpec, where: str, changed: list[str]) -> StudyChangedError:
    return StudyChangedError(
        f"{spec.path}: {'; '.join(changed)}: the file differs from the study {spec.name!r} stored in {where}, "
        "whose trials were run and scored with the stored value: restore the file, or use another --out for the "
        "changed study")


def check_resumed(spec: StudySpec, study: Any, study_dir: Path | None) -> bool:
    """Refuse a study file that is not the stored study's (:class:`StudyChangedError`). True when the study has
    no record yet but its logs confirm the file: the caller records it once its own checks pass too."""
    where = str(study_dir) if study_dir is not None else "the study folder"
    current = definition(spec)
    stored = study.user_attrs.get(DEFINITION)
    if isinstance(stored, dict):
        changed = differences(stored, current)
        if changed:
            raise refusal(spec, where, changed)
        return False
    _check_legacy(spec, study, study_dir, where, current)
    return True


def _check_legacy(spec: StudySpec, study: Any, study_dir: Path | None, where: str, current: dict[str, Any]) -> None:
    """A study without a record: what it stored (base, objective names) and what its last completed trial's
    logs show (scenarios, training seeds, the objective values they give) must agree with the file."""
    attrs = study.user_attrs
    changed = differences({"base": attrs["base"]} if "base" in attrs else {}, current)
    names = attrs.get("objectives")
    if names is not None and names != [o.name for o in spec.objectives]:
        changed.append(f"objectives: {_text('', names)} → {_text('', [o.name for o in spec.objectives])}")
    if changed:
        raise refusal(spec, where, changed)
    complete = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE,))
    if not complete or study_dir is None:  # no score stored yet: nothing the file could contradict
        return
    from analysis.metrics import metrics_table
    from analysis.objectives import objective_value

    last = complete[-1]
    logs = sorted(trial_dir(study_dir, last.number).glob("*.mcap"))
    if not logs:
        raise StudyChangedError(
            f"{spec.path}: the study {spec.name!r} in {where} was stored without a record of its study file, and "
            f"the logs of its trial {last.number} ({trial_dir(study_dir, last.number)}) that would confirm the "
            "file's scenarios and seeds are missing: restore them, or use another --out")
    episodes, _ = metrics_table(logs)
    ran = {"scenarios": list(dict.fromkeys(episodes["scenario"])) if not episodes.empty else [],
           "train_seeds": sorted({int(s) for s in episodes["seed"]}) if not episodes.empty else []}
    expected = {(s, seed) for s in spec.scenarios for seed in spec.train.seeds}
    if set(zip(episodes["scenario"], map(int, episodes["seed"]), strict=True)) != expected or \
            len(episodes) != len(expected):
        shown = {"scenarios": ran["scenarios"],
                 "train_seeds": {"start": ran["train_seeds"][0], "count": len(ran["train_seeds"])}
                 if ran["train_seeds"] == list(range(ran["train_seeds"][0], ran["train_seeds"][-1] + 1))
                 else [str(s) for s in ran["train_seeds"]]} if ran["train_seeds"] else ran
        changed = differences(shown, current) or [f"scenarios x train_seeds: trial {last.number}'s logs are "
                                                  f"{len(episodes)} episodes, the file's {len(expected)}"]
        raise refusal(spec, where, [f"{c} (trial {last.number}'s logs)" for c in changed])
    for o, stored_value in zip(spec.objectives, last.values, strict=True):
        value = objective_value(episodes, o)
        if not math.isclose(value, stored_value, rel_tol=1e-9, abs_tol=1e-12):
            raise refusal(spec, where, [f"objectives: {o.name} of trial {last.number} is {stored_value:.6g} "
                                        f"stored → {value:.6g} from its logs by the file's objective"])
