"""Per-episode metrics computed from a log alone (definitions in the README, units in the column names).

``metrics_table(paths)`` gives one row per readable, finished episode plus a list of the logs left out, each
with its ``kind`` (:data:`analysis.logs.LEFT_OUT_KINDS`: a copy of another log, not a regular file, a CRC or
schema check that failed, truncated, outcome ``error``/``interrupted``, ...) and the reason.
``analyse_logs(paths)`` adds each episode's group (:mod:`analysis.run_parameters`): what the report and the
sweep's summary pool.
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import shapely

from analysis.episode_log import EpisodeLog, load_episode
from analysis.logs import SKIPPED_KINDS, LogError, find_logs, read_logs
from analysis.run_parameters import EPISODE_PARAMETERS, Grouping, find_grouping, is_success, parameters_of
from fuzzynav.geometry import swept_distance, wrap_180
from fuzzynav.portable_math import dist, norm2

PARAMETERS = EPISODE_PARAMETERS
EXCLUDED_OUTCOMES = ("error", "interrupted", "incomplete")
RUN_PARAMETERS = "run_parameters"  # transport column: the log's parameters as JSON (dropped from the tables)


@dataclass(frozen=True)
class MetricOptions:
    """``turn_threshold_deg``: smallest heading change (degrees per step) that counts towards a turn."""

    turn_threshold_deg: float = 5.0


def turn_count(heading_changes_deg: np.ndarray, threshold_deg: float = 5.0) -> int:
    """Maximal runs of consecutive steps whose heading change has the same sign and |change| >= threshold."""
    sign = np.where(np.abs(heading_changes_deg) >= threshold_deg, np.sign(heading_changes_deg), 0)
    starts = (sign != 0) & (np.concatenate([[0], sign[:-1]]) != sign)
    return int(starts.sum())


def _static_gaps(solid: shapely.Geometry, pos: np.ndarray, steps: int) -> np.ndarray:
    """Per step, the distance (cm) from the static world to the robot centre's straight move ``pos[k]`` ->
    ``pos[k + 1]`` (a point when the robot stood still), all steps in one vectorised shapely call."""
    if steps == 0 or solid.is_empty:
        return np.full(steps, math.inf)
    p0, p1 = pos[:steps], pos[1:steps + 1]
    still = norm2(p1 - p0) < 1e-9  # as the simulator decides between a point and a segment
    paths = np.empty(steps, dtype=object)
    paths[still] = shapely.points(p1[still])
    paths[~still] = shapely.linestrings(np.stack([p0[~still], p1[~still]], axis=1))
    shapely.prepare(solid)
    return shapely.distance(solid, paths)


def _dynamic_gaps(truth: list[dict[str, Any]], pos: np.ndarray, radius: float, steps: int
                  ) -> tuple[float, list[set[str]]]:
    """Smallest surface gap (cm) to any moving obstacle over the episode, and per step the ids of the
    obstacles touched while both moved straight over the step (all (step, obstacle) pairs at once)."""
    pairs = [(k, o) for k in range(min(steps, len(truth))) for o in truth[k]["obstacles"]]
    touching: list[set[str]] = [set() for _ in range(steps)]
    if not pairs:
        return math.inf, touching
    k = np.array([p[0] for p in pairs])
    o0 = np.array([(o["x_cm"], o["y_cm"]) for _, o in pairs])
    o1 = np.array([(o["next_x_cm"], o["next_y_cm"]) for _, o in pairs])
    radii = np.array([o["radius_cm"] for _, o in pairs])
    gaps = swept_distance(pos[k], pos[k + 1], o0, o1) - radius - radii
    for i in np.nonzero(gaps < -1e-9)[0]:
        touching[k[i]].add(pairs[i][1]["id"])
    return float(gaps.min()), touching


def _contacts(touching: list[set[str]]) -> int:
    """Contact events: each id counts when it enters contact (was not touching on the previous step)."""
    count, before = 0, set()
    for now in touching:
        count += len(now - before)
        before = now
    return count


def episode_metrics(log: EpisodeLog, options: MetricOptions | None = None) -> dict[str, Any]:
    """All metrics of one episode (see the README for the definitions)."""
    opt = options or MetricOptions()
    pos = log.positions
    r = log.robot_radius
    row: dict[str, Any] = {p: log.meta.get(p) for p in PARAMETERS}
    row["h_wait"] = int(row["h_wait"]) if row["h_wait"] not in (None, "") else None
    row["seed"] = int(row["seed"]) if row["seed"] not in (None, "") else None
    row.update(log=str(log.path), outcome=log.outcome, steps=log.steps)
    seg = norm2(np.diff(pos, axis=0)) if len(pos) > 1 else np.zeros(0)
    row["path_length_cm"] = math.fsum(seg.tolist())
    dh = wrap_180(np.diff(log.headings)) if len(pos) > 1 else np.zeros(0)
    row["turn_count"] = turn_count(dh, opt.turn_threshold_deg)
    row["heading_change_deg_total"] = math.fsum(np.abs(dh).tolist())

    # contacts recomputed from the logged geometry (swept over each step, as the simulator does)
    steps = len(log.states)
    gap_static = _static_gaps(log.static_geometry(), pos, steps) - r
    touching_static = [{"static"} if g < -1e-9 else set() for g in gap_static]
    gap_dynamic, touching_dynamic = _dynamic_gaps(log.truth, pos, r, steps)
    flags_static = [{"static"} if st["contact_static"] else set() for st in log.states]
    flags_dynamic = [set(st["contact_dynamic"]) for st in log.states]
    row["collisions_static"] = _contacts(touching_static)
    row["collisions_dynamic"] = _contacts(touching_dynamic)
    logged = (_contacts(flags_static), _contacts(flags_dynamic))
    row["collision_check_agrees"] = logged == (row["collisions_static"], row["collisions_dynamic"])
    row["collisions_logged_static"], row["collisions_logged_dynamic"] = logged
    row["min_clearance_static_cm"] = float(gap_static.min()) if len(gap_static) and np.isfinite(gap_static.min()) \
        else math.nan
    row["min_clearance_dynamic_cm"] = gap_dynamic if math.isfinite(gap_dynamic) else math.nan

    # goal
    t_goal = math.nan
    if log.goal is not None and log.goal_tolerance is not None and len(pos) > 1:
        reached = np.nonzero(norm2(pos[1:] - np.array(log.goal)) <= log.goal_tolerance + 1e-6)[0]
        if len(reached):
            t_goal = float((reached[0] + 1) * log.dt)
    row["time_to_goal_s"] = t_goal
    row["success"] = is_success(log.outcome, row["collisions_static"] + row["collisions_dynamic"], t_goal)
    straight = dist(log.goal, pos[0]) if log.goal is not None and len(pos) else math.nan
    row["path_efficiency"] = straight / row["path_length_cm"] if row["success"] and row["path_length_cm"] > 0 \
        else math.nan

    # planner
    modes = [d["mode"] for d in log.decisions]
    speeds = np.array([d["v_cm_s"] for d in log.decisions]) if log.decisions else np.zeros(0)
    row["wait_steps"] = int(sum(1 for m, v in zip(modes, speeds, strict=True) if m in ("wait", "stop") and v == 0))
    plans = [d["planning"] for d in log.decisions if d.get("planning")]
    row["detour_count"] = sum(1 for p in plans if p["strategy"] == "detour")
    row["plans_made"] = len(plans)
    row["detour_extra_length_cm"] = _detour_extra(pos, modes)
    row["tpt_collisions_predicted"] = sum(1 for t in log.tpts.values() if any(any(r_) for r_ in t["collide"][1:]))
    ade, fde = _tpt_errors(log)
    row["tpt_ade_cm"], row["tpt_fde_cm"] = ade, fde
    times = np.array([d["compute_time_us"] for d in log.decisions]) if log.decisions else np.zeros(0)
    row["compute_time_us_median"] = float(np.median(times)) if len(times) else math.nan
    row["compute_time_us_p99"] = float(np.percentile(times, 99)) if len(times) else math.nan
    return row


def _detour_extra(pos: np.ndarray, modes: list[str]) -> float:
    """For each maximal run of detour steps: executed length minus the straight line between its ends."""
    extra, k = 0.0, 0
    while k < len(modes):
        if modes[k] != "detour":
            k += 1
            continue
        j = k
        while j < len(modes) and modes[j] == "detour":
            j += 1
        run = pos[k:j + 1]
        extra += math.fsum(norm2(np.diff(run, axis=0)).tolist()) - dist(run[-1], run[0])
        k = j
    return extra


def _tpt_errors(log: EpisodeLog) -> tuple[float, float]:
    """Average and final displacement error (cm) of the table's obstacle predictions against the logged
    truth: each predicted obstacle is matched to the nearest true obstacle at the table's time (within
    its radius + 50 cm); rows past the end of the episode are not scored."""
    if not log.tpts or not log.truth:
        return math.nan, math.nan
    truth_at = {m["step"]: {o["id"]: (o["x_cm"], o["y_cm"]) for o in m["obstacles"]} for m in log.truth}
    errors, finals = [], []
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
                errors.extend(errs.tolist())
                finals.append(float(errs[-1]))
    return (math.fsum(errors) / len(errors), math.fsum(finals) / len(finals)) if errors else (math.nan, math.nan)


def _metrics_rows(paths: list[Path], options: MetricOptions | None) -> tuple[list[dict], list[dict]]:
    """Metrics rows of the usable logs among ``paths``, in order, and the logs left out with their outcome (when
    unread: ``skipped`` on purpose — a copy, a conflict, not a regular file — else ``unreadable``), their ``kind``
    and the reason. Each row and left-out log whose metadata could be read
    carries its run parameters as JSON text in ``RUN_PARAMETERS``: identical texts (episodes of one
    configuration) are one object, so a worker sends each configuration once per chunk."""
    rows, excluded = [], []
    texts: dict[str, str] = {}

    def parameters(log: EpisodeLog) -> str:
        text = json.dumps(parameters_of(log.meta, log.config), default=str)
        return texts.setdefault(text, text)

    def seed(log: EpisodeLog) -> int | None:
        try:
            return int(log.meta["seed"])
        except (KeyError, ValueError):
            return None

    for path in paths:
        try:
            log = load_episode(path)
        except LogError as err:
            excluded.append({"log": str(path), "outcome": "skipped" if err.kind in SKIPPED_KINDS else "unreadable",
                             "kind": err.kind, "reason": str(err)})
            continue
        if not log.complete:
            excluded.append({"log": str(path), "outcome": log.outcome, RUN_PARAMETERS: parameters(log),
                             "seed": seed(log), "kind": "truncated",
                             "reason": "truncated: the file ends before the MCAP summary "
                             f"(killed run or damaged copy; {log.steps} steps readable, outcome {log.outcome})"})
            continue
        if log.outcome in EXCLUDED_OUTCOMES:
            why = {"incomplete": "truncated: no /episode outcome (killed run?)",
                   "error": f"episode raised: {(log.episode or {}).get('reason', '')}",
                   "interrupted": "episode interrupted"}[log.outcome]
            excluded.append({"log": str(path), "outcome": log.outcome, RUN_PARAMETERS: parameters(log),
                             "seed": seed(log), "kind": log.outcome, "reason": why})
            continue
        row = episode_metrics(log, options)
        row[RUN_PARAMETERS] = parameters(log)
        rows.append(row)
    return rows, excluded


def _read(paths: Iterable[str | Path], options: MetricOptions | None, jobs: int) -> tuple[list[dict], list[dict]]:
    parts = read_logs(functools.partial(_metrics_rows, options=options), find_logs(paths), jobs)
    return [r for rows, _ in parts for r in rows], [e for _, excluded in parts for e in excluded]


def metrics_table(paths: Iterable[str | Path], options: MetricOptions | None = None, jobs: int = 1
                  ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(one row per usable episode, logs left out with the reason), in the order of :func:`find_logs`.

    ``jobs`` > 1 (or -1: every core) reads the logs in that many worker processes when there are many
    (:func:`analysis.logs.read_logs`); the result is the same as with ``jobs=1``."""
    rows, excluded = _read(paths, options, jobs)
    table = pd.DataFrame(rows)
    return (table.drop(columns=[RUN_PARAMETERS], errors="ignore"),
            pd.DataFrame(excluded, columns=["log", "kind", "reason"]))


