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
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from itertools import chain
from operator import itemgetter
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from analysis.deferred import deferred, load
from analysis.episode_log import EpisodeLog, load_episode
from analysis.file_names import printable
from analysis.horizon_errors import COLUMN_PATTERN, horizon_errors
from analysis.log_inputs import find_logs
from analysis.logs import SKIPPED_KINDS, LogError, RejectedLog, collector_paused, read_logs
from analysis.run_parameters import EPISODE_PARAMETERS, Grouping, find_grouping, is_success, parameters_of
from analysis.tpt_errors import ADE_PREFIX, FDE_PREFIX, STANDING_MODELS, model_columns, obstacle_models, tpt_errors
from analysis.trace import KeptTraces, Trace
from fuzzynav.numerics.geometry import swept_distance, wrap_180
from fuzzynav.numerics.portable_math import bearing_deg, dist, norm2

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

PARAMETERS = EPISODE_PARAMETERS
EXCLUDED_OUTCOMES = ("error", "interrupted", "incomplete")
RUN_PARAMETERS = "run_parameters"  # transport column: the log's parameters as JSON (dropped from the tables)


@dataclass(frozen=True)
class MetricOptions:
    """Thresholds of the metrics (README metric table).

    ``turn_threshold_deg``: smallest heading change (degrees per step) that counts towards a turn;
    ``near_miss_cm``: a step whose clearance to an obstacle is in [0, this) cm is a near miss;
    ``stall_speed_cm_s``: a step moving slower than this (cm/s) away from the goal is stalled;
    ``personal_space_cm``: the personal-space radius beyond a moving obstacle's surface (cm; 45 cm is the edge
    of Hall's intimate zone, the personal-space radius Francis et al. 2023 cite for pedestrians)."""

    turn_threshold_deg: float = 5.0
    near_miss_cm: float = 20.0
    stall_speed_cm_s: float = 1.0
    personal_space_cm: float = 45.0


#: unit of every per-episode column (``""``: a count, a flag, a ratio or a label); the Parquet tables carry it
COLUMN_UNITS: dict[str, str] = {
    "log": "", "outcome": "", "steps": "steps", "path_length_cm": "cm", "turn_count": "turns",
    "heading_change_deg_total": "deg", "collisions_static": "contacts", "collisions_dynamic": "contacts",
    "collision_check_agrees": "", "collisions_logged_static": "contacts", "collisions_logged_dynamic": "contacts",
    "min_clearance_static_cm": "cm", "min_clearance_dynamic_cm": "cm", "time_to_goal_s": "s", "success": "",
    "path_efficiency": "", "wait_steps": "steps", "detour_count": "plans", "plans_made": "plans",
    "detour_extra_length_cm": "cm", "tpt_collisions_predicted": "tables", "tpt_ade_cm": "cm", "tpt_fde_cm": "cm",
    "compute_time_us_median": "us", "compute_time_us_p99": "us", "h_wait": "steps",
    # the standard navigation metrics (issue #18)
    "spl": "", "path_irregularity_deg_per_m": "deg/m", "accel_mean_cm_s2": "cm/s^2", "accel_max_cm_s2": "cm/s^2",
    "jerk_mean_cm_s3": "cm/s^3", "jerk_max_cm_s3": "cm/s^3", "min_ttc_s": "s", "near_miss_steps": "steps",
    "stalled_time_s": "s", "collisions_wall": "contacts", "collisions_static_obstacle": "contacts",
    "personal_space_intrusion_s": "s",
    # TPT prediction error per obstacle model (issue #17); another model's columns too (column_unit)
    **{prefix + model: "cm" for model in STANDING_MODELS for prefix in (ADE_PREFIX, FDE_PREFIX)},
}
#: the standard metrics' columns, in table order (definitions and sources: README metric table)
STANDARD_METRICS = ("spl", "path_irregularity_deg_per_m", "accel_mean_cm_s2", "accel_max_cm_s2", "jerk_mean_cm_s3",
                    "jerk_max_cm_s3", "min_ttc_s", "near_miss_steps", "stalled_time_s", "collisions_wall",
                    "collisions_static_obstacle", "personal_space_intrusion_s")


