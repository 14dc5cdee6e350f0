"""``social_force``: pedestrians of Helbing & Molnár (1995), "Social force model for pedestrian dynamics",
Physical Review E 51(5), 4282–4286, written from the paper (equations numbered as there).

Each pedestrian α feels, in cm/s²:

- a **driving force** towards its preferred velocity v⁰·e (its intent, :mod:`fuzzynav.pedestrians.intent`),
  relaxing within τ: ``(v⁰ e − v) / τ`` (Eq. 2);
- a **repulsion from every other moving obstacle** β (pedestrians of any model, scripted obstacles, and the
  robot when ``sees_robot``): ``−∇_r V(b)`` with ``V(b) = V⁰ exp(−b/σ)`` (Eq. 4), where b is the semi-minor
  axis of the ellipse through α's position with foci at β and at β's position a step ahead
  (``2b = √((‖r‖ + ‖r − v_β Δt e_β‖)² − (v_β Δt)²)``, Eq. 3, r = r_α − r_β, v_β β's speed): people keep
  more room in front of a walker than behind. The paper writes the step with e, its symbol for a
  pedestrian's desired direction (Eq. 1), and describes the ellipse as pointing in the direction of motion;
  ``step_ahead`` chooses the reading (both keep the step's length ``s = v_β Δt`` at β's actual speed):

  - ``velocity`` (default): e_β is the direction β moves in, so the step is β's velocity vector times Δt;
  - ``desired_direction``: e_β is β's desired direction (pysocialforce's reading: ``r_ab − Δt·speed_b·e_b``
    with e_b its desired direction). This model knows it for the pedestrians of its own group (their
    preferred velocity's direction, as for the field of view); a group member standing with no preferred
    velocity, the other models' pedestrians, scripted obstacles and the robot step along their velocity as
    in ``velocity``.

  The readings differ where a pedestrian does not move where it wants to (pushed aside, turning towards its
  next waypoint). The gradient is computed in closed form, with ``a = r − s e_β``:
  ``∇_r b = (‖r‖ + ‖a‖) / (4b) · (r/‖r‖ + a/‖a‖)``;
- a **repulsion from walls and static obstacles** B: ``−∇ U`` with ``U = U⁰ exp(−d/R)`` (Eq. 5), d the gap
  between α's disc and the nearest point of each wall, polygon edge and circle (one term per edge: a corner
  counts twice, which the paper's "nearest point of the border" does not; the difference is a few cm/s²
  at a corner);
- the **field of view**: a repulsion from behind (outside 2φ around e) is weighted by c (Eq. 7).

The paper's attractive forces (friends, shop windows) and its fluctuation term are not modelled. Velocities are
capped at ``max_speed_factor``·v⁰ (the paper's v^max = 1.3 v⁰, Eq. 6's speed limit). The paper's constants are
in metres: V⁰ = 2.1 m²/s², σ = 0.3 m, Δt = 2 s, U⁰ = 10 m²/s², R = 0.2 m, τ = 0.5 s, φ = 100°, c = 0.5; here
in cm (V⁰ = 21,000 cm²/s², σ = 30 cm, U⁰ = 100,000 cm²/s², R = 20 cm). Pedestrians are points for each other
(the paper's model; the repulsion keeps them about 50 cm apart) and discs of their radius for walls.

The world's walls are solid: a pedestrian pushed through one (by strong parameters or a high speed) is put
back against it and its velocity into it set to 0. Integration: the episode's step dt is split into substeps of
at most ``substep_s`` (semi-implicit Euler: velocity first, then position with the new velocity); during them
the other obstacles and the robot move straight at their velocities of the step's start (what a pedestrian sees
at that time). Every sum is taken in a fixed order (:func:`fuzzynav.numerics.portable_math.sequential_sum`) and exp is
:func:`~fuzzynav.numerics.portable_math.exp_array`, so the trajectories are the same on every CPU.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fuzzynav.numerics.geometry import away_from_static, keep_inside
from fuzzynav.numerics.portable_math import exp_array, norm2, sequential_sum, sin_cos_deg
from fuzzynav.pedestrians.base import CrowdView, in_range, one_of, register_obstacle_model, substeps
from fuzzynav.pedestrians.intent import Intent

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle

#: the readings of the other's step ahead in Eq. 3 (module docstring)
STEP_AHEAD = ("velocity", "desired_direction")

#: floor of b (cm) in the gradient's 1/b (see :func:`agent_repulsion`): 1 cm bounds the factor u/(4b) to a
#: quarter of the pedestrians' distance in cm
B_FLOOR_CM = 1.0


@dataclass(frozen=True)
class SocialForceConfig:
    """The model's constants (cm, s, degrees); defaults are the paper's, converted from metres."""

    relaxation_s: float = 0.5  # τ_α
    agent_strength_cm2_s2: float = 21_000.0  # V⁰_αβ
    agent_range_cm: float = 30.0  # σ
    step_time_s: float = 2.0  # Δt, how far ahead the other's step is seen
    # e_β of the step ahead: β's direction of motion (velocity) or its desired direction (desired_direction,
    # pysocialforce's reading); the paper's words allow both (module docstring)
    step_ahead: str = "velocity"
    wall_strength_cm2_s2: float = 100_000.0  # U⁰_αB
    wall_range_cm: float = 20.0  # R
    fov_deg: float = 100.0  # φ, half the angle of sight
    fov_weight: float = 0.5  # c, the weight of what is outside the sight
    max_speed_factor: float = 1.3  # v^max / v⁰
    sees_robot: bool = True  # does the robot repel the pedestrians (False: they walk through its place)
    substep_s: float = 0.25  # integration substep (the paper's equations are continuous)
    arrive_cm: float = 30.0  # a waypoint is reached within this distance

    def __post_init__(self) -> None:
        # the lower bounds keep every force finite: a range of 1e-300 cm would make V⁰/σ infinite
        in_range(self.relaxation_s, "relaxation_s", 0.01, 60, "s")
        in_range(self.agent_strength_cm2_s2, "agent_strength_cm2_s2", 0, 1e9, "cm²/s²")
        in_range(self.agent_range_cm, "agent_range_cm", 1, 10_000, "cm")
        in_range(self.step_time_s, "step_time_s", 0, 60, "s")
        one_of(self.step_ahead, "step_ahead", STEP_AHEAD)
        in_range(self.wall_strength_cm2_s2, "wall_strength_cm2_s2", 0, 1e9, "cm²/s²")
        in_range(self.wall_range_cm, "wall_range_cm", 1, 10_000, "cm")
        in_range(self.fov_deg, "fov_deg", 0, 180, "deg")
        in_range(self.fov_weight, "fov_weight", 0, 1)
        in_range(self.max_speed_factor, "max_speed_factor", 1, 10)
        # the work per step grows as dt / substep_s; 0.01 s is 100 substeps of a 1 s step
        in_range(self.substep_s, "substep_s", 0.01, 10, "s")
        in_range(self.arrive_cm, "arrive_cm", 0, 10_000, "cm", lo_open=True)


def agent_repulsion(rel: np.ndarray, other_vel: np.ndarray, strength: float, range_cm: float,
                    step_time_s: float) -> np.ndarray:
    """−∇_r V(b(r)) (cm/s²) for relative positions ``rel`` = r_α − r_β (…, 2) cm of pedestrians α from others
    β whose step ahead is ``other_vel`` · ``step_time_s`` (``other_vel`` (…, 2) cm/s: β's velocity, or its
    speed along its desired direction, module docstring): Eqs. 3–4 in closed form. Zero where r = 0 (α is β:
    no direction).

    The paper's b has an infinite gradient on the segment from β to β's position Δt ahead (b = 0 there): b is
    floored at :data:`B_FLOOR_CM` in the factor 1/b, which bounds the push (on the segment itself the two unit
    vectors cancel, and at its far end only the one from β remains)."""
    ahead = rel - other_vel * step_time_s  # r − v_β Δt
    r1, r2 = norm2(rel), norm2(ahead)
    s = norm2(other_vel) * step_time_s  # (other_vel may be one row broadcast over α: computed once per β)
    u = r1 + r2
    b = 0.5 * np.sqrt(np.maximum(u * u - s * s, 0.0))
    apart1, apart2 = r1 > 0.0, r2 > 0.0
    unit1 = np.where(apart1[..., None], rel / np.where(apart1, r1, 1.0)[..., None], 0.0)
    unit2 = np.where(apart2[..., None], ahead / np.where(apart2, r2, 1.0)[..., None], 0.0)
    grad = (u / (4.0 * np.maximum(b, B_FLOOR_CM)))[..., None] * (unit1 + unit2)
    magnitude = strength / range_cm * exp_array(-b / range_cm) * np.where(apart1, 1.0, 0.0)
    return magnitude[..., None] * grad


def wall_repulsion(positions: np.ndarray, radii: np.ndarray, segments: np.ndarray, circles: np.ndarray,
                   strength: float, range_cm: float) -> np.ndarray:
    """Σ_B −∇U (cm/s²) on discs at ``positions`` (n, 2) cm of ``radii`` (n,) cm from every wall, polygon edge and
    static circle: Eq. 5 on the gap between the disc and the nearest point (0 for a disc that overlaps)."""
    gaps, away = away_from_static(positions, segments, circles)
    gap = np.maximum(gaps - radii[:, None], 0.0)
    magnitude = strength / range_cm * exp_array(-gap / range_cm)
    force = magnitude[..., None] * away
    return np.stack([sequential_sum(force[..., 0]), sequential_sum(force[..., 1])], axis=-1)


def _substep_force(x: np.ndarray, v: np.ndarray, pref: np.ndarray, o_pos0: np.ndarray, o_vel: np.ndarray,
                   tau: float, radii: np.ndarray, segments: np.ndarray, circles: np.ndarray,
                   c: SocialForceConfig, cos_fov: float) -> np.ndarray:
    """The force (n, 2) cm/s² on each of a group's pedestrians at positions ``x`` (n, 2) cm with velocities ``v``
    (n, 2) cm/s, preferred velocities ``pref`` (n, 2) cm/s and disc radii ``radii`` (n,) cm, for the substep
    starting ``tau`` s after the step's: the driving force, plus the sum of the field-of-view-weighted
    repulsions from the group itself and from the other obstacles (at ``o_pos0`` + ``o_vel`` · tau, (k, 2) cm
    and cm/s), plus the sum of the repulsions of the walls ``segments`` (M, 4) cm and circles ``circles``
    (C, 3) cm. ``cos_fov``: cos φ."""
    force = (pref - v) / c.relaxation_s
    # e: each pedestrian's desired direction (0 for one standing without a preferred velocity)
    speed = norm2(pref)
    e = pref / np.where(speed > 0.0, speed, 1.0)[:, None]
    # the group's steps ahead: at its speed along e in the desired_direction reading, when it has a direction
    step = np.where((speed > 0.0)[:, None], e * norm2(v)[:, None], v) if c.step_ahead == "desired_direction" else v
    # the group's pedestrians and every other obstacle at this substep; a pedestrian's pair with itself (r = 0)
    # has no direction and gives no force
    all_pos = np.vstack([x, o_pos0 + o_vel * tau]) if len(o_pos0) else x
    all_step = np.vstack([step, o_vel]) if len(o_pos0) else step
    if len(all_pos):  # (always, but for an empty group with no others: sequential_sum needs a term)
        rel = x[:, None, :] - all_pos[None, :, :]
        pair_f = agent_repulsion(rel, all_step[None, :, :], c.agent_strength_cm2_s2, c.agent_range_cm,
                                 c.step_time_s)
        # Eq. 7: a repulsion whose source is outside the angle of sight around e counts c times
        towards = -(e[:, None, 0] * pair_f[..., 0] + e[:, None, 1] * pair_f[..., 1])
        seen = towards >= norm2(pair_f) * cos_fov
        pair_f = pair_f * np.where(seen, 1.0, c.fov_weight)[..., None]
        force = force + np.stack([sequential_sum(pair_f[..., 0]), sequential_sum(pair_f[..., 1])], axis=-1)
    if len(segments) + len(circles):  # (a world without walls or circles: nothing to sum)
        force = force + wall_repulsion(x, radii, segments, circles, c.wall_strength_cm2_s2, c.wall_range_cm)
    return force


@register_obstacle_model("social_force")
class SocialForceModel:
    """The pedestrians of one ``social_force`` group (module docstring)."""

    config_class = SocialForceConfig

    def __init__(self, obstacles: Sequence[DynamicObstacle], config: SocialForceConfig) -> None:
        self.config = config
        self.intent = Intent(obstacles, config.arrive_cm)
        self.radii = np.array([o.radius for o in obstacles], dtype=float)
        self.cos_fov = sin_cos_deg(config.fov_deg)[1]
        self.x = self.intent.starts.copy()
        self.v = np.zeros_like(self.x)

    def reset(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        self.intent.reset()
        self.x = self.intent.starts.copy()
        self.v = self.intent.initial_velocities()
        return self.x.copy(), self.v.copy()

    def step(self, view: CrowdView, indices: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
        c = self.config
        n_sub, h = substeps(dt, c.substep_s)
        o_pos0, o_vel, _ = view.others(indices, c.sees_robot)
        segments, circles = view.world.segments, view.world.circles
        v_max = c.max_speed_factor * self.intent.speeds
        x, v = self.x, self.v
        for k in range(n_sub):
            tau = k * h
            pref = self.intent.preferred(x)
            force = _substep_force(x, v, pref, o_pos0, o_vel, tau, self.radii, segments, circles, c, self.cos_fov)
            v = v + force * h
            length = norm2(v)
            over = length > v_max
            if over.any():  # (usually none is: then v is already the result)
                v = np.where(over[:, None], v * (v_max / np.where(over, length, 1.0))[:, None], v)
            x, v = keep_inside(x + v * h, v, self.radii, view.world.bounds)
        self.x, self.v = x, v
        return x.copy(), v.copy()
