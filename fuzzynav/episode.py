"""An episode: the world stepped deterministically from a seed, one :class:`StepRecord` per step.

Gymnasium-style core: ``Episode(scenario, controller, config, seed)``, then ``step()`` until ``done``
(or iterate ``run()``). Each step: sense (sonar, laser) at time t -> perceive moving obstacles -> decide
-> move the robot (unicycle) and the obstacles to t + dt -> check contacts (swept over the step), goal
and step limit. Same scenario, controller, config and seed give identical records.

Outcomes: ``goal`` (within the goal tolerance), ``collision`` (a contact with ``terminate_on_collision``;
otherwise contacts are counted and the run goes on), ``timeout`` (``max_steps`` steps without reaching
the goal). Units: cm, s, degrees, cm/s.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.controller.fuzzy_spec import ControllerSpec
from fuzzynav.kinematics import RobotLimits, RobotState, step_unicycle
from fuzzynav.numerics import portable_math
from fuzzynav.numerics.geometry import swept_distance, wrap_360
from fuzzynav.numerics.portable_random import NormalStream
from fuzzynav.params import limits
from fuzzynav.params.checks import check_config_fields
from fuzzynav.pedestrians.crowd import Crowd, check_crowd_work
from fuzzynav.planning.layer import (
    ActivePlan,
    Decision,
    FuzzyPolicyConfig,
    Observation,
    PlanningLayer,
    build_planning_layer,
)
from fuzzynav.planning.planner import PlannerConfig
from fuzzynav.policies.base import Policy
from fuzzynav.scenarios.scenario import Scenario
from fuzzynav.scenarios.world import world_of
from fuzzynav.sensing import laser as laser_mod
from fuzzynav.sensing.laser import LaserConfig, LaserScan
from fuzzynav.sensing.perception import Perceived, PerceptionConfig, perceive
from fuzzynav.sensing.sonar import Sonar, SonarConfig
from fuzzynav.sensing.tracking import Track, TrackerState

OUTCOMES = ("goal", "collision", "timeout")


@dataclass(frozen=True)
class EpisodeConfig:
    """Everything but the scenario and the controller definition. ``dt`` in seconds. ``policy`` names the
    navigation policy (registered name or import path, :mod:`fuzzynav.policies.base`) and ``navigator`` holds its
    parameters (for ``fuzzy``, a :class:`FuzzyPolicyConfig`)."""

    dt: float = 1.0
    robot: RobotLimits = field(default_factory=RobotLimits)
    sonar: SonarConfig = field(default_factory=SonarConfig)
    laser: LaserConfig = field(default_factory=LaserConfig)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    navigator: Any = field(default_factory=FuzzyPolicyConfig)
    terminate_on_collision: bool = True
    policy: str = "fuzzy"

    def __post_init__(self) -> None:
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ValueError(f"dt: must be a positive number of seconds, got {self.dt}")
        # every number of the tree: finite and in its documented range (fuzzynav.params.limits)
        check_config_fields(self)
        self._check_speeds_fit_robot()

    def _check_speeds_fit_robot(self) -> None:
        """Every speed the policy commands or the planner plans with must be one the robot drives
        (``robot.v_min`` .. ``robot.v_max``, cm/s): the robot clamps a command into that range, so a planned
        move at 1e-300 cm/s, or a direct speed of 5 under v_min 10, would be driven at another speed than the
        table predicted, and the plan's collision check would be about a motion that never happens."""
        lo, hi = self.robot.v_min, self.robot.v_max
        speeds = [(f"planner.successor_speeds[{i}]", v) for i, v in enumerate(self.planner.successor_speeds)]
        speeds += [("planner.cruise_speed", self.planner.cruise_speed)]
        # every policy's own commanded speeds, as its config declares them (limits.ranged(..., robot_speed=True))
        speeds += [(f"navigator.{name}", v) for name, v in limits.robot_speed_fields(self.navigator)]
        for field_, v in speeds:
            if not lo <= v <= hi:
                raise ValueError(f"{field_}: {v:g} cm/s is outside the robot's speed range [{lo:g}, {hi:g}] cm/s "
                                 "(robot.v_min, robot.v_max): the robot cannot drive it")


