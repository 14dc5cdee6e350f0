"""The navigation-policy seam: one small interface every way of driving the robot implements.

A policy maps what the robot senses at one step to the command of that step::

    policy = make_policy("dwa", params, context)       # registry below; params from conf/navigator/<name>.yaml
    policy.reset(seed)                                  # before each episode
    action = policy.act(observation)                    # every step: Action(mode, dtheta_deg, v_cm_s, fields)

The observation is the same for every policy (:class:`fuzzynav.planning.layer.Observation`): the robot's state
(odometry: x, y in cm, heading in degrees, last speed in cm/s), the goal (cm), the three sonar readings (left,
front, right; cm), the perceived moving obstacles (tracks: position cm, velocity cm/s, radius cm; from the
laser tracker, or the truth under ``perception=ground_truth``) and the static laser returns (world points, cm).
The command is a steering increment (degrees, positive = counter-clockwise) and a speed (cm/s; 0 = stand
still), which the robot clamps to its limits (:class:`fuzzynav.kinematics.RobotLimits`) and executes as a
turn followed by a straight move of ``v · dt``.

Policies are the paper's static controller slot: the Trajectory Prediction Table's wait/detour layer
(:mod:`fuzzynav.planning.planner`) can run on top of any of them (``planner.strategy``), or not at all (``none``).

Rules for a policy, so that logs stay reproducible and comparable:

- deterministic for a seed: randomness only from the generator ``reset`` derives from the seed;
- portable numerics: no BLAS/LAPACK (no ``@``, ``np.dot``, ``np.linalg``) and no CPU-dependent reductions
  (use :mod:`fuzzynav.numerics.portable_math`), so that a log is the same on every CPU;
- ``fields`` are the policy's own values for the log (numbers and short strings), e.g. DWA's best score.

Choosing a policy in a run (``conf/navigator/<name>.yaml``): ``navigator.policy`` names a registered policy
(``fuzzy``, ``dwa``, ``apf``, ``vfh``, ``orca``, ``direct``), and the other keys of the ``navigator`` section are
its parameters. A policy defined outside fuzzynav is named by ``navigator._target_`` instead, the import path
of its factory (``my_package.my_module.MyPolicy``): it is called as ``MyPolicy(params, context)`` like the
registered ones, and may set ``config_class`` (a frozen dataclass) to have its parameters checked when the
configuration is read rather than when the first episode starts. A field declared with
``fuzzynav.params.limits.ranged(default, Range(...))`` is checked against its range; with ``robot_speed=True``
(a speed the policy commands as it is, cm/s) also against the robot's ``v_min`` .. ``v_max``, like the built-in
policies' cruise speeds.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib
import inspect
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Protocol, runtime_checkable

import numpy as np

from fuzzynav.kinematics import RobotLimits, RobotState
from fuzzynav.params.names import AGENT, DEFAULT_POLICY, IMPORT_PATH, NAME
from fuzzynav.params.parsing import from_dict
from fuzzynav.registry import load_plugins, one_line, source_digest
from fuzzynav.sensing.tracking import Track


@dataclass(frozen=True)
class Observation:
    """What the robot knows at one step: its own state (odometry), the goal (cm), sonar readings
    (left, front, right; cm), perceived moving obstacles and static laser points (P, 2; cm).

    ``static_points`` is a read-only view (writing raises): the wait/detour layer reads the same observation
    after the policy, and the log records it, so a policy must not change it (copy it to work on it)."""

    state: RobotState
    goal: tuple[float, float]
    sonar: tuple[float, float, float]
    tracks: tuple[Track, ...]
    static_points: np.ndarray

    def __post_init__(self) -> None:
        points = self.static_points
        if isinstance(points, np.ndarray) and points.flags.writeable:
            points = points.view()  # the caller's own array stays as it was
            points.flags.writeable = False
            object.__setattr__(self, "static_points", points)


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
    controller: Any = None
    """The run's fuzzy controller (:class:`fuzzynav.controller.fuzzy_fast.FastEvaluator`, the ``controller`` group), for
    policies that use one; None where none is configured."""


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
    """Class or function decorator: make a policy available as ``name`` (a name is registered once). A factory
    may carry ``config_class``, the frozen dataclass of its parameters (checked when a configuration is read)."""

    def add(factory: PolicyFactory) -> PolicyFactory:
        if not isinstance(name, str) or not NAME.fullmatch(name):
            raise ValueError(f"policy name {str(name)[:40]!r}: expected a lowercase letter, then up to 31 lowercase "
                             "letters, digits or _")
        if name == AGENT:
            raise ValueError(f"policy name {AGENT!r} is reserved (the commands of a Gymnasium agent)")
        if name in POLICIES and POLICIES[name] is not factory:
            raise ValueError(f"policy {name!r} is already registered ({POLICIES[name]!r:.80})")
        config_class = getattr(factory, "config_class", None)
        if config_class is not None and not (isinstance(config_class, type) and dataclasses.is_dataclass(config_class)):
            raise ValueError(f"policy {name!r}: config_class must be a dataclass, got {config_class!r:.60}")
        POLICIES[name] = factory
        return factory

    return add


#: the entry-point group of policies from other installed packages (:mod:`fuzzynav.registry`)
ENTRY_POINT_GROUP = "fuzzynav.policies"


def _builtin_policies() -> None:
    """Register fuzzynav's own policies (every module of :mod:`fuzzynav.policies`) and those of other
    packages' ``fuzzynav.policies`` entry points, on first use, so that importing this seam imports none."""
    load_plugins("fuzzynav.policies", ENTRY_POINT_GROUP, lambda name, factory: register_policy(name)(factory),
                 POLICIES.get)


