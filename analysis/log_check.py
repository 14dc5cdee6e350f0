"""What the analysis reads from a log, checked before it is believed.

Three levels, each raising :class:`CheckError` with the field and the problem:

* :func:`check_metadata` — the ``fuzzynav.run`` record: seed (at most 2^53 - 1, exact in the analysis's float
  tables) and h_wait are non-negative integers, names are safe labels (letters, digits, ``_-.``, not starting
  with ``.``, at most 64 characters), the strategy and perception are known values, the config is
  a YAML mapping of plain values (finite numbers, string keys, at most ``MAX_CONFIG_NODES`` nodes: no alias
  bombs) whose step length ``dt`` (s) is positive, and whose copies of the shown parameters agree with the
  record; a ``config_hash`` that is a SHA-256 must be the hash of the config and seed (as ``runners.run``
  computes it), so a damaged or edited record is caught even in logs without a data-section CRC.
* :func:`check_message` — per topic, the fields of a message that the analysis uses: present, of the JSON type
  the topic's schema gives (``runners/fuzzynav_schemas.py``, ``runners/foxglove_schemas.py``; a test keeps the
  two in agreement), finite, and in their documented range (cm quantities within ±``MAX_CM``, headings in
  [0, 360] degrees, ...). Hand-written rather than jsonschema (a dev dependency only): a few microseconds per
  message, number fields of one range and the TPT's tables checked together with map/set/min/max, where
  jsonschema takes tens of times longer and the analysis must stay above 50 episodes/s.
* :func:`check_episode` — the messages together: one message per step and topic, numbered from 0; log times at
  step * dt; the robot's and the moving obstacles' positions continuous from one step to the next (each step's
  ``next_*`` is the following step's position); the TPT's shape and step length; the ``/episode`` step count and
  time; the decisions' strategy and h_wait those of the metadata.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Callable, Mapping
from itertools import chain
from operator import itemgetter
from typing import TYPE_CHECKING, Any

import yaml

if TYPE_CHECKING:
    from analysis.episode_log import EpisodeLog

MAX_CM = 1e9  # the scenario files' limit on coordinates (cm); speeds (cm/s) and sonar readings share it
MAX_US = 1e12  # compute time of one decision (µs): 11 days
MAX_DT_S = 1e6  # step length (s)
MAX_CONFIG_BYTES = 1 << 20
MAX_CONFIG_NODES = 100_000
NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,63}")  # safe as a label and a file-name part (no "..")
MAX_SEED = 2**53 - 1  # the analysis's tables hold seeds as float64: larger ones would merge
STRATEGIES = ("auto", "wait", "detour", "none")
PERCEPTIONS = ("laser", "ground_truth")
OUTCOMES = ("goal", "collision", "timeout", "error", "interrupted")
FINISHED = ("goal", "collision", "timeout")  # outcomes whose log must hold every step
MODES = ("direct", "fuzzy", "wait", "detour", "evade", "stop")
PLAN_STRATEGIES = ("wait", "detour", "evade", "stop")
TIME_TOLERANCE_NS = 1000  # log times are round(step * dt * 1e9): 1 µs of slack for the float product
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class CheckError(ValueError):
    """A value the analysis would read is missing, of the wrong type, out of range or inconsistent.
    ``where``: the field's path (``x_cm``, ``obstacles[2].radius_cm``); ``problem``: what is wrong."""

    def __init__(self, where: str, problem: str) -> None:
        super().__init__(f"{where}: {problem}" if where else problem)
        self.where, self.problem = where, problem

    def inside(self, prefix: str) -> CheckError:
        """The same problem one level up (``prefix`` is the enclosing field or ``[index]``)."""
        joined = prefix if not self.where else f"{prefix}{self.where}" if self.where.startswith("[") \
            else f"{prefix}.{self.where}"
        return CheckError(joined, self.problem)


Check = Callable[[Any], None]  # raises CheckError (with an empty ``where``) if the value is not acceptable


