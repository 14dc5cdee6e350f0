"""Scenario model: the world an episode runs in, as a frozen dataclass tree that maps 1:1 onto YAML.

All lengths are in cm, speeds in cm/s, headings in degrees counter-clockwise from +x::

    name: head_on
    bounds: [0, 0, 1000, 600]              # xmin, ymin, xmax, ymax; leaving them is a static collision
    robot: {start: [100, 300], heading: 0, goal: [900, 300], radius: 20}
    static_obstacles:
      - polygon: [[400, 0], [450, 0], [450, 150]]
      - circle: {center: [600, 450], radius: 40}
    dynamic_obstacles:
      - {id: walker, radius: 20, start: [900, 300], velocity: [-20, 0]}
      - {id: loop, radius: 25, waypoints: [[200, 100], [800, 100]], speed: 30, loop: true}
    max_steps: 200
    goal_tolerance: 20                     # default: robot radius

:func:`scenario_from_dict` validates plain data and raises one :class:`ScenarioError` per problem, its
message starting with the field, e.g. ``static_obstacles[2].polygon: self-intersecting``. Constructing
:class:`Scenario` directly runs the same geometric checks, size limits and name checks. Every number is
finite with |x| <= 1e9; ``name`` and obstacle ids are safe file-name parts; counts (obstacles, vertices,
waypoints, max_steps) are bounded by :mod:`fuzzynav.params.limits`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import shapely
from shapely.geometry import Point, Polygon, box
from shapely.validation import explain_validity

from fuzzynav.numerics.portable_math import dist
from fuzzynav.params import limits
from fuzzynav.params.checks import check_count, check_key, check_name, check_text, key_text, kind_of, show
from fuzzynav.params.names import ROBOT_DEFAULTS, SCENARIO_DEFAULTS

Vec2 = tuple[float, float]


class ScenarioError(ValueError):
    """An invalid scenario; the message starts with the offending field."""


@dataclass(frozen=True)
class RobotSpec:
    """The robot: start position (cm), initial heading (degrees CCW from +x), goal (cm), radius (cm)."""

    start: Vec2
    goal: Vec2
    heading: float = 0.0
    radius: float = 20.0


@dataclass(frozen=True)
class Circle:
    """A circle: centre (cm) and radius (cm)."""

    center: Vec2
    radius: float


@dataclass(frozen=True)
class StaticObstacle:
    """A static obstacle: exactly one of ``polygon`` (vertices, cm) or ``circle``."""

    polygon: tuple[Vec2, ...] | None = None
    circle: Circle | None = None

    def geometry(self) -> shapely.Geometry:
        """The obstacle as a shapely geometry (circles are 64-gon approximations, inscribed to < 0.1 %)."""
        if self.circle is not None:
            return Point(self.circle.center).buffer(self.circle.radius, quad_segs=16)
        return Polygon(self.polygon)


@dataclass(frozen=True)
class DynamicObstacle:
    """A moving disc. Either constant velocity (``start`` cm, ``velocity`` cm/s) or a waypoint path
    (``waypoints`` cm, ``speed`` cm/s, ``loop``: return to the first waypoint and repeat; otherwise the
    obstacle stops at the last waypoint). ``model`` names how it moves (:mod:`fuzzynav.pedestrians.base`; None:
    ``scripted``, the path exactly, passing through everything); a reactive model starts on the path and takes
    it as the pedestrian's intent (preferred velocity, or the waypoints to walk through). ``model_params``: the
    model's checked parameters (its ``config_class``)."""

    id: str
    radius: float
    start: Vec2 | None = None
    velocity: Vec2 | None = None
    waypoints: tuple[Vec2, ...] | None = None
    speed: float | None = None
    loop: bool = False
    model: str | None = None
    model_params: Any = None


