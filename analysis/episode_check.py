"""The messages of one episode log checked together, after each passed :func:`analysis.log_check.check_message`:
one message per step and topic, numbered from 0; log times at step * dt (ns); the first scene is the static world;
the robot starts at the scenario's start pose and each step's ``distance_to_goal_cm`` is the distance from the
position after the move to the goal (when the log carries its scenario); the robot's and the moving obstacles'
positions continue from one step to the next (each step's ``next_*`` is the following step's position); scans and
their moving beams agree; TPTs have the episode's step length, the config's horizon and margin, their step's
robot, and are the tables their own first rows make; plans have their table; the decisions' strategy,
policy and h_wait are the metadata's; a finished episode has every step and the time ``/episode`` reports. Raises
:class:`CheckError`."""

from __future__ import annotations

import contextlib
import functools
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from analysis.json_checks import CheckError, accepts_all, array, number, obj, points
from analysis.log_check import FINISHED, MAX_CONFIG_BYTES, POSITIVE_CM, TIME_TOLERANCE_NS, YAML_LOADER
from fuzzynav.numerics.prediction import table_rows
from fuzzynav.params.names import DEFAULT_POLICY, ROBOT_DEFAULTS, SCENARIO_DEFAULTS

if TYPE_CHECKING:
    from analysis.episode_log import EpisodeLog


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
    _check_scenario_is_the_configs(log)
    _check_against_scenario(log)
    _check_robot_path(log)
    _check_obstacle_paths(log)
    _check_beams(log)
    _check_tpts(log)
    _check_decisions(log, times)
    _check_counts(log, times)
    _check_outcome(log)


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


@functools.lru_cache(maxsize=16)
def parse_world(text: str) -> Any:
    """The parsed ``scenario_yaml`` metadata (None when it is too long or not YAML). Read-only: shared by the
    checks of one log (two of them read it), the TPT error per obstacle model (:mod:`analysis.tpt_errors`) and the
    logs of a sweep, which often log the same world text."""
    try:
        return yaml.load(text, Loader=YAML_LOADER) if len(text) <= MAX_CONFIG_BYTES else None
    except (yaml.YAMLError, RecursionError):
        return None


def _scenario(log: EpisodeLog) -> dict | None:
    """The logged scenario (metadata ``scenario_yaml``) when it is one with a robot, else None."""
    world = parse_world(log.meta.get("scenario_yaml", ""))
    return world if isinstance(world, dict) and world.get("robot") is not None else None


def _check_outcome(log: EpisodeLog) -> None:
    """A finished episode's outcome (of a log with its scenario) is what its last step shows, as
    :mod:`fuzzynav.episode` decides it: ``goal`` ends within the scenario's goal tolerance of the goal, ``timeout``
    at the scenario's ``max_steps`` outside it, ``collision`` on a step with a contact. A log whose ``/episode``
    outcome was rewritten (timeout to goal, 550 cm from the goal) was counted as a success."""
    world = _scenario(log)  # a log of runners.run (hand-written logs have no scenario: their outcome is as written)
    if world is None or not log.complete or log.episode is None or log.episode["outcome"] not in FINISHED \
            or not log.states:
        return
    outcome, last = log.episode["outcome"], log.states[-1]
    if outcome == "collision":
        if not last["contact_static"] and not last["contact_dynamic"]:
            raise CheckError("/episode outcome", f"'collision', but the last step (step {last['step']}) has no "
                                                 "contact")
        return
    robot = world["robot"]
    tol = world.get("goal_tolerance")
    try:
        tol = float(robot["radius"] if tol is None else tol)
        gx, gy = (float(v) for v in robot["goal"])
        max_steps = int(world.get("max_steps", 300))
    except (TypeError, ValueError, KeyError):
        return  # _check_against_scenario names a malformed robot
    d = math.hypot(last["next_x_cm"] - gx, last["next_y_cm"] - gy)
    slack = 1e-6 * max(1.0, tol)  # the episode measures with its own (portable) distance
    if outcome == "goal" and d > tol + slack:
        raise CheckError("/episode outcome", f"'goal', but the robot ends {d:.1f} cm from the goal (goal tolerance "
                                             f"{tol:g} cm, metadata scenario_yaml)")
    if outcome == "timeout":
        if d < tol - slack:
            raise CheckError("/episode outcome", f"'timeout', but the robot ends {d:.1f} cm from the goal, within "
                                                 f"the goal tolerance {tol:g} cm")
        if len(log.states) != max_steps:
            raise CheckError("/episode outcome", f"'timeout' after {len(log.states)} steps, the scenario's "
                                                 f"max_steps is {max_steps}")