def _kind(value: Any) -> str:
    return "null" if value is None else {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
                                         list: "an array", dict: "an object"}.get(type(value), type(value).__name__)


def number(lo: float = -MAX_CM, hi: float = MAX_CM) -> Check:
    """A JSON number (not a boolean) in [lo, hi]; NaN and infinities fail the range test."""
    def check(v: Any) -> None:
        t = type(v)
        if t is not float and t is not int:
            raise CheckError("", f"expected a number, got {_kind(v)}")
        if not lo <= v <= hi:
            raise CheckError("", f"{v!r} is out of range [{lo:g}, {hi:g}]")
    check.bounds = (lo, hi)  # type: ignore[attr-defined]  # lets obj() check such fields together
    return check


def integer(lo: int = 0, hi: int = 2**63 - 1) -> Check:
    def check(v: Any) -> None:
        if type(v) is not int:
            raise CheckError("", f"expected an integer, got {_kind(v)}")
        if not lo <= v <= hi:
            raise CheckError("", f"{v!r} is out of range [{lo}, {hi}]")
    return check


def boolean(v: Any) -> None:
    if type(v) is not bool:
        raise CheckError("", f"expected a boolean, got {_kind(v)}")


def string(v: Any) -> None:
    if type(v) is not str:
        raise CheckError("", f"expected a string, got {_kind(v)}")


def one_of(*values: str) -> Check:
    allowed = frozenset(values)

    def check(v: Any) -> None:
        if type(v) is not str or v not in allowed:
            raise CheckError("", f"{v!r} is not one of {', '.join(values)}")
    return check


def nullable(inner: Check) -> Check:
    def check(v: Any) -> None:
        if v is not None:
            inner(v)
    return check


def array(item: Check, min_items: int = 0, length: int | None = None) -> Check:
    """A JSON array of ``item``s (at least ``min_items``; exactly ``length`` when given)."""
    def check(v: Any) -> None:
        if type(v) is not list:
            raise CheckError("", f"expected an array, got {_kind(v)}")
        if len(v) < min_items or (length is not None and len(v) != length):
            raise CheckError("", f"{len(v)} items, expected {length if length is not None else f'>= {min_items}'}")
        i = 0
        try:
            for i, x in enumerate(v):  # noqa: B007 - i names the failing item
                item(x)
        except CheckError as err:
            raise err.inside(f"[{i}]") from None
    return check


class _Slow(Exception):
    """The fast path of :func:`obj` saw something wrong: the field-by-field path says what."""


def obj(**fields: Check) -> Check:
    """A JSON object with at least these fields (others are not read, so not checked). Number fields with the
    same range are checked together at C speed (one ``itemgetter``, a set of types, min and max); the rest, and
    any object the fast path refuses, field by field."""
    items = tuple(fields.items())
    by_range: dict[tuple[float, float], list[str]] = {}
    for name, field_check in items:
        bounds = getattr(field_check, "bounds", None)
        if bounds is not None:
            by_range.setdefault(bounds, []).append(name)
    groups = tuple((itemgetter(*names), lo, hi) for (lo, hi), names in by_range.items() if len(names) > 1)
    grouped = {name for (_lo, _hi), names in by_range.items() if len(names) > 1 for name in names}
    others = tuple((name, c) for name, c in items if name not in grouped)

    def field_by_field(v: Any) -> None:
        name = ""
        try:
            for name, field_check in items:
                field_check(v[name])
        except KeyError:
            raise CheckError(name, "missing") from None
        except CheckError as err:
            raise err.inside(name) from None

    def check(v: Any) -> None:
        if type(v) is not dict:
            raise CheckError("", f"expected an object, got {_kind(v)}")
        try:
            for get, lo, hi in groups:
                values = get(v)
                if not (set(map(type, values)) <= _NUMERIC and lo <= min(values) and max(values) <= hi):
                    raise _Slow
            for name, field_check in others:
                field_check(v[name])
        except (KeyError, CheckError, _Slow):
            field_by_field(v)
            raise CheckError("", "not acceptable") from None  # unreachable while the two paths agree
    return check