def column_unit(column: str) -> str:
    """The unit of a per-episode column: :data:`COLUMN_UNITS`, and ``cm`` for the TPT error columns of a model
    outside :data:`analysis.tpt_errors.STANDING_MODELS` (``""`` for a column without a unit)."""
    if column in COLUMN_UNITS:
        return COLUMN_UNITS[column]
    if column.startswith((ADE_PREFIX, FDE_PREFIX)):
        return "cm"
    match = COLUMN_PATTERN.fullmatch(column)  # the per-horizon errors on recorded people (analysis.horizon_errors)
    return ("" if match.group(3) else "cm") if match else ""


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


def _wall_gaps(bounds: tuple[float, float, float, float] | None, pos: np.ndarray, steps: int) -> np.ndarray:
    """Per step, the distance (cm) from the robot centre's straight move ``pos[k]`` -> ``pos[k + 1]`` to the
    walls (negative outside them). Inside the rectangle the distance to its boundary is concave along a segment,
    so the smallest is at an end of the move: no geometry library needed."""
    if steps == 0 or bounds is None:
        return np.full(steps, math.inf)
    xmin, ymin, xmax, ymax = bounds
    ends = np.stack([pos[:steps], pos[1:steps + 1]])  # (2, steps, 2)
    inside = np.minimum.reduce([ends[..., 0] - xmin, xmax - ends[..., 0], ends[..., 1] - ymin, ymax - ends[..., 1]])
    return inside.min(axis=0)


_TRUTH = itemgetter("x_cm", "y_cm", "next_x_cm", "next_y_cm", "vx_cm_s", "vy_cm_s", "radius_cm")


@dataclass(frozen=True)
class MovingPairs:
    """Every (step, moving obstacle) pair of an episode's first ``steps`` truth messages, read once for the
    contact, clearance and time-to-collision metrics: ``step`` (pairs,) step indices; ``xy``, ``next_xy`` (pairs, 2)
    positions at the step and after it (cm); ``velocity`` (pairs, 2) cm/s; ``radius`` (pairs,) cm; ``ids``."""

    step: np.ndarray
    xy: np.ndarray
    next_xy: np.ndarray
    velocity: np.ndarray
    radius: np.ndarray
    ids: list[str]


def moving_pairs(truth: list[dict[str, Any]], steps: int) -> MovingPairs:
    """:class:`MovingPairs` of the first ``steps`` messages of ``truth`` (``/obstacles/truth``, checked): the pairs
    of obstacles in the world over the whole step (``present`` and ``next_present``; a log without them has every
    obstacle present), as the simulator's contacts count them — an absent person is in no metric."""
    obstacles = [(k, o) for k in range(min(steps, len(truth))) for o in truth[k]["obstacles"]
                 if o.get("present", True) and o.get("next_present", True)]
    values = np.array([_TRUTH(o) for _, o in obstacles], dtype=float).reshape(-1, 7)
    return MovingPairs(step=np.array([k for k, _ in obstacles], dtype=np.intp),
                       xy=np.ascontiguousarray(values[:, 0:2]), next_xy=np.ascontiguousarray(values[:, 2:4]),
                       velocity=np.ascontiguousarray(values[:, 4:6]), radius=np.ascontiguousarray(values[:, 6]),
                       ids=[o["id"] for _, o in obstacles])


def _dynamic_gaps(moving: MovingPairs, pos: np.ndarray, radius: float, steps: int
                  ) -> tuple[float, list[set[str]], np.ndarray]:
    """Smallest surface gap (cm) to any moving obstacle over the episode, per step the ids of the obstacles
    touched while both moved straight over the step (all (step, obstacle) pairs at once), and per step the
    smallest such gap (cm; inf on a step without moving obstacles)."""
    touching: list[set[str]] = [set() for _ in range(steps)]
    per_step = np.full(steps, math.inf)
    if not moving.ids:
        return math.inf, touching, per_step
    k = moving.step
    gaps = swept_distance(pos[k], pos[k + 1], moving.xy, moving.next_xy) - radius - moving.radius
    for i in np.nonzero(gaps < -1e-9)[0]:
        touching[k[i]].add(moving.ids[i])
    np.minimum.at(per_step, k, gaps)
    return float(gaps.min()), touching, per_step