_FIXED_KEYS = ("name", "bounds", "max_steps", "goal_tolerance")
_ROBOT_KEYS = ("start", "goal", "heading", "radius")
_OBSTACLE_KEYS = ("id", "radius", "start", "velocity")


def _check_scenario_is_the_configs(log: EpisodeLog) -> None:
    """A fixed scenario (the config's ``scenario`` section has its robot: not generated per seed) is the world the
    metadata ``scenario_yaml`` logs, keys a scenario leaves out at their defaults (:mod:`fuzzynav.params.names`).
    The config is covered by ``config_hash``, ``scenario_yaml`` is not: edited, an episode of one scenario was
    counted in another's group; deleted, the checks against the scenario were skipped and a collision could be
    relabelled a goal."""
    scenario = log.config.get("scenario")
    world = parse_world(log.meta.get("scenario_yaml", ""))
    if isinstance(scenario, dict) and "generator" in scenario and (
            not isinstance(world, dict) or not isinstance(world.get("robot"), dict)):
        # the world a generator made is logged by every run: without it, the checks against the scenario (start,
        # goal, outcome, TPTs) were skipped
        raise CheckError("metadata scenario_yaml", "missing or not a scenario, but the config's scenario is made by "
                                                   f"generator {str(scenario.get('generator'))[:64]!r}")
    if not isinstance(scenario, dict) or not isinstance(scenario.get("robot"), dict):
        return  # generated per seed (its world is the generator's), or a hand-written log with no scenario
    if not isinstance(world, dict) or not isinstance(world.get("robot"), dict):
        raise CheckError("metadata scenario_yaml", "missing or not a scenario, but the config's scenario "
                                                   f"{str(scenario.get('name'))[:64]!r} is a fixed one")
    # what the run read (fuzzynav.scenarios.scenario.scenario_from_dict): a key left out is its default there
    pairs = [(f"robot.{key}", scenario["robot"].get(key, ROBOT_DEFAULTS.get(key)),
              world["robot"].get(key, ROBOT_DEFAULTS.get(key))) for key in _ROBOT_KEYS]
    pairs += [(key, scenario.get(key, SCENARIO_DEFAULTS.get(key)), world.get(key, SCENARIO_DEFAULTS.get(key)))
              for key in _FIXED_KEYS]
    ours, logged = scenario.get("dynamic_obstacles") or [], world.get("dynamic_obstacles") or []
    if not isinstance(ours, list) or not isinstance(logged, list) or len(ours) != len(logged):
        raise CheckError("metadata scenario_yaml dynamic_obstacles", "not the config's scenario's moving obstacles")
    pairs += [(f"dynamic_obstacles[{i}].{key}", a.get(key) if isinstance(a, dict) else a,
               b.get(key) if isinstance(b, dict) else b) for i, (a, b) in enumerate(zip(ours, logged, strict=True))
              for key in _OBSTACLE_KEYS]
    for where, expected, got in pairs:
        if not _same_value(expected, got):
            raise CheckError(f"metadata scenario_yaml {where}", f"{str(got)[:80]} is not the config's scenario's "
                                                                f"{str(expected)[:80]}")