_NUMERIC = frozenset({int, float})
_LIST = frozenset({list})
_BOOL = frozenset({bool})


def _fast(accept: Callable[[Any], bool], slow: Check) -> Check:
    """``accept`` decides the common case at C speed; when it says no, ``slow`` (the same rule, item by item)
    finds the item and says what is wrong."""
    def check(v: Any) -> None:
        if not accept(v):
            slow(v)
            raise CheckError("", "not acceptable")  # unreachable while the two rules agree
    return check


def numbers(lo: float = -MAX_CM, hi: float = MAX_CM, min_items: int = 0, length: int | None = None) -> Check:
    """An array of numbers in [lo, hi] (the large TPT and laser arrays: checked with set, min and max)."""
    def accept(v: Any) -> bool:
        if type(v) is not list or len(v) < min_items or (length is not None and len(v) != length):
            return False
        return not v or (set(map(type, v)) <= _NUMERIC and lo <= min(v) and max(v) <= hi)
    return _fast(accept, array(number(lo, hi), min_items, length))


def _are_points(v: Any) -> bool:
    """An array of [x, y] number pairs within ±MAX_CM (map, set, min and max: no Python loop per pair)."""
    if type(v) is not list:
        return False
    if not v:
        return True
    if not set(map(type, v)) <= _LIST or set(map(len, v)) != {2}:
        return False
    coords = list(chain.from_iterable(v))
    return set(map(type, coords)) <= _NUMERIC and min(coords) >= -MAX_CM and max(coords) <= MAX_CM


def points(min_items: int = 0) -> Check:
    """An array of [x, y] pairs of numbers (cm)."""
    return _fast(lambda v: _are_points(v) and len(v) >= min_items, array(array(number(), length=2), min_items))


def point_rows(min_items: int = 0) -> Check:
    """An array of arrays of [x, y] pairs (the TPT's predicted obstacle positions, [row][obstacle])."""
    def accept(v: Any) -> bool:
        return type(v) is list and len(v) >= min_items and set(map(type, v)) <= _LIST \
            and _are_points(list(chain.from_iterable(v)))
    return _fast(accept, array(points(), min_items))


def boolean_rows(min_items: int = 0) -> Check:
    """An array of arrays of booleans (the TPT's collision matrix)."""
    def accept(v: Any) -> bool:
        return type(v) is list and len(v) >= min_items and set(map(type, v)) <= _LIST \
            and set(map(type, chain.from_iterable(v))) <= _BOOL
    return _fast(accept, array(array(boolean), min_items))


CM, SPEED = number(), number()
POSITIVE_CM = number(1e-9, MAX_CM)
READING = number(0.0, MAX_CM)
HEADING = number(0.0, 360.0)
STEP = integer()
_POINT = obj(x=number(-MAX_CM / 100, MAX_CM / 100), y=number(-MAX_CM / 100, MAX_CM / 100))  # m

_TPT_SCALARS = obj(step=STEP, n_traj=integer(1, 1_000_000), dt_s=number(1e-9, MAX_DT_S),
                   robot_radius_cm=POSITIVE_CM, obstacle_ids=array(integer()), obstacle_radii_cm=numbers(0.0))
_TPT_TABLES = obj(robot_cm=points(1), obstacles_cm=point_rows(1), collide=boolean_rows(1))