def min_time_to_collision(moving: MovingPairs, pos: np.ndarray, radius: float, dt: float) -> float:
    """Smallest constant-velocity time to collision (s) with a moving obstacle over the episode (``moving``: its
    pairs over the steps that have a next position, ``min(len(pos) - 1, len(truth))``).

    At each step k, the robot at ``pos[k]`` keeps the velocity of its move over the step,
    (``pos[k + 1]`` − ``pos[k]``) / dt, and each obstacle its logged true velocity (``vx_cm_s``, ``vy_cm_s``);
    the TTC is the first time t >= 0 at which the centres are ``radius`` + the obstacle's radius apart:
    0 when they already overlap, inf when they never meet (moving apart or passing). NaN when the episode has
    no moving obstacle at all (nothing to measure), inf when it has some but never on a collision course."""
    if not moving.ids:
        return math.nan
    k = moving.step
    rel = moving.xy - pos[k]
    robot_v = (pos[k + 1] - pos[k]) / dt
    w = moving.velocity - robot_v  # obstacle relative to the robot
    reach = radius + moving.radius
    # |rel + w t| = reach: a t^2 + b t + c = 0; the first root when approaching (b < 0) and the lines meet
    a = np.einsum("ij,ij->i", w, w)
    b = 2.0 * np.einsum("ij,ij->i", rel, w)
    c = np.einsum("ij,ij->i", rel, rel) - reach * reach
    disc = b * b - 4.0 * a * c
    ttc = np.full(len(k), math.inf)
    meets = (a > 0) & (b < 0) & (disc >= 0)
    ttc[meets] = (-b[meets] - np.sqrt(disc[meets])) / (2.0 * a[meets])
    ttc[c <= 0] = 0.0  # overlapping now
    return float(ttc.min())


def motion_smoothness(pos: np.ndarray, dt: float) -> tuple[float, float, float, float]:
    """(mean, max) acceleration (cm/s²) and (mean, max) jerk (cm/s³) of the robot's translation.

    The velocity of each step's move is v_k = (``pos[k + 1]`` − ``pos[k]``) / dt; acceleration |v_{k+1} − v_k| / dt
    and jerk |v_{k+2} − 2 v_{k+1} + v_k| / dt² are finite differences of the velocity vector, so a change of the
    direction of travel counts as well as a change of speed; the rotation rate itself (turning in place) does not.
    NaN with fewer than two moves (acceleration) or three (jerk)."""
    v = np.diff(pos, axis=0) / dt if len(pos) > 1 else np.zeros((0, 2))
    acc = norm2(np.diff(v, n=1, axis=0)) / dt if len(v) > 1 else np.zeros(0)
    jerk = norm2(np.diff(v, n=2, axis=0)) / (dt * dt) if len(v) > 2 else np.zeros(0)

    def mean_max(x: np.ndarray) -> tuple[float, float]:
        return (math.fsum(x.tolist()) / len(x), float(x.max())) if len(x) else (math.nan, math.nan)

    return (*mean_max(acc), *mean_max(jerk))


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
    headings = log.headings
    dh = wrap_180(np.diff(headings)) if len(pos) > 1 else np.zeros(0)
    row["turn_count"] = turn_count(dh, opt.turn_threshold_deg)
    row["heading_change_deg_total"] = math.fsum(np.abs(dh).tolist())

    # contacts recomputed from the logged geometry (swept over each step, as the simulator does)
    steps = len(log.states)
    gap_static = _static_gaps(log.static_geometry(), pos, steps) - r
    touching_static = [{"static"} if g < -1e-9 else set() for g in gap_static]
    moving = moving_pairs(log.truth, steps)  # steps <= len(pos) - 1: every pair has a next position
    gap_dynamic, touching_dynamic, gap_dynamic_steps = _dynamic_gaps(moving, pos, r, steps)
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
    row.update(_standard_metrics(log, opt, row, gap_dynamic_steps, pos, headings, moving))

    # planner
    modes = [d["mode"] for d in log.decisions]
    speeds = np.array([d["v_cm_s"] for d in log.decisions]) if log.decisions else np.zeros(0)
    row["wait_steps"] = int(sum(1 for m, v in zip(modes, speeds, strict=True) if m in ("wait", "stop") and v == 0))
    plans = [d["planning"] for d in log.decisions if d.get("planning")]
    row["detour_count"] = sum(1 for p in plans if p["strategy"] == "detour")
    row["plans_made"] = len(plans)
    row["detour_extra_length_cm"] = _detour_extra(pos, modes)
    row["tpt_collisions_predicted"] = sum(1 for t in log.tpts.values() if any(chain.from_iterable(t["collide"][1:])))
    ade, fde, by_model = tpt_errors(log)
    row["tpt_ade_cm"], row["tpt_fde_cm"] = ade, fde
    row.update(model_columns(by_model, obstacle_models(log.meta).values()))
    row.update(horizon_errors(log))  # recorded people: per horizon step, the TPT against constant velocity
    row["compute_time_us_median"], row["compute_time_us_p99"] = median_and_p99(
        [d["compute_time_us"] for d in log.decisions])
    return row


