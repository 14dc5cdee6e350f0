"""The obstacle-model seam: how moving obstacles move, one model per obstacle (``model:`` in the scenario).

A model owns some of a scenario's moving obstacles and advances them one time step at a time::

    model = factory(obstacles, config)          # the obstacles (DynamicObstacle) that name this model
    positions, velocities = model.reset(rng)    # at t = 0; (n, 2) cm and cm/s
    positions, velocities = model.step(view, indices, dt)  # at t + dt, given the world at t
    present = model.presence(step)              # optional: (n,) bool, who is in the world at step ``step``

``view`` (:class:`CrowdView`) holds the static world, the robot (pose, speed, radius) and *every* moving
obstacle at time t, whatever model moves it, so that pedestrians of one model avoid those of another and the
robot; ``indices`` are the model's own rows in it. All models step from the same state (simultaneous update:
the order of the models does not matter).

Presence: a model whose people come and go (``recorded``: a recorded pedestrian exists only between its first
and last annotation) has a ``presence(step)`` method saying which of its obstacles are in the world at step
``step`` (t = step * dt). An absent obstacle is not sensed, cannot be touched, is avoided by nobody and is in no
metric; its position is only kept (where it will appear, or where it left) so that its row stays continuous in the
log. A model without the method has its obstacles present throughout (every model before presence).

Obstacles that name the same model with equal parameters share one instance; a model whose obstacles each carry
their own data in their parameters (``recorded``: each person's times) has a static ``group_key(config)`` saying
what one instance shares, and is given its obstacles with the first one's config (each obstacle's own is its
``model_params``). A model whose obstacles ignore everyone has ``reactive = False``: they may start overlapping.

Models register with :func:`register_obstacle_model`; the built-ins (``scripted``, ``social_force``, ``orca``,
``random_walk``) are the modules of :mod:`fuzzynav.pedestrians`, found without a list (:mod:`fuzzynav.registry`),
and another package's model is an entry point of group ``fuzzynav.pedestrians``. Adding one is a module with a
factory carrying ``config_class`` (a frozen dataclass of its parameters, checked when the scenario is read).
Units: cm, s, cm/s, degrees.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from fuzzynav.numerics.portable_math import sin_cos_deg
from fuzzynav.params.checks import check_key, key_text, show
from fuzzynav.params.names import NAME
from fuzzynav.registry import load_plugins, one_line, source_digest

if TYPE_CHECKING:
    from fuzzynav.kinematics import RobotState
    from fuzzynav.scenarios.scenario import DynamicObstacle
    from fuzzynav.scenarios.world import World

MAX_ABS = 1e15  # a parameter's absolute value before its own range is checked

#: start of the note a KeyboardInterrupt gets when it comes out of a model's code: "pedestrian model 'x': step()"
MODEL_NOTE = "pedestrian model "


class ObstacleModelError(ValueError):
    """A pedestrian model's own code failed (its construction, ``reset``, ``step``, ``presence``), or returned what
    no obstacle can be: the episode ends as ``error`` with this message, which names the model."""


def call_model(name: str, what: str, function: Callable[..., Any], *args: Any) -> Any:
    """``function(*args)``, a call into model ``name``'s own code (``what``: "step()", "reset(rng)" ...): whatever
    it raises (``SystemExit`` included: a model must not end a run or a whole sweep with exit status 0) is an
    :class:`ObstacleModelError` "pedestrian model 'name': what failed: Type: message". ``KeyboardInterrupt`` (a
    signal's, or the model's own) goes on with a note naming the model, for the runner to tell them apart, as a
    policy's does (:mod:`fuzzynav.planning.layer`)."""
    try:
        return function(*args)
    except KeyboardInterrupt as err:
        err.add_note(f"{MODEL_NOTE}{name!r}: {what}")
        raise
    except BaseException as err:
        # already named: the framework's own check, or a ValueError of fuzzynav's own models ("recorded: ...")
        if isinstance(err, ObstacleModelError) or (isinstance(err, ValueError) and _own_model(name)):
            raise
        raise ObstacleModelError(f"pedestrian model {name!r}: {what} failed: {one_line(err)}") from err