def check_tpt(v: Any) -> None:
    """A TPT message: its fields, and its shape — n_traj + 1 rows of the robot's position, and of one position
    and one collision flag per obstacle column. The tables (the largest message of a step) are checked with
    map, set, min and max over the whole table; item by item only to say what is wrong."""
    _TPT_SCALARS(v)
    rows, k = v["n_traj"] + 1, len(v["obstacle_ids"])
    robot, obstacles, collide = v.get("robot_cm"), v.get("obstacles_cm"), v.get("collide")
    if (_are_points(robot) and len(robot) == rows
            and type(obstacles) is list and len(obstacles) == rows and set(map(type, obstacles)) <= _LIST
            and set(map(len, obstacles)) <= {k} and _are_points(list(chain.from_iterable(obstacles)))
            and type(collide) is list and len(collide) == rows and set(map(type, collide)) <= _LIST
            and set(map(len, collide)) <= {k} and set(map(type, chain.from_iterable(collide))) <= _BOOL
            and len(v["obstacle_radii_cm"]) == k):
        return
    _TPT_TABLES(v)
    for name in ("robot_cm", "obstacles_cm", "collide"):
        if len(v[name]) != rows:
            raise CheckError(name, f"{len(v[name])} rows, expected n_traj + 1 = {rows}")
    if len(v["obstacle_radii_cm"]) != k:
        raise CheckError("obstacle_radii_cm", f"{len(v['obstacle_radii_cm'])} values for {k} obstacles")
    for name in ("obstacles_cm", "collide"):
        for i, row in enumerate(v[name]):
            if len(row) != k:
                raise CheckError(f"{name}[{i}]", f"{len(row)} columns for {k} obstacles")
    raise CheckError("", "not acceptable")  # unreachable while the fast and slow rules agree


MESSAGE_CHECKS: dict[str, Check] = {
    "/robot/state": obj(step=STEP, x_cm=CM, y_cm=CM, heading_deg=HEADING, v_cm_s=SPEED, next_x_cm=CM,
                        next_y_cm=CM, next_heading_deg=HEADING, radius_cm=POSITIVE_CM, contact_static=boolean,
                        contact_dynamic=array(string), distance_to_goal_cm=READING),
    "/obstacles/truth": obj(step=STEP, obstacles=array(obj(id=string, x_cm=CM, y_cm=CM, next_x_cm=CM, next_y_cm=CM,
                                                           radius_cm=POSITIVE_CM))),
    "/planner/decision": obj(
        step=STEP, mode=one_of(*MODES), new_plan=boolean, left_cm=READING, front_cm=READING, right_cm=READING,
        angle_deg=number(0.0, 180.0), dtheta_deg=number(), v_cm_s=READING, strategy=string,
        planning=nullable(obj(strategy=one_of(*PLAN_STRATEGIES), tc=STEP, tS=STEP, tG=STEP, wait_time=STEP,
                              h_wait=STEP, reason=string)),
        compute_time_us=number(0.0, MAX_US)),
    "/tpt": check_tpt,
    "/episode": obj(outcome=one_of(*OUTCOMES), steps=STEP, time_s=number(0.0, MAX_US), contacts=STEP,
                    reason=string),
    "/tracks": obj(step=STEP, moving_beams=array(integer(0, 2**31)), tracks=array(obj(
        id=integer(), x_cm=CM, y_cm=CM, vx_cm_s=SPEED, vy_cm_s=SPEED, radius_cm=POSITIVE_CM))),
    "/sonar": obj(step=STEP, left_cm=READING, front_cm=READING, right_cm=READING),
    "/laser": obj(ranges=numbers(0.0, MAX_CM / 100, min_items=1), intensities=numbers(0.0, MAX_CM)),
    "/log": obj(level=integer(), message=string),
    # the first /scene: walls, static obstacles and goal (foxglove.SceneUpdate, metres)
    "/scene": obj(entities=array(obj(
        id=string, lines=array(obj(points=array(_POINT))),
        cylinders=array(obj(pose=obj(position=_POINT), size=obj(x=number(0.0, MAX_CM / 100))))))),
}
"""Per topic, the fields the analysis reads (metrics, episode loading, replay, rendering)."""

TOPIC_SCHEMAS = {"/scene": "foxglove.SceneUpdate", "/laser": "foxglove.LaserScan", "/log": "foxglove.Log",
                 "/sonar": "fuzzynav.Sonar", "/tracks": "fuzzynav.Tracks", "/robot/state": "fuzzynav.RobotState",
                 "/obstacles/truth": "fuzzynav.ObstaclesTruth", "/tpt": "fuzzynav.TPT",
                 "/planner/decision": "fuzzynav.Decision", "/episode": "fuzzynav.Episode"}