def median_and_p99(values: list[float]) -> tuple[float, float]:
    """``np.median`` and ``np.percentile(values, 99)`` (linear) of finite numbers, computed as numpy computes them
    — the same order statistics, the mean of the middle two, the same interpolation steps — without numpy's
    per-call cost (it was a twentieth of an episode's metrics); NaN for no values (or a NaN among them)."""
    ordered = sorted(map(float, values))
    n = len(ordered)
    if n == 0 or any(map(math.isnan, ordered)):
        return math.nan, math.nan
    half = n // 2
    median = ordered[half] if n % 2 else (ordered[half - 1] + ordered[half]) / 2
    virtual = (n - 1) * (99 / 100)  # numpy's virtual index of the linear method
    if virtual >= n - 1:
        return median, ordered[-1]
    below = math.floor(virtual)
    a, b, gamma = ordered[below], ordered[below + 1], virtual - below
    diff = b - a
    return median, (b - diff * (1 - gamma) if gamma >= 0.5 else a + diff * gamma)  # numpy's _lerp


def _standard_metrics(log: EpisodeLog, opt: MetricOptions, row: dict[str, Any], gap_dynamic_steps: np.ndarray,
                      pos: np.ndarray, headings: np.ndarray, moving: MovingPairs) -> dict[str, Any]:
    """The standard navigation metrics (README metric table, with sources), from the log and the columns of
    ``row`` computed before (path length, success, heading change); ``pos``, ``headings`` and ``moving``: the log's
    positions, headings and (step, moving obstacle) pairs, read once per episode. Distances cm, times s, angles
    degrees."""
    r, dt, steps = log.robot_radius, log.dt, len(log.states)
    out: dict[str, Any] = {}
    path = row["path_length_cm"]
    # SPL (Anderson et al. 2018): the shortest path is bounded below by the straight line to the goal's
    # tolerance circle (obstacles ignored), so this SPL is an upper bound of the true one
    if log.goal is not None and log.goal_tolerance is not None and len(pos):
        shortest = max(0.0, dist(log.goal, pos[0]) - log.goal_tolerance)
        longest = max(path, shortest)
        # a start already within the tolerance (ℓ = 0): every successful path is as short as it can be
        out["spl"] = float(row["success"]) * (shortest / longest if shortest > 0 else 1.0)
    else:
        out["spl"] = math.nan
    # path irregularity (Guzzi et al. 2013, SocNavBench): rotation beyond the one turn to face the goal, per metre
    if path > 0 and log.goal is not None:
        needed = abs(float(wrap_180(bearing_deg(pos[0][0], pos[0][1], *log.goal) - headings[0])))
        out["path_irregularity_deg_per_m"] = max(0.0, row["heading_change_deg_total"] - needed) / (path / 100.0)
    else:
        out["path_irregularity_deg_per_m"] = math.nan
    (out["accel_mean_cm_s2"], out["accel_max_cm_s2"], out["jerk_mean_cm_s3"],
     out["jerk_max_cm_s3"]) = motion_smoothness(pos, dt)
    out["min_ttc_s"] = min_time_to_collision(moving, pos, r, dt)
    # clearance to obstacles, walls excluded (in a corridor every step would be a near miss), swept over each step
    gap_obstacles = _static_gaps(log.static_obstacles(), pos, steps) - r if log.static_polygons \
        else np.full(steps, math.inf)
    clearance = np.minimum(gap_obstacles, gap_dynamic_steps)
    out["near_miss_steps"] = int(np.count_nonzero((clearance >= 0) & (clearance < opt.near_miss_cm)))
    speed = norm2(np.diff(pos, axis=0)) / dt if steps else np.zeros(0)
    away = norm2(pos[:steps] - np.array(log.goal)) > log.goal_tolerance + 1e-6 \
        if log.goal is not None and log.goal_tolerance is not None else np.ones(steps, dtype=bool)
    out["stalled_time_s"] = int(np.count_nonzero((speed < opt.stall_speed_cm_s) & away)) * dt
    gap_walls = _wall_gaps(log.bounds, pos, steps) - r
    out["collisions_wall"] = _contacts([{"wall"} if g < -1e-9 else set() for g in gap_walls])
    out["collisions_static_obstacle"] = _contacts([{"static"} if g < -1e-9 else set() for g in gap_obstacles])
    out["personal_space_intrusion_s"] = int(np.count_nonzero(gap_dynamic_steps < opt.personal_space_cm)) * dt
    return out


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


