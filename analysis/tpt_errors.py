"""How well the Trajectory Prediction Table predicted the moving obstacles, from the log alone: average and final
displacement error (ADE, FDE; cm) of its obstacle rows against the logged truth, for all obstacles and per
obstacle model (the constant-velocity prediction fits scripted obstacles by construction; reactive pedestrians
turn and slow down).

An obstacle's model is the ``model`` of its entry in the logged scenario (metadata ``scenario_yaml``;
``scripted`` where the entry names none, or where the log has no readable scenario — every log written before
obstacle models had only scripted obstacles; the log check refuses a scenario whose obstacles are not the log's).

Per-model columns (:func:`model_columns`): ``tpt_ade_cm_<model>`` and ``tpt_fde_cm_<model>`` for each model of
:data:`STANDING_MODELS`, in every row, and for every other model that a log's scenario names (a plug-in model), in
the rows of the logs that name it (a table's other rows have NaN there, as for a model without predictions).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from itertools import chain
from operator import itemgetter
from typing import Any

import numpy as np

from analysis.episode_check import parse_world
from analysis.episode_log import EpisodeLog
from fuzzynav.numerics.portable_math import norm2
from fuzzynav.params.names import DEFAULT_MODEL, NAME

#: the models whose columns every metrics row has, NaN where the episode has no predictions of them: fuzzynav's
#: built-in models when the per-model columns came (issue #17). The datasets' manifests hash these columns and a
#: verify fails on a column that is no longer computed, so they stay even where no log has such obstacles
STANDING_MODELS = ("scripted", "social_force", "orca", "random_walk")
ADE_PREFIX, FDE_PREFIX = "tpt_ade_cm_", "tpt_fde_cm_"  # + the model's name: its columns
_XY = itemgetter("x_cm", "y_cm")


def obstacle_models(meta: Mapping[str, str]) -> dict[str, str]:
    """Obstacle id -> model name from the logged scenario; {} when the log has no readable scenario."""
    world = parse_world(meta.get("scenario_yaml", ""))
    entries = world.get("dynamic_obstacles") if isinstance(world, dict) else None
    if not isinstance(entries, list):
        return {}
    out = {}
    for entry in entries:
        if isinstance(entry, dict) and isinstance(entry.get("id"), str):
            model = entry.get("model")
            out[entry["id"]] = model if isinstance(model, str) else DEFAULT_MODEL
    return out


def tpt_errors(log: EpisodeLog) -> tuple[float, float, dict[str, tuple[float, float]]]:
    """(ADE, FDE) in cm over all predicted obstacles, and per obstacle model. Each predicted obstacle is matched to
    the nearest true obstacle at the table's time (within its radius + 50 cm; the first of equally near ones); rows
    past the end of the episode are not scored. NaN where nothing was predicted.

    The tables of one shape (rows x obstacle columns) are scored together as arrays; the means are correctly
    rounded sums (``math.fsum``), so they do not depend on that order."""
    nan = (math.nan, math.nan)
    if not log.tpts or not log.truth:
        return *nan, {}
    obstacles = scored_tables(log)
    if obstacles is None:
        return *nan, {}
    errors: dict[str, list[np.ndarray]] = {}
    finals: dict[str, list[np.ndarray]] = {}
    for scored in obstacles.scored:
        for model, errs, final in _score(scored, obstacles.model_of):
            errors.setdefault(model, []).append(errs)
            finals.setdefault(model, []).append(final)
    if not errors:
        return *nan, {}
    by_model = {m: _mean(errors[m]) for m in errors}
    finals_by_model = {m: _mean(finals[m]) for m in finals}
    return (_mean([e for es in errors.values() for e in es]), _mean([f for fs in finals.values() for f in fs]),
            {m: (by_model[m], finals_by_model[m]) for m in by_model})


@dataclass(frozen=True)
class ScoredTables:
    """The tables of one shape (``rows`` rows x obstacle columns) matched to the logged truth (:func:`tpt_errors`).
    ``step`` (tables,): each table's step; ``match`` (tables, k): the true obstacle of each column; ``errs``
    (tables, rows - 1, k): cm between row h's prediction and the matched obstacle's true position h steps later;
    ``counted`` (tables, rows - 1, k): the errors that are scored (matched, within the episode, the obstacle
    present); ``final`` (tables, k) the error of the last scored row, scored where ``has_final``."""

    step: np.ndarray
    match: np.ndarray
    errs: np.ndarray
    counted: np.ndarray
    final: np.ndarray
    has_final: np.ndarray


@dataclass(frozen=True)
class MatchedObstacles:
    """A log's TPT tables matched to its truth: ``ids`` the true obstacles (in the truth's column order),
    ``model_of`` each one's model, ``truth`` (steps, obstacles, 2) cm (inf where absent), ``scored`` per shape."""

    ids: list[str]
    model_of: np.ndarray
    truth: np.ndarray
    scored: list[ScoredTables]