def registered_policies() -> dict[str, PolicyFactory]:
    """Every registered policy by name: fuzzynav's own and other packages' (their entry points), loaded now."""
    _builtin_policies()
    return dict(POLICIES)


def policy_factory(name: str) -> PolicyFactory:
    """The factory of policy ``name``: a registered name, or the import path of a factory defined outside
    fuzzynav (``package.module.Factory``); ``ValueError`` naming ``navigator.policy`` / ``navigator._target_``."""
    _builtin_policies()
    if name in POLICIES:
        return POLICIES[name]
    if not IMPORT_PATH.fullmatch(name):
        raise ValueError(f"navigator.policy: unknown policy {name[:60]!r} (known: {', '.join(sorted(POLICIES))}; "
                         "a policy of your own: navigator._target_=package.module.Factory)")
    module_name, _, attr = name.rpartition(".")
    try:
        module = importlib.import_module(module_name)
    except ImportError as err:  # ModuleNotFoundError included; the module's own import errors too
        raise ValueError(f"navigator._target_: cannot import {module_name!r} ({err}); is its directory on "
                         "PYTHONPATH?") from None
    except KeyboardInterrupt:
        raise
    except BaseException as err:  # user code: any failure of its import (SystemExit included) is this field's error
        raise ValueError(f"navigator._target_: importing {module_name!r} failed: {type(err).__name__}: "
                         f"{str(err)[:200]}") from None
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise ValueError(f"navigator._target_: {module_name!r} has no callable {attr!r}")
    return factory


def policy_source_digest(name: str) -> str:
    """SHA-256 of the source file of a policy's module when the policy is not fuzzynav's own: a ``_target_``
    policy's, or one registered by another package ('' for fuzzynav's own, whose code the fuzzynav version
    identifies, and for a module without a source file). Part of an episode's identity, so that a resumed sweep
    re-runs the episodes of a policy whose code changed instead of keeping their old logs."""
    if name in POLICIES:
        return source_digest(POLICIES[name])
    if not IMPORT_PATH.fullmatch(name):
        return ""
    module = importlib.import_module(name.rpartition(".")[0])  # imported already, by policy_factory
    try:
        source = inspect.getsourcefile(module)
        data = Path(source).read_bytes() if source else b""
    except (OSError, TypeError):
        return ""
    return hashlib.sha256(data).hexdigest() if data else ""


