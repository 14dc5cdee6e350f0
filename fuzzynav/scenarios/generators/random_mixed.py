"""``random_mixed``: static discs and boxes scattered between start and goal, plus moving obstacles crossing the
start-goal line at random places and times (cm, cm/s, s; the seam: :mod:`fuzzynav.scenarios.generator`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from fuzzynav.numerics.portable_math import dist, sin_cos_deg
from fuzzynav.numerics.portable_random import uniform
from fuzzynav.params.checks import check_key, key_text
from fuzzynav.scenarios.generator import CLEAR_CM, ROBOT_RADIUS, param, register_generator
from fuzzynav.scenarios.scenario import ScenarioError


def _outside_statics(p0: np.ndarray, vel: np.ndarray, placed: list[tuple[np.ndarray, float]],
                     box: tuple[float, float, float, float], start: np.ndarray, start_clear: float,
                     what: str) -> np.ndarray:
    """``p0`` (cm), or the first point along the obstacle's own path (1 s earlier, then 1 s later, up to 60 s)
    that is inside ``box`` (xmin, ymin, xmax, ymax), outside the circle around every static obstacle (centre,
    half size × √2) and ``start_clear`` away from the robot's start. A moving obstacle that starts inside a
    static one is hidden there from the laser (scenario validation refuses it). No random draw: only the
    scenarios that had the problem change."""
    def free(p: np.ndarray) -> bool:
        inside = box[0] <= p[0] <= box[2] and box[1] <= p[1] <= box[3]
        return (inside and dist(p, start) >= start_clear
                and all(dist(p, c) > size * math.sqrt(2) for c, size in placed))
    if free(p0):
        return p0
    for k in range(1, 61):
        for sign in (-1.0, 1.0):
            candidate = p0 + sign * k * vel
            if free(candidate):
                return candidate
    raise ScenarioError(f"params.n_static: {what} finds no start outside the static obstacles along its path "
                        "(ask for fewer or smaller static obstacles)")


@register_generator("random_mixed")
def random_mixed(params: Mapping[str, Any], seed: int, name: str = "random_mixed") -> dict[str, Any]:
    """Static discs and boxes scattered between start and goal, plus moving obstacles crossing the
    start-goal line at random places and times. Returns the scenario as plain data (YAML form)."""
    known = {"width", "height", "n_static", "static_size", "n_dynamic", "speed", "dynamic_radius", "max_steps"}
    for key in params:
        check_key(key, "params", ScenarioError)
        if key not in known:
            raise ScenarioError(f"params.{key_text(key)}: unknown parameter (known: {', '.join(sorted(known))})")
    w = param(params, "width", 1200, float)
    h = param(params, "height", 800, float)
    n_static = param(params, "n_static", 5, int)
    size_lo, size_hi = param(params, "static_size", (20, 60), tuple)
    n_dynamic = param(params, "n_dynamic", 3, int)
    v_lo, v_hi = param(params, "speed", (10, 30), tuple)
    r_lo, r_hi = param(params, "dynamic_radius", (15, 25), tuple)
    max_steps = param(params, "max_steps", 250, int)
    if w < 400 or h < 300:
        raise ScenarioError(f"params.width/height: at least 400 x 300 cm, got {w} x {h}")
    if v_lo <= 0 or r_lo <= 0 or size_lo <= 0:
        raise ScenarioError("params.speed/dynamic_radius/static_size: minimum must be > 0")
    # sizes that can never fit the world: refused for every seed alike (they placed nothing, or put a moving
    # obstacle's start far outside the bounds, without a word)
    static_max = (h - 20) / 2  # a static obstacle keeps 10 cm from the top and bottom walls (see below)
    if n_static > 0 and size_lo >= static_max:
        raise ScenarioError(f"params.static_size: [{size_lo:g}, {size_hi:g}] cm does not fit the {w:g} x {h:g} cm "
                            f"world (a radius or half side must be below (height - 20) / 2 = {static_max:g} cm)")
    dynamic_max = min(w, h) / 2
    if n_dynamic > 0 and r_hi > dynamic_max:
        raise ScenarioError(f"params.dynamic_radius: [{r_lo:g}, {r_hi:g}] cm does not fit the {w:g} x {h:g} cm "
                            f"world (a moving obstacle's radius must be at most {dynamic_max:g} cm)")
    rng = np.random.default_rng((int(seed), 7))
    start = np.array([100.0, h / 2])
    goal = np.array([w - 100.0, h / 2])
    keep_out = ROBOT_RADIUS + CLEAR_CM
    statics: list[dict[str, Any]] = []
    placed: list[tuple[np.ndarray, float]] = []
    for _ in range(n_static):
        for _attempt in range(200):
            size = uniform(rng, size_lo, size_hi)
            if h - size - 10 <= size + 10:
                continue  # too big for this height
            centre = np.array([uniform(rng, min(250.0, w / 2), max(w - 250.0, w / 2)),
                               uniform(rng, size + 10, h - size - 10)])
            if min(dist(centre, start), dist(centre, goal)) < keep_out + size * math.sqrt(2):
                continue
            if any(dist(centre, c) < size * math.sqrt(2) + s * math.sqrt(2) + 2 * ROBOT_RADIUS
                   for c, s in placed):
                continue
            placed.append((centre, size))
            if rng.random() < 0.5:
                statics.append({"circle": {"center": [round(float(centre[0]), 3), round(float(centre[1]), 3)],
                                           "radius": round(float(size), 3)}})
            else:
                x0, y0, x1, y1 = (round(float(v), 3) for v in (*centre - size, *centre + size))
                statics.append({"polygon": [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]})
            break
    if len(statics) < n_static:  # a scenario labelled n_static=5 with fewer obstacles is a silent wrong result
        raise ScenarioError(f"params.n_static: placed {len(statics)} of {n_static} static obstacles (static_size "
                            f"[{size_lo:g}, {size_hi:g}] cm does not fit that many into the {w:g} x {h:g} cm world "
                            "clear of start, goal and each other, in 200 tries each; ask for fewer or smaller)")
    dynamics = []
    for i in range(n_dynamic):
        radius = round(uniform(rng, r_lo, r_hi), 3)
        speed = uniform(rng, v_lo, v_hi)
        cross_x = uniform(rng, min(300.0, w / 2), max(w - 300.0, w / 2))
        from_below = rng.random() < 0.5
        sin, cos = sin_cos_deg(uniform(rng, -30, 30) + (90.0 if from_below else -90.0))
        vel = np.array([cos, sin]) * speed
        # time at which it should cross the line: when the robot (about 25 cm/s) could be there, +- jitter
        t_cross = max(2.0, (cross_x - start[0]) / 25.0 + uniform(rng, -6, 6))
        p0 = np.array([cross_x, h / 2]) - vel * t_cross
        p0 = np.clip(p0, [radius, radius], [w - radius, h - radius])
        if dist(p0, start) < ROBOT_RADIUS + radius + CLEAR_CM:
            p0 = p0 + np.array([0.0, (1 if p0[1] >= start[1] else -1) * (ROBOT_RADIUS + radius + CLEAR_CM)])
        p0 = _outside_statics(p0, vel, placed, (radius, radius, w - radius, h - radius), start,
                              ROBOT_RADIUS + radius + CLEAR_CM, f"dynamic obstacle m{i}")
        dynamics.append({"id": f"m{i}", "radius": radius, "start": [round(float(p0[0]), 3), round(float(p0[1]), 3)],
                         "velocity": [round(float(vel[0]), 3), round(float(vel[1]), 3)]})
    return {"name": name, "description": f"random_mixed generated with seed {seed}", "bounds": [0, 0, w, h],
            "robot": {"start": start.tolist(), "heading": 0.0, "goal": goal.tolist(), "radius": ROBOT_RADIUS},
            "static_obstacles": statics, "dynamic_obstacles": dynamics, "max_steps": max_steps}