def scored_tables(log: EpisodeLog) -> MatchedObstacles | None:
    """The log's TPT tables matched to the logged truth, one :class:`ScoredTables` per table shape; None when the
    log has no tables or no obstacles. Each predicted obstacle is matched to the nearest true obstacle at the
    table's time (within its radius + 50 cm; the first of equally near ones); rows past the end of the episode are
    not scored."""
    if not log.tpts or not log.truth:
        return None
    ids = [o["id"] for o in log.truth[0]["obstacles"]]  # the same obstacles at every step (the log check)
    last = {oid: j for j, oid in enumerate(ids)}  # an id given twice: its last entry, as a dict of the step keeps
    if not last:
        return None
    columns = list(last.values())
    truth = _pairs([list(map(_XY, m["obstacles"])) for m in log.truth], len(ids))
    absent = [(k, j) for k, m in enumerate(log.truth) for j, o in enumerate(m["obstacles"])
              if not o.get("present", True)]
    if absent:  # nowhere: matched to no table column, and the rows predicting it after it left are not scored
        steps, rows = zip(*absent, strict=True)
        truth[list(steps), list(rows)] = math.inf
    truth = truth[:, columns]  # (steps, obstacles, 2)
    models = obstacle_models(log.meta)
    model_of = np.array([models.get(oid, DEFAULT_MODEL) for oid in last])
    by_shape: dict[tuple[int, int], list[dict[str, Any]]] = {}
    for step, t in log.tpts.items():
        if step < len(truth) and t["obstacle_radii_cm"]:
            by_shape.setdefault((len(t["obstacles_cm"]), len(t["obstacle_radii_cm"])), []).append(t)
    scored = [_match(truth, tables, rows, k) for (rows, k), tables in by_shape.items() if rows >= 2]
    return MatchedObstacles(list(last), model_of, truth, scored)


def _match(truth: np.ndarray, tables: list[dict[str, Any]], rows: int, k: int) -> ScoredTables:
    """:class:`ScoredTables` of ``tables`` of ``rows`` (>= 2: a table of the present only predicts nothing) rows
    and ``k`` obstacle columns, all within the truth's steps. ``truth``: (steps, obstacles, 2) cm."""
    n_steps = len(truth)
    step = np.array([t["step"] for t in tables])
    predicted = _table_pairs([t["obstacles_cm"] for t in tables], k).reshape(len(tables), rows, k, 2)
    radius = np.array([t["obstacle_radii_cm"] for t in tables], dtype=float)  # (tables, k)
    now = truth[step]  # (tables, obstacles, 2)
    d0 = norm2(now[:, None, :, :] - predicted[:, 0, :, None, :])  # (tables, k, obstacles)
    match = np.argmin(d0, axis=2)  # (tables, k)
    near = np.take_along_axis(d0, match[..., None], axis=2)[..., 0] <= radius + 50.0
    scored = np.minimum(rows - 1, n_steps - 1 - step)  # rows after the table's own that the truth still covers
    ahead = np.arange(1, rows)
    at = np.minimum(step[:, None] + ahead[None, :], n_steps - 1)  # (tables, rows - 1), clipped where unscored
    actual = truth[at[:, :, None], match[:, None, :]]  # (tables, rows - 1, k, 2)
    errs = norm2(predicted[:, 1:] - actual)  # (tables, rows - 1, k)
    # an absent obstacle's truth is inf (tpt_errors): its rows are not scored
    counted = (ahead[None, :] <= scored[:, None])[:, :, None] & near[:, None, :] & np.isfinite(errs)
    has_final = near & (scored >= 1)[:, None]  # (tables, k)
    final = np.take_along_axis(errs, np.maximum(scored - 1, 0)[:, None, None], axis=1)[:, 0, :]  # (tables, k)
    has_final &= np.isfinite(final)
    return ScoredTables(step, match, errs, counted, final, has_final)