def split_navigator_section(data: Mapping[str, Any] | None) -> tuple[str, dict[str, Any]]:
    """(policy name or import path, parameters) of a ``navigator`` config section: ``policy`` or ``_target_``
    (not both; neither = :data:`DEFAULT_POLICY`), the other keys are the policy's parameters."""
    params = dict(data or {})
    for key in ("policy", "_target_"):
        if key in params and params[key] is None:  # null on the command line: not "the default", a mistake
            what = "a policy name" if key == "policy" else "an import path"
            raise ValueError(f"navigator.{key}: null (give {what})")
    name = params.pop("policy", None)
    target = params.pop("_target_", None)
    if name is not None and target is not None:
        raise ValueError("navigator._target_: give either navigator.policy (a registered policy) or "
                         "navigator._target_ (your own), not both")
    if target is not None:
        if target == "???":  # Hydra's mark of a mandatory value (conf/navigator/custom.yaml)
            raise ValueError("navigator._target_: not given (navigator=custom needs "
                             "navigator._target_=package.module.Factory; a sweep over every navigator leaves the "
                             "template out with navigator='glob(*,exclude=custom)')")
        if not isinstance(target, str) or not IMPORT_PATH.fullmatch(target):
            raise ValueError(f"navigator._target_: expected an import path such as my_package.MyPolicy (at most 200 "
                             f"characters), got {str(target)[:60]!r}")
        return target, params
    if name is None:
        return DEFAULT_POLICY, params
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise ValueError(f"navigator.policy: expected a policy name such as dwa, got {str(name)[:60]!r}")
    return name, params


def policy_params(name: str, params: Mapping[str, Any]) -> Any:
    """The parameters of policy ``name`` checked and frozen: an instance of the factory's ``config_class``
    where it has one (an unknown key or a bad value raises ``ValueError`` naming ``navigator.<key>``), else a
    read-only mapping."""
    factory = policy_factory(name)
    config_class = getattr(factory, "config_class", None)
    if config_class is None:
        return MappingProxyType(dict(params))
    if not (isinstance(config_class, type) and dataclasses.is_dataclass(config_class)):
        raise ValueError(f"navigator: policy {name!r}: config_class must be a dataclass, got {config_class!r:.60}")
    try:
        return from_dict(config_class, params, "navigator")
    except ValueError:
        raise
    except KeyboardInterrupt:
        raise
    except BaseException as err:  # a user's config_class (its __post_init__) failing otherwise
        raise ValueError(f"navigator: policy {name!r}: its config_class failed: {one_line(err)}") from None


def make_policy(name: str, params: Any, context: PolicyContext) -> Policy:
    """The policy ``name`` (registered, or an import path) built with ``params`` (its ``navigator`` section
    without ``policy``, or the checked config from :func:`policy_params`) for a robot (``context``);
    ``ValueError`` naming the field for an unknown name or a bad parameter."""
    factory = policy_factory(name)
    try:
        policy = factory(params, context)
    except KeyboardInterrupt:
        raise
    except ValueError as err:
        if name in POLICIES:  # fuzzynav's own name the field
            raise
        raise ValueError(f"navigator: policy {name!r}: {one_line(err, with_type=False)}") from None
    except BaseException as err:  # a policy of the user's own (SystemExit included): the config's error
        raise ValueError(f"navigator: building policy {name!r} failed: {one_line(err)}") from None
    if isinstance(policy, type) or not isinstance(policy, Policy):
        raise ValueError(f"navigator: {name!r} built {type(policy).__name__}, which is not a policy (it needs "
                         "name, reset(seed) and act(observation))")
    return policy
