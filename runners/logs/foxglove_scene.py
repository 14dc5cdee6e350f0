"""The ``/scene`` topic of an episode's log (``foxglove.SceneUpdate``, metres and radians): the static world once,
then per step the robot, the moving obstacles, the TPT's predicted lines and hits, and the current plan; and the
Foxglove geometry builders the other topics share (poses, stamps, cm -> m).

The per-step message is the largest of a step (~19 KB with 20 pedestrians) and has the same shape every step, so it
is written from byte templates instead of being built as nested dicts and encoded: a template is the compact JSON
of a part built by the same builders as the static scene with sentinel numbers where the step's values go, split
there once (per process, or per episode for parts sized by the episode); a step encodes all its numbers with orjson
in one call and fills the templates. The bytes are exactly orjson's encoding of the dict form
(``tests/test_foxglove_scene.py`` compares the two), so logs and recorded datasets are unchanged.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import orjson

from fuzzynav.numerics.portable_math import atan2_deg_array, sin_cos_deg, sin_cos_deg_array

FRAME = "world"

BLUE = {"r": 0.15, "g": 0.4, "b": 0.95, "a": 1.0}
GREEN = {"r": 0.1, "g": 0.75, "b": 0.2, "a": 0.5}
RED = {"r": 0.9, "g": 0.2, "b": 0.15, "a": 1.0}
GREY = {"r": 0.45, "g": 0.45, "b": 0.45, "a": 1.0}
CYAN = {"r": 0.0, "g": 0.8, "b": 0.9, "a": 0.9}
ORANGE = {"r": 1.0, "g": 0.6, "b": 0.0, "a": 0.9}
PURPLE = {"r": 0.6, "g": 0.2, "b": 0.85, "a": 1.0}
HIT = {"r": 1.0, "g": 0.0, "b": 0.0, "a": 0.35}

_NO_ROTATION = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}  # shared read-only: the quaternion of heading 0
_ORIGIN = {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": _NO_ROTATION}
_FOREVER = {"sec": 0, "nsec": 0}
_NUMPY = orjson.OPT_SERIALIZE_NUMPY  # numpy scalars and arrays encoded as the equal Python floats are
_NO_PRIMITIVES = {kind: () for kind in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts",
                                         "models")}  # shared read-only defaults: written as empty arrays


# -- dict builders ------------------------------------------------------------------------------------------------
def stamp(t: float) -> dict[str, int]:
    """``foxglove.Time`` of ``t`` seconds."""
    ns = round(t * 1e9)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def metres(cm: float) -> float:
    """cm -> m, rounded to 0.1 mm (half to even, as :func:`points_m` rounds with numpy, except that a value that
    rounds to zero is 0.0 here and keeps its sign there; each is kept as it was: logs are compared byte for byte):
    geometry for Foxglove (the analysis reads moving positions from the cm topics, the static world from the first
    scene)."""
    return round(cm / 100.0 * 10_000.0) / 10_000.0


def _metres_array(points_cm) -> np.ndarray:
    """Every element of an array of cm in m, rounded to 0.1 mm by numpy (multiply, round half to even, divide: as
    :func:`metres`, but -0.0 where a negative value rounds to zero)."""
    return (np.asarray(points_cm, dtype=np.float64) / 100.0).round(4)  # np.round's own method, without its wrapper


def points_m(points_cm, z_m: float) -> list[dict]:
    """``foxglove.Point3`` list of an (N, 2) array of cm points, in m rounded to 0.1 mm, at height ``z_m``."""
    return [point(x, y, z_m) for x, y in _metres_array(points_cm).reshape(-1, 2).tolist()]


def point(x_m: float, y_m: float, z_m: float) -> dict:
    """A ``foxglove.Point3`` (m)."""
    return {"x": x_m, "y": y_m, "z": z_m}


def half_angle(heading_deg: float) -> tuple[float, float]:
    """(z, w) of the quaternion of a rotation by ``heading_deg`` about the vertical (portable: log content must not
    depend on the CPU); exactly (0.0, 1.0) for heading 0. A numpy scalar is taken as the equal float (the same
    half; the JSON is the same)."""
    return (0.0, 1.0) if heading_deg == 0.0 else sin_cos_deg(float(heading_deg) / 2.0)


def pose_m(x_m: float, y_m: float, z_m: float, qz: float, qw: float) -> dict:
    """A ``foxglove.Pose`` at (x, y, z) m rotated about the vertical by the quaternion (0, 0, qz, qw)."""
    orientation = _NO_ROTATION if (qz, qw) == (0.0, 1.0) else {"x": 0.0, "y": 0.0, "z": qz, "w": qw}
    return {"position": {"x": x_m, "y": y_m, "z": z_m}, "orientation": orientation}


def pose(x_cm: float, y_cm: float, heading_deg: float = 0.0, z_m: float = 0.0) -> dict:
    """A ``foxglove.Pose`` at (x, y) cm (written in m, 0.1 mm) and height ``z_m``, heading ``heading_deg``."""
    return pose_m(metres(x_cm), metres(y_cm), float(z_m), *half_angle(heading_deg))


def entity(stamp: dict[str, int], eid: str, **primitives: Any) -> dict:
    """A ``foxglove.SceneEntity`` (lifetime 0: until replaced) with the given primitive lists."""
    return {"timestamp": stamp, "frame_id": FRAME, "id": eid, "lifetime": _FOREVER,
            "frame_locked": False, "metadata": (), **_NO_PRIMITIVES, **primitives}


def disc(x_cm: float, y_cm: float, r_cm: float, height_m: float, color: dict) -> dict:
    """A ``foxglove.CylinderPrimitive`` of radius ``r_cm`` standing at (x, y) cm."""
    return cylinder(metres(x_cm), metres(y_cm), metres(2 * r_cm), height_m, color)


def cylinder(x_m: float, y_m: float, diameter_m: float, height_m: float, color: dict) -> dict:
    """A ``foxglove.CylinderPrimitive`` standing at (x, y) m."""
    return {"pose": pose_m(x_m, y_m, height_m / 2, 0.0, 1.0),
            "size": {"x": diameter_m, "y": diameter_m, "z": height_m},
            "bottom_scale": 1.0, "top_scale": 1.0, "color": color}


def arrow(pose: dict, shaft_m: float, head_m: float, color: dict) -> dict:
    """A ``foxglove.ArrowPrimitive`` (shaft 3 cm and head 8 cm wide)."""
    return {"pose": pose, "shaft_length": shaft_m, "shaft_diameter": 0.03, "head_length": head_m,
            "head_diameter": 0.08, "color": color}


def line(points_cm, color: dict, loop: bool = False, thickness_m: float = 0.02, z_m: float = 0.01) -> dict:
    """A ``foxglove.LinePrimitive`` through an (N, 2) array of cm points."""
    return line_m(points_m(points_cm, z_m), color, loop, thickness_m)


def line_m(points: Any, color: dict, loop: bool = False, thickness_m: float = 0.02) -> dict:
    """A ``foxglove.LinePrimitive`` through ``foxglove.Point3`` points (m, from :func:`points_m`)."""
    return {"type": 1 if loop else 0, "pose": _ORIGIN, "thickness": thickness_m, "scale_invariant": False,
            "points": points, "color": color, "colors": (), "indices": ()}


def scene(entities: Any) -> dict:
    """A ``foxglove.SceneUpdate`` adding or replacing ``entities``."""
    return {"deletions": (), "entities": entities}


def static_scene(scenario) -> dict:
    """The first ``/scene`` message: walls, static obstacles (discs or polygon outlines) and the goal disc."""
    xmin, ymin, xmax, ymax = scenario.bounds
    t0 = stamp(0.0)
    entities = [entity(t0, "walls", lines=[line([(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)], GREY,
                                                loop=True, thickness_m=0.04)])]
    for i, obs in enumerate(scenario.static_obstacles):
        if obs.circle is not None:
            c = obs.circle
            entities.append(entity(t0, f"static/{i}", cylinders=[disc(*c.center, c.radius, 0.3, GREY)]))
        else:
            entities.append(entity(t0, f"static/{i}", lines=[line(obs.polygon, GREY, loop=True, thickness_m=0.03)]))
    gx, gy = scenario.robot.goal
    entities.append(entity(t0, "goal", cylinders=[disc(gx, gy, scenario.tolerance, 0.02, GREEN)]))
    return scene(entities)


# -- byte templates -----------------------------------------------------------------------------------------------
def _sentinel(i: int) -> float:
    # below 1e-5: no value a template bakes in can be one (metres() gives 0 or at least 1e-4, the constants are
    # short decimals), and no sentinel's digits are inside another's
    return float(f"1.{i:03d}987654321e-300")


def template(build: Callable[..., Any], slots: int) -> bytes:
    """``%``-format bytes of ``orjson.dumps(build(v0, v1, ...))`` with ``%b`` where each v_i is encoded: fill with
    ``fmt % (b0, b1, ...)``, each b_i the JSON of v_i. ``build`` must encode its arguments once each, in order."""
    sentinels = [_sentinel(i) for i in range(slots)]
    text = orjson.dumps(build(*sentinels))
    pieces, rest = [], text
    for s in sentinels:
        key = orjson.dumps(s)
        if text.count(key) != 1 or key not in rest:
            raise ValueError(f"template: slot value {s} is not encoded once, in argument order")
        head, rest = rest.split(key)
        pieces.append(head)
    pieces.append(rest)
    return b"%b".join(piece.replace(b"%", b"%%") for piece in pieces)


def encoded(values: list) -> list[bytes]:
    """orjson's encoding of each of ``values`` (numbers), from one call (a number's JSON holds no comma)."""
    return orjson.dumps(values, option=_NUMPY)[1:-1].split(b",") if values else []


_POINT = template(lambda x, y, z: point(x, y, z), 3).split(b"%b")  # '{"x":', ',"y":', ',"z":', '}'


def point_lists(xy: list, z_m: float) -> list[bytes]:
    """The JSON of ``[point(x, y, z_m) for x, y in pairs]`` for each list of [x, y] pairs (m) in ``xy``, made from one
    encoding of all pairs: ``[[x,y],[x,y]]`` becomes ``[{"x":x,"y":y,"z":z},...]`` by replacing the separators."""
    if not xy:
        return []
    if not xy[0]:
        return [b"[]"] * len(xy)
    first, x_to_y, y_to_z, last = _POINT
    between_points = y_to_z + orjson.dumps(z_m) + last + b"," + first
    end = y_to_z + orjson.dumps(z_m) + last + b"]"
    columns = orjson.dumps(xy)[3:-3].split(b"]],[[")  # each "x,y],[x,y],...,[x,y"
    return [b"[" + first + c.replace(b",", x_to_y).replace(b"]" + x_to_y + b"[", between_points) + end
            for c in columns]


_SCENE = template(lambda entities: scene(entities), 1)
_TPT = template(lambda sec, nsec, hits, lines: entity({"sec": sec, "nsec": nsec}, "tpt", cylinders=hits,
                                                      lines=lines), 4)
_PLAN = template(lambda sec, nsec, lines: entity({"sec": sec, "nsec": nsec}, "plan", lines=lines), 3)
_ABSENT = template(lambda sec, nsec, eid: entity({"sec": sec, "nsec": nsec}, eid), 3)  # a person not in the world
_TPT_ROBOT_LINE = template(lambda points: line_m(points, CYAN), 1)
_TPT_OBSTACLE_LINE = template(lambda points: line_m(points, ORANGE), 1)
_TPT_Z, _ROBOT_Z, _OBSTACLE_Z, _HEADING_Z, _HIT_HEIGHT = 0.02, 0.2, 0.3, 0.3, 0.05


@functools.lru_cache(maxsize=256)
def _robot(radius_cm: float) -> bytes:
    """The robot entity (disc and heading arrow) of a robot of ``radius_cm``: slots sec, nsec, arrow x, y, qz, qw,
    disc x, y."""
    return template(lambda sec, nsec, ax, ay, qz, qw, x, y: entity(
        {"sec": sec, "nsec": nsec}, "robot",
        arrows=[arrow(pose_m(ax, ay, _ROBOT_Z, qz, qw), metres(radius_cm), metres(radius_cm * 0.6), BLUE)],
        cylinders=[cylinder(x, y, metres(2 * radius_cm), _ROBOT_Z, BLUE)]), 8)


@functools.lru_cache(maxsize=256)
def _obstacle(radius_cm: float) -> tuple[bytes, bytes]:
    """A moving obstacle's entity (slots sec, nsec, id, arrows, disc x, y; the id a slot, so no name from a scenario
    is part of a template) and its heading arrow (slots x, y, qz, qw)."""
    return (template(lambda sec, nsec, eid, arrows, x, y: entity({"sec": sec, "nsec": nsec}, eid, arrows=arrows,
                     cylinders=[cylinder(x, y, metres(2 * radius_cm), _OBSTACLE_Z, RED)]), 6),
            template(lambda x, y, qz, qw: arrow(pose_m(x, y, _HEADING_Z, qz, qw), metres(radius_cm),
                                                metres(radius_cm * 0.6), RED), 4))


@functools.lru_cache(maxsize=256)
def _hit(robot_radius_cm: float) -> bytes:
    """A predicted collision of the TPT: a disc of the robot's size (slots x, y)."""
    return template(lambda x, y: cylinder(x, y, metres(2 * robot_radius_cm), _HIT_HEIGHT, HIT), 2)


