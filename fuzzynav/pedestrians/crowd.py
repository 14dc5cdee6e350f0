"""All moving obstacles of an episode, moved by their models (:mod:`fuzzynav.pedestrians.base`).

Obstacles that name the same model with the same parameters share one model instance (so a social-force crowd
is one system); every model steps from the same :class:`~fuzzynav.pedestrians.base.CrowdView` (simultaneous
update). Positions in cm, velocities in cm/s.

Every call into a model's code goes through :func:`~fuzzynav.pedestrians.base.call_model`: whatever it raises is one
:class:`~fuzzynav.pedestrians.base.ObstacleModelError` naming the model and the call. What a model is given to read
(the view's arrays) and the state the crowd keeps (what the log records) are read-only arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzynav.kinematics import RobotState
from fuzzynav.params import limits
from fuzzynav.params.names import DEFAULT_MODEL
from fuzzynav.pedestrians.base import (
    CrowdView,
    ObstacleModel,
    ObstacleModelError,
    call_model,
    model_config,
    model_factory,
    model_presence,
    read_only,
    substeps,
)

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle
    from fuzzynav.scenarios.world import World

#: the second word of the obstacles' random streams ``default_rng((seed, OBSTACLE_STREAM, group))``: independent of the
#: sensor noise (``default_rng(seed)``) and of the generators' ``(seed, 7)``, so a scripted scenario (which
#: draws nothing) keeps its logs, and a model's draws never shift the sensor noise
OBSTACLE_STREAM = 11


def obstacle_rng(seed: int, group: int) -> np.random.Generator:
    """The random stream of the ``group``-th model instance of an episode with ``seed``."""
    return np.random.default_rng((seed, OBSTACLE_STREAM, group))


def crowd_work(obstacles: Sequence[DynamicObstacle], dt: float, max_steps: int) -> int:
    """Pedestrian-substeps an episode of ``max_steps`` steps of ``dt`` seconds may cost: for every obstacle whose
    model integrates in substeps (``model_params.substep_s``), ceil(dt / substep_s) per step."""
    per_step = 0
    for o in obstacles:
        substep = getattr(o.model_params, "substep_s", None)
        if substep:
            per_step += substeps(dt, substep)[0]
    return per_step * max_steps


def check_crowd_work(obstacles: Sequence[DynamicObstacle], dt: float, max_steps: int) -> None:
    """``ValueError`` naming ``dynamic_obstacles`` when :func:`crowd_work` exceeds its limit
    (:mod:`fuzzynav.params.limits`):
    100 ORCA pedestrians with 0.01 s substeps for 100,000 steps would run for days."""
    work = crowd_work(obstacles, dt, max_steps)
    if work > limits.MAX_PEDESTRIAN_SUBSTEPS:
        raise ValueError(f"dynamic_obstacles: {work:,} pedestrian-substeps per episode (pedestrians x substeps per "
                         f"step x max_steps), more than the limit of {limits.MAX_PEDESTRIAN_SUBSTEPS:,} (use fewer "
                         "pedestrians, a larger model_params.substep_s or fewer max_steps)")


def model_name(obstacle: DynamicObstacle) -> str:
    """The obstacle's model (``scripted`` when its entry names none)."""
    return obstacle.model or DEFAULT_MODEL