"""The schema each topic read must declare (when its channel declares one: hand-written test logs do not)."""


def check_message(topic: str, msg: Any) -> None:
    """Raise :class:`CheckError` if ``msg`` lacks a field the analysis reads from ``topic`` or has a bad one."""
    check = MESSAGE_CHECKS.get(topic)
    if check is not None:
        check(msg)


# -- metadata -------------------------------------------------------------------------------------------------
REQUIRED_METADATA = ("seed", "scenario", "strategy", "h_wait", "controller", "perception")
_DIGITS = re.compile(r"[0-9]{1,20}")
_SHA256 = re.compile(r"[0-9a-f]{64}")
_ALIASES = (("planner", "h_wait", "h_wait"), ("planner", "strategy", "strategy"), ("controller", "name", "controller"),
            ("perception", "mode", "perception"), ("scenario", "name", "scenario"))


def check_metadata(meta: Mapping[str, str]) -> tuple[dict[str, Any], float | None]:
    """(the parsed config, its ``dt`` in s or None when the config does not give it). ``meta``: the
    ``fuzzynav.run`` record (string values)."""
    for key in REQUIRED_METADATA:
        if key not in meta:
            raise CheckError(key, "missing")
    for key, most in (("seed", MAX_SEED), ("h_wait", 1_000_000)):
        value = meta[key]
        if not _DIGITS.fullmatch(value):
            raise CheckError(key, f"{value[:40]!r} is not a non-negative integer")
        if int(value) > most:
            raise CheckError(key, f"{value} is out of range [0, {most}]")
    for key in ("scenario", "controller"):
        if not NAME.fullmatch(meta[key]):
            raise CheckError(key, f"{meta[key][:80]!r} is not a name (letters, digits, _-., not starting with "
                                  "'.', at most 64)")
    for key, allowed in (("strategy", STRATEGIES), ("perception", PERCEPTIONS)):
        if meta[key] not in allowed:
            raise CheckError(key, f"{meta[key][:40]!r} is not one of {', '.join(allowed)}")
    config = _parse_config(meta.get("config", ""))
    for section, key, meta_key in _ALIASES:
        node = config.get(section)
        if isinstance(node, dict) and key in node and str(node[key]) != meta[meta_key]:
            raise CheckError(f"config {section}.{key}", f"{node[key]!r} disagrees with {meta_key} "
                                                        f"{meta[meta_key]!r}")
    _check_sonar_sectors(config)
    dt = config.get("dt")
    if dt is not None:
        try:
            number(1e-9, MAX_DT_S)(dt)
        except CheckError as err:
            raise err.inside("config dt") from None
        dt = float(dt)
    digest = meta.get("config_hash", "")
    if _SHA256.fullmatch(digest) and "fuzzynav_version" in meta and \
            digest != config_hash(meta.get("config", ""), meta["seed"], meta["fuzzynav_version"]):
        raise CheckError("config_hash", "is not the hash of the config and seed (edited or damaged metadata)")
    return config, dt


def config_hash(config_yaml: str, seed: str, fuzzynav_version: str) -> str:
    """``runners.run.config_hash`` for a recorded config, seed and fuzzynav version (a test keeps them equal)."""
    body = "\n".join(line for line in config_yaml.splitlines() if not line.startswith("resume:"))
    return hashlib.sha256(f"{body}\nseed={seed}\nfuzzynav={fuzzynav_version}".encode()).hexdigest()


