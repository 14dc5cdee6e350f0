"""Hand-made scenes for the policy tests (tests/test_apf.py, test_vfh.py, test_dwa.py, test_orca.py): the
robot context, observations, walls of laser returns, a seeded random observation, and a closed loop that
drives a policy with the robot's kinematics. Units: cm, s, degrees, cm/s."""

from __future__ import annotations

import math

import numpy as np

from fuzzynav.kinematics import RobotLimits, RobotState, step_unicycle
from fuzzynav.numerics.geometry import segment_point_distance
from fuzzynav.planning.layer import Observation
from fuzzynav.policies.base import Policy, PolicyContext
from fuzzynav.sensing.tracking import Track

CTX = PolicyContext(RobotLimits(), robot_radius=20.0)
NO_POINTS = np.zeros((0, 2))
LASER_RANGE_CM = 250.0


def observe(state: RobotState, goal: tuple[float, float], points: np.ndarray = NO_POINTS,
            tracks: tuple[Track, ...] = ()) -> Observation:
    """An observation with free sonar (130 cm each), the given tracks and static laser returns (cm)."""
    return Observation(state, goal, (130.0, 130.0, 130.0), tracks, np.asarray(points, dtype=float))


def in_laser_range(state: RobotState, points: np.ndarray) -> np.ndarray:
    """The points (cm) within laser range of the robot (no occlusion: enough for single walls seen from one side)."""
    return points[np.hypot(points[:, 0] - state.x, points[:, 1] - state.y) <= LASER_RANGE_CM]


def wall(x: float, y_from: float, y_to: float, spacing: float = 5.0) -> np.ndarray:
    """Laser-like returns (cm) every ``spacing`` cm along the segment x = const, y_from..y_to."""
    ys = np.arange(y_from, y_to + spacing / 2, spacing)
    return np.column_stack([np.full(len(ys), x), ys])


def random_observation(seed: int) -> Observation:
    """300 returns 45-250 cm around the robot and 5 tracks, drawn from ``seed`` (for determinism tests)."""
    rng = np.random.default_rng(seed)
    angles = rng.uniform(0.0, 2 * np.pi, 300)
    ranges = rng.uniform(45.0, 250.0, 300)
    points = np.column_stack([ranges * np.cos(angles), ranges * np.sin(angles)])
    tracks = tuple(Track(i, *rng.uniform(-200, 200, 2), *rng.uniform(-30, 30, 2), 20.0) for i in range(5))
    return observe(RobotState(10.0, -5.0, 33.0, 25.0), (400.0, 250.0), points, tracks)


def drive(policy: Policy, goal: tuple[float, float], points: np.ndarray, steps: int,
          tolerance: float = 20.0) -> tuple[list[RobotState], float]:
    """Run ``policy`` from the origin heading +x among static ``points`` (cm) with the robot's kinematics
    until it is within ``tolerance`` (cm) of ``goal`` or ``steps`` steps have passed: the states visited and
    the smallest distance (cm) from the robot's centre to any point over every step's straight move."""
    states, closest = [RobotState(0.0, 0.0, 0.0)], math.inf
    policy.reset(0)
    for _ in range(steps):
        s = states[-1]
        action = policy.act(observe(s, goal, in_laser_range(s, points)))
        nxt = step_unicycle(s, action.dtheta_deg, action.v_cm_s, CTX.dt, CTX.limits)
        gap = segment_point_distance(np.array([s.x, s.y]), np.array([nxt.x, nxt.y]), points)
        closest = min(closest, float(gap.min()))
        states.append(nxt)
        if math.hypot(nxt.x - goal[0], nxt.y - goal[1]) <= tolerance:
            break
    return states, closest