@dataclass(frozen=True)
class Scenario:
    """A complete scenario (cm, s, degrees). ``goal_tolerance`` None means the robot radius."""

    bounds: tuple[float, float, float, float]
    robot: RobotSpec
    static_obstacles: tuple[StaticObstacle, ...] = ()
    dynamic_obstacles: tuple[DynamicObstacle, ...] = ()
    max_steps: int = 300
    goal_tolerance: float | None = None
    name: str = "unnamed"
    description: str = ""

    def __post_init__(self) -> None:
        validate_geometry(self)

    @property
    def tolerance(self) -> float:
        """Goal tolerance in cm (the robot radius unless set)."""
        return self.robot.radius if self.goal_tolerance is None else self.goal_tolerance


# -- parsing from plain data ----------------------------------------------------------------------------


def _finite(value: Any, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ScenarioError(f"{path}: expected a number, got {show(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ScenarioError(f"{path}: must be finite, got {show(value)}")
    if abs(x) > limits.MAX_COORD_CM:
        raise ScenarioError(f"{path}: {show(value)} is out of range (|x| <= {limits.MAX_COORD_CM:g} cm)")
    return x


def _positive(value: Any, path: str) -> float:
    x = _finite(value, path)
    if x <= 0:
        raise ScenarioError(f"{path}: must be > 0, got {show(value)}")
    return x


def _vec2(value: Any, path: str) -> Vec2:
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != 2:
        raise ScenarioError(f"{path}: expected [x, y], got {show(value)}")
    return (_finite(value[0], f"{path}[0]"), _finite(value[1], f"{path}[1]"))


def _points(value: Any, path: str, minimum: int, maximum: int) -> tuple[Vec2, ...]:
    if not _is_list(value):
        raise ScenarioError(f"{path}: expected a list of [x, y] points, got {show(value)}")
    if len(value) < minimum:
        raise ScenarioError(f"{path}: needs at least {minimum} point(s), got {len(value)}")
    check_count(len(value), path, maximum, ScenarioError, "points")  # before converting them: bounded work
    return tuple(_vec2(p, f"{path}[{i}]") for i, p in enumerate(value))


def _is_list(value: Any) -> bool:
    return isinstance(value, Sequence) and not isinstance(value, str | bytes)


def _mapping(value: Any, path: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ScenarioError(f"{path}: expected a mapping, got {kind_of(value)}")
    return value


def _keys(data: Mapping[str, Any], allowed: set[str], required: set[str], path: str) -> None:
    prefix = f"{path}." if path else ""
    for key in data:
        check_key(key, path, ScenarioError)
        if key not in allowed:
            raise ScenarioError(f"{prefix}{key_text(key)}: unknown key (allowed: {', '.join(sorted(allowed))})")
    for key in sorted(required):
        if key not in data or data[key] is None:
            raise ScenarioError(f"{prefix}{key}: missing")


def _robot(data: Any) -> RobotSpec:
    data = _mapping(data, "robot")
    _keys(data, {"start", "goal", "heading", "radius"}, {"start", "goal"}, "robot")
    return RobotSpec(start=_vec2(data["start"], "robot.start"), goal=_vec2(data["goal"], "robot.goal"),
                     heading=_finite(data.get("heading", ROBOT_DEFAULTS["heading"]), "robot.heading"),
                     radius=_positive(data.get("radius", ROBOT_DEFAULTS["radius"]), "robot.radius"))


def _static(data: Any, path: str) -> StaticObstacle:
    data = _mapping(data, path)
    _keys(data, {"polygon", "circle"}, set(), path)
    has = [k for k in ("polygon", "circle") if data.get(k) is not None]
    if len(has) != 1:
        raise ScenarioError(f"{path}: give exactly one of polygon or circle")
    if has[0] == "polygon":
        return StaticObstacle(polygon=_points(data["polygon"], f"{path}.polygon", 3, limits.MAX_POLYGON_VERTICES))
    c = _mapping(data["circle"], f"{path}.circle")
    _keys(c, {"center", "radius"}, {"center", "radius"}, f"{path}.circle")
    return StaticObstacle(circle=Circle(center=_vec2(c["center"], f"{path}.circle.center"),
                                        radius=_positive(c["radius"], f"{path}.circle.radius")))


def _dynamic(data: Any, path: str) -> DynamicObstacle:
    data = _mapping(data, path)
    _keys(data, {"id", "radius", "start", "velocity", "waypoints", "speed", "loop", "model", "model_params"},
          {"id", "radius"}, path)
    # an id is a name like the scenario's (it names the obstacle in logs and tables): a string, so that `id: 123`
    # and `id: 0x7B` are not the same obstacle by accident
    oid = check_name(data["id"], f"{path}.id", ScenarioError)
    radius = _positive(data["radius"], f"{path}.radius")
    has_cv = data.get("start") is not None or data.get("velocity") is not None
    has_wp = data.get("waypoints") is not None
    if has_cv == has_wp:
        raise ScenarioError(f"{path}: give either start + velocity or waypoints + speed")
    if has_cv:
        for key in ("start", "velocity"):
            if data.get(key) is None:
                raise ScenarioError(f"{path}.{key}: missing")
        if data.get("speed") is not None or data.get("loop"):
            raise ScenarioError(f"{path}: speed and loop go with waypoints, not with start + velocity")
        return DynamicObstacle(id=str(oid), radius=radius, start=_vec2(data["start"], f"{path}.start"),
                               velocity=_vec2(data["velocity"], f"{path}.velocity"), **_model(data, path))
    waypoints = _points(data["waypoints"], f"{path}.waypoints", 1, limits.MAX_WAYPOINTS)
    if data.get("speed") is None:
        raise ScenarioError(f"{path}.speed: missing")
    speed = _positive(data["speed"], f"{path}.speed")
    loop = data.get("loop", False)
    if not isinstance(loop, bool):
        raise ScenarioError(f"{path}.loop: expected true or false, got {show(loop)}")
    return DynamicObstacle(id=str(oid), radius=radius, waypoints=waypoints, speed=speed, loop=loop,
                           **_model(data, path))


def _check_model(dyn: DynamicObstacle, path: str) -> None:
    """A constructed obstacle's model: a known name with its own checked parameters (what :func:`_model` makes)."""
    from fuzzynav.pedestrians.base import model_factory

    try:
        config_class = model_factory(dyn.model, f"{path}.model").config_class
    except ValueError as err:
        raise ScenarioError(str(err)) from None
    if not isinstance(dyn.model_params, config_class):
        raise ScenarioError(f"{path}.model_params: expected the model's {config_class.__name__}, got "
                            f"{show(dyn.model_params)}")


def _check_reactive_starts(reactive: Sequence[tuple[int, DynamicObstacle]]) -> None:
    """Pedestrians of reactive models must not start overlapping each other: two at one point have no direction
    to avoid each other in, and would move as one (scripted obstacles pass through everything, so may overlap)."""
    starts = [(i, d, d.start if d.waypoints is None else d.waypoints[0]) for i, d in reactive]
    for a, (i, di, pi) in enumerate(starts):
        for j, dj, pj in starts[a + 1:]:
            if dist(pi, pj) < di.radius + dj.radius:
                raise ScenarioError(f"dynamic_obstacles[{j}]: starts overlapping dynamic_obstacles[{i}] (pedestrians "
                                    f"of reactive models, {dj.model} and {di.model}, must start apart)")


def _model(data: Mapping[str, Any], path: str) -> dict[str, Any]:
    """``model`` and ``model_params`` of an obstacle entry, checked (:mod:`fuzzynav.pedestrians.base`); none when
    the entry names no model (so a scripted scenario's logged YAML is what it was before models existed)."""
    from fuzzynav.pedestrians.base import model_config  # the models import this module

    name, params = data.get("model"), data.get("model_params")
    if name is None:
        if params is not None:
            raise ScenarioError(f"{path}.model_params: given without a model (add model: <name>)")
        return {}
    try:
        return {"model": name, "model_params": model_config(name, params, f"{path}.model_params")}
    except ValueError as err:
        raise ScenarioError(str(err)) from None


def check_dynamic_count(models: list[Any]) -> None:
    """The size limits of ``dynamic_obstacles`` (their ``model`` entries, None where none): recorded people
    (:data:`fuzzynav.params.limits.MAX_RECORDED_PEOPLE`) and the others (``MAX_DYNAMIC_OBSTACLES``) each."""
    recorded = sum(1 for m in models if m == limits.RECORDED_MODEL)
    check_count(len(models) - recorded, "dynamic_obstacles", limits.MAX_DYNAMIC_OBSTACLES, ScenarioError,
                "obstacles (other than recorded people)")
    check_count(recorded, "dynamic_obstacles", limits.MAX_RECORDED_PEOPLE, ScenarioError,
                f"obstacles of model {limits.RECORDED_MODEL}")


def scenario_from_dict(data: Mapping[str, Any]) -> Scenario:
    """Validate plain data (as loaded from YAML) and build a :class:`Scenario`."""
    data = _mapping(data, "scenario")
    _keys(data, {"name", "description", "bounds", "robot", "static_obstacles", "dynamic_obstacles",
                 "max_steps", "goal_tolerance"}, {"bounds", "robot"}, "")
    name = check_name(data.get("name", SCENARIO_DEFAULTS["name"]), "name", ScenarioError)
    description = check_text(data.get("description", SCENARIO_DEFAULTS["description"]), "description",
                             ScenarioError)
    b = data["bounds"]
    if not _is_list(b) or len(b) != 4:
        raise ScenarioError(f"bounds: expected [xmin, ymin, xmax, ymax], got {show(b)}")
    bounds = tuple(_finite(v, f"bounds[{i}]") for i, v in enumerate(b))
    statics = data.get("static_obstacles") or []
    dynamics = data.get("dynamic_obstacles") or []
    for key, value in (("static_obstacles", statics), ("dynamic_obstacles", dynamics)):
        if not _is_list(value):
            raise ScenarioError(f"{key}: expected a list")
    check_count(len(statics), "static_obstacles", limits.MAX_STATIC_OBSTACLES, ScenarioError, "obstacles")
    check_dynamic_count([o.get("model") if isinstance(o, Mapping) else None for o in dynamics])
    max_steps = data.get("max_steps", SCENARIO_DEFAULTS["max_steps"])
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise ScenarioError(f"max_steps: expected a positive integer, got {show(max_steps)}")
    check_count(max_steps, "max_steps", limits.MAX_STEPS, ScenarioError, "steps")
    tol = data.get("goal_tolerance", SCENARIO_DEFAULTS["goal_tolerance"])
    return Scenario(
        name=name, description=description,
        bounds=bounds, robot=_robot(data["robot"]),  # type: ignore[arg-type]
        static_obstacles=tuple(_static(o, f"static_obstacles[{i}]") for i, o in enumerate(statics)),
        dynamic_obstacles=tuple(_dynamic(o, f"dynamic_obstacles[{i}]") for i, o in enumerate(dynamics)),
        max_steps=max_steps, goal_tolerance=None if tol is None else _positive(tol, "goal_tolerance"))


# -- geometric validation ---------------------------------------------------------------------------------


def validate_limits(s: Scenario) -> None:
    """Names, sizes and numbers of a constructed scenario (what :func:`scenario_from_dict` checks while parsing,
    for scenarios built in code): safe names, bounded counts, every number finite with |x| <= 1e9."""
    check_name(s.name, "name", ScenarioError)
    check_text(s.description, "description", ScenarioError)
    if isinstance(s.max_steps, bool) or not isinstance(s.max_steps, int) or s.max_steps < 1:
        raise ScenarioError(f"max_steps: expected a positive integer, got {show(s.max_steps)}")
    check_count(s.max_steps, "max_steps", limits.MAX_STEPS, ScenarioError, "steps")
    check_count(len(s.static_obstacles), "static_obstacles", limits.MAX_STATIC_OBSTACLES, ScenarioError, "obstacles")
    check_dynamic_count([o.model for o in s.dynamic_obstacles])
    numbers: list[tuple[str, Any]] = [(f"bounds[{i}]", v) for i, v in enumerate(s.bounds)]
    numbers += [("robot.start", s.robot.start), ("robot.goal", s.robot.goal), ("robot.heading", s.robot.heading),
                ("robot.radius", s.robot.radius), ("goal_tolerance", s.goal_tolerance)]
    vertices = 0
    for i, obs in enumerate(s.static_obstacles):
        if obs.polygon is not None:
            check_count(len(obs.polygon), f"static_obstacles[{i}].polygon", limits.MAX_POLYGON_VERTICES,
                        ScenarioError, "points")
            vertices += len(obs.polygon)
            numbers.append((f"static_obstacles[{i}].polygon", obs.polygon))
        if obs.circle is not None:
            numbers += [(f"static_obstacles[{i}].circle.center", obs.circle.center),
                        (f"static_obstacles[{i}].circle.radius", obs.circle.radius)]
    check_count(vertices, "static_obstacles", limits.MAX_TOTAL_VERTICES, ScenarioError, "polygon vertices")
    for i, dyn in enumerate(s.dynamic_obstacles):
        path = f"dynamic_obstacles[{i}]"
        check_name(dyn.id, f"{path}.id", ScenarioError)
        if dyn.waypoints is not None:
            check_count(len(dyn.waypoints), f"{path}.waypoints", limits.MAX_WAYPOINTS, ScenarioError, "points")
        numbers += [(f"{path}.{key}", getattr(dyn, key)) for key in ("radius", "start", "velocity", "waypoints",
                                                                      "speed")]
    for path, value in numbers:
        _check_finite_tree(value, path)


def _check_finite_tree(value: Any, path: str) -> None:
    """Every number in ``value`` (a number, a point or a list of points; None allowed) finite, |x| <= 1e9."""
    if value is None:
        return
    if isinstance(value, tuple | list):
        for i, item in enumerate(value):
            _check_finite_tree(item, f"{path}[{i}]")
        return
    _finite(value, path)


def validate_geometry(s: Scenario) -> None:
    """Check the limits (:func:`validate_limits`), then the relations between the parts of a scenario; raise
    :class:`ScenarioError` on the first problem."""
    validate_limits(s)
    xmin, ymin, xmax, ymax = s.bounds
    if not (xmin < xmax and ymin < ymax):
        raise ScenarioError(f"bounds: need xmin < xmax and ymin < ymax, got {list(s.bounds)}")
    area = box(xmin, ymin, xmax, ymax)
    r = s.robot.radius
    if r <= 0:
        raise ScenarioError(f"robot.radius: must be > 0, got {r}")
    start, goal = Point(s.robot.start), Point(goal_xy := s.robot.goal)
    if not area.covers(start):
        raise ScenarioError(f"robot.start: {list(s.robot.start)} is outside bounds {list(s.bounds)}")
    if not area.covers(goal):
        raise ScenarioError(f"robot.goal: {list(goal_xy)} is outside bounds {list(s.bounds)}")
    if start.distance(area.exterior) < r:
        raise ScenarioError(f"robot.start: the robot (radius {r} cm) does not fit inside the bounds there")
    if goal.distance(area.exterior) < r:  # the robot would have to cross the wall to stand at its goal
        raise ScenarioError(f"robot.goal: the robot (radius {r} cm) does not fit inside the bounds there")
    from fuzzynav.pedestrians.base import model_factory  # the models import this module

    reactive: list[tuple[int, DynamicObstacle]] = []
    for i, dyn in enumerate(s.dynamic_obstacles):
        if dyn.model is not None or dyn.model_params is not None:
            _check_model(dyn, f"dynamic_obstacles[{i}]")
            check = getattr(model_factory(dyn.model, "model"), "check_obstacle", None)
            if check is not None:  # what the model needs of the entry beyond its parameters (recorded: a time each)
                try:
                    check(dyn)
                except ValueError as err:
                    raise ScenarioError(f"dynamic_obstacles[{i}].{err}") from None
            # scripted and recorded obstacles pass through everything (``reactive = False``), so may overlap
            if dyn.model != "scripted" and getattr(model_factory(dyn.model, "model"), "reactive", True):
                reactive.append((i, dyn))
    _check_reactive_starts(reactive)
    if s.tolerance <= 0:
        raise ScenarioError(f"goal_tolerance: must be > 0, got {s.goal_tolerance}")
    if start.distance(goal) <= s.tolerance:
        raise ScenarioError(f"robot.goal: equal to robot.start (within goal_tolerance {s.tolerance} cm)")
    for i, obs in enumerate(s.static_obstacles):
        path = f"static_obstacles[{i}]"
        if obs.circle is not None:
            if obs.circle.radius <= 0:
                raise ScenarioError(f"{path}.circle.radius: must be > 0, got {obs.circle.radius}")
            geom = obs.geometry()
        else:
            if obs.polygon is None or len(obs.polygon) < 3:
                raise ScenarioError(f"{path}.polygon: needs at least 3 points")
            for k in range(1, len(obs.polygon)):  # a closing point equal to the first is fine
                if obs.polygon[k] == obs.polygon[k - 1]:
                    raise ScenarioError(f"{path}.polygon[{k}]: repeats the point before it (a zero-length edge)")
            geom = obs.geometry()
            if not geom.is_valid:
                reason = explain_validity(geom)
                what = "self-intersecting" if "Self-intersection" in reason else reason
                raise ScenarioError(f"{path}.polygon: {what}")
            if geom.area <= 0:
                raise ScenarioError(f"{path}.polygon: has zero area")
        if not geom.intersects(area):  # a typo (a centre in mm, a swapped sign): it could never be met
            shape = "circle" if obs.circle is not None else "polygon"
            raise ScenarioError(f"{path}.{shape}: wholly outside bounds {list(s.bounds)}")
        if geom.contains(start) or geom.distance(start) < r:
            raise ScenarioError(f"{path}: overlaps the robot at robot.start (radius {r} cm)")
        if geom.covers(goal):
            raise ScenarioError(f"robot.goal: inside {path}")
    seen: set[str] = set()
    for i, dyn in enumerate(s.dynamic_obstacles):
        path = f"dynamic_obstacles[{i}]"
        if dyn.id in seen:
            raise ScenarioError(f"{path}.id: duplicate id {show(dyn.id)}")
        seen.add(dyn.id)
        if dyn.radius <= 0:
            raise ScenarioError(f"{path}.radius: must be > 0, got {dyn.radius}")
        if dyn.waypoints is not None:
            if len(dyn.waypoints) == 0:
                raise ScenarioError(f"{path}.waypoints: empty")
            if dyn.speed is None or dyn.speed <= 0:
                raise ScenarioError(f"{path}.speed: must be > 0 with waypoints, got {dyn.speed}")
            first = dyn.waypoints[0]
        else:
            if dyn.start is None or dyn.velocity is None:
                raise ScenarioError(f"{path}: constant-velocity obstacles need start and velocity")
            first = dyn.start
        if Point(first).distance(start) < r + dyn.radius:
            raise ScenarioError(f"{path}: overlaps the robot at robot.start")
        # the world's bounds are walls: a moving obstacle starting or heading for a point outside them is a typo
        # (a coordinate in mm, a swapped sign), and one starting inside a static obstacle is never seen there
        points = [("start", dyn.start)] if dyn.waypoints is None else [
            (f"waypoints[{k}]", w) for k, w in enumerate(dyn.waypoints)]
        for name, xy in points:
            if not area.covers(Point(xy)):
                raise ScenarioError(f"{path}.{name}: {list(xy)} is outside bounds {list(s.bounds)}")
        for k, obs in enumerate(s.static_obstacles):
            if obs.geometry().covers(Point(first)):
                raise ScenarioError(f"{path}: starts inside static_obstacles[{k}]")