@dataclass(frozen=True)
class StepRecord:
    """One step. ``state`` is the robot at sensing time ``time_s``; ``next_state`` after moving.

    ``obstacle_positions`` / ``obstacle_velocities`` are the true moving obstacles at ``time_s`` (cm,
    cm/s; order of ``Episode.obstacle_ids``), ``obstacle_next_positions`` at ``time_s + dt``.
    ``contact_static`` / ``contact_dynamic`` tell whether the robot touched something during the step
    (swept); ``new_contacts`` counts contacts that started on this step. ``outcome`` is set on the last
    record only. ``compute_time_us`` is the wall time of the decision (not reproducible).
    ``obstacle_present`` / ``obstacle_next_present`` (N,) bool: which obstacles are in the world at ``time_s``
    and at ``time_s + dt`` — None when no obstacle model of the scenario has presence (all present, always).
    ``obstacle_reacting`` (N,) bool: which obstacles moved over the step by their reaction to the robot, not their
    replay (recorded people, :mod:`fuzzynav.pedestrians.recorded`) — None when no model of the scenario reacts."""

    step: int
    time_s: float
    state: RobotState
    next_state: RobotState
    sonar: tuple[float, float, float]
    scan: LaserScan
    tracks: tuple[Track, ...]
    moving_beams: np.ndarray
    static_points: np.ndarray
    decision: Decision
    obstacle_positions: np.ndarray
    obstacle_velocities: np.ndarray
    obstacle_next_positions: np.ndarray
    contact_static: bool
    contact_dynamic: tuple[str, ...]
    new_contacts: int
    distance_to_goal: float
    outcome: str | None
    compute_time_us: float = 0.0
    obstacle_present: np.ndarray | None = None
    obstacle_next_present: np.ndarray | None = None
    obstacle_reacting: np.ndarray | None = None


@dataclass(frozen=True)
class _Sensed:
    """One step's sensing (:meth:`Episode.observe`), kept until the step acts on it."""

    observation: Observation
    scan: LaserScan
    perceived: Perceived
    positions: np.ndarray
    velocities: np.ndarray
    present: np.ndarray | None
    tracker: TrackerState