@dataclass
class Analysis:
    """Episodes of a set of logs with their groups: ``episodes`` has the metrics, each group dimension's value
    (full key), ``scenario_label``, ``variant`` and ``setting`` (see :class:`Grouping`), rows in the groups'
    natural order then by seed; ``excluded`` the logs left out (log, outcome, kind, reason, and their labels
    when the metadata was readable); ``runs`` one parameter dict per episode row."""

    episodes: pd.DataFrame
    excluded: pd.DataFrame
    grouping: Grouping
    runs: list[dict[str, Any]]


def analyse_logs(paths: Iterable[str | Path], options: MetricOptions | None = None, jobs: int = 1,
                 split_provenance: bool = False) -> Analysis:
    """Metrics of every usable log and the group of each episode. The grouping is found over every log whose
    metadata is readable (left-out ones too, so that the summary can count them in their group)."""
    rows, excluded = _read(paths, options, jobs)
    distinct = {text: json.loads(text) for text in {r[RUN_PARAMETERS] for r in rows + excluded if RUN_PARAMETERS in r}}
    grouping = find_grouping(list(distinct.values()), split_provenance)
    labels = {text: grouping.columns(run) for text, run in distinct.items()}
    order = {text: rank for rank, text in enumerate(sorted(distinct, key=lambda t: grouping.sort_key(distinct[t])))}
    rows.sort(key=lambda r: (order[r[RUN_PARAMETERS]], r["seed"] if r["seed"] is not None else -1, r["log"]))
    runs = [distinct[r[RUN_PARAMETERS]] for r in rows]
    episodes = pd.DataFrame([{**{k: v for k, v in r.items() if k != RUN_PARAMETERS}, **labels[r[RUN_PARAMETERS]]}
                             for r in rows])
    left_out = pd.DataFrame([{"log": e["log"], "outcome": e["outcome"], **_left_out_labels(e, distinct, labels),
                              "kind": e["kind"], "reason": e["reason"]} for e in excluded],
                            columns=["log", "outcome", *EPISODE_PARAMETERS, "scenario_label", "variant", "kind",
                                     "reason"])
    return Analysis(episodes, left_out, grouping, runs)


def left_out_counts(excluded: pd.DataFrame) -> str:
    """How many logs were left out of each kind, most first: ``2 duplicate, 1 crc`` (empty when none)."""
    if excluded.empty or "kind" not in excluded:
        return ""
    counts = excluded["kind"].value_counts(sort=False)
    return ", ".join(f"{n} {kind}" for kind, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def _left_out_labels(entry: dict, distinct: dict[str, dict], labels: dict[str, dict]) -> dict[str, Any]:
    """Shown parameters and group labels of a left-out log (empty when its metadata was unreadable)."""
    text = entry.get(RUN_PARAMETERS)
    if text is None:
        return {}
    run = distinct[text]
    return {**{k: run.get(k) for k in EPISODE_PARAMETERS if k != "seed"}, "seed": entry.get("seed"),
            "scenario_label": labels[text]["scenario_label"], "variant": labels[text]["variant"]}
