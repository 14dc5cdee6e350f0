"""Seeded crowd scenarios: pedestrians with a model (:mod:`fuzzynav.pedestrians.base`) around the robot's path.

- ``crowd_crossing``: ``n`` pedestrians (2–30) cross the robot's path, half from each side, at random places,
  starting at random distances from it (so they arrive one after another);
- ``corridor_flow``: bidirectional flow in a corridor: ``n`` pedestrians walk its length back and forth in
  random lanes, half starting each way, while the robot drives through;
- ``random_walkers``: ``n`` pedestrians start anywhere clear of the robot, in random directions, and (with the
  default model ``random_walk``) wander;
- ``groups``: ``n_groups`` groups of ``group_size`` pedestrians cross the robot's path, each group walking
  side by side (``spacing_cm`` apart) with one intent: the same speed and parallel waypoints.

Common parameters: ``model`` (default ``social_force``; ``random_walk`` for random_walkers) and ``model_params``
(given to every pedestrian), ``speed`` [min, max] cm/s (preferred walking speed), ``radius`` [min, max] cm,
``max_steps``. Every start is clear of the robot's start and of the other pedestrians' starts. The generator's
random stream is ``default_rng((seed, 7))`` (as :mod:`fuzzynav.scenarios.generator`), drawn through
:mod:`fuzzynav.numerics.portable_random`. Units: cm, cm/s, s.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from fuzzynav.numerics.portable_math import dist, sin_cos_deg
from fuzzynav.numerics.portable_random import uniform
from fuzzynav.params.checks import check_key, key_text, show
from fuzzynav.pedestrians.base import model_config
from fuzzynav.scenarios.generator import CLEAR_CM, ROBOT_RADIUS, param, register_generator
from fuzzynav.scenarios.scenario import ScenarioError

#: how far a pedestrian's waypoints stay from the walls (cm, beyond its radius): a social-force pedestrian is held
#: where the wall's push equals its drive, about 90 cm from a wall at the default parameters (U⁰/R e^(−d/R) =
#: v⁰/τ), so a waypoint nearer the wall would never be reached (it would stand there instead of walking on)
WALL_CLEAR_CM = 120.0

#: parameters every crowd generator takes, with their defaults
_COMMON = {"model": "social_force", "model_params": None, "speed": (20.0, 40.0), "radius": (18.0, 25.0),
           "max_steps": 300}


def _check_known(params: Mapping[str, Any], own: set[str]) -> None:
    known = own | set(_COMMON)
    for key in params:
        check_key(key, "params", ScenarioError)
        if key not in known:
            raise ScenarioError(f"params.{key_text(key)}: unknown parameter (known: {', '.join(sorted(known))})")


def _fits(common: Mapping[str, Any], h: float) -> None:
    """Pedestrians of the largest radius must be able to start on either side of the path, clear of it."""
    r = common["radius"][1]
    if 3 * r + 50.0 >= h / 2:
        raise ScenarioError(f"params.radius: {r:g} cm pedestrians do not fit beside the path in a {h:g} cm high "
                            "world (need 3 x radius + 50 < height / 2)")


def _open_world(params: Mapping[str, Any], common: Mapping[str, Any], seed: int
                ) -> tuple[float, float, np.random.Generator, np.ndarray, np.ndarray]:
    """The open ``width`` x ``height`` world (cm, at least 600 x 400) of crowd_crossing, random_walkers and groups:
    (w, h, the generator's random stream, robot start (100, h/2), goal (w - 100, h/2))."""
    w, h = param(params, "width", 1200, float), param(params, "height", 800, float)
    if w < 600 or h < 400:
        raise ScenarioError(f"params.width/height: at least 600 x 400 cm, got {w:g} x {h:g}")
    _fits(common, h)
    return w, h, np.random.default_rng((int(seed), 7)), np.array([100.0, h / 2]), np.array([w - 100.0, h / 2])


def _common(params: Mapping[str, Any], default_model: str = "social_force") -> dict[str, Any]:
    model = params.get("model", default_model)
    if not isinstance(model, str):
        raise ScenarioError(f"params.model: expected an obstacle model's name, got {show(model)}")
    model_params = params.get("model_params")
    if model_params is not None and not isinstance(model_params, Mapping):
        raise ScenarioError(f"params.model_params: expected a mapping, got {show(model_params)}")
    try:  # checked here, also when no pedestrian is generated, and named as the generator's parameter
        model_config(model, model_params, "params.model_params")
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    speed = param(params, "speed", _COMMON["speed"], tuple)
    radius = param(params, "radius", _COMMON["radius"], tuple)
    if speed[0] <= 0 or radius[0] <= 0:
        raise ScenarioError("params.speed/radius: minimum must be > 0")
    return {"model": model, "model_params": None if model_params is None else dict(model_params), "speed": speed,
            "radius": radius, "max_steps": param(params, "max_steps", _COMMON["max_steps"], int)}


class _Placer:
    """Draws pedestrian starts clear of the robot's start and of each other (rejection, bounded tries)."""

    def __init__(self, rng: np.random.Generator, robot_start: np.ndarray, what: str, count: str = "params.n") -> None:
        self.rng, self.robot_start, self.what, self.count = rng, robot_start, what, count
        self.placed: list[tuple[np.ndarray, float]] = []

    def free(self, p: np.ndarray, radius: float) -> bool:
        return (dist(p, self.robot_start) >= ROBOT_RADIUS + radius + CLEAR_CM
                and all(dist(p, q) >= radius + r + 10.0 for q, r in self.placed))

    def place(self, draw: Callable[[], np.ndarray], radius: float) -> np.ndarray:
        for _ in range(200):
            p = draw()
            if self.free(p, radius):
                self.placed.append((p, radius))
                return p
        raise ScenarioError(f"{self.count}: no free start for {self.what} {len(self.placed)} in 200 tries (ask for "
                            "fewer or smaller pedestrians, or a larger world)")


def _pedestrian(i: int, radius: float, waypoints: list[np.ndarray], speed: float, loop: bool,
                common: Mapping[str, Any]) -> dict[str, Any]:
    entry = {"id": f"p{i}", "radius": round(radius, 3),
             "waypoints": [[round(float(w[0]), 3), round(float(w[1]), 3)] for w in waypoints],
             "speed": round(speed, 3), "loop": loop, "model": common["model"]}
    if common["model_params"] is not None:
        entry["model_params"] = common["model_params"]
    return entry


def _scenario(name: str, kind: str, seed: int, w: float, h: float, start: np.ndarray, goal: np.ndarray,
              dynamics: list[dict[str, Any]], common: Mapping[str, Any],
              statics: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    return {"name": name, "description": f"{kind} generated with seed {seed}", "bounds": [0, 0, w, h],
            "robot": {"start": start.tolist(), "heading": 0.0, "goal": goal.tolist(), "radius": ROBOT_RADIUS},
            "static_obstacles": statics or [], "dynamic_obstacles": dynamics, "max_steps": common["max_steps"]}


@register_generator("crowd_crossing")
def crowd_crossing(params: Mapping[str, Any], seed: int, name: str = "crowd_crossing") -> dict[str, Any]:
    """``n`` pedestrians cross the robot's path (module docstring). World ``width`` x ``height`` cm (1200 x 800);
    the robot goes from (100, h/2) to (w - 100, h/2)."""
    _check_known(params, {"n", "width", "height"})
    common = _common(params)
    n = param(params, "n", 10, int)
    w, h, rng, start, goal = _open_world(params, common, seed)
    placer = _Placer(rng, start, "pedestrian")
    dynamics = []
    for i in range(n):
        radius = uniform(rng, *common["radius"])
        speed = uniform(rng, *common["speed"])
        from_below = i % 2 == 0
        side = -1.0 if from_below else 1.0  # where it starts relative to the path
        p0 = placer.place(lambda r=radius, s=side: np.array([
            uniform(rng, 250.0, w - 250.0), h / 2 + s * uniform(rng, 2 * r + 40.0, h / 2 - r - 10.0)]), radius)
        end = np.array([p0[0], h / 2 - side * (h / 2 - radius - WALL_CLEAR_CM)])
        dynamics.append(_pedestrian(i, radius, [p0, end], speed, False, common))
    return _scenario(name, "crowd_crossing", seed, w, h, start, goal, dynamics, common)


@register_generator("corridor_flow")
def corridor_flow(params: Mapping[str, Any], seed: int, name: str = "corridor_flow") -> dict[str, Any]:
    """Bidirectional flow in a ``length`` x ``width`` cm corridor (1600 x 400; module docstring); the robot drives
    from (100, w/2) to (length - 100, w/2)."""
    _check_known(params, {"n", "length", "width"})
    common = _common(params)
    n = param(params, "n", 8, int)
    length, width = param(params, "length", 1600, float), param(params, "width", 400, float)
    if length < 800 or width < 200:
        raise ScenarioError(f"params.length/width: at least 800 x 200 cm, got {length:g} x {width:g}")
    if 2 * common["radius"][1] + 20.0 > width:
        raise ScenarioError(f"params.radius: {common['radius'][1]:g} cm pedestrians do not fit a {width:g} cm corridor")
    rng = np.random.default_rng((int(seed), 7))
    start, goal = np.array([100.0, width / 2]), np.array([length - 100.0, width / 2])
    placer = _Placer(rng, start, "pedestrian")
    dynamics = []
    for i in range(n):
        radius = uniform(rng, *common["radius"])
        speed = uniform(rng, *common["speed"])
        lane = uniform(rng, radius + 10.0, width - radius - 10.0)
        p0 = placer.place(lambda r=radius, y=lane: np.array([uniform(rng, r + 10.0, length - r - 10.0), y]), radius)
        ends = [np.array([radius + WALL_CLEAR_CM, p0[1]]), np.array([length - radius - WALL_CLEAR_CM, p0[1]])]
        toward = ends[i % 2]  # even: walking against the robot
        dynamics.append(_pedestrian(i, radius, [p0, toward, ends[1 - i % 2]], speed, True, common))
    return _scenario(name, "corridor_flow", seed, length, width, start, goal, dynamics, common)


@register_generator("random_walkers")
def random_walkers(params: Mapping[str, Any], seed: int, name: str = "random_walkers") -> dict[str, Any]:
    """``n`` pedestrians anywhere in a ``width`` x ``height`` cm world (1200 x 800), clear of the robot's start,
    each with a random direction (module docstring)."""
    _check_known(params, {"n", "width", "height"})
    common = _common(params, default_model="random_walk")
    n = param(params, "n", 8, int)
    w, h, rng, start, goal = _open_world(params, common, seed)
    placer = _Placer(rng, start, "pedestrian")
    dynamics = []
    for i in range(n):
        radius = uniform(rng, *common["radius"])
        speed = uniform(rng, *common["speed"])
        p0 = placer.place(lambda r=radius: np.array([uniform(rng, r + 10.0, w - r - 10.0),
                                                     uniform(rng, r + 10.0, h - r - 10.0)]), radius)
        s, c = sin_cos_deg(uniform(rng, 0.0, 360.0))
        # its intent for reactive models: walk that way to the world's edge and back
        reach = min(w, h) / 2
        far = np.clip(p0 + reach * np.array([c, s]), [radius + WALL_CLEAR_CM, radius + WALL_CLEAR_CM],
                      [w - radius - WALL_CLEAR_CM, h - radius - WALL_CLEAR_CM])
        if dist(far, p0) < 1.0:
            far = np.array([w / 2, h / 2])
        dynamics.append(_pedestrian(i, radius, [p0, far], speed, True, common))
    return _scenario(name, "random_walkers", seed, w, h, start, goal, dynamics, common)


@register_generator("groups")
def groups(params: Mapping[str, Any], seed: int, name: str = "groups") -> dict[str, Any]:
    """``n_groups`` groups of ``group_size`` pedestrians crossing the robot's path side by side (module
    docstring); world ``width`` x ``height`` cm (1200 x 800)."""
    _check_known(params, {"n_groups", "group_size", "spacing_cm", "width", "height"})
    common = _common(params)
    n_groups = param(params, "n_groups", 3, int)
    size = param(params, "group_size", 3, int)
    spacing = param(params, "spacing_cm", 60.0, float)
    w, h, rng, start, goal = _open_world(params, common, seed)
    if n_groups < 1 or size < 1 or n_groups * size > 100:
        raise ScenarioError(f"params.n_groups/group_size: between 1 and 100 pedestrians in all, got "
                            f"{n_groups} x {size}")
    if spacing < 2 * common["radius"][1]:
        raise ScenarioError(f"params.spacing_cm: {spacing:g} cm is less than two radii ({common['radius'][1]:g} cm)")
    if (size - 1) * spacing + 2 * common["radius"][1] + 520.0 > w:
        raise ScenarioError(f"params.group_size: {size} side by side, {spacing:g} cm apart, do not fit the "
                            f"{w:g} cm wide world")
    placer = _Placer(rng, start, "group", "params.n_groups")
    dynamics = []
    for g in range(n_groups):
        speed = uniform(rng, *common["speed"])
        radius = common["radius"][1]
        side = -1.0 if g % 2 == 0 else 1.0
        half = (size - 1) * spacing / 2
        # the group's centre; its members stand on a line across their direction of walking
        centre = placer.place(lambda s=side, a=half, r=radius: np.array([
            uniform(rng, 250.0 + a, w - 250.0 - a), h / 2 + s * uniform(rng, 2 * r + 40.0, h / 2 - r - 10.0)]),
            half + radius)
        for m in range(size):
            p0 = centre + np.array([-half + m * spacing, 0.0])
            end = np.array([p0[0], h / 2 - side * (h / 2 - radius - WALL_CLEAR_CM)])
            dynamics.append(_pedestrian(g * size + m, radius, [p0, end], speed, False, common))
    return _scenario(name, "groups", seed, w, h, start, goal, dynamics, common)