class Episode:
    """One run of a scenario (see the module docstring)."""

    def __init__(self, scenario: Scenario, controller: ControllerSpec | FastEvaluator,
                 config: EpisodeConfig | None = None, seed: int = 0, policy: Policy | None = None) -> None:
        """``policy``: drive with this policy object instead of the one ``config.policy`` names (the Gymnasium
        environment puts its agent's actions there); the wait/detour layer runs on top of it either way."""
        self.scenario = scenario
        self.config = config or EpisodeConfig()
        self.seed = seed
        self.world = world_of(scenario.bounds, scenario.static_obstacles)  # shared: read-only
        check_crowd_work(scenario.dynamic_obstacles, self.config.dt, scenario.max_steps)
        self.crowd = Crowd(scenario.dynamic_obstacles, self.world, scenario.robot.radius)
        self.obstacle_ids = self.crowd.ids
        evaluator = controller if isinstance(controller, FastEvaluator) else FastEvaluator(controller)
        r = scenario.robot.radius
        self.sonar = Sonar(self.config.sonar, r)
        if policy is None:
            self.navigator = build_planning_layer(self.config.policy, self.config.navigator, self.config.planner,
                                             self.config.robot, r, self.config.dt, self.config.sonar.front, evaluator)
        else:
            self.navigator = PlanningLayer(policy, self.config.planner, self.config.robot, r, self.config.dt)
        self.reset()

    def reset(self) -> None:
        """Back to the start (same seed, same run)."""
        robot = self.scenario.robot
        self.state = RobotState(robot.start[0], robot.start[1], wrap_360(robot.heading), 0.0)
        self.step_index = 0
        self.outcome: str | None = None
        self.contacts = 0
        self._noise = NormalStream(np.random.default_rng(self.seed))
        self._tracker = TrackerState()
        self._plan: ActivePlan | None = None
        self._sensed: _Sensed | None = None
        self.crowd.reset(self.seed)
        self.navigator.reset(self.seed)
        self._touching: set[str] = set()

    def observe(self) -> tuple[Observation, LaserScan]:
        """What the robot senses at the current step (time ``step_index · dt``): the policy's observation and the
        laser frame. Sensing draws the frame's noise and advances the tracker, so it happens once per step: a
        second call returns the same, and :meth:`step` acts on it (the Gymnasium environment shows it to its
        agent before the agent chooses the action)."""
        if self.done:
            raise RuntimeError("episode is over; call reset()")
        if self._sensed is None:
            cfg, s = self.config, self.state
            t = self.step_index * cfg.dt
            pos, vel = self.crowd.positions, self.crowd.velocities
            present = self.crowd.present if self.crowd.has_presence else None
            discs = np.column_stack([pos, self.crowd.radii]) if len(pos) else np.zeros((0, 3))
            speeds = portable_math.norm2(vel) if len(vel) else None
            if present is not None:  # an absent person reflects no beam and no sonar ping
                discs = discs[present]
                speeds = None if speeds is None else speeds[present]
            sonar = self.sonar.read(s.x, s.y, s.heading, self.world.solid, discs, speeds)
            scan = laser_mod.scan(cfg.laser, s.x, s.y, s.heading, self.world.segments, self.world.circles, discs,
                                  self._noise)
            tracker, seen = perceive(cfg.perception, self._tracker, scan, t, pos, vel, self.crowd.radii,
                                     self._noise, present)
            obs = Observation(s, self.scenario.robot.goal, sonar, seen.tracks, seen.static_points)
            self._sensed = _Sensed(obs, scan, seen, pos, vel, present, tracker)
        return self._sensed.observation, self._sensed.scan

    @property
    def done(self) -> bool:
        return self.outcome is not None

    def step(self) -> StepRecord:
        """Advance one time step and return its record."""
        if self.done:
            raise RuntimeError("episode is over; call reset()")
        cfg, dt, s = self.config, self.config.dt, self.state
        t = self.step_index * dt
        self.observe()  # this step's sensing, unless the Gymnasium environment already asked for it
        sensed, self._sensed = self._sensed, None
        obs, scan, seen = sensed.observation, sensed.scan, sensed.perceived
        pos, vel, self._tracker = sensed.positions, sensed.velocities, sensed.tracker
        sonar, goal = obs.sonar, obs.goal
        started = time.perf_counter()
        decision, self._plan = self.navigator.decide(obs, self._plan)
        compute_us = (time.perf_counter() - started) * 1e6
        nxt = step_unicycle(s, decision.dtheta_deg, decision.v_cm_s, dt, cfg.robot)
        # the obstacles move over the same step, seeing the robot where it was when it sensed (they react to
        # what they see, not to the command it has just chosen)
        next_pos, _ = self.crowd.step(s, dt)
        present, next_present = sensed.present, self.crowd.present if self.crowd.has_presence else None
        p0, p1 = np.array([s.x, s.y]), np.array([nxt.x, nxt.y])
        r = self.scenario.robot.radius
        static_hit = self.world.static_contact(p0, p1, r)
        hits = _swept_contacts(p0, p1, pos, next_pos, r, self.crowd.radii)
        if present is not None:
            # a person is touchable over a step only while in the world at both its ends: between two of its
            # annotations, where its motion is the recording's (it is nowhere before it appears or after it leaves)
            hits = [k for k in hits if present[k] and next_present[k]]
        dynamic_hit = tuple(self.obstacle_ids[k] for k in hits)
        touching = set(dynamic_hit) | ({"static"} if static_hit else set())
        new_contacts = len(touching - self._touching)
        self._touching = touching
        self.contacts += new_contacts
        dist = portable_math.dist((nxt.x, nxt.y), goal)
        self.state = nxt
        self.step_index += 1
        if touching and cfg.terminate_on_collision:
            self.outcome = "collision"
        elif dist <= self.scenario.tolerance:
            self.outcome = "goal"
        elif self.step_index >= self.scenario.max_steps:
            self.outcome = "timeout"
        return StepRecord(step=self.step_index - 1, time_s=t, state=s, next_state=nxt, sonar=sonar, scan=scan,
                          tracks=seen.tracks, moving_beams=seen.moving_beams, static_points=seen.static_points,
                          decision=decision,
                          obstacle_positions=pos, obstacle_velocities=vel, obstacle_next_positions=next_pos,
                          contact_static=static_hit, contact_dynamic=dynamic_hit, new_contacts=new_contacts,
                          distance_to_goal=dist, outcome=self.outcome, compute_time_us=compute_us,
                          obstacle_present=present, obstacle_next_present=next_present,
                          obstacle_reacting=self.crowd.reacting if self.crowd.has_reactions else None)

    def run(self) -> Iterator[StepRecord]:
        """Yield records until the episode ends."""
        while not self.done:
            yield self.step()


def _swept_contacts(p0: np.ndarray, p1: np.ndarray, o0: np.ndarray, o1: np.ndarray, radius: float,
                    radii: np.ndarray) -> list[int]:
    """Indices of obstacles that come closer than the sum of radii to the robot while both move
    straight from (p0, o0) to (p1, o1) over the step."""
    if len(o0) == 0:
        return []
    closest = swept_distance(p0, p1, o0, o1)
    return [int(k) for k in np.nonzero(closest < radius + radii)[0]]