def _parse_config(text: str) -> dict[str, Any]:
    if len(text) > MAX_CONFIG_BYTES:
        raise CheckError("config", f"{len(text)} characters (more than {MAX_CONFIG_BYTES})")
    try:
        config = yaml.load(text, Loader=_YAML_LOADER)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}" if mark is not None else ""
        what = " ".join(str(getattr(err, "problem", None) or getattr(err, "reason", None) or err).split())
        raise CheckError("config", f"not valid YAML{where} ({what})") from None
    except RecursionError:
        raise CheckError("config", "nested too deeply") from None
    if config is None:
        return {}
    if not isinstance(config, dict):
        raise CheckError("config", f"expected a mapping, got {_kind(config)}")
    _check_plain(config)
    return config


def _check_plain(config: dict[str, Any]) -> None:
    """Every key a string, every value null, boolean, finite number, string, list or mapping; at most
    ``MAX_CONFIG_NODES`` nodes counted with repetition, so that aliases cannot make later walks explode."""
    budget = MAX_CONFIG_NODES
    stack: list[tuple[str, Any]] = [("", config)]
    while stack:
        where, node = stack.pop()
        budget -= 1
        if budget < 0:
            raise CheckError("config", f"more than {MAX_CONFIG_NODES} values (YAML aliases?)")
        t = type(node)
        if t is dict:
            for key, value in node.items():
                if type(key) is not str:
                    raise CheckError(f"config {where or '(top level)'}", f"key {key!r} is not a string")
                stack.append((f"{where}.{key}" if where else key, value))
        elif t is list:
            stack.extend((f"{where}[{i}]", value) for i, value in enumerate(node))
        elif t is float:
            if not math.isfinite(node):
                raise CheckError(f"config {where}", f"{node!r} is not finite")
        elif node is not None and t not in (bool, int, str):
            raise CheckError(f"config {where}", f"unexpected value type {t.__name__}")


def _check_sonar_sectors(config: dict[str, Any]) -> None:
    """The sonar sectors the replay draws (``sensors.sonar.left`` etc.): [from, to] in degrees."""
    sonar = (config.get("sensors") or {}).get("sonar") if isinstance(config.get("sensors"), dict) else None
    if not isinstance(sonar, dict):
        return
    for name in ("left", "front", "right"):
        if name in sonar:
            try:
                array(number(-360.0, 360.0), length=2)(sonar[name])
            except CheckError as err:
                raise err.inside(f"config sensors.sonar.{name}") from None


# -- the episode as a whole ----------------------------------------------------------------------------------
def check_episode(log: EpisodeLog, times: Mapping[str, list[int]], config_dt: float | None) -> None:
    """Consistency of the loaded messages (see the module docstring). ``times``: per topic read, the log time
    (ns) of each message in order. Sets ``log.dt`` (s): ``config_dt``, or from the log times when the config
    does not give it."""
    per_step = {"/robot/state": log.states, "/obstacles/truth": log.truth, "/planner/decision": log.decisions,
                "/tracks": log.tracks, "/sonar": log.sonar}
    for topic, messages in per_step.items():
        for k, msg in enumerate(messages):
            if msg["step"] != k:
                raise CheckError(f"{topic} message {k}", f"step {msg['step']}, expected {k} (steps from 0, one "
                                                         "message per step)")
    log.dt = config_dt if config_dt is not None else _dt_from_log(log, times)
    for topic in (*per_step, "/laser"):
        _check_times(topic, times.get(topic, ()), log.dt)
    _check_world(log, times)
    _check_against_scenario(log)
    _check_robot_path(log)
    _check_obstacle_paths(log)
    _check_beams(log)
    _check_tpts(log)
    _check_decisions(log, times)
    _check_counts(log, times)


def _dt_from_log(log: EpisodeLog, times: Mapping[str, list[int]]) -> float:
    """The step length (s) when the config does not give it: the log time of step 1, else the episode's time per
    step, else 1 s (an episode of one step or none has no time to measure)."""
    states = times.get("/robot/state", ())
    if len(states) > 1 and states[1] > 0:
        return states[1] / 1e9
    if log.episode and log.episode["steps"] > 0 and log.episode["time_s"] > 0:
        return log.episode["time_s"] / log.episode["steps"]
    return 1.0


