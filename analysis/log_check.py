"""What the analysis reads from a log, checked before it is believed.

Each raises :class:`CheckError` (:mod:`analysis.json_checks`) with the field and the problem:

* :func:`check_metadata` — the ``fuzzynav.run`` record: seed (at most 2^53 - 1, exact in the analysis's float
  tables) and h_wait are non-negative integers, names are safe labels (letters, digits, ``_-.``, not starting
  with ``.``, at most 64 characters), the strategy and perception are known values, the config is
  a YAML mapping of plain values (finite numbers, string keys, at most ``MAX_CONFIG_NODES`` nodes: no alias
  bombs) whose step length ``dt`` (s) is positive, and whose copies of the shown parameters agree with the
  record; ``config_hash`` (present, a SHA-256) must be the hash of the config, seed and ``fuzzynav_version`` (as
  ``runners.run`` computes it), so a damaged or edited record is caught even in logs without a data-section CRC.
* :func:`check_message` — per topic, the fields of a message that the analysis reads (:data:`READ`): present, of
  the JSON type the topic's schema gives (:mod:`analysis.log_format`, the schemas the writer embeds in every log),
  finite, and in their range (:data:`RANGES`: cm quantities within ±``MAX_CM``, headings in [0, 360] degrees,
  ...). The checks are built from the schemas at import (:mod:`analysis.schema_checks`: JSON type -> rule of
  :mod:`analysis.json_checks`), not validated with jsonschema (a dev dependency only): 3-20 µs per message, where
  jsonschema's validators take 0.2-1.5 ms, 60-160 times as long (measured on a paper_fig5 log), which would bring
  the analysis from above 50 to about 6 episodes/s. What the schema describes and the analysis does not read is
  :data:`UNREAD`; what the schema requires and the analysis takes as optional, :data:`LENIENT`.
* :func:`analysis.episode_check.check_episode` — the messages together (its own module).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from itertools import chain
from typing import Any

import yaml

from analysis.json_checks import (
    DICT_TYPES,
    LIST_TYPES,
    MAX_CM,
    Check,
    CheckError,
    accepts_all,
    are_booleans,
    are_points,
    are_tables,
    array,
    kind_of,
    number,
    with_batch,
)
from analysis.log_format import SCHEMAS, TOPICS
from analysis.schema_checks import Ranges, build_check, field_paths
from fuzzynav.episode_identity import POLICY_SOURCE, RECORDING, config_hash  # what runners.run records: one definition
from fuzzynav.params import limits
from fuzzynav.params import names as policy_names
from fuzzynav.params.names import DEFAULT_POLICY, STRATEGIES

__all__ = ["LENIENT", "MESSAGE_CHECKS", "RANGES", "READ", "TOPIC_SCHEMAS", "UNREAD", "CheckError", "check_message",
           "check_metadata", "config_hash", "messages_acceptable"]

MAX_US = 1e12  # compute time of one decision (µs): 11 days
MIN_DT_S, MAX_DT_S = limits.MIN_DT_S, limits.MAX_DT_S  # the step lengths (s) a run accepts: one definition
MAX_CONFIG_BYTES = 1 << 20
MAX_CONFIG_NODES = 100_000
NAME = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,63}")  # safe as a label and a file-name part (no "..")
MAX_SEED = 2**53 - 1  # the analysis's tables hold seeds as float64: larger ones would merge
PERCEPTIONS = ("laser", "ground_truth")
FINISHED = ("goal", "collision", "timeout")  # outcomes whose log must hold every step
TIME_TOLERANCE_NS = 1000  # log times are round(step * dt * 1e9): 1 µs of slack for the float product
YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

POSITIVE_CM = number(1e-9, MAX_CM)  # a radius (episode_check's too)
MAX_M = MAX_CM / 100  # the Foxglove topics' lengths are metres

READ: dict[str, tuple[str, ...]] = {
    "/robot/state": ("step", "x_cm", "y_cm", "heading_deg", "v_cm_s", "next_x_cm", "next_y_cm", "next_heading_deg",
                     "radius_cm", "contact_static", "contact_dynamic", "distance_to_goal_cm"),
    "/obstacles/truth": ("step", *(f"obstacles.{name}" for name in ("id", "x_cm", "y_cm", "next_x_cm", "next_y_cm",
                                                                     "radius_cm", "vx_cm_s", "vy_cm_s"))),
    "/planner/decision": ("step", "mode", "new_plan", "left_cm", "front_cm", "right_cm", "angle_deg", "dtheta_deg",
                          "v_cm_s", "strategy", *(f"planning.{name}" for name in ("strategy", "tc", "tS", "tG",
                                                                                    "wait_time", "h_wait", "reason")),
                          "compute_time_us"),
    "/tpt": ("step", "n_traj", "dt_s", "robot_radius_cm", "obstacle_ids", "obstacle_radii_cm", "robot_cm",
             "obstacles_cm", "collide"),
    "/episode": ("outcome", "steps", "time_s", "contacts", "reason"),
    "/tracks": ("step", "moving_beams", *(f"tracks.{name}" for name in ("id", "x_cm", "y_cm", "vx_cm_s", "vy_cm_s",
                                                                       "radius_cm"))),
    "/sonar": ("step", "left_cm", "front_cm", "right_cm"),
    "/laser": ("ranges", "intensities"),
    "/log": ("level", "message"),
    # the first /scene: walls, static obstacles and goal (foxglove.SceneUpdate, metres)
    "/scene": ("entities.id", "entities.lines.points.x", "entities.lines.points.y",
               "entities.cylinders.pose.position.x", "entities.cylinders.pose.position.y", "entities.cylinders.size.x"),
}
"""Per topic, the fields the analysis reads (metrics, episode loading, replay, rendering), dotted, arrays
transparent: each is demanded and checked as its schema (:mod:`analysis.log_format`) types it, within
:data:`RANGES`. The schema's other fields (:data:`UNREAD`) and fields it does not describe are not read, so not
checked; a field read that the schema does not describe or require is an error at import."""

LENIENT = {"/planner/decision": ("policy", "policy_fields"),
           "/obstacles/truth": ("obstacles.present", "obstacles.next_present", "obstacles.reacting")}
"""Fields the analysis takes as optional: logs written before policies could be chosen have no ``policy`` and
``policy_fields`` (:func:`_check_decision` checks them when present); only scenarios whose obstacles come and go
(recorded people) write ``present`` and ``next_present``, and only those whose people may react ``reacting``
(:func:`_check_truth` checks them when present)."""

RANGES = Ranges(
    numbers=[
        # Foxglove topics: metres
        (r"^/laser ranges\[\]$", 0.0, MAX_M),
        (r"^/laser intensities\[\]$", 0.0, MAX_CM),
        (r"^/scene .*\.size\.[xyz]$", 0.0, MAX_M),
        (r"^/scene ", -MAX_M, MAX_M),
        # fuzzynav topics: units in the names
        (r"(^| |\.|_)radius_cm$", 1e-9, MAX_CM),  # a disc's radius is positive
        (r"_radii_cm\[\]$", 0.0, MAX_CM),
        (r" (left|front|right|distance_to_goal)_cm$", 0.0, MAX_CM),  # sonar readings and distances
        (r"^/planner/decision v_cm_s$", 0.0, MAX_CM),  # the commanded speed
        (r"heading_deg$", 0.0, 360.0),
        (r"^/planner/decision angle_deg$", 0.0, 180.0),  # the included angle
        (r" dt_s$", MIN_DT_S, MAX_DT_S),
        (r"(_us| time_s)$", 0.0, MAX_US),
        (r"_(cm|cm_s|deg)(\[\])*$", -MAX_CM, MAX_CM),  # positions, velocities, the steering increment
    ],
    integers=[(r" n_traj$", 1, 1_000_000), (r" moving_beams\[\]$", 0, 2**31)],  # others: [0, 2**63 - 1]
    min_items=[(r"^/laser ranges$", 1), (r"^/tpt (robot_cm|obstacles_cm|collide)$", 1)])
"""The ranges of the numbers read (finite, and within what the quantity can be; cm quantities within
±``MAX_CM``), of the integers (and the schema's minimum; steps, counts and ids are not negative), and the least
lengths of arrays, by ``"<topic> <path>"`` (:class:`analysis.schema_checks.Ranges`)."""


def _derived(topic: str, paths: tuple[str, ...]) -> Check:
    return build_check(topic, SCHEMAS[TOPICS[topic]](), paths, RANGES)


def _enum(schema: dict, field: str) -> tuple[str, ...]:
    return tuple(schema["properties"][field]["enum"])


OUTCOMES = _enum(SCHEMAS["fuzzynav.Episode"](), "outcome")
PLAN_STRATEGIES = _enum(SCHEMAS["fuzzynav.Decision"]()["properties"]["planning"]["oneOf"][0], "strategy")

_TPT_SCALARS = _derived("/tpt", READ["/tpt"][:6])
_TPT_TABLES = _derived("/tpt", READ["/tpt"][6:])


def check_tpt(v: Any) -> None:
    """A TPT message: its fields, and its shape — n_traj + 1 rows of the robot's position, and of one position
    and one collision flag per obstacle column. The tables (the largest message of a step) are checked with
    map, set, min and max over the whole table; item by item only to say what is wrong."""
    _TPT_SCALARS(v)
    rows, k = v["n_traj"] + 1, len(v["obstacle_ids"])
    robot, obstacles, collide = v.get("robot_cm"), v.get("obstacles_cm"), v.get("collide")
    if (are_points(robot) and len(robot) == rows
            and type(obstacles) is list and len(obstacles) == rows and set(map(type, obstacles)) <= LIST_TYPES
            and set(map(len, obstacles)) <= {k} and are_points(list(chain.from_iterable(obstacles)))
            and type(collide) is list and len(collide) == rows and set(map(type, collide)) <= LIST_TYPES
            and set(map(len, collide)) <= {k} and are_booleans(list(chain.from_iterable(collide)))
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


def _tpts_acceptable(vs: list[Any]) -> bool:
    """:func:`check_tpt`'s acceptance over a whole episode's tables at once (see :func:`accepts_all`)."""
    if not accepts_all(_TPT_SCALARS, vs):
        return False
    rows = [v["n_traj"] + 1 for v in vs]
    ks = [len(v["obstacle_ids"]) for v in vs]
    if [len(v["obstacle_radii_cm"]) for v in vs] != ks:
        return False
    robot = [v.get("robot_cm") for v in vs]
    if not (_all_lists(robot) and list(map(len, robot)) == rows and are_points(list(chain.from_iterable(robot)))):
        return False
    return (are_tables([v.get("obstacles_cm") for v in vs], rows, ks)
            and are_tables([v.get("collide") for v in vs], rows, ks, booleans=True))


def _all_lists(values: list[Any]) -> bool:
    return set(map(type, values)) <= LIST_TYPES


with_batch(check_tpt, _tpts_acceptable)

_DECISION = _derived("/planner/decision", READ["/planner/decision"])


def _check_decision(v: Any) -> None:
    """A decision: its fields (:data:`_DECISION`), and, in logs written since policies can be chosen, the policy
    that decided (a registered name or an import path) and its own values (numbers, booleans, strings)."""
    _DECISION(v)
    if "policy" in v and not policy_names.is_policy_id(v["policy"]):
        raise CheckError("policy", f"{str(v['policy'])[:60]!r} is not a policy name or import path")
    fields = v.get("policy_fields", {})
    if type(fields) is not dict:
        raise CheckError("policy_fields", f"expected an object, got {kind_of(fields)}")
    for key, value in fields.items():
        if type(value) in (bool, str) or (type(value) in (int, float) and math.isfinite(value)):
            continue
        raise CheckError(f"policy_fields.{str(key)[:40]}", f"expected a finite number, a boolean or a string, got "
                                                           f"{kind_of(value)}")


_POLICY_FIELD_TYPES = frozenset({bool, str, int, float})


def _decisions_acceptable(vs: list[Any]) -> bool:
    """:func:`_check_decision`'s acceptance over a whole episode's decisions at once (see :func:`accepts_all`)."""
    if not accepts_all(_DECISION, vs):
        return False
    policies = {v["policy"] for v in vs if "policy" in v}
    if not all(map(policy_names.is_policy_id, policies)):
        return False
    fields = [v.get("policy_fields", {}) for v in vs]
    if not set(map(type, fields)) <= DICT_TYPES:
        return False
    values = list(chain.from_iterable(f.values() for f in fields))
    return set(map(type, values)) <= _POLICY_FIELD_TYPES \
        and all(math.isfinite(x) for x in values if type(x) is float or type(x) is int)


with_batch(_check_decision, _decisions_acceptable)


_TRUTH = _derived("/obstacles/truth", READ["/obstacles/truth"])


def _check_truth(v: Any) -> None:
    """A truth message: its fields (:data:`_TRUTH`), and the presence of its obstacles where the log records it —
    both ``present`` and ``next_present``, booleans, or neither (every obstacle present throughout) — and
    ``reacting``, a boolean, where the log records it."""
    _TRUTH(v)
    for i, o in enumerate(v["obstacles"]):
        given = ("present" in o) + ("next_present" in o)
        if given == 1:
            raise CheckError(f"obstacles[{i}]", "has one of present and next_present without the other")
        if given and not (type(o["present"]) is bool and type(o["next_present"]) is bool):
            raise CheckError(f"obstacles[{i}].present", "present and next_present must be true or false")
        if "reacting" in o and type(o["reacting"]) is not bool:
            raise CheckError(f"obstacles[{i}].reacting", "must be true or false")


def _truths_acceptable(vs: list[Any]) -> bool:
    """:func:`_check_truth`'s acceptance over a whole episode's messages at once (see :func:`accepts_all`)."""
    if not accepts_all(_TRUTH, vs):
        return False
    for v in vs:
        for o in v["obstacles"]:
            if ("present" in o or "next_present" in o) and not (
                    type(o.get("present")) is bool and type(o.get("next_present")) is bool):
                return False
            if "reacting" in o and type(o["reacting"]) is not bool:
                return False
    return True


with_batch(_check_truth, _truths_acceptable)


MESSAGE_CHECKS: dict[str, Check] = {topic: _derived(topic, paths) for topic, paths in READ.items()}
MESSAGE_CHECKS.update({"/planner/decision": _check_decision, "/tpt": check_tpt, "/obstacles/truth": _check_truth})
"""Per topic, the check of a message: :data:`READ`'s fields as the schema types them, within :data:`RANGES`; the
TPT's shape and the decision's policy besides."""



def _unread(topic: str) -> tuple[str, ...]:
    read = (*READ[topic], *LENIENT.get(topic, ()))
    unread = [p for p in field_paths(SCHEMAS[TOPICS[topic]]())
              if not any(p == r or p.startswith(f"{r}.") or r.startswith(f"{p}.") for r in read)]
    return tuple(p for p in unread if not any(p.startswith(f"{q}.") for q in unread))


UNREAD = {topic: _unread(topic) for topic in READ}
"""Per topic, the fields its schema describes that the analysis does not read, so does not check (a field
named here is not read at any depth)."""

TOPIC_SCHEMAS = {topic: TOPICS[topic] for topic in READ}
"""The schema each topic read must declare (a JSON schema of this name; fuzzynav's writer declares every one)."""


def check_message(topic: str, msg: Any) -> None:
    """Raise :class:`CheckError` if ``msg`` lacks a field the analysis reads from ``topic`` or has a bad one."""
    check = MESSAGE_CHECKS.get(topic)
    if check is not None:
        check(msg)


def messages_acceptable(topic: str, msgs: list[Any]) -> bool:
    """Whether :func:`check_message` accepts every one of ``msgs`` (one topic's), decided over the list at once; it
    never says what is wrong — when it says no, check the messages one by one."""
    check = MESSAGE_CHECKS.get(topic)
    return check is None or accepts_all(check, msgs)


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
    for key in (POLICY_SOURCE, RECORDING):
        source = meta.get(key)
        if source is not None and not _SHA256.fullmatch(source):
            raise CheckError(key, f"{source[:80]!r} is not a SHA-256 digest")
    if "policy" in meta and not policy_names.is_policy_id(meta["policy"]):  # logs before policies have none
        raise CheckError("policy", f"{meta['policy'][:80]!r} is not a policy name or import path")
    config = _parse_config(meta.get("config", ""))
    navigator = config.get("navigator")
    if "policy" not in meta and isinstance(navigator, dict) and ("policy" in navigator or "_target_" in navigator):
        # only logs written before policies could be chosen lack it, and their config names none
        raise CheckError("policy", "missing, but the config's navigator section names a policy")
    if "policy" in meta and isinstance(navigator, dict):
        named = navigator.get("policy", navigator.get("_target_", DEFAULT_POLICY))
        if str(named) != meta["policy"]:
            raise CheckError("config navigator.policy", f"{named!r} disagrees with policy {meta['policy']!r}")
    for section, key, meta_key in _ALIASES:
        node = config.get(section)
        if isinstance(node, dict) and key in node and str(node[key]) != meta[meta_key]:
            raise CheckError(f"config {section}.{key}", f"{node[key]!r} disagrees with {meta_key} "
                                                        f"{meta[meta_key]!r}")
    _check_sonar_sectors(config)
    dt = config.get("dt")
    if dt is not None:
        try:
            number(MIN_DT_S, MAX_DT_S)(dt)
        except CheckError as err:
            raise err.inside("config dt") from None
        dt = float(dt)
    if "config" not in meta:  # else the hash check below blamed the hash for the config's absence
        raise CheckError("config", "missing (the metadata has a config_hash but no config)" if "config_hash" in meta
                         else "missing")
    # every log runners.run writes has both: without them the check of the record could be switched off by
    # deleting a key, and an edited config (another run's parameters) was pooled into the wrong group
    digest, version = meta.get("config_hash"), meta.get("fuzzynav_version")
    if digest is None or version is None:
        raise CheckError("config_hash" if digest is None else "fuzzynav_version",
                         "missing (every log fuzzynav writes has it: edited metadata or not fuzzynav's log)")
    if not _SHA256.fullmatch(digest):
        raise CheckError("config_hash", f"{digest[:80]!r} is not a SHA-256 digest")
    if digest != config_hash(meta["config"], meta["seed"], version):
        raise CheckError("config_hash", "is not the hash of the config and seed (edited or damaged metadata)")
    return config, dt


_PARSED: dict[str, dict[str, Any]] = {}
"""Config text -> its parsed and checked config: the episodes of one job log the same text (a sweep's 105 logs hold
21), and parsing it was a fifth of reading a log."""
_PARSED_MAX = 64


def _parse_config(text: str) -> dict[str, Any]:
    """The metadata's config, parsed and checked (:class:`CheckError` otherwise): a new object for each caller."""
    config = _PARSED.get(text)
    if config is None:
        config = _parse_config_text(text)
        if len(_PARSED) >= _PARSED_MAX:
            _PARSED.pop(next(iter(_PARSED)), None)
        _PARSED[text] = config
    return _plain_copy(config)


def _plain_copy(node: Any) -> Any:
    """A copy of checked config data (mappings, lists and immutable scalars only: :func:`_check_plain`); without
    recursion, as a config may nest deeper than Python's recursion limit."""
    if type(node) is not dict and type(node) is not list:
        return node
    root: Any = {} if type(node) is dict else []
    stack = [(node, root)]
    while stack:
        source, target = stack.pop()
        for key, value in (source.items() if type(source) is dict else enumerate(source)):
            kind = type(value)
            if kind is dict or kind is list:
                value_copy: Any = {} if kind is dict else []
                stack.append((value, value_copy))
            else:
                value_copy = value
            if type(target) is dict:
                target[key] = value_copy
            else:
                target.append(value_copy)
    return root


def _parse_config_text(text: str) -> dict[str, Any]:
    if len(text) > MAX_CONFIG_BYTES:
        raise CheckError("config", f"{len(text)} characters (more than {MAX_CONFIG_BYTES})")
    try:
        config = yaml.load(text, Loader=YAML_LOADER)
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
        raise CheckError("config", f"expected a mapping, got {kind_of(config)}")
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
