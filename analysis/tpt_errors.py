"""How well the Trajectory Prediction Table predicted the moving obstacles, from the log alone: average and final
displacement error (ADE, FDE; cm) of its obstacle rows against the logged truth, for all obstacles and per
obstacle model (the constant-velocity prediction fits scripted obstacles by construction; reactive pedestrians
turn and slow down).

An obstacle's model is the ``model`` of its entry in the logged scenario (metadata ``scenario_yaml``;
``scripted`` where the entry names none, or where the log has no readable scenario — every log written before
obstacle models had only scripted obstacles; the log check refuses a scenario whose obstacles are not the log's).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from analysis.episode_check import parse_world
from analysis.episode_log import EpisodeLog
from fuzzynav.obstacle_model import DEFAULT_MODEL
from fuzzynav.portable_math import norm2

#: the models whose errors have their own columns (``tpt_ade_cm_<model>``, ``tpt_fde_cm_<model>``): fuzzynav's
#: built-ins; an obstacle of another model counts in ``tpt_ade_cm`` only
MODEL_COLUMNS = ("scripted", "social_force", "orca", "random_walk")


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
    the nearest true obstacle at the table's time (within its radius + 50 cm); rows past the end of the episode
    are not scored. NaN where nothing was predicted."""
    nan = (math.nan, math.nan)
    if not log.tpts or not log.truth:
        return *nan, {}
    models = obstacle_models(log.meta)
    truth_at = {m["step"]: {o["id"]: (o["x_cm"], o["y_cm"]) for o in m["obstacles"]} for m in log.truth}
    errors: dict[str, list[float]] = {}
    finals: dict[str, list[float]] = {}
    for step, t in log.tpts.items():
        now = truth_at.get(step)
        if not now:
            continue
        ids = list(now)
        true_now = np.array([now[i] for i in ids])
        predicted = np.array(t["obstacles_cm"], dtype=float).reshape(len(t["obstacles_cm"]), -1, 2)  # (rows, K, 2)
        for j, radius in enumerate(t["obstacle_radii_cm"]):
            pred = predicted[:, j]  # (n_traj + 1, 2)
            d0 = norm2(true_now - pred[0])
            match = int(np.argmin(d0))
            if d0[match] > radius + 50.0:
                continue
            oid = ids[match]
            rows = [k for k in range(1, len(pred)) if oid in truth_at.get(step + k, {})]
            if rows:
                actual = np.array([truth_at[step + k][oid] for k in rows])
                errs = norm2(pred[rows] - actual)
                model = models.get(oid, DEFAULT_MODEL)
                errors.setdefault(model, []).extend(errs.tolist())
                finals.setdefault(model, []).append(float(errs[-1]))
    if not errors:
        return *nan, {}
    every = [e for errs in errors.values() for e in errs]
    every_final = [f for fs in finals.values() for f in fs]
    by_model = {m: (math.fsum(errors[m]) / len(errors[m]), math.fsum(finals[m]) / len(finals[m]))
                for m in errors}
    return math.fsum(every) / len(every), math.fsum(every_final) / len(every_final), by_model


def model_columns(by_model: Mapping[str, tuple[float, float]]) -> dict[str, Any]:
    """The per-model columns of an episode's metrics row (NaN for models it has no predictions of)."""
    row: dict[str, Any] = {}
    for model in MODEL_COLUMNS:
        ade, fde = by_model.get(model, (math.nan, math.nan))
        row[f"tpt_ade_cm_{model}"], row[f"tpt_fde_cm_{model}"] = ade, fde
    return row