def _check_times(topic: str, times: list[int] | tuple, dt: float) -> None:
    step_ns = dt * 1e9
    for k, t in enumerate(times):
        if abs(t - k * step_ns) > TIME_TOLERANCE_NS:
            raise CheckError(f"{topic} message {k}", f"log time {t} ns, expected step * dt = {k * step_ns:.0f} ns "
                                                     f"(dt {dt:g} s)")


def _check_world(log: EpisodeLog, times: Mapping[str, list[int]]) -> None:
    """The first ``/scene`` is the static world at time 0: walls and goal (a later scene in its place, e.g. when
    the first was dropped, has neither). A complete log has one."""
    if "/scene" not in times:
        return
    if not times["/scene"]:
        if log.complete:
            raise CheckError("/scene", "no scene message: the static world is unknown")
        return
    if times["/scene"][0] != 0 or log.bounds is None or log.goal is None:
        raise CheckError("/scene", "the first scene is not the static world at time 0 (walls and goal)")


_ROBOT = obj(start=array(number(), length=2), goal=array(number(), length=2), heading=number(-1e6, 1e6),
             radius=POSITIVE_CM)


def _check_against_scenario(log: EpisodeLog) -> None:
    """The exact world of the episode (the ``scenario_yaml`` metadata that ``runners.run`` writes; hand-written
    logs have none, or a placeholder that is not a scenario): the robot starts at its start pose with its
    radius, each step's ``distance_to_goal_cm`` is the distance from the position after the move to the goal,
    and the scene's goal is that goal (to the 0.1 mm the scene rounds to)."""
    text = log.meta.get("scenario_yaml", "")
    try:
        world = yaml.load(text, Loader=_YAML_LOADER) if len(text) <= MAX_CONFIG_BYTES else None
    except (yaml.YAMLError, RecursionError):
        world = None
    robot = world.get("robot") if isinstance(world, dict) else None
    if robot is None:
        return
    try:
        _ROBOT(robot)
    except CheckError as err:
        raise err.inside("metadata scenario_yaml robot") from None
    (x0, y0), (gx, gy) = robot["start"], robot["goal"]  # type: ignore[index]
    states = log.states
    if states and (states[0]["x_cm"], states[0]["y_cm"], states[0]["heading_deg"], states[0]["radius_cm"]) != (
            x0, y0, robot["heading"] % 360.0, robot["radius"]):  # type: ignore[index]
        raise CheckError("/robot/state step 0", "not the scenario's start pose and radius (metadata scenario_yaml)")
    for k, st in enumerate(states):
        d = math.hypot(st["next_x_cm"] - gx, st["next_y_cm"] - gy)
        if abs(d - st["distance_to_goal_cm"]) > 1e-6 * max(1.0, d):
            raise CheckError(f"/robot/state step {k}", f"the position after the move is {d:.6f} cm from the goal, "
                                                       f"distance_to_goal_cm says {st['distance_to_goal_cm']!r}")
    if log.goal is not None and max(abs(log.goal[0] - gx), abs(log.goal[1] - gy)) > 0.011:
        raise CheckError("/scene goal", f"{log.goal} is not the scenario's goal ({gx}, {gy})")


def _check_robot_path(log: EpisodeLog) -> None:
    states = log.states
    for k in range(len(states) - 1):
        a, b = states[k], states[k + 1]
        if a["next_x_cm"] != b["x_cm"] or a["next_y_cm"] != b["y_cm"] or a["next_heading_deg"] != b["heading_deg"]:
            raise CheckError(f"/robot/state step {k + 1}", "position or heading differs from step "
                                                           f"{k}'s next_x_cm/next_y_cm/next_heading_deg")
    if states and any(s["radius_cm"] != states[0]["radius_cm"] for s in states):
        raise CheckError("/robot/state radius_cm", "changes during the episode")