def _metrics_rows(paths: list[Path], options: MetricOptions | None, traces: bool = False
                  ) -> tuple[list[dict], list[dict], KeptTraces | None]:
    """Metrics rows of the usable logs among ``paths``, in order, and the logs left out with their outcome (when
    unread: ``skipped`` on purpose — a copy, a conflict, not a regular file — else ``unreadable``), their ``kind``
    and the reason. Each row and left-out log whose metadata could be read
    carries its run parameters as JSON text in ``RUN_PARAMETERS``: identical texts (episodes of one
    configuration) are one object, so a worker sends each configuration once per chunk. With ``traces``, the
    third item keeps what the report's pictures need of these logs (:class:`analysis.trace.KeptTraces`), else it
    is None."""
    rows, excluded = [], []
    kept = KeptTraces() if traces else None
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
        with collector_paused():
            row, left_out = _metrics_row(path, options, parameters, seed, kept)
        if row is not None:
            rows.append(row)
        else:
            excluded.append(left_out)
    return rows, excluded, kept


def _metrics_row(path: Path, options: MetricOptions | None, parameters: Callable[[EpisodeLog], str],
                 seed: Callable[[EpisodeLog], int | None], kept: KeptTraces | None = None
                 ) -> tuple[dict | None, dict]:
    """One log's metrics row, or (None, the log left out and why): see :func:`_metrics_rows`; a usable episode is
    offered to ``kept``."""
    try:
        log = load_episode(path)
    except LogError as err:
        return None, {"log": printable(str(path)), "outcome": "skipped" if err.kind in SKIPPED_KINDS else "unreadable",
                      "kind": err.kind, "reason": printable(str(err))}
    if not log.complete:
        return None, {"log": str(path), "outcome": log.outcome, RUN_PARAMETERS: parameters(log), "seed": seed(log),
                      "kind": "truncated", "reason": "truncated: the file ends before the MCAP summary "
                      f"(killed run or damaged copy; {log.steps} steps readable, outcome {log.outcome})"}
    if log.outcome in EXCLUDED_OUTCOMES:
        why = {"incomplete": "truncated: no /episode outcome (killed run?)",
               "error": f"episode raised: {(log.episode or {}).get('reason', '')}",
               "interrupted": "episode interrupted"}[log.outcome]
        return None, {"log": str(path), "outcome": log.outcome, RUN_PARAMETERS: parameters(log), "seed": seed(log),
                      "kind": log.outcome, "reason": why}
    row = episode_metrics(log, options)
    row[RUN_PARAMETERS] = parameters(log)
    if kept is not None:
        kept.offer(row[RUN_PARAMETERS], row["success"], row["seed"], log, row["log"])
    return row, {}


def _read(paths: Iterable[str | Path], options: MetricOptions | None, jobs: int, traces: bool = False,
          meanwhile: Callable[[], object] | None = None) -> tuple[list[dict], list[dict], KeptTraces | None]:
    logs = find_logs(paths)
    parts = read_logs(functools.partial(_metrics_rows, options=options, traces=traces), logs, jobs, meanwhile,
                      _join_kept if traces else None)
    rows, excluded = [r for rows, _, _ in parts for r in rows], [e for _, excluded, _ in parts for e in excluded]
    kept = KeptTraces() if traces else None
    for _, _, part in parts:
        if kept is not None and part is not None:
            kept.merge(part)
    rows, excluded = _copies_for_lost_logs(logs, rows, excluded, options, kept)
    return rows, excluded, kept