class StepScenes:
    """The per-step ``/scene`` messages of one episode, as bytes: the robot (disc and heading), each moving obstacle
    (disc; an arrow along its velocity when ``headings[i]``, i.e. a reactive obstacle model), the TPT's predicted
    robot and obstacle lines and its hits, and the plan's line (built when a plan is made, repeated while it runs)."""

    def __init__(self, robot_radius_cm: float, obstacle_ids: Sequence[str], radii_cm: Sequence[float],
                 headings: Sequence[bool]) -> None:
        self._robot = _robot(robot_radius_cm)
        self._obstacles = [(*_obstacle(float(r)), orjson.dumps(f"obstacle/{oid}"), bool(h))
                           for oid, r, h in zip(obstacle_ids, radii_cm, headings, strict=True)]
        self._plan = b"[]"
        self._shows = np.array([h for *_, h in self._obstacles], dtype=bool)
        self._any_shows = bool(self._shows.any())  # scripted obstacles only (e.g. ``mixed``): no arrow to draw

    def _arrow_quaternions(self, velocities_cm_s: np.ndarray) -> list[float]:
        """qz, qw, qz, qw, ... of the heading arrows drawn this step (the obstacles that show their heading and move),
        in obstacle order: :func:`half_angle` of each velocity's direction, in two array calls (the same bits as one
        at a time: the array and scalar forms of the portable functions agree bit for bit)."""
        if not self._any_shows:
            return []
        v = np.asarray(velocities_cm_s, dtype=np.float64).reshape(-1, 2)
        drawn = self._shows & ((v[:, 0] != 0.0) | (v[:, 1] != 0.0))
        if not drawn.any():
            return []
        heading = atan2_deg_array(v[drawn, 1], v[drawn, 0])
        qz, qw = sin_cos_deg_array(heading / 2.0)
        level = heading == 0.0  # half_angle's exact (0, 1) for heading 0
        return np.stack([np.where(level, 0.0, qz), np.where(level, 1.0, qw)], axis=1).ravel().tolist()

    def message(self, when: dict[str, int], x_cm: float, y_cm: float, heading_deg: float, positions_cm: np.ndarray,
                velocities_cm_s: np.ndarray, tpt, plan, new_plan: bool, present: np.ndarray | None = None) -> bytes:
        """The ``/scene`` message of a step at ``when`` (``foxglove.Time``): robot at (x, y) cm heading
        ``heading_deg``; moving obstacles at ``positions_cm`` (N, 2) with ``velocities_cm_s`` (N, 2); ``tpt`` the
        step's :class:`fuzzynav.planning.tpt.TPT` or None; ``plan`` the running plan (None: no plan), ``new_plan``
        whether
        it was made this step (its line starts at the robot's position); ``present`` (N,) bool which obstacles are in
        the world (None: all): an absent one's entity is sent empty (it replaces the disc drawn before)."""
        if present is not None:  # an absent person has no heading arrow (its slot would shift the others')
            velocities_cm_s = np.where(np.asarray(present, bool)[:, None], velocities_cm_s, 0.0)
        positions = [metres(v) for xy in positions_cm.tolist() for v in xy]
        headings = self._arrow_quaternions(velocities_cm_s)
        hits_at = []  # the TPT's robot positions (m) where it predicts a collision (after the first row)
        if tpt is not None:
            robot_line = _metres_array(tpt.robot).tolist()
            hits_at = [metres(v) for row in np.flatnonzero(np.asarray(tpt.collide)[1:].any(axis=1)).tolist()
                       for v in tpt.robot[row + 1].tolist()]
        numbers = encoded([when["sec"], when["nsec"], metres(x_cm), metres(y_cm), *half_angle(heading_deg),
                           *positions, *headings, *hits_at])
        sec, nsec, rx, ry, rqz, rqw = numbers[:6]
        at = 6
        entities = [self._robot % (sec, nsec, rx, ry, rqz, rqw, rx, ry)]
        heads = iter(range(6 + len(positions), len(numbers), 2))
        absent = [False] * len(self._obstacles) if present is None else (~np.asarray(present, bool)).tolist()
        for (body, arrow_text, eid, shows), (vx, vy), gone in zip(self._obstacles, velocities_cm_s.tolist(), absent,
                                                                  strict=True):
            x, y = numbers[at], numbers[at + 1]
            at += 2
            if gone:  # its velocity was zeroed above: no arrow slot was used
                entities.append(_ABSENT % (sec, nsec, eid))
                continue
            arrows = b"[]"
            if shows and (vx != 0.0 or vy != 0.0):
                h = next(heads)
                arrows = b"[" + arrow_text % (x, y, numbers[h], numbers[h + 1]) + b"]"
            entities.append(body % (sec, nsec, eid, arrows, x, y))
        lines = hits = b"[]"
        if tpt is not None:
            z = _TPT_Z
            robot_points, = point_lists([robot_line], z)
            obstacle_lines = [_TPT_OBSTACLE_LINE % (p,) for p in point_lists(
                _metres_array(tpt.obstacles).transpose(1, 0, 2).tolist(), z)] if len(tpt.obstacle_ids) else []
            lines = b"[" + b",".join([_TPT_ROBOT_LINE % (robot_points,), *obstacle_lines]) + b"]"
            first_hit = 6 + len(positions) + len(headings)
            hit = _hit(tpt.robot_radius)
            hits = b"[" + b",".join(hit % (numbers[i], numbers[i + 1])
                                    for i in range(first_hit, len(numbers), 2)) + b"]"
        entities.append(_TPT % (sec, nsec, hits, lines))
        if plan is None:
            self._plan = b"[]"
        elif new_plan:
            self._plan = orjson.dumps([line([[x_cm, y_cm], *plan.path.tolist()], PURPLE, thickness_m=0.04, z_m=0.03)],
                                      option=_NUMPY)
        entities.append(_PLAN % (sec, nsec, self._plan))
        return _SCENE % (b"[" + b",".join(entities) + b"]",)