def _check_obstacle_paths(log: EpisodeLog) -> None:
    truth = log.truth
    for k in range(len(truth) - 1):
        now, after = truth[k]["obstacles"], truth[k + 1]["obstacles"]
        if len(now) != len(after):
            raise CheckError(f"/obstacles/truth step {k + 1}", f"{len(after)} obstacles, step {k} has {len(now)}")
        for a, b in zip(now, after, strict=True):
            if a["id"] != b["id"] or a["next_x_cm"] != b["x_cm"] or a["next_y_cm"] != b["y_cm"] \
                    or a["radius_cm"] != b["radius_cm"]:
                raise CheckError(f"/obstacles/truth step {k + 1}", f"obstacle {b['id']!r} does not continue step "
                                                                   f"{k}'s obstacle {a['id']!r}")


def _check_beams(log: EpisodeLog) -> None:
    """Each scan has one intensity per range, and the beams the tracker calls moving are beams of the scan."""
    for k, laser in enumerate(log.laser):
        n = len(laser["ranges"])
        if len(laser["intensities"]) != n:
            raise CheckError(f"/laser message {k} intensities", f"{len(laser['intensities'])} values for {n} beams")
        if k < len(log.tracks) and log.tracks[k]["moving_beams"] and max(log.tracks[k]["moving_beams"]) >= n:
            raise CheckError(f"/tracks step {k} moving_beams", f"beam {max(log.tracks[k]['moving_beams'])} of a "
                                                               f"{n}-beam scan")


def _check_tpts(log: EpisodeLog) -> None:
    for step, t in log.tpts.items():
        if abs(t["dt_s"] - log.dt) > 1e-9 * log.dt:
            raise CheckError(f"/tpt step {step} dt_s", f"{t['dt_s']!r} s, the episode's step is {log.dt!r} s")


def _check_decisions(log: EpisodeLog, times: Mapping[str, list[int]]) -> None:
    """Each decision's strategy and plan h_wait are the metadata's; a plan is made from a TPT of its step."""
    strategy, h_wait = log.meta["strategy"], int(log.meta["h_wait"])
    tables = "/tpt" in times
    for k, d in enumerate(log.decisions):
        if tables and d["planning"] is not None and k not in log.tpts:
            raise CheckError(f"/planner/decision step {k} planning", "a plan without a /tpt table of its step")
        if d["strategy"] != strategy:
            raise CheckError(f"/planner/decision step {k} strategy", f"{d['strategy']!r}, the metadata says "
                                                                     f"{strategy!r}")
        plan = d["planning"]
        if plan is not None and plan["h_wait"] != h_wait:
            raise CheckError(f"/planner/decision step {k} planning.h_wait", f"{plan['h_wait']}, the metadata says "
                                                                            f"{h_wait}")


def _check_counts(log: EpisodeLog, times: Mapping[str, list[int]]) -> None:
    """A finished episode (goal, collision, timeout) has one message per step on every per-step topic read, as
    many steps as ``/episode`` says, and its time; TPTs lie within the steps."""
    if log.complete and "/episode" in times and log.episode is None:
        raise CheckError("/episode", "no outcome message, although the file was closed normally")
    n = len(log.states) if "/robot/state" in times else None
    if n is not None:
        for step in log.tpts:
            if step >= n and log.complete:
                raise CheckError(f"/tpt step {step}", f"beyond the episode's {n} steps")
    if not log.complete or log.episode is None or log.episode["outcome"] not in FINISHED:
        return
    steps = log.episode["steps"]
    for topic, messages in times.items():
        if topic in ("/robot/state", "/obstacles/truth", "/planner/decision", "/tracks", "/sonar", "/laser") \
                and len(messages) != steps:
            raise CheckError(topic, f"{len(messages)} messages for the {steps} steps /episode reports")
    if abs(log.episode["time_s"] - steps * log.dt) > 1e-6 * max(1.0, steps * log.dt):
        raise CheckError("/episode time_s", f"{log.episode['time_s']!r} s for {steps} steps of {log.dt!r} s")