def _join_kept(done: dict[int, Any]) -> dict[int, Any]:
    """In a forked worker, before its chunks' results travel back: the traces each chunk kept (up to 20 per run
    configuration each) joined into its first chunk's (20 per run configuration in all), so that a worker sends
    back at most what the report keeps, however many chunks it read."""
    first: KeptTraces | None = None
    out: dict[int, Any] = {}
    for i in sorted(done):
        result = done[i]
        if isinstance(result, tuple) and isinstance(result[2], KeptTraces):
            if first is None:
                first = result[2]
            else:
                first.merge(result[2])
                result = (result[0], result[1], None)
        out[i] = result
    return out


def _copies_for_lost_logs(logs: list[Path], rows: list[dict], excluded: list[dict], options: MetricOptions | None,
                          kept: KeptTraces | None = None) -> tuple[list[dict], list[dict]]:
    """The log counted for an episode among identical copies was chosen (and verified) before the metrics read
    it; if it cannot be read by then (deleted or damaged while the report ran), its next readable copy is counted
    instead: the episode counts once, not zero times. The lost log stays in the left-out list with its reason."""
    copies: dict[str, list[Path]] = {}
    for path in logs:
        if isinstance(path, RejectedLog) and path.kind == "duplicate" and getattr(path, "copy_of", None):
            copies.setdefault(path.copy_of, []).append(path)
    if not copies:
        return rows, excluded
    for entry in [e for e in excluded if e["log"] in copies and e["kind"] not in SKIPPED_KINDS]:
        for copy in copies[entry["log"]]:
            found, _, copy_kept = _metrics_rows([Path(str(copy))], options, kept is not None)
            if found:
                rows.extend(found)
                if kept is not None and copy_kept is not None:
                    kept.merge(copy_kept)
                excluded = [e for e in excluded if e["log"] != str(copy)]
                entry["reason"] = f"{entry['reason']} (its copy {copy} is counted instead)"
                break
    return rows, excluded


def metrics_table(paths: Iterable[str | Path], options: MetricOptions | None = None, jobs: int = 1
                  ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(one row per usable episode, logs left out with the reason), in the order of
    :func:`analysis.log_inputs.find_logs`.

    ``jobs`` > 1 (or -1: every core) reads the logs in that many worker processes when there are many
    (:func:`analysis.logs.read_logs`); the result is the same as with ``jobs=1``."""
    rows, excluded, _ = _read(paths, options, jobs)
    table = pd.DataFrame(rows)
    return (table.drop(columns=[RUN_PARAMETERS], errors="ignore"),
            pd.DataFrame(excluded, columns=["log", "kind", "reason"]))


@dataclass
class Analysis:
    """Episodes of a set of logs with their groups: ``episodes`` has the metrics, each group dimension's value
    (full key), ``scenario_label``, ``variant`` and ``setting`` (see :class:`Grouping`), rows in the groups'
    natural order then by seed; ``excluded`` the logs left out (log, outcome, kind, reason, and their labels
    when the metadata was readable); ``runs`` one parameter dict per episode row; ``traces`` and
    ``first_contacts`` what the report's pictures need, kept from the same reading of the logs
    (``analyse_logs(..., traces=True)``: :class:`analysis.trace.KeptTraces`; empty otherwise, and the report reads
    the logs it pictures)."""

    episodes: pd.DataFrame
    excluded: pd.DataFrame
    grouping: Grouping
    runs: list[dict[str, Any]]
    traces: dict[str, Trace] = field(default_factory=dict)
    first_contacts: dict[str, int | None] = field(default_factory=dict)


def analyse_logs(paths: Iterable[str | Path], options: MetricOptions | None = None, jobs: int = 1,
                 split_provenance: bool = False, traces: bool = False,
                 meanwhile: Callable[[], object] | None = None) -> Analysis:
    """Metrics of every usable log and the group of each episode. The grouping is found over every log whose
    metadata is readable (left-out ones too, so that the summary can count them in their group). ``traces``: also
    keep what the report's pictures need of the logs (:class:`analysis.trace.KeptTraces`), so that a report of this
    analysis reads each log once. ``meanwhile``: work of this process's own, done while workers forked from it read
    the logs (:func:`analysis.logs.read_logs`; not called without them), after loading pandas (the readers do
    without it: :mod:`analysis.deferred`)."""

    def tables_library() -> None:
        load(pd)
        if meanwhile is not None:
            meanwhile()

    rows, excluded, kept = _read(paths, options, jobs, traces, tables_library)
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
    if kept is None:
        return Analysis(episodes, left_out, grouping, runs)
    return Analysis(episodes, left_out, grouping, runs, kept.traces(), kept.contacts)


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
