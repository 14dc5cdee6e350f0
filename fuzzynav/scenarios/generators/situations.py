"""Seeded situations that test what a reactive method may miss: a person standing in the path, a fast mover
among slow pedestrians, and a doorway that pedestrians cross.

- ``standing_person``: one person stands still on the robot's path (``walk_in_cm`` 0), or walks
  ``walk_in_cm`` across to it and stops there, while ``n`` pedestrians cross the path as in ``crowd_crossing``.
  The person is ``scripted`` (it ignores everything, also the robot): an obstacle that does not move is
  still an obstacle, whether it always stood or stopped.
- ``fast_mover``: ``n`` slow pedestrians (``speed``, default 15–30 cm/s) cross the path, and one walks back
  and forth across it at ``fast_speed`` cm/s (default 70), at a place the robot passes early.
- ``doorway``: a ``wall_cm`` thick wall across the world with a ``door_cm`` wide door on the robot's path;
  ``n`` pedestrians walk across the robot's line of travel near the door, on both sides of the wall, and
  one walks through the door against the robot.

Common parameters as the crowd generators (:mod:`fuzzynav.scenarios.generators.crowds`): ``model``,
``model_params``, ``speed`` [min, max] cm/s, ``radius`` [min, max] cm, ``max_steps``; world ``width`` x
``height`` cm (1200 x 800); the robot goes from (100, h/2) to (w - 100, h/2). The random stream is
``default_rng((seed, 7))``. Units: cm, cm/s.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from fuzzynav.numerics.portable_math import dist
from fuzzynav.numerics.portable_random import uniform
from fuzzynav.scenarios.generator import param, register_generator
from fuzzynav.scenarios.generators.crowds import (
    WALL_CLEAR_CM,
    _check_known,
    _common,
    _open_world,
    _pedestrian,
    _Placer,
    _scenario,
)
from fuzzynav.scenarios.scenario import ScenarioError

#: the slow walkers' default preferred speed (cm/s) in ``fast_mover``
SLOW_SPEED = (15.0, 30.0)


def _crossers(n: int, rng: np.random.Generator, placer: _Placer, w: float, h: float, common: Mapping[str, Any],
              x_range: tuple[float, float], first_id: int = 0) -> list[dict[str, Any]]:
    """``n`` pedestrians crossing the robot's line (y = h/2) at x in ``x_range``, alternately from below and above,
    as in ``crowd_crossing``."""
    out = []
    for i in range(n):
        radius = uniform(rng, *common["radius"])
        speed = uniform(rng, *common["speed"])
        side = -1.0 if i % 2 == 0 else 1.0
        p0 = placer.place(lambda r=radius, s=side: np.array([
            uniform(rng, *x_range), h / 2 + s * uniform(rng, 2 * r + 40.0, h / 2 - r - 10.0)]), radius)
        end = np.array([p0[0], h / 2 - side * (h / 2 - radius - WALL_CLEAR_CM)])
        out.append(_pedestrian(first_id + i, radius, [p0, end], speed, False, common))
    return out


@register_generator("standing_person")
def standing_person(params: Mapping[str, Any], seed: int, name: str = "standing_person") -> dict[str, Any]:
    """A person standing on the robot's path (or walking ``walk_in_cm`` to it and stopping) among ``n`` crossing
    pedestrians (module docstring)."""
    _check_known(params, {"n", "walk_in_cm", "width", "height"})
    common = _common(params)
    n = param(params, "n", 4, int)
    walk_in = param(params, "walk_in_cm", 0.0, float)
    w, h, rng, start, goal = _open_world(params, common, seed)
    if walk_in > h / 2 - 60.0:
        raise ScenarioError(f"params.walk_in_cm: {walk_in:g} cm does not fit beside the path in a {h:g} cm high "
                            f"world (at most {h / 2 - 60.0:g})")
    radius = uniform(rng, *common["radius"])
    spot = np.array([uniform(rng, 400.0, w - 400.0), h / 2 + uniform(rng, -10.0, 10.0)])
    side = -1.0 if uniform(rng, 0.0, 1.0) < 0.5 else 1.0
    person: dict[str, Any] = {"id": "standing", "radius": round(radius, 3), "model": "scripted"}
    if walk_in > 0:
        # walks in at 30 cm/s and stands from then on (a scripted path ends where its last waypoint is)
        origin = spot + np.array([0.0, side * walk_in])
        person.update(waypoints=[[round(float(p[0]), 3), round(float(p[1]), 3)] for p in (origin, spot)],
                      speed=30.0, loop=False)
    else:
        person.update(start=[round(float(spot[0]), 3), round(float(spot[1]), 3)], velocity=[0.0, 0.0])
    placer = _Placer(rng, start, "pedestrian")
    placer.placed.append((spot, radius + 60.0))  # the crossers start clear of the person and of its walk in
    if walk_in > 0:
        placer.placed.append((spot + np.array([0.0, side * walk_in]), radius + 60.0))
    dynamics = [person, *_crossers(n, rng, placer, w, h, common, (250.0, w - 250.0))]
    return _scenario(name, "standing_person", seed, w, h, start, goal, dynamics, common)


@register_generator("fast_mover")
def fast_mover(params: Mapping[str, Any], seed: int, name: str = "fast_mover") -> dict[str, Any]:
    """``n`` slow crossing pedestrians and one walking back and forth across the path at ``fast_speed`` cm/s
    (module docstring)."""
    _check_known(params, {"n", "fast_speed", "width", "height"})
    common = _common({"speed": list(SLOW_SPEED), **params})
    n = param(params, "n", 6, int)
    fast = param(params, "fast_speed", 70.0, float)
    if not 0 < fast <= 500:
        raise ScenarioError(f"params.fast_speed: must be in (0, 500] cm/s, got {fast:g}")
    w, h, rng, start, goal = _open_world(params, common, seed)
    radius = common["radius"][1]
    # where the robot, at 25 cm/s, is 6-12 s after its start: the mover crosses there every (h - 2 x clearance) /
    # fast_speed seconds, so on every seed it meets the robot's path while the robot is near
    x = uniform(rng, 250.0, min(400.0, w - 250.0))
    ends = [np.array([x, radius + WALL_CLEAR_CM]), np.array([x, h - radius - WALL_CLEAR_CM])]
    placer = _Placer(rng, start, "pedestrian")
    p0 = ends[0] if uniform(rng, 0.0, 1.0) < 0.5 else ends[1]
    placer.placed.append((p0, radius))
    mover = _pedestrian(0, radius, [p0, ends[1] if p0 is ends[0] else ends[0]], fast, True, common)
    mover["id"] = "fast"
    dynamics = [mover, *_crossers(n, rng, placer, w, h, common, (250.0, w - 250.0), first_id=1)]
    return _scenario(name, "fast_mover", seed, w, h, start, goal, dynamics, common)


@register_generator("doorway")
def doorway(params: Mapping[str, Any], seed: int, name: str = "doorway") -> dict[str, Any]:
    """A wall with a door on the robot's path, pedestrians crossing near it and one coming through it (module
    docstring)."""
    _check_known(params, {"n", "door_cm", "wall_cm", "width", "height"})
    common = _common(params)
    n = param(params, "n", 4, int)
    door = param(params, "door_cm", 120.0, float)
    wall = param(params, "wall_cm", 20.0, float)
    w, h, rng, start, goal = _open_world(params, common, seed)
    if not 2 * 20.0 + 20.0 <= door <= h - 100.0:
        raise ScenarioError(f"params.door_cm: must be between 60 (the robot and 10 cm each side) and height - 100 "
                            f"({h - 100.0:g}), got {door:g}")
    if not 0 < wall <= 200:
        raise ScenarioError(f"params.wall_cm: must be in (0, 200], got {wall:g}")
    x0, x1 = w / 2 - wall / 2, w / 2 + wall / 2
    low, high = h / 2 - door / 2, h / 2 + door / 2
    statics = [{"polygon": [[x0, 0.0], [x1, 0.0], [x1, low], [x0, low]]},
               {"polygon": [[x0, high], [x1, high], [x1, h], [x0, h]]}]
    placer = _Placer(rng, start, "pedestrian")
    half = (n + 1) // 2
    near = 80.0 + common["radius"][1]  # crossing lanes start this far from the wall's faces
    dynamics = [*_crossers(half, rng, placer, w, h, common, (x0 - 250.0, x0 - near)),
                *_crossers(n - half, rng, placer, w, h, common, (x1 + near, x1 + 250.0), first_id=half)]
    radius = common["radius"][0]
    through = [np.array([w - 150.0, h / 2 + uniform(rng, -20.0, 20.0)]), np.array([150.0, h / 2])]
    if all(dist(through[0], q) >= radius + r + 10.0 for q, r in placer.placed):
        dynamics.append(_pedestrian(n, radius, through, uniform(rng, *common["speed"]), False, common))
    return _scenario(name, "doorway", seed, w, h, start, goal, dynamics, common, statics)
