"""The TPT's prediction error on recorded people per horizon step, against the constant-velocity baseline of the
trajectory-prediction benchmarks on the same predictions, from the log alone.

For every prediction of a recorded person (an obstacle of model ``recorded``) by the Trajectory Prediction Table —
a table at step s, an obstacle column matched to the person (:func:`analysis.tpt_errors.scored_tables`), its row h
predicting step s + h — the baseline predicts the same person at the same step: its position at s·dt plus h·dt times
its velocity over the last annotation interval (from the annotations the logged scenario holds: ``waypoints`` and
``model_params.t_s``; the interval is the smallest between two annotations of the scenario, 0.4 s in ETH/UCY), as
``python -m runners.recordings predict`` does on the recording itself. Both are compared with the logged truth.

A prediction is scored at horizon k when its rows 1 … k are all scored by the TPT error (matched, within the
episode, the person present), the person is still a replay at step s + k (not ``reacting``: a reacting person walks
by a model, not as recorded) and the recording has it one annotation interval before s·dt. Per episode and k:
FDE_k, the mean error at row k, and ADE_k, the mean over those predictions of the mean error over rows 1 … k (cm),
each for the table (``tpt``) and the baseline (``cv``), and the number of predictions (:data:`COLUMN_PATTERN`).
Means are correctly rounded sums (``math.fsum``): they do not depend on the order of the tables.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from analysis.episode_check import parse_world
from analysis.episode_log import EpisodeLog
from analysis.tpt_errors import scored_tables
from fuzzynav.numerics.portable_math import norm2

MODEL = "recorded"
PREDICTORS = ("tpt", "cv")
#: the per-episode columns: ``rec_<predictor>_<ade|fde>_cm_h<k>`` (cm) and ``rec_predictions_h<k>`` (a count)
COLUMN_PATTERN = re.compile(r"rec_(?:(tpt|cv)_(ade|fde)_cm|(predictions))_h([1-9][0-9]*)")


def column(predictor: str, error: str, k: int) -> str:
    """The column of ``predictor``'s (``tpt`` | ``cv``) ``error`` (``ade`` | ``fde``) at horizon ``k``."""
    return f"rec_{predictor}_{error}_cm_h{k}"


def count_column(k: int) -> str:
    """The column of the number of predictions scored at horizon ``k``."""
    return f"rec_predictions_h{k}"


def horizons_of_columns(columns: Any) -> list[int]:
    """The horizons k that have columns among ``columns`` (a metrics table's), ascending."""
    return sorted({int(m.group(4)) for c in columns if (m := COLUMN_PATTERN.fullmatch(str(c))) and m.group(3)})


def recorded_tracks(meta: Mapping[str, str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Obstacle id -> (annotation times s, positions (n, 2) cm) of the logged scenario's recorded people; {} when
    the log has none (or no readable scenario)."""
    world = parse_world(meta.get("scenario_yaml", ""))
    entries = world.get("dynamic_obstacles") if isinstance(world, dict) else None
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for entry in entries if isinstance(entries, list) else []:
        if not (isinstance(entry, dict) and entry.get("model") == MODEL and isinstance(entry.get("id"), str)):
            continue
        params = entry.get("model_params") or {}
        t, xy = params.get("t_s") if isinstance(params, dict) else None, entry.get("waypoints")
        try:
            times, points = np.array(t, dtype=float), np.array(xy, dtype=float)
        except (TypeError, ValueError):
            continue  # the log check refuses such a scenario; nothing to score here
        if times.ndim == 1 and len(times) >= 2 and points.shape == (len(times), 2):
            out[entry["id"]] = (times, points)
    return out


def _interval(tracks: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> float:
    """The annotation interval (s): the smallest positive difference between two annotation times of a track."""
    steps = [d for t, _ in tracks.values() for d in np.diff(t).tolist() if d > 1e-9]
    return min(steps) if steps else math.nan


def _at(track: tuple[np.ndarray, np.ndarray], times: np.ndarray) -> np.ndarray:
    t, xy = track
    return np.stack([np.interp(times, t, xy[:, 0]), np.interp(times, t, xy[:, 1])], axis=-1)


def horizon_errors(log: EpisodeLog) -> dict[str, float]:
    """The per-horizon columns of an episode (module docstring); {} when the log has no TPT prediction of a
    recorded person. Every horizon 1 … (longest table − 1) has its columns; NaN where nothing was scored."""
    tracks = recorded_tracks(log.meta)
    if not tracks:
        return {}
    matched = scored_tables(log)
    if matched is None or not matched.scored:
        return {}
    interval = _interval(tracks)
    if not math.isfinite(interval):
        return {}
    reacting = np.array([[bool(o.get("reacting", False)) for o in m["obstacles"]] for m in log.truth], dtype=bool)
    index = {oid: j for j, oid in enumerate(o["id"] for o in log.truth[0]["obstacles"])}
    reacting = reacting[:, [index[oid] for oid in matched.ids]] if len(reacting) else reacting
    horizon = max(s.errs.shape[1] for s in matched.scored)
    sums: dict[tuple[str, str, int], list[float]] = {}
    counts = [0] * horizon
    for scored in matched.scored:
        _baseline(log.dt, matched, scored, tracks, interval, reacting, sums, counts)
    row: dict[str, float] = {}
    if not any(counts):
        return {}
    for k in range(1, horizon + 1):
        n = counts[k - 1]
        for predictor in PREDICTORS:
            for error in ("ade", "fde"):
                values = sums.get((predictor, error, k), [])
                row[column(predictor, error, k)] = math.fsum(values) / n if n else math.nan
        row[count_column(k)] = float(n)
    return row


def _baseline(dt: float, matched: Any, scored: Any, tracks: Mapping[str, tuple[np.ndarray, np.ndarray]],
              interval: float, reacting: np.ndarray, sums: dict[tuple[str, str, int], list[float]],
              counts: list[int]) -> None:
    """Add one shape's scored predictions of recorded people to ``sums`` and ``counts`` (per horizon)."""
    n_tables, n_rows, k = scored.errs.shape
    n_steps = len(matched.truth)
    for i in range(n_tables):
        s = int(scored.step[i])
        now = s * dt
        for c in range(k):
            j = int(scored.match[i, c])
            oid = matched.ids[j]
            if oid not in tracks or matched.model_of[j] != MODEL:
                continue
            t, _ = tracks[oid]
            if now - interval < t[0] - 1e-9 or now > t[-1] + 1e-9:
                continue  # the baseline has no velocity (or the person is not recorded at s·dt)
            ok = scored.counted[i, :, c].copy()
            steps = np.minimum(s + np.arange(1, n_rows + 1), n_steps - 1)
            ok &= ~reacting[steps, j] if len(reacting) else ok
            prefix = np.cumprod(ok).astype(bool)  # rows 1 … h all scored
            if not prefix[0]:
                continue
            last = int(prefix.sum())
            here = _at(tracks[oid], np.array([now]))[0]
            before = _at(tracks[oid], np.array([now - interval]))[0]
            velocity = (here - before) / interval
            ahead = np.arange(1, last + 1) * dt
            cv = here[None, :] + velocity[None, :] * ahead[:, None]
            truth = matched.truth[s + np.arange(1, last + 1), j]
            errors = {"tpt": scored.errs[i, :last, c].tolist(), "cv": norm2(cv - truth).tolist()}
            for h in range(1, last + 1):
                counts[h - 1] += 1
                for predictor, e in errors.items():
                    sums.setdefault((predictor, "fde", h), []).append(e[h - 1])
                    sums.setdefault((predictor, "ade", h), []).append(math.fsum(e[:h]) / h)
