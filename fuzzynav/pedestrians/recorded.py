"""``recorded``: real people replayed exactly as a recording has them (they ignore the robot, as in SocNavBench).

A recorded person is a scenario obstacle whose ``waypoints`` are its annotated positions (cm) and whose
``model_params.t_s`` are their times (s from the episode's start; the first may be negative: the annotation
before the window, so that the person is where the recording has it at t = 0). The scenario generator
``recorded`` (:mod:`fuzzynav.scenarios.generators.recorded`) makes these entries from a recording file; a scenario
file may also list them by hand.

At step k (t = k·dt) a person is where :func:`fuzzynav.pedestrians.recording.resample` puts it — the linear
interpolation between its two annotations around t — and is *present* (:mod:`fuzzynav.pedestrians.base`,
presence) only from its first to its last annotation, within ``until_s`` (the window's length: after it the
recording is not replayed), and inside ``crop`` (x0, y0, x1, y1 cm) when one is given. An absent person stands,
with zero velocity, at its first annotation until it first appears, then where it was last present; a present
person's velocity is its recorded path's (the slope of the segment between the annotations around t, the segment
after t on an annotation's time), so that the ground truth and the TPT's table see the recording's own motion.

**Reacting** (``react_cm`` > 0): a person stops being a replay at the first step at which it is present and its
surface is within ``react_cm`` of the robot's; from there it walks to its recorded destination (its last
waypoint) at its mean recorded speed (the entry's ``speed``) as a pedestrian of ``react_model`` (``social_force``
or ``orca``, with that model's default parameters: it avoids the robot and every other present person), and
leaves the world (absent) once within that model's ``arrive_cm`` of the destination, or at ``until_s``. The
crowd's ``reacting`` says which people's motion over a step is their reaction's; the log records it from the
step the person stopped being a replay (``/obstacles/truth`` ``reacting``).

One model instance replays every recorded person of a scenario that shares ``until_s``, ``crop`` and the reaction
parameters (:func:`RecordedModel.group_key`): the replayed positions of all of them at every step are computed
once per ``dt``
(arrays, no per-person Python work per step), so a person far from the robot costs one row of an array
lookup. Units: cm, s, cm/s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from fuzzynav.numerics.portable_math import norm2
from fuzzynav.pedestrians.base import CrowdView, in_range, model_config, model_factory, one_of, register_obstacle_model
from fuzzynav.pedestrians.recording import PedestrianTrack, Recording, resample

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle

MAX_TIME_S = 1e6  # a recording's times (s): ETH/UCY recordings last minutes
REACT_MODELS = ("social_force", "orca")
#: the most person-steps replayed (about 40 bytes each): 300 people over a 300-s window at dt = 0.02 s
MAX_GRID = 5_000_000  # the reactive models a recorded person may become


@dataclass(frozen=True)
class RecordedConfig:
    """``t_s``: the times (s from the episode's start, strictly increasing) of the obstacle's waypoints, one per
    waypoint; ``until_s``: the person is absent after this time (s; the window's length); ``crop``: () or
    (x0, y0, x1, y1) cm, the person is present only inside it (boundary included); ``react_cm``: 0 (a replay
    throughout) or the surface distance (cm) to the robot at which the person starts reacting, as a pedestrian of
    ``react_model`` (``social_force`` or ``orca``; module docstring)."""

    t_s: tuple[float, ...] = ()
    until_s: float = MAX_TIME_S
    crop: tuple[float, ...] = ()
    react_cm: float = 0.0
    react_model: str = "social_force"

    def __post_init__(self) -> None:
        if not self.t_s:
            raise ValueError("t_s: missing (one time per waypoint, s)")
        for i, t in enumerate(self.t_s):
            in_range(t, f"t_s[{i}]", -MAX_TIME_S, MAX_TIME_S, "s")
            if i and not t > self.t_s[i - 1]:
                raise ValueError(f"t_s[{i}]: {t!r} s is not after t_s[{i - 1}] = {self.t_s[i - 1]!r} s (times must "
                                 "increase)")
        in_range(self.until_s, "until_s", 0.0, MAX_TIME_S, "s")
        in_range(self.react_cm, "react_cm", 0.0, 1e5, "cm")
        one_of(self.react_model, "react_model", REACT_MODELS)
        if self.crop and (len(self.crop) != 4 or not (self.crop[0] < self.crop[2] and self.crop[1] < self.crop[3])):
            raise ValueError(f"crop: expected [x0, y0, x1, y1] cm with x0 < x1 and y0 < y1, got {list(self.crop)}")


@register_obstacle_model("recorded")
class RecordedModel:
    """Replays its people (module docstring); the view is not used (they ignore the robot and each other)."""

    config_class = RecordedConfig
    #: recorded people pass through everyone, so they may start overlapping (couples walk closer than two radii)
    reactive = False

    @staticmethod
    def group_key(config: RecordedConfig) -> tuple:
        """What the people of one model instance share (their own times differ): the window and the crop."""
        return (config.until_s, config.crop, config.react_cm, config.react_model)

    @staticmethod
    def check_obstacle(obstacle: DynamicObstacle) -> None:
        """A recorded person's entry has waypoints and one time per waypoint (``ValueError`` naming the field)."""
        if obstacle.waypoints is None:
            raise ValueError("waypoints: missing (a recorded person's annotated positions, cm)")
        if len(obstacle.model_params.t_s) != len(obstacle.waypoints):
            raise ValueError(f"model_params.t_s: {len(obstacle.model_params.t_s)} times for "
                             f"{len(obstacle.waypoints)} waypoints (one time per waypoint)")

    def __init__(self, obstacles: Sequence[DynamicObstacle], config: RecordedConfig) -> None:
        self.ids = tuple(o.id for o in obstacles)
        tracks, self._first = [], np.zeros((len(obstacles), 2))
        for i, o in enumerate(obstacles):
            own: RecordedConfig = o.model_params
            self.check_obstacle(o)
            xy = np.array(o.waypoints, dtype=float)
            tracks.append(PedestrianTrack(o.id, np.array(own.t_s, dtype=float), xy))
            self._first[i] = xy[0]
        self.recording = Recording(f"recorded obstacles {self.ids[:1]}", tuple(tracks), 0.0)
        self.until_s = config.until_s
        self.crop = tuple(config.crop) if config.crop else None
        self.react_cm, self.react_model = config.react_cm, config.react_model
        self._obstacles = tuple(obstacles)
        self.radii = np.array([o.radius for o in obstacles], dtype=float)
        self._dt: float | None = None
        self._reset_reactions()

    @property
    def reacts(self) -> bool:
        """Whether its people may stop being a replay (``react_cm`` > 0): the crowd then reports ``reacting``."""
        return self.react_cm > 0

    def _reset_reactions(self) -> None:
        #: per person: whether its motion is now its reaction's (not the recording's), and its reactive model
        self.reacting = np.zeros(len(self.ids), dtype=bool)
        self._walkers: dict[int, Any] = {}
        self._arrived = np.zeros(len(self.ids), dtype=bool)

    # -- the whole replay at a run's dt, once ------------------------------------------------------------------
    def _grid(self, dt: float | None) -> None:
        """Positions, velocities and presence of every person at every step k·dt from 0 to ``until_s`` (or to the
        last annotation, if sooner); ``dt`` None: at t = 0 only (what a reset needs, at every dt)."""
        if dt is not None and self._dt == dt:
            return
        last = max(float(t.t_s[-1]) for t in self.recording.tracks)
        end = 0.0 if dt is None else max(0.0, min(self.until_s, last))
        dt_grid = 1.0 if dt is None else dt
        steps = math.floor(end / dt_grid + 1e-9) + 1
        if steps * len(self.ids) > MAX_GRID:  # the arrays below hold every person at every step
            raise ValueError(f"recorded: {len(self.ids)} people x {steps:,} steps of {dt_grid:g} s is more than "
                             f"{MAX_GRID:,} positions to replay (a larger dt, or a shorter window: until_s)")
        r = resample(self.recording, dt_grid, 0.0, end, self.crop)
        n, steps = len(self.ids), len(r.times_s)
        present = np.zeros((n, steps), dtype=bool)
        xy = np.full((n, steps, 2), np.nan)
        row = {pid: i for i, pid in enumerate(self.ids)}
        for j, pid in enumerate(r.ids):
            present[row[pid]], xy[row[pid]] = r.present[j], r.xy_cm[j]
        present &= r.times_s[None, :] <= self.until_s + 1e-9
        # an absent person stays where it was last present, and before its first presence at its first annotation
        # (the same at every dt, so that a reset, which knows no dt, agrees with the run's grid)
        index = np.broadcast_to(np.arange(steps), (n, steps))
        latest = np.maximum.accumulate(np.where(present, index, -1), axis=1)
        held = np.take_along_axis(xy, np.maximum(latest, 0)[..., None], axis=1)
        held = np.where((latest < 0)[..., None], self._first[:, None, :], held)
        # exact copies where present (interpolation NaN elsewhere is replaced by the held position)
        self._xy = np.where(present[..., None], xy, held)
        self._velocity = np.zeros((n, steps, 2))
        for i, track in enumerate(self.recording.tracks):
            if len(track.t_s) < 2 or not present[i].any():
                continue
            times = r.times_s[present[i]]
            segment = np.clip(np.searchsorted(track.t_s, times + 1e-9, side="right") - 1, 0, len(track.t_s) - 2)
            slope = (track.xy_cm[segment + 1] - track.xy_cm[segment]) \
                / (track.t_s[segment + 1] - track.t_s[segment])[:, None]
            self._velocity[i, present[i]] = slope
        self._present = present
        self._dt = dt

    def _at(self, step: int) -> tuple[np.ndarray, np.ndarray]:
        k = min(step, self._xy.shape[1] - 1)
        velocity = self._velocity[:, k] if step == k else np.zeros((len(self.ids), 2))
        return self._xy[:, k].copy(), velocity.copy()

    # -- the model seam ----------------------------------------------------------------------------------------
    def reset(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        self._grid(None)  # t = 0 is the same at every dt; step() replaces it with the run's whole grid
        self._reset_reactions()
        return self._at(0)

    def step(self, view: CrowdView, indices: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        if not (math.isfinite(dt) and dt > 0):
            raise ValueError(f"recorded: dt must be a positive number of seconds, got {dt!r}")
        self._grid(dt)
        pos, vel = self._at(view.step + 1)
        if self.react_cm > 0:
            self._start_reactions(view, indices)
            for i, walker in self._walkers.items():
                if self._arrived[i]:  # it has left where the recording has it leave: it stays there, absent
                    pos[i], vel[i] = walker.x[0], 0.0
                    continue
                p, v = walker.step(view, indices[i:i + 1], dt)
                pos[i], vel[i] = p[0], v[0]
                destination = np.array(self._obstacles[i].waypoints[-1], dtype=float)
                self._arrived[i] = bool(norm2(p[0] - destination) <= walker.config.arrive_cm)
        return pos, vel

    def _start_reactions(self, view: CrowdView, indices: np.ndarray) -> None:
        """The people present now whose surface is within ``react_cm`` of the robot's start reacting: each becomes
        one pedestrian of ``react_model`` where it is, moving as it is, heading for its recorded destination."""
        k = view.step
        if k >= self._present.shape[1]:
            return
        here = view.positions[indices]
        gap = norm2(here - np.array([view.robot.x, view.robot.y])) - self.radii - view.robot_radius
        for i in np.nonzero(self._present[:, k] & ~self.reacting & (gap <= self.react_cm))[0].tolist():
            o = self._obstacles[i]
            walker_entry = replace(o, waypoints=(tuple(here[i].tolist()), o.waypoints[-1]),
                                   model=self.react_model, model_params=None)
            config = model_config(self.react_model, None, f"dynamic_obstacles[{i}].model_params.react_model")
            walker = model_factory(self.react_model, "react_model")([walker_entry], config)
            walker.reset(np.random.default_rng(0))  # (draws nothing: social force and ORCA are deterministic)
            walker.x, walker.v = here[i:i + 1].copy(), view.velocities[indices[i]:indices[i] + 1].copy()
            self._walkers[i] = walker
            self.reacting[i] = True

    def presence(self, step: int) -> np.ndarray:
        """Who is in the world at step ``step`` of the last dt (after the replay's last step: nobody); a reacting
        person until it arrives at its destination, within the window."""
        if step >= self._present.shape[1]:
            present = np.zeros(len(self.ids), dtype=bool)
        else:
            present = self._present[:, step].copy()
        if self._walkers:
            in_window = step * (self._dt or 0.0) <= self.until_s + 1e-9
            present[self.reacting] = in_window & ~self._arrived[self.reacting]
        return present