def _own_model(name: str) -> bool:
    """Whether model ``name`` is one of fuzzynav's own (its factory defined in a module of fuzzynav)."""
    module = getattr(MODELS.get(name), "__module__", None)
    return isinstance(module, str) and module.startswith("fuzzynav.")


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` itself, made read-only (``flags.writeable = False``): what a model is given to read (the
    :class:`CrowdView`) raises when written to, instead of changing the other obstacles and the log."""
    array.flags.writeable = False
    return array


@dataclass(frozen=True)
class CrowdView:
    """The world at time ``time_s`` (step ``step``) as every model sees it when stepping.

    ``positions``/``velocities`` (N, 2) and ``radii`` (N,) are all moving obstacles (cm, cm/s) in the
    scenario's order; ``robot`` the robot's pose and last speed (cm, degrees, cm/s), ``robot_radius`` cm;
    ``present`` (N,) bool which of them are in the world now (None: all of them). The arrays are read-only
    (a model that writes into them fails with an error naming it): a model returns its obstacles' new state,
    it does not change anyone's current one."""

    world: World
    robot: RobotState
    robot_radius: float
    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray
    time_s: float
    step: int
    present: np.ndarray | None = None

    def others(self, indices: np.ndarray, sees_robot: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the obstacles at ``indices`` avoid: every other moving obstacle, then the robot when
        ``sees_robot`` (its velocity along its heading at its last speed) — positions (m, 2) cm, velocities
        (m, 2) cm/s, radii (m,) cm. Absent obstacles (``present``) are not there to avoid."""
        mask = np.ones(len(self.positions), dtype=bool) if self.present is None else self.present.copy()
        mask[indices] = False
        pos, vel, radii = self.positions[mask], self.velocities[mask], self.radii[mask]
        if sees_robot:
            sin_h, cos_h = sin_cos_deg(self.robot.heading)
            pos = np.vstack([pos, [[self.robot.x, self.robot.y]]])
            vel = np.vstack([vel, [[self.robot.v * cos_h, self.robot.v * sin_h]]])
            radii = np.append(radii, self.robot_radius)
        return pos, vel, radii


def substeps(dt: float, substep_s: float) -> tuple[int, float]:
    """How a step of ``dt`` seconds is integrated in substeps of at most ``substep_s`` seconds: (count, length s)."""
    count = max(1, math.ceil(dt / substep_s - 1e-9))
    return count, dt / count


class ObstacleModel(Protocol):
    """Moves the obstacles it was built with (in the order given). ``reset`` may draw from ``rng`` (the episode's
    obstacle stream, :func:`fuzzynav.pedestrians.crowd.obstacle_rng`); ``step`` must be deterministic given what
    ``reset``
    drew, the view and ``dt``, and must not use CPU-dependent arithmetic (BLAS, numpy's SIMD reductions or
    transcendental functions: use :mod:`fuzzynav.numerics.portable_math`)."""

    def reset(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]: ...

    def step(self, view: CrowdView, indices: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]: ...


def model_presence(model: Any, step: int, n: int, name: str) -> np.ndarray | None:
    """Which of a model's ``n`` obstacles are in the world at step ``step`` ((n,) bool), from its optional
    ``presence`` method; None when the model has none (all present, always). Anything but n booleans is a
    ``ValueError`` naming the model."""
    presence = getattr(model, "presence", None)
    if presence is None:
        return None
    value = np.asarray(call_model(name, "presence(step)", presence, step))
    if value.shape != (n,) or value.dtype != bool:
        raise ObstacleModelError(f"pedestrian model {name!r}: presence returned {value.dtype} of shape {value.shape}, "
                         f"expected ({n},) booleans")
    return value


ObstacleModelFactory = Callable[[Sequence["DynamicObstacle"], Any], ObstacleModel]
MODELS: dict[str, ObstacleModelFactory] = {}
#: the entry-point group of obstacle models from other installed packages (:mod:`fuzzynav.registry`)
ENTRY_POINT_GROUP = "fuzzynav.pedestrians"


def register_obstacle_model(name: str) -> Callable[[ObstacleModelFactory], ObstacleModelFactory]:
    """Class decorator: make an obstacle model available as ``name`` (``model: name`` in a scenario). The factory
    must carry ``config_class``, the frozen dataclass of its parameters (``model_params:``)."""

    def add(factory: ObstacleModelFactory) -> ObstacleModelFactory:
        if not NAME.fullmatch(name):
            raise ValueError(f"obstacle model name {name!r}: lowercase letters, digits and _")
        if name in MODELS and MODELS[name] is not factory:
            raise ValueError(f"obstacle model {name!r} is already registered ({MODELS[name]!r})")
        config_class = getattr(factory, "config_class", None)
        if not (isinstance(config_class, type) and dataclasses.is_dataclass(config_class)):
            raise ValueError(f"obstacle model {name!r}: its factory needs a dataclass config_class")
        MODELS[name] = factory
        return factory

    return add


def registered_models() -> dict[str, ObstacleModelFactory]:
    """Every registered obstacle model by name: fuzzynav's own and other packages' (their entry points)."""
    _load_models()
    return dict(MODELS)


def model_source_digest(name: str) -> str:
    """SHA-256 of the source of model ``name``'s module when another package registered it ('' for fuzzynav's own
    and for unknown names): part of the identity of the episodes whose scenario uses it."""
    _load_models()
    return source_digest(MODELS[name]) if name in MODELS else ""


def _load_models() -> None:
    load_plugins("fuzzynav.pedestrians", ENTRY_POINT_GROUP, lambda n, f: register_obstacle_model(n)(f), MODELS.get)


def model_factory(name: Any, field: str) -> ObstacleModelFactory:
    """The factory of model ``name``; ``ValueError`` naming ``field`` for an unknown one."""
    _load_models()
    if not isinstance(name, str) or name not in MODELS:
        raise ValueError(f"{field}: unknown obstacle model {show(name)} (known: {', '.join(sorted(MODELS))})")
    return MODELS[name]


def model_config(name: str, params: Any, field: str) -> Any:
    """The parameters of model ``name`` checked and frozen (an instance of its ``config_class``); ``params`` is
    the scenario's ``model_params`` mapping (None: the defaults). ``ValueError`` naming ``field.<key>``."""
    config_class = model_factory(name, field.rpartition(".")[0] + ".model").config_class
    if params is None:
        params = {}
    if isinstance(params, config_class):
        return params
    if not isinstance(params, Mapping):
        raise ValueError(f"{field}: expected a mapping of parameters, got {show(params)}")
    hints = typing.get_type_hints(config_class)
    names = [f.name for f in dataclasses.fields(config_class)]
    kwargs = {}
    for key, value in params.items():
        check_key(key, field)
        where = f"{field}.{key_text(key)}"
        if key not in names:
            raise ValueError(f"{where}: unknown parameter of model {name!r} (allowed: {', '.join(names) or 'none'})")
        kwargs[key] = _coerce(hints[key], value, where)
    try:
        return config_class(**kwargs)
    except ValueError as err:  # the config classes name the parameter first: "relaxation_s: must be ..."
        raise ValueError(f"{field}.{err}") from None
    except KeyboardInterrupt:
        raise
    except BaseException as err:  # another package's config class (its __post_init__), SystemExit included
        raise ValueError(f"{field}: model {name!r}: its config_class failed: {one_line(err)}") from None


def _coerce(hint: Any, value: Any, where: str) -> Any:
    """``value`` as the parameter's type: bool, str, int, float, or a tuple of floats (lists in YAML)."""
    if hint is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{where}: expected true or false, got {show(value)}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ValueError(f"{where}: expected a string, got {show(value)}")
        return value
    if typing.get_origin(hint) is tuple:
        if not isinstance(value, list | tuple) or len(value) > 1_000:
            raise ValueError(f"{where}: expected a list of numbers, got {show(value)}")
        return tuple(_coerce(float, v, f"{where}[{i}]") for i, v in enumerate(value))
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{where}: expected {'an integer' if hint is int else 'a number'}, got {show(value)}")
    if isinstance(value, int) and abs(value) > MAX_ABS:  # math.isfinite overflows on a 400-digit integer
        raise ValueError(f"{where}: must be at most {MAX_ABS:g} in absolute value, got {show(value)}")
    if not math.isfinite(value):
        raise ValueError(f"{where}: must be finite, got {value!r}")
    if hint is int:
        if not isinstance(value, int):
            raise ValueError(f"{where}: expected an integer, got {value!r}")
        return value
    return float(value)


def in_range(value: float, name: str, lo: float, hi: float, unit: str = "", lo_open: bool = False) -> None:
    """For the config classes' ``__post_init__``: ``ValueError("name: must be in [lo, hi] unit, got x")``."""
    ok = (value > lo if lo_open else value >= lo) and value <= hi
    if not ok:
        bracket = "(" if lo_open else "["
        raise ValueError(f"{name}: must be in {bracket}{lo:g}, {hi:g}]{' ' + unit if unit else ''}, got {value!r}")


def one_of(value: str, name: str, choices: tuple[str, ...]) -> None:
    """For the config classes' ``__post_init__``: ``ValueError("name: unknown value 'x' (known: a, b)")``."""
    if value not in choices:
        raise ValueError(f"{name}: unknown value {show(value)} (known: {', '.join(choices)})")