def _same_value(a: Any, b: Any) -> bool:
    """Equal as the scenario's values: numbers by value (the config writes 600, the world 600.0), lists item by
    item, anything else by equality."""
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return float(a) == float(b)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same_value(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def _check_against_scenario(log: EpisodeLog) -> None:
    """The exact world of the episode (the ``scenario_yaml`` metadata that ``runners.run`` writes; hand-written
    logs have none, or a placeholder that is not a scenario): the robot starts at its start pose with its
    radius, each step's ``distance_to_goal_cm`` is the distance from the position after the move to the goal,
    and the scene's goal is that goal (to the 0.1 mm the scene rounds to)."""
    world = parse_world(log.meta.get("scenario_yaml", ""))
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
    tol = world.get("goal_tolerance")
    tol = robot["radius"] if tol is None else tol  # type: ignore[index]
    # the metrics measure the time to the goal with the scene's goal disc: it must be the scenario's tolerance
    if log.goal_tolerance is not None and isinstance(tol, int | float) and not isinstance(tol, bool) \
            and abs(log.goal_tolerance - float(tol)) > 0.011:
        raise CheckError("/scene goal", f"a disc of radius {log.goal_tolerance:g} cm, not the scenario's goal "
                                        f"tolerance ({float(tol):g} cm, metadata scenario_yaml)")
    _check_obstacle_ids(log, world)


def _check_obstacle_ids(log: EpisodeLog, world: dict) -> None:
    """The moving obstacles of the logged truth are the scenario's (by id, in order): the analysis reads each
    obstacle's model from the scenario (TPT error per model), so a scenario that names other obstacles than the
    log moved is not this log's."""
    entries = world.get("dynamic_obstacles") or []
    ids = [e.get("id") if isinstance(e, dict) else None for e in entries] if isinstance(entries, list) else None
    radii = [e.get("radius") if isinstance(e, dict) else None for e in entries] if isinstance(entries, list) else []
    for m in log.truth:
        logged = [o["id"] for o in m["obstacles"]]
        if logged != ids:
            raise CheckError(f"/obstacles/truth step {m['step']}", f"obstacle ids {logged[:5]} are not the "
                                                                   f"scenario's {(ids or [])[:5]} (metadata "
                                                                   "scenario_yaml dynamic_obstacles)")
        # their sizes too: a walker logged at 5 cm instead of 20 moved every clearance and near miss
        for o, radius in zip(m["obstacles"], radii, strict=True):
            if isinstance(radius, int | float) and not isinstance(radius, bool) and o["radius_cm"] != float(radius):
                raise CheckError(f"/obstacles/truth step {m['step']} {o['id']} radius_cm",
                                 f"{o['radius_cm']!r} is not the scenario's {radius!r} (metadata scenario_yaml "
                                 "dynamic_obstacles)")


def _check_robot_path(log: EpisodeLog) -> None:
    states = log.states
    for k in range(len(states) - 1):
        a, b = states[k], states[k + 1]
        if a["next_x_cm"] != b["x_cm"] or a["next_y_cm"] != b["y_cm"] or a["next_heading_deg"] != b["heading_deg"]:
            raise CheckError(f"/robot/state step {k + 1}", "position or heading differs from step "
                                                           f"{k}'s next_x_cm/next_y_cm/next_heading_deg")
    if states and any(s["radius_cm"] != states[0]["radius_cm"] for s in states):
        raise CheckError("/robot/state radius_cm", "changes during the episode")
    _check_robot_moves(log)


def _check_robot_moves(log: EpisodeLog) -> None:
    """Each step moves the robot as :func:`fuzzynav.kinematics.step_unicycle` does: ``next_v_cm_s`` × dt along
    ``next_heading_deg``, a speed within the config's ``robot`` limits (0 or [v_min, v_max]) and a turn of at most
    ``max_turn_deg``, for a log whose config has the ``robot`` section runners.run writes. A robot moved 490 cm in
    one step of 25 cm/s (and back) was counted as a faster success."""
    robot = log.config.get("robot")
    if not isinstance(robot, dict):  # a hand-written log (tests): its poses are whatever it says
        return
    limits = {key: robot.get(key) for key in ("v_min", "v_max", "max_turn_deg")}
    limits = {k: float(v) for k, v in limits.items() if isinstance(v, int | float) and not isinstance(v, bool)}
    decisions = log.decisions if len(log.decisions) == len(log.states) else [None] * len(log.states)
    for k, (st, decision) in enumerate(zip(log.states, decisions, strict=True)):
        v = st["next_v_cm_s"]
        if v != 0.0 and not limits.get("v_min", 0.0) - _TOL <= v <= limits.get("v_max", math.inf) + _TOL:
            raise CheckError(f"/robot/state step {k} next_v_cm_s", f"{v!r} is not 0 and outside the config's robot "
                                                                   f"speed limits [{limits.get('v_min', 0.0):g}, "
                                                                   f"{limits.get('v_max', math.inf):g}] cm/s")
        turn = abs((st["next_heading_deg"] - st["heading_deg"] + 180.0) % 360.0 - 180.0)
        if turn > limits.get("max_turn_deg", 180.0) + 1e-6:
            raise CheckError(f"/robot/state step {k}", f"turns {turn:.3f}°, more than the config's robot "
                                                       f"max_turn_deg {limits['max_turn_deg']:g}")
        length = v * log.dt
        sin, cos = math.sin(math.radians(st["next_heading_deg"])), math.cos(math.radians(st["next_heading_deg"]))
        dx, dy = st["next_x_cm"] - st["x_cm"], st["next_y_cm"] - st["y_cm"]
        if math.hypot(dx - length * cos, dy - length * sin) > _TOL * max(1.0, length, abs(st["x_cm"]),
                                                                          abs(st["y_cm"])):
            raise CheckError(f"/robot/state step {k}", f"moves ({dx:.3f}, {dy:.3f}) cm, not next_v_cm_s × dt = "
                                                       f"{length:.3f} cm along next_heading_deg "
                                                       f"{st['next_heading_deg']:.3f}")
        if decision is not None and "v_min" in limits and "v_max" in limits and "max_turn_deg" in limits:
            _check_command(k, st, decision, limits)


def _check_command(k: int, st: dict, decision: dict, limits: dict[str, float]) -> None:
    """The step's move is its decision's, as the simulator applies it: the speed 0 for a decision of 0 or less,
    else clamped to [v_min, v_max]; the heading turned by ``dtheta_deg`` clamped to ±max_turn_deg. Decisions
    rewritten to wait while the robot kept moving were counted as waiting."""
    v = decision["v_cm_s"]
    speed = 0.0 if v <= 0.0 else max(limits["v_min"], min(limits["v_max"], v))
    if abs(st["next_v_cm_s"] - speed) > _TOL * max(1.0, speed):
        raise CheckError(f"/robot/state step {k} next_v_cm_s", f"{st['next_v_cm_s']!r}, but the step's decision "
                                                               f"v_cm_s {v!r} moves the robot at {speed:g} cm/s")
    turn = max(-limits["max_turn_deg"], min(limits["max_turn_deg"], decision["dtheta_deg"]))
    off = abs((st["heading_deg"] + turn - st["next_heading_deg"] + 180.0) % 360.0 - 180.0)
    if off > 1e-6:
        raise CheckError(f"/robot/state step {k} next_heading_deg", f"{st['next_heading_deg']!r}, but the step's "
                                                                    f"decision turns {decision['dtheta_deg']!r}° "
                                                                    f"from {st['heading_deg']!r}°")


_TOL = 1e-6
"""Relative slack of the robot's kinematics check: the simulator's own (portable) sine and cosine differ from
``math``'s in the last bits."""


def _check_obstacle_paths(log: EpisodeLog) -> None:
    truth = log.truth
    for k in range(len(truth) - 1):
        now, after = truth[k]["obstacles"], truth[k + 1]["obstacles"]
        if len(now) != len(after):
            raise CheckError(f"/obstacles/truth step {k + 1}", f"{len(after)} obstacles, step {k} has {len(now)}")
        for a, b in zip(now, after, strict=True):
            if a["id"] != b["id"] or a["next_x_cm"] != b["x_cm"] or a["next_y_cm"] != b["y_cm"] \
                    or a["radius_cm"] != b["radius_cm"] or a.get("next_present") != b.get("present") \
                    or (a.get("reacting") and not b.get("reacting")) or ("reacting" in a) != ("reacting" in b):
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
    """Each table has the episode's step length, the config's ``planner.n_traj`` and ``planner.safety_margin_cm``
    (where the config gives them), and its step's robot position and radius (``/robot/state``); in a log with its
    scenario, it is the table its own first row makes (:func:`_check_tpt_prediction`)."""
    world = _scenario(log)
    goal = None
    if world is not None:
        with contextlib.suppress(TypeError, ValueError, KeyError):  # (_check_against_scenario names a bad robot)
            goal = (float(world["robot"]["goal"][0]), float(world["robot"]["goal"][1]))
    planner = log.config.get("planner")
    planner = planner if isinstance(planner, dict) else {}
    swept = planner.get("swept_tpt")
    sweeps = (swept,) if isinstance(swept, bool) else (True, False)  # a config that does not say: either
    configured = {name: value for name in ("n_traj", "safety_margin_cm")
                  if isinstance(value := planner.get(name), int | float) and not isinstance(value, bool)}
    inputs_checked = goal is not None and accepts_all(_TPT_INPUTS, list(log.tpts.values()))
    for step, t in log.tpts.items():
        if abs(t["dt_s"] - log.dt) > 1e-9 * log.dt:
            raise CheckError(f"/tpt step {step} dt_s", f"{t['dt_s']!r} s, the episode's step is {log.dt!r} s")
        for name, value in configured.items():
            if t.get(name) != value:
                raise CheckError(f"/tpt step {step} {name}", f"{t.get(name)!r}, the config's planner.{name} is "
                                                             f"{value!r}")
        if step < len(log.states):
            state = log.states[step]
            if t["robot_radius_cm"] != state["radius_cm"]:
                raise CheckError(f"/tpt step {step} robot_radius_cm", f"{t['robot_radius_cm']!r}, the robot's "
                                                                      f"radius is {state['radius_cm']!r}")
            if t["robot_cm"][0] != [state["x_cm"], state["y_cm"]]:
                raise CheckError(f"/tpt step {step} robot_cm[0]", f"{t['robot_cm'][0]}, not the robot's position "
                                                                  f"at that step {[state['x_cm'], state['y_cm']]}")
        if goal is not None:
            try:
                _check_tpt_prediction(t, goal, sweeps, inputs_checked)
            except CheckError as err:
                raise CheckError(f"/tpt step {step} {err.where}".rstrip(), err.problem) from None


_TPT_INPUTS = obj(robot_speed_cm_s=number(0.0), safety_margin_cm=number(0.0), obstacle_velocities_cm_s=points())
_ROW_TOLERANCE = 1e-9
"""Relative tolerance of a logged row against the recomputed one: code before the portable numerics (2e7e3ab) made
the same rows to within an ulp; an edit that changes a metric moves a row by far more."""


def _check_tpt_prediction(t: dict[str, Any], goal: tuple[float, float], sweeps: tuple[bool, ...],
                          inputs_checked: bool = False) -> None:
    """The table is what :func:`fuzzynav.numerics.prediction.table_rows` makes of its first row: the robot straight
    to the goal at ``robot_speed_cm_s``, each obstacle at its velocity (both to :data:`_ROW_TOLERANCE`), and the
    collision marks of those positions with the radii and margin it logs, exactly (``sweeps``: with the swept
    marks, without, or either). An edited row or flag changed ``tpt_ade_cm`` and ``tpt_collisions_predicted``
    without a word. Shapes were checked with the message (:func:`check_tpt`); ``inputs_checked``: the fields only
    this check reads were, too (over the whole episode at once)."""
    if not inputs_checked:
        _TPT_INPUTS(t)
    n, k = t["n_traj"], len(t["obstacle_ids"])
    if len(t["obstacle_velocities_cm_s"]) != k:
        raise CheckError("obstacle_velocities_cm_s", f"{len(t['obstacle_velocities_cm_s'])} values for {k} obstacles")
    robot = np.array(t["robot_cm"], dtype=float).reshape(n + 1, 2)
    obstacles = np.array(t["obstacles_cm"], dtype=float).reshape(n + 1, k, 2)
    collide = np.array(t["collide"], dtype=bool).reshape(n + 1, k)
    vel = np.array(t["obstacle_velocities_cm_s"], dtype=float).reshape(k, 2)
    radii = np.array(t["obstacle_radii_cm"], dtype=float)

    @functools.cache
    def made(swept: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # (each at most once)
        return table_rows(robot[0], goal, t["robot_speed_cm_s"], obstacles[0], vel, radii, t["robot_radius_cm"], n,
                          t["dt_s"], t["safety_margin_cm"], swept)

    rows, columns, marks = made(sweeps[0])
    off = np.abs(rows - robot) > _ROW_TOLERANCE * np.maximum(1.0, np.abs(rows))
    if off.any():
        row = int(np.flatnonzero(off.any(axis=1))[0])
        raise CheckError(f"robot_cm[{row}]", f"{robot[row].tolist()}, not row 0 moved straight to the goal at "
                                             f"robot_speed_cm_s ({rows[row].tolist()})")
    off = np.abs(columns - obstacles) > _ROW_TOLERANCE * np.maximum(1.0, np.abs(columns))
    if off.any():
        row, col = (int(i) for i in np.argwhere(off.any(axis=2))[0])
        raise CheckError(f"obstacles_cm[{row}][{col}]", f"{obstacles[row, col].tolist()}, not row 0 moved at the "
                                                        f"obstacle's velocity ({columns[row, col].tolist()})")
    if np.array_equal(marks, collide):
        return
    alternatives = [made(swept)[2] for swept in sweeps[1:]]
    if True in sweeps:  # before 752785e a pass that starts inside the margin (row 0 marked) did not mark step 1
        sampled, swept_marks = made(False)[2], made(True)[2]
        earlier = swept_marks.copy()
        earlier[1] = sampled[1] | (swept_marks[1] & ~sampled[0])
        alternatives.append(earlier)
    if any(np.array_equal(other, collide) for other in alternatives):
        return
    nearest = min([marks, *alternatives], key=lambda other: int((other != collide).sum()))  # the mark to name
    row, col = (int(i) for i in np.argwhere(nearest != collide)[0])
    raise CheckError(f"collide[{row}][{col}]", f"{bool(collide[row, col])}, where the table's own positions, radii "
                                               f"and safety margin say {bool(nearest[row, col])}")


def _check_decisions(log: EpisodeLog, times: Mapping[str, list[int]]) -> None:
    """Each decision's strategy, policy and plan h_wait are the metadata's; a plan is made from a TPT of its
    step."""
    strategy, h_wait = log.meta["strategy"], int(log.meta["h_wait"])
    tables = "/tpt" in times
    for k, d in enumerate(log.decisions):
        if tables and d["planning"] is not None and k not in log.tpts:
            raise CheckError(f"/planner/decision step {k} planning", "a plan without a /tpt table of its step")
        if d["strategy"] != strategy:
            raise CheckError(f"/planner/decision step {k} strategy", f"{d['strategy']!r}, the metadata says "
                                                                     f"{strategy!r}")
        # the policy that decided: the metadata's (a log written before policies has neither: fuzzy)
        if d.get("policy", DEFAULT_POLICY) != log.meta.get("policy", DEFAULT_POLICY):
            raise CheckError(f"/planner/decision step {k} policy", f"{str(d.get('policy', 'missing'))[:60]!r}, the "
                                                                   f"metadata says {log.meta.get('policy', 'none')!r}")
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