class Crowd:
    """The moving obstacles of a scenario: :meth:`reset` to t = 0, then :meth:`step` once per time step."""

    def __init__(self, obstacles: Sequence[DynamicObstacle], world: World, robot_radius: float) -> None:
        self.ids = tuple(o.id for o in obstacles)
        self.radii = read_only(np.array([o.radius for o in obstacles], dtype=float))
        self.models_of = tuple(model_name(o) for o in obstacles)
        self.world = world
        self.robot_radius = robot_radius
        groups: dict[tuple, list[int]] = {}
        configs = []
        for i, o in enumerate(obstacles):
            name = model_name(o)
            config = model_config(name, o.model_params, f"dynamic_obstacles[{i}].model_params")
            configs.append(config)
            # a model whose obstacles each carry their own data (recorded people: their times) says what one
            # instance shares (``group_key``), so that one instance moves them all
            group_key = getattr(model_factory(name, "model"), "group_key", None)
            key = config if group_key is None else call_model(name, "group_key(config)", group_key, config)
            groups.setdefault((name, key), []).append(i)
        self._models: list[tuple[ObstacleModel, np.ndarray, str]] = []
        for (name, _), members in groups.items():
            model = call_model(name, "factory(obstacles, config)", model_factory(name, "model"),
                               [obstacles[i] for i in members], configs[members[0]])
            self._models.append((model, np.array(members, dtype=int), name))
        self.positions = read_only(np.zeros((len(obstacles), 2)))
        self.velocities = read_only(np.zeros((len(obstacles), 2)))
        #: which obstacles are in the world now ((N,) bool; :mod:`fuzzynav.pedestrians.base`, presence)
        self.present = read_only(np.ones(len(obstacles), dtype=bool))
        #: whether any model says who is present (``presence``): only then does the log record presence, so that the
        #: logs of every scenario before presence stay byte for byte what they were
        self.has_presence = any(hasattr(model, "presence") for model, _, _ in self._models)
        #: which obstacles moved over the last step by their reaction instead of their replay ((N,) bool; recorded
        #: people with ``react_cm``); logged only when a model ``reacts``
        self.reacting = read_only(np.zeros(len(obstacles), dtype=bool))
        self.has_reactions = any(getattr(model, "reacts", False) for model, _, _ in self._models)
        self.step_index = 0

    def __len__(self) -> int:
        return len(self.ids)

    def reset(self, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """Every obstacle at t = 0: positions (N, 2) cm and velocities (N, 2) cm/s."""
        pos = np.zeros((len(self.ids), 2))
        vel = np.zeros((len(self.ids), 2))
        for group, (model, members, name) in enumerate(self._models):
            result = call_model(name, "reset(rng)", model.reset, obstacle_rng(seed, group))
            p, v = _model_arrays(result, name, "reset", len(members))
            pos[members], vel[members] = p, v
        self.positions, self.velocities, self.step_index = read_only(pos), read_only(vel), 0
        self.present = self._presence(0)
        self.reacting = read_only(np.zeros(len(self.ids), dtype=bool))
        return pos, vel

    def _presence(self, step: int) -> np.ndarray:
        """Which obstacles are in the world at step ``step`` (all of a model without ``presence``)."""
        present = np.ones(len(self.ids), dtype=bool)
        for model, members, name in self._models:
            mine = model_presence(model, step, len(members), name)
            if mine is not None:
                present[members] = mine
        return read_only(present)

    def step(self, robot: RobotState, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Advance every obstacle from the current time (step ``step_index``) by ``dt`` seconds, seeing the robot
        as it was at the current time; returns and keeps the new positions and velocities."""
        if not len(self.ids):
            self.step_index += 1
            return self.positions, self.velocities
        view = CrowdView(self.world, robot, self.robot_radius, self.positions, self.velocities, self.radii,
                         self.step_index * dt, self.step_index, self.present if self.has_presence else None)
        pos = np.zeros_like(self.positions)
        vel = np.zeros_like(self.velocities)
        for model, members, name in self._models:
            p, v = _model_arrays(call_model(name, "step()", model.step, view, members, dt), name, "step",
                                 len(members))
            pos[members], vel[members] = p, v
        if not (np.isfinite(pos).all() and np.isfinite(vel).all()):
            bad = int(np.nonzero(~(np.isfinite(pos).all(axis=1) & np.isfinite(vel).all(axis=1)))[0][0])
            raise FloatingPointError(f"obstacle {self.ids[bad]!r} ({self.models_of[bad]}): non-finite position or "
                                     f"velocity at step {self.step_index + 1}")
        self.positions, self.velocities = read_only(pos), read_only(vel)
        self.step_index += 1
        if self.has_presence:
            self.present = self._presence(self.step_index)
        if self.has_reactions:
            reacting = np.zeros(len(self.ids), dtype=bool)
            for model, members, _ in self._models:
                if getattr(model, "reacts", False):
                    reacting[members] = model.reacting
            self.reacting = read_only(reacting)
        return pos, vel


def _model_arrays(result: Any, name: str, method: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The (positions, velocities) a model's ``reset`` or ``step`` returned for its ``n`` pedestrians, each of shape
    (n, 2): anything else is an :class:`ObstacleModelError` naming the model (a (2,) array would otherwise be
    broadcast to every pedestrian of the group without a word)."""
    try:
        p, v = result
    except (TypeError, ValueError):
        raise ObstacleModelError(f"pedestrian model {name!r}: {method} returned {type(result).__name__}, expected "
                         f"(positions, velocities)") from None
    arrays = []
    for what, value in (("positions", p), ("velocities", v)):
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ObstacleModelError(f"pedestrian model {name!r}: {method} returned {what} that are not "
                                     "numbers") from None
        if array.shape != (n, 2):
            raise ObstacleModelError(f"pedestrian model {name!r}: {method} returned {what} of shape {array.shape}, "
                             f"expected ({n}, 2) for its {n} pedestrian(s)")
        arrays.append(array)
    return arrays[0], arrays[1]