def _score(scored: ScoredTables, model_of: np.ndarray):
    """Yield (model, displacement errors, final errors) in cm of one shape's tables; ``model_of``: per obstacle."""
    model = model_of[scored.match]  # (tables, k)
    for name in dict.fromkeys(model[scored.has_final].tolist()):
        mine = model == name
        yield name, scored.errs[scored.counted & mine[:, None, :]], scored.final[scored.has_final & mine]


def _pairs(rows: list[list[Any]], k: int) -> np.ndarray:
    """(len(rows), k, 2) float array (cm) of rows of ``k`` [x, y] pairs each (checked by the log check): the same
    values as ``np.array(rows, dtype=float)``, read flat (numpy's discovery of a nested list's shape cost half of
    the TPT scoring)."""
    if set(map(len, rows)) - {k}:
        raise ValueError(f"rows of {sorted(set(map(len, rows)))} pairs, expected {k}")
    flat = chain.from_iterable(chain.from_iterable(rows))
    return np.fromiter(flat, dtype=float, count=2 * k * len(rows)).reshape(len(rows), k, 2)


def _table_pairs(tables: list[list[Any]], k: int) -> np.ndarray:
    """The (rows of all ``tables``, k, 2) float array (cm) of tables of rows of ``k`` [x, y] pairs (checked by the
    log check): :func:`_pairs` of their rows."""
    return _pairs(list(chain.from_iterable(tables)), k)


def _mean(parts: list[np.ndarray]) -> float:
    values = list(chain.from_iterable(part.tolist() for part in parts))
    return math.fsum(values) / len(values)


def model_columns(by_model: Mapping[str, tuple[float, float]], models: Iterable[str] = ()) -> dict[str, Any]:
    """The per-model columns of an episode's metrics row: ``by_model`` (:func:`tpt_errors`) for the models of
    :data:`STANDING_MODELS`, then for the other ``models`` (those the log's scenario names: :func:`obstacle_models`)
    and the others of ``by_model``, by name; NaN for a model without predictions. A model whose name is not a
    model's (:data:`fuzzynav.params.names.NAME`: only a hand-made log has one) has no columns: its obstacles count
    in ``tpt_ade_cm`` and ``tpt_fde_cm`` only."""
    others = sorted(m for m in {*models, *by_model} if m not in STANDING_MODELS and NAME.fullmatch(m))
    row: dict[str, Any] = {}
    for model in (*STANDING_MODELS, *others):
        ade, fde = by_model.get(model, (math.nan, math.nan))
        row[ADE_PREFIX + model], row[FDE_PREFIX + model] = ade, fde
    return row


def models_of_columns(columns: Iterable[object]) -> list[str]:
    """The models that have per-model columns among ``columns`` (a metrics table's), in the columns' order."""
    return [str(c)[len(ADE_PREFIX):] for c in columns if str(c).startswith(ADE_PREFIX)]
