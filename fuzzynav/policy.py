"""The navigation-policy seam: one small interface every way of driving the robot implements.

A policy maps what the robot senses at one step to the command of that step::

    policy = make_policy("dwa", params, context)       # registry below; params from conf/navigator/<name>.yaml
    policy.reset(seed)                                  # before each episode
    action = policy.act(observation)                    # every step: Action(mode, dtheta_deg, v_cm_s, fields)

The observation is the same for every policy (:class:`fuzzynav.navigator.Observation`): the robot's state
(odometry: x, y in cm, heading in degrees, last speed in cm/s), the goal (cm), the three sonar readings (left,
front, right; cm), the perceived moving obstacles (tracks: position cm, velocity cm/s, radius cm; from the
laser tracker, or the truth under ``perception=ground_truth``) and the static laser returns (world points, cm).
The command is a steering increment (degrees, positive = counter-clockwise) and a speed (cm/s; 0 = stand
still), which the robot clamps to its limits (:class:`fuzzynav.kinematics.RobotLimits`) and executes as a
turn followed by a straight move of ``v · dt``.

Policies are the paper's static controller slot: the Trajectory Prediction Table's wait/detour layer
(:mod:`fuzzynav.planner`) can run on top of any of them (``planner.strategy``), or not at all (``none``).

Rules for a policy, so that logs stay reproducible and comparable:

- deterministic for a seed: randomness only from the generator ``reset`` derives from the seed;
- portable numerics: no BLAS/LAPACK (no ``@``, ``np.dot``, ``np.linalg``) and no CPU-dependent reductions
  (use :mod:`fuzzynav.portable_math`), so that a log is the same on every CPU;
- ``fields`` are the policy's own values for the log (numbers and short strings), e.g. DWA's best score.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from fuzzynav.kinematics import RobotLimits

if TYPE_CHECKING:
    from fuzzynav.navigator import Observation


@dataclass(frozen=True)
class Action:
    """One step's command and why: ``mode`` names what the policy did (e.g. ``direct``, ``fuzzy``, ``dwa``),
    ``dtheta_deg`` the steering increment (degrees, + = left), ``v_cm_s`` the speed (cm/s, 0 = stand still),
    ``fields`` the policy's own values for the log."""

    mode: str
    dtheta_deg: float
    v_cm_s: float
    fields: Mapping[str, float | str] = field(default_factory=dict)


@dataclass(frozen=True)
class PolicyContext:
    """What a policy may know about the robot besides its observations: its limits, radius (cm), the time
    step (s) and the sonar's front sector (degrees relative to the heading)."""

    limits: RobotLimits
    robot_radius: float
    dt: float = 1.0
    front_sector_deg: tuple[float, float] = (-30.0, 30.0)


@runtime_checkable
class Policy(Protocol):
    """A navigation policy (see the module docstring)."""

    name: str

    def reset(self, seed: int) -> None:
        """Forget everything from an earlier episode; derive any randomness from ``seed``."""

    def act(self, observation: Observation) -> Action:
        """The command for this step."""


PolicyFactory = Callable[[Mapping[str, Any], PolicyContext], Policy]

#: policy name -> factory(params, context); filled by :func:`register_policy`
POLICIES: dict[str, PolicyFactory] = {}


def register_policy(name: str) -> Callable[[PolicyFactory], PolicyFactory]:
    """Class or function decorator: make a policy available as ``name`` (a name is registered once)."""

    def add(factory: PolicyFactory) -> PolicyFactory:
        if name in POLICIES and POLICIES[name] is not factory:
            raise ValueError(f"policy {name!r} is already registered ({POLICIES[name]!r})")
        POLICIES[name] = factory
        return factory

    return add


def make_policy(name: str, params: Mapping[str, Any], context: PolicyContext) -> Policy:
    """The registered policy ``name`` built with ``params`` (its YAML section) for a robot (``context``);
    ``ValueError`` naming the policy for an unknown name or a bad parameter."""
    if name not in POLICIES:
        raise ValueError(f"policy: unknown policy {name!r} (known: {', '.join(sorted(POLICIES)) or 'none'})")
    return POLICIES[name](params, context)
