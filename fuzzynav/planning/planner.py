"""Dynamic path planning with the Trajectory Prediction Table: the paper's listing, lines 1-60.

Names follow the listing: ``tc`` (first predicted collision step), ``tS = tc - 1`` (last safe step),
``tG`` (first collision-free step after ``tc``; ``n_traj + 1`` if the collision lasts to the end of the
table), ``wait_time = tG - tS - 1``, ``h_wait``, ``find_new_path``, ``get_successors``, ``φLow``.
Steps are counted from now: step 0 is the present, step k is ``k·dt`` seconds ahead. Positions in cm,
speeds in cm/s, angles in degrees (CCW from +x).

A plan is the list of positions the robot should occupy at steps 1, 2, ..., L.

- **Wait** (line 17): follow the predicted robot trajectory to ``rS = rTraj(tS)`` and stay there until
  step ``tG - 1`` (``wait_time`` steps of waiting). Chosen when ``wait_time < h_wait`` or
  ``tG == n_traj + 1``, and the robot standing at ``rS`` collides with nothing during the wait — and,
  with ``wait_check_horizon`` (ours, default), nor standing there until the end of the table: ``tG`` is
  computed for the *moving* robot, and a robot that stands in an oncoming obstacle's path is hit after
  ``tG - 1``.
- **Detour** (lines 19-35): back up one step (``tS' = tS - 1`` if ``tS > 1``), follow ``rTraj`` to
  ``rS' = rTraj(tS')``, then repeatedly move to the successor with minimal ``f = g + h`` (``g``: step
  length, ``h``: distance to ``rG = rTraj(tG)``; a successor whose move collides costs ∞) until within
  ``detour_tolerance_cm`` of ``rG``. With ``avoid_static_points`` (ours) the moves along ``rTraj`` to
  ``rS'`` are checked against the static points too, and ``tS'`` backs up further to the last step
  ``rTraj`` reaches clear of them (``rTraj`` is the straight run to the goal, which knows no walls).

Choices where the listing is silent (documented in the README, tested):

- ``tc = 1``: ``tS = 0`` is the present position; waiting means standing still now, a detour starts here.
- A move "collides" if, during the step, the robot disc comes closer to any tracked obstacle than the sum
  of radii plus the safety margin (exact minimum distance of the two straight motions over the step), or,
  with ``avoid_static_points``, closer than the robot radius plus ``static_margin_cm`` to a laser return
  that is not a moving obstacle. With ``respect_turn_limit`` a successor that needs a sharper turn than
  the robot can make in one step also costs ∞ (so that every plan is executable).
- Ties in ``f``: moves straight at ``rG`` all have ``f = |rG - r|``; ``tie_break = fastest`` (ours, what
  the text asks: "the robot has to move faster") takes the fastest of them, ``listing`` the first
  successor in the listing's order (speeds outer, headings inner).
- The listing's loop does not end when ``rG`` is never reached: the detour fails when no successor is
  finite or ``rG`` is not reached within ``detour_max_steps``. Then, with ``fallbacks`` (ours, default),
  ``auto`` waits at ``rS`` if that is safe (whatever ``h_wait`` says), else in place, else evades (below),
  else stops for one step; ``detour`` waits in place, else evades, else stops; ``wait`` waits at ``rS``,
  else in place, else stops. A stop is a one-step plan at the present position; the robot re-plans on the
  next step. Without ``fallbacks`` there is no new path (line 10): the robot goes on as if no collision
  were predicted, and plans again on the next table.
- ``φLow``: ``phi_low_rule = paper`` is lines 39-49 literally. Its 19 headings span the half-plane on
  one side of the obstacle's line of motion, so a robot that has stepped off that line can never come
  back to it: with a head-on obstacle (rG on the obstacle's line) no detour can reach rG. The literal
  rule also picks the half-plane *not* containing the target for φ < 180° and θ < φ (and for
  φ >= 180° and θ < φ - 180°). ``target_side`` picks the half-plane that contains the bearing θ to rG
  (what the text describes). ``toward_goal`` (the default, ours) centres the 19 headings on θ
  (φLow = θ - 90°), so the robot can side-step either way and return; it is what makes head-on
  obstacles avoidable.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from fuzzynav.numerics.clearance import segment_point_clearance
from fuzzynav.numerics.geometry import angle_difference_deg, swept_distance, wrap_180, wrap_360
from fuzzynav.numerics.portable_math import atan2_deg, bearing_deg, dist, norm2, sin_cos_deg_array
from fuzzynav.params.names import STRATEGIES
from fuzzynav.planning.tpt import TrajectoryPredictionTable

PHI_LOW_RULES = ("paper", "target_side", "toward_goal")
DETOUR_SEARCHES = ("greedy", "astar")
TIE_BREAKS = ("fastest", "listing")
PREDICT_SPEEDS = ("command", "present")


@dataclass(frozen=True)
class PlannerConfig:
    """Dynamic path planning parameters (see the module docstring)."""

    strategy: str = "auto"
    h_wait: int = 2
    n_traj: int = 9
    safety_margin_cm: float = 10.0
    swept_tpt: bool = True
    successor_speeds: tuple[float, ...] = (10.0, 25.0, 40.0)
    n_headings: int = 19
    heading_step_deg: float = 10.0
    phi_low_rule: str = "toward_goal"
    detour_search: str = "greedy"
    astar_max_expansions: int = 3000
    detour_tolerance_cm: float = 10.0
    detour_max_steps: int = 30
    respect_turn_limit: bool = True
    avoid_static_points: bool = True
    static_margin_cm: float = 5.0
    cruise_speed: float = 25.0
    plan_tolerance_cm: float = 10.0
    plan_check_margin_cm: float = 5.0
    replan_every_step: bool = False
    recheck_plan: bool = True
    evade_when_blocked: bool = True
    fallbacks: bool = True
    wait_check_horizon: bool = True
    tie_break: str = "fastest"
    predict_speed: str = "command"

    def __post_init__(self) -> None:
        if self.strategy not in STRATEGIES:
            raise ValueError(f"planner.strategy: unknown strategy {self.strategy!r} "
                             f"(known: {', '.join(STRATEGIES)})")
        if self.phi_low_rule not in PHI_LOW_RULES:
            raise ValueError(f"planner.phi_low_rule: unknown rule {self.phi_low_rule!r} "
                             f"(known: {', '.join(PHI_LOW_RULES)})")
        if self.detour_search not in DETOUR_SEARCHES:
            raise ValueError(f"planner.detour_search: unknown search {self.detour_search!r} "
                             f"(known: {', '.join(DETOUR_SEARCHES)})")
        if self.tie_break not in TIE_BREAKS:
            raise ValueError(f"planner.tie_break: unknown rule {self.tie_break!r} (known: {', '.join(TIE_BREAKS)})")
        if self.predict_speed not in PREDICT_SPEEDS:
            raise ValueError(f"planner.predict_speed: unknown rule {self.predict_speed!r} "
                             f"(known: {', '.join(PREDICT_SPEEDS)})")
        if self.astar_max_expansions < 1:
            raise ValueError(f"planner.astar_max_expansions: must be >= 1, got {self.astar_max_expansions}")
        if self.h_wait < 0:
            raise ValueError(f"planner.h_wait: must be >= 0, got {self.h_wait}")
        if self.n_traj < 1:
            raise ValueError(f"planner.n_traj: must be >= 1, got {self.n_traj}")
        if not self.successor_speeds or any(v <= 0 for v in self.successor_speeds):
            raise ValueError(f"planner.successor_speeds: need positive speeds, got {self.successor_speeds}")
        if self.n_headings < 1 or self.heading_step_deg <= 0:
            raise ValueError("planner.n_headings / heading_step_deg: must be positive")
        for name in ("safety_margin_cm", "static_margin_cm", "plan_check_margin_cm"):
            if getattr(self, name) < 0:
                raise ValueError(f"planner.{name}: must be >= 0, got {getattr(self, name)}")
        for name in ("detour_tolerance_cm", "cruise_speed", "plan_tolerance_cm"):
            if getattr(self, name) <= 0:
                raise ValueError(f"planner.{name}: must be > 0, got {getattr(self, name)}")
        if self.detour_max_steps < 1:
            raise ValueError(f"planner.detour_max_steps: must be >= 1, got {self.detour_max_steps}")


@dataclass(frozen=True)
class Plan:
    """A short-term path: ``path[i]`` is the position (cm) to occupy at step i+1 after planning.

    ``strategy``: wait | detour | stop. The listing's quantities are kept for logs and explanations;
    ``detour_start`` is tS' (detour only) and ``obstacle_id`` the colliding track."""

    strategy: str
    path: np.ndarray
    tc: int
    tS: int
    tG: int
    wait_time: int
    obstacle_id: int
    detour_start: int | None = None
    phi_low_deg: float | None = None
    reason: str = ""


def find_collision_window(tpt: TrajectoryPredictionTable) -> tuple[int, int, int, int] | None:
    """Lines 1-5: (tc, tS, tG, obstacle column) of the first predicted collision, or None.

    ``tG`` is the first step after ``tc`` at which the robot does not collide with that obstacle
    (``n_traj + 1`` if it collides until the end of the table)."""
    first = tpt.first_collision()
    if first is None:
        return None
    tc, col = first
    t_g = tpt.n_traj + 1
    for k in range(tc + 1, tpt.n_traj + 1):
        if not tpt.collide[k, col]:
            t_g = k
            break
    return tc, tc - 1, t_g, col


def phi_low(theta_deg: float, phi_deg: float, rule: str = "paper") -> float:
    """Lines 39-49: the first of the 19 successor headings (degrees, [0, 360)).

    ``theta_deg``: bearing from the robot to rG; ``phi_deg``: the obstacle's moving angle (both [0, 360))."""
    theta, phi = wrap_360(theta_deg), wrap_360(phi_deg)
    if rule == "toward_goal":
        return wrap_360(theta - 90.0)
    if rule == "target_side":
        return phi if wrap_360(theta - phi) < 180.0 else wrap_360(phi + 180.0)
    if phi < 180.0:
        return phi if theta < phi + 180.0 else phi + 180.0
    return phi - 180.0 if theta < phi else phi


def get_successors(r: Sequence[float], r_goal: Sequence[float], phi_deg: float, speeds: Sequence[float],
                   dt: float = 1.0, n_headings: int = 19, heading_step_deg: float = 10.0,
                   rule: str = "paper") -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Lines 38-60: the 3 × 19 = 57 next positions from ``r`` (cm).

    Returns positions (S, 2) cm in the listing's order (speed outer, heading inner), their speeds (cm/s),
    their headings (degrees) and φLow."""
    theta = bearing_deg(r[0], r[1], r_goal[0], r_goal[1])
    low = phi_low(theta, phi_deg, rule)
    headings = low + heading_step_deg * np.arange(n_headings)
    v = np.repeat(np.asarray(speeds, dtype=float), n_headings)
    h = np.tile(headings, len(speeds))
    sin, cos = sin_cos_deg_array(h)
    pos = np.stack([r[0] + v * dt * cos, r[1] + v * dt * sin], axis=1)
    return pos, v, wrap_360(h), low


def obstacle_gaps(tpt: TrajectoryPredictionTable, start: np.ndarray, ends: np.ndarray, step: int) -> np.ndarray:
    """Smallest surface-to-surface distance (cm) between the robot and each tracked obstacle while the robot
    moves from ``start`` (at step-1) to each of ``ends`` (at ``step``); exact, both moving straight.
    Shape (S, J)."""
    ends = np.atleast_2d(ends)
    o0 = tpt.obstacles_at(step - 1)  # (J, 2)
    o1 = tpt.obstacles_at(step)
    closest = swept_distance(start, ends[:, None, :], o0, o1)  # (S, J)
    return closest - tpt.robot_radius - tpt.obstacle_radii[None, :]


def moves_collide(tpt: TrajectoryPredictionTable | None, start: np.ndarray, ends: np.ndarray, step: int,
                  static_points: np.ndarray | None, static_clearance: float,
                  margin: float | None = None) -> np.ndarray:
    """For moves from ``start`` (at step-1) to each of ``ends`` (at ``step``), True where the robot comes
    closer than the safety margin (the table's, unless ``margin`` is given) to a tracked obstacle during
    the step, or closer than ``static_clearance`` (cm) to a static point. ``tpt`` None: no moving obstacle
    is perceived, only the static points count."""
    ends = np.atleast_2d(ends)
    out = np.zeros(len(ends), dtype=bool)
    if tpt is not None and len(tpt.obstacle_ids):
        limit = tpt.safety_margin if margin is None else margin
        out |= (obstacle_gaps(tpt, start, ends, step) < limit).any(axis=1)
    if static_points is not None and len(static_points):
        out |= segment_point_clearance(start, ends, static_points) < static_clearance
    return out


def path_collides(tpt: TrajectoryPredictionTable | None, path: np.ndarray, start: np.ndarray,
                  static_points: np.ndarray | None, static_clearance: float, margin: float | None = None) -> bool:
    """True if following ``path`` (positions at steps 1..L) from ``start`` collides at any step."""
    prev = np.asarray(start, dtype=float)
    for k, p in enumerate(path, start=1):
        if moves_collide(tpt, prev, p[None, :], k, static_points, static_clearance, margin)[0]:
            return True
        prev = p
    return False


def hold_to_horizon(path: np.ndarray, n_steps: int) -> np.ndarray:
    """``path`` (positions at steps 1..L, cm) followed by standing at its last position up to step
    ``n_steps``: what a wait must survive, since the robot is still standing there when the wait ends and
    an oncoming obstacle may reach it after ``tG - 1``."""
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(path) >= n_steps:
        return path
    return np.concatenate([path, np.repeat(path[-1:], n_steps - len(path), axis=0)])


def _wait_path(tpt: TrajectoryPredictionTable, t_s: int, t_g: int) -> np.ndarray:
    """Line 17: rTraj(1 -> tS-1), then stay at rTraj(tS) up to step tG-1."""
    steps = [tpt.robot_at(min(k, t_s)) for k in range(1, max(t_g, 2))]
    return np.array(steps).reshape(-1, 2)


def _detour(tpt: TrajectoryPredictionTable, t_s: int, t_g: int, col: int, heading_deg: float,
            config: PlannerConfig, static_points: np.ndarray | None, static_clearance: float,
            max_turn_deg: float) -> tuple[np.ndarray | None, int, float, str, str]:
    """Lines 19-35. Returns (path or None, tS', φLow of the first expansion, reason, and a note when tS' backed
    up further than the listing's tS - 1 because rTraj passes a static point, else "")."""
    t_s1 = t_s - 1 if t_s > 1 else t_s
    r_goal = tpt.robot_at(t_g)
    prefix = [tpt.robot_at(k) for k in range(1, t_s1 + 1)]
    backed = ""
    if static_points is not None and len(static_points) and prefix:
        # the listing follows rTraj up to rS' unchecked; rTraj is the robot's straight run to the goal, which
        # ignores walls the laser sees (the sonar-driven fuzzy control would have turned away from them), so the
        # detour starts from the last position rTraj reaches clear of every static point instead
        ends = np.array(prefix)
        starts = np.vstack([tpt.robot[:1], ends[:-1]])
        clear = [not moves_collide(None, a, b[None, :], k + 1, static_points, static_clearance)[0]
                 for k, (a, b) in enumerate(zip(starts, ends, strict=True))]
        if not all(clear):
            safe = clear.index(False)
            backed = f" (tS' {t_s1} -> {safe}: rTraj to step {safe + 1} passes a static point)"
            t_s1, prefix = safe, prefix[:safe]
    start = tpt.robot_at(t_s1)
    heading = heading_deg if t_s1 == 0 else _bearing(tpt.robot[0], tpt.goal, heading_deg)
    phi = float(tpt.obstacle_angles_deg[col])

    def expand(current: np.ndarray, head: float, time: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Successors of ``current`` at step ``time`` with their f = g + h (∞ when the move collides)."""
        succ, _speeds, heads, low = get_successors(current, r_goal, phi, config.successor_speeds, tpt.dt,
                                                   config.n_headings, config.heading_step_deg,
                                                   config.phi_low_rule)
        g = norm2(succ - current)
        f = g + norm2(succ - r_goal)
        bad = moves_collide(tpt, current, succ, time + 1, static_points, static_clearance)
        if config.respect_turn_limit:
            bad |= np.abs(angle_difference_deg(heads, head)) > max_turn_deg + 1e-9
        return succ, heads, np.where(bad, np.inf, f), low

    standing = all(dist(p, tpt.robot[0]) == 0.0 for p in prefix)
    if standing and dist(start, r_goal) <= config.detour_tolerance_cm:
        # rG is where the robot stands (a policy commanding v = 0 is predicted standing): the "detour" would be no
        # step at all (a plan with nothing to follow) or a wait labelled detour; the fallbacks decide instead
        # (wait in place if that is safe, evade, stop)
        return None, t_s1, 0.0, "rG is where the robot stands: no detour to make", backed
    search = _greedy if config.detour_search == "greedy" else _astar
    path, low, why = search(expand, start, heading, t_s1, r_goal, config)
    if path is None:
        return None, t_s1, low, why + backed, backed
    return np.array(prefix + path).reshape(-1, 2), t_s1, low, why, backed


def _greedy(expand, start: np.ndarray, heading: float, t_s1: int, r_goal: np.ndarray,
            config: PlannerConfig) -> tuple[list | None, float, str]:
    """Lines 23-35 literally: always move to the successor with minimal f, no backtracking. Moves along the
    same heading straight at rG all have f = |rG - current| exactly; such ties (within 1e-9 cm) go to the
    faster move, as the paper's text asks ("the robot has to move faster"), then to the listing's order."""
    current, time, path, first_low = start, t_s1, [], None
    while dist(current, r_goal) > config.detour_tolerance_cm:
        if time - t_s1 >= config.detour_max_steps:
            return None, first_low or 0.0, f"rG not reached within {config.detour_max_steps} steps"
        succ, heads, f, low = expand(current, heading, time)
        first_low = low if first_low is None else first_low
        best = _argmin_prefer_fast(f, norm2(succ - current)) if config.tie_break == "fastest" else int(np.argmin(f))
        if not np.isfinite(f[best]):
            return None, first_low, f"no collision-free successor at step {time + 1}"
        current, heading = succ[best], float(heads[best])
        path.append(current)
        time += 1
    return path, first_low or 0.0, "rG reached"


def _argmin_prefer_fast(f: np.ndarray, step_lengths: np.ndarray, tie_cm: float = 1e-9) -> int:
    """Index of the minimal f; among near-ties the longest step (fastest), then the first in order."""
    best = float(np.min(f))
    if not np.isfinite(best):
        return int(np.argmin(f))
    tied = np.nonzero(f <= best + tie_cm)[0]
    return int(tied[np.argmax(step_lengths[tied])])


def _astar(expand, start: np.ndarray, heading: float, t_s1: int, r_goal: np.ndarray,
           config: PlannerConfig) -> tuple[list | None, float, str]:
    """Our extension (the paper calls its search "similar to A*"): best-first search over the same
    successors and costs, with g accumulated along the path and backtracking, in (position, step) space.
    States are merged on a 10 cm grid (first arrival wins); ties in f go to the path with fewer steps."""
    first_low = None
    h0 = dist(start, r_goal)
    heap: list = [(h0, 0, 0, 0.0, tuple(start), heading, t_s1, None)]
    parents: dict[int, tuple] = {}
    seen: set[tuple[int, int]] = set()
    counter = 0
    expansions = 0
    while heap:
        _f, depth, node_id, g, pos, head, time, parent = heapq.heappop(heap)
        parents[node_id] = (pos, parent)
        here = np.array(pos)
        if dist(pos, r_goal) <= config.detour_tolerance_cm and depth > 0:
            path = []
            nid = node_id
            while nid is not None and parents[nid][1] is not None:
                path.append(np.array(parents[nid][0]))
                nid = parents[nid][1]
            return path[::-1], first_low or 0.0, f"rG reached ({expansions} expansions)"
        key = (round(pos[0] / 10.0), round(pos[1] / 10.0))
        if key in seen or depth >= config.detour_max_steps:
            continue
        seen.add(key)
        expansions += 1
        if expansions > config.astar_max_expansions:
            return None, first_low or 0.0, f"rG not reached within {config.astar_max_expansions} expansions"
        succ, heads, f, low = expand(here, head, time)
        first_low = low if first_low is None else first_low
        steps = norm2(succ - here)
        for i in np.nonzero(np.isfinite(f))[0]:
            counter += 1
            g2 = g + float(steps[i])
            h2 = dist(succ[i], r_goal)
            heapq.heappush(heap, (g2 + h2, depth + 1, counter, g2, tuple(succ[i]), float(heads[i]), time + 1,
                                  node_id))
    return None, first_low or 0.0, "no collision-free path to rG"


def _bearing(p: np.ndarray, goal: Sequence[float], default: float) -> float:
    dx, dy = goal[0] - p[0], goal[1] - p[1]
    return default if dx == 0 and dy == 0 else bearing_deg(p[0], p[1], goal[0], goal[1])


def find_new_path(tpt: TrajectoryPredictionTable, config: PlannerConfig, heading_deg: float,
                  static_points: np.ndarray | None = None, robot_radius: float | None = None,
                  max_turn_deg: float = 120.0) -> Plan | None:
    """Lines 1-37: plan around the first predicted collision of ``tpt``; None when none is predicted, or
    when every option failed and ``config.fallbacks`` is off (the listing then has no new path).
    ``Plan.reason`` states the rule that decided and, when an option was rejected, why.

    ``heading_deg`` is the robot's present heading; ``static_points`` (P, 2) cm are laser returns that
    are not moving obstacles (used when ``config.avoid_static_points``)."""
    window = find_collision_window(tpt)
    if window is None:
        return None
    tc, t_s, t_g, col = window
    wait_time = t_g - t_s - 1
    oid = tpt.obstacle_ids[col]
    radius = tpt.robot_radius if robot_radius is None else robot_radius
    pts = static_points if config.avoid_static_points else None
    clearance = radius + config.static_margin_cm
    here = tpt.robot[0]

    def make(strategy: str, path: np.ndarray, reason: str, **kw) -> Plan:
        return Plan(strategy=strategy, path=path, tc=tc, tS=t_s, tG=t_g, wait_time=wait_time,
                    obstacle_id=oid, reason=reason, **kw)

    def stands_safely(path: np.ndarray) -> bool:
        """The listing's "no collision during waiting"; with ``wait_check_horizon`` (ours) the robot must
        also stay clear standing at the end of the wait until the end of the table."""
        check = hold_to_horizon(path, tpt.n_traj) if config.wait_check_horizon else path
        return not path_collides(tpt, check, here, pts, clearance)

    def wait_plan() -> np.ndarray | None:
        path = _wait_path(tpt, t_s, t_g)
        return path if stands_safely(path) else None

    def detour(why: str) -> Plan | None:
        path, t_s1, low, failed, backed = _detour(tpt, t_s, t_g, col, heading_deg, config, pts, clearance,
                                                  max_turn_deg)
        if path is not None:
            return make("detour", path, f"{why}: detour from tS' = {t_s1}{backed}", detour_start=t_s1,
                        phi_low_deg=low)
        nonlocal detour_failure
        detour_failure = failed
        return None

    def fallback(why: str, evade: bool) -> Plan | None:
        """Ours, after every listed option failed: stand still if that is safe; else (auto/detour) evade;
        else stop for one step. Without ``fallbacks`` (the listing) there is no plan."""
        if not config.fallbacks:
            return None
        in_place = np.repeat(here[None, :], max(t_g - 1, 1), axis=0)
        if stands_safely(in_place):
            return make("wait", in_place, f"{why}: wait in place")
        why = f"{why}, standing still collides"
        if evade and config.evade_when_blocked:
            target = _evade(tpt, here, heading_deg, config, pts, clearance, max_turn_deg)
            if target is not None:
                return make("evade", target[None, :], f"{why}: evade")
        return make("stop", here[None, :].copy(), f"{why}: stop and re-plan")

    detour_failure = ""
    strategy = config.strategy
    if strategy == "wait":
        path = wait_plan()
        if path is not None:
            return make("wait", path, "wait strategy: wait at rS")
        return fallback("wait strategy: waiting at rS collides", evade=False)
    if strategy == "detour":
        return detour("detour strategy") or fallback(f"detour strategy: detour failed ({detour_failure})",
                                                     evade=True)
    # auto: lines 16-17, else 19-35
    if t_g == tpt.n_traj + 1:
        rule = f"collision lasts to the end of the table (tG = {t_g})"
    elif wait_time < config.h_wait:
        rule = f"waitTime {wait_time} < hWait {config.h_wait}"
    else:
        rule = ""
    if rule:
        path = wait_plan()
        if path is not None:
            return make("wait", path, f"{rule}: wait at rS")
        plan = detour(f"{rule} but waiting at rS collides")
        if plan is not None:
            return plan
        return fallback(f"{rule} but waiting at rS collides, detour failed ({detour_failure})", evade=True)
    rule = f"waitTime {wait_time} >= hWait {config.h_wait}"
    plan = detour(rule)
    if plan is not None:
        return plan
    if config.fallbacks:
        path = wait_plan()
        if path is not None:
            return make("wait", path, f"{rule}, detour failed ({detour_failure}): wait at rS instead")
        return fallback(f"{rule}, detour failed ({detour_failure}), waiting at rS collides", evade=True)
    return None


def _evade(tpt: TrajectoryPredictionTable, here: np.ndarray, heading_deg: float, config: PlannerConfig,
           static_points: np.ndarray | None, static_clearance: float, max_turn_deg: float) -> np.ndarray | None:
    """Our safety net when nothing else is safe: the one-step move (successor speeds × headings within the
    turn limit, 10° apart) that keeps the largest clearance to the tracked obstacles over the table,
    assuming the robot then stands. None if every move hits a static point."""
    headings = heading_deg + np.arange(-max_turn_deg, max_turn_deg + 1e-9, config.heading_step_deg)
    speeds = np.asarray(config.successor_speeds, dtype=float)
    v = np.repeat(speeds, len(headings))
    sin, cos = sin_cos_deg_array(np.tile(headings, len(speeds)))
    ends = here[None, :] + (v * tpt.dt)[:, None] * np.stack([cos, sin], axis=1)
    gap = obstacle_gaps(tpt, here, ends, 1).min(axis=1)  # the move itself (swept)
    for k in range(2, tpt.n_traj + 1):  # then standing at the end point
        centre_gap = norm2(ends[:, None, :] - tpt.obstacles_at(k)[None, :, :])
        gap = np.minimum(gap, (centre_gap - tpt.robot_radius - tpt.obstacle_radii[None, :]).min(axis=1))
    if static_points is not None and len(static_points):
        gap = np.where(segment_point_clearance(here, ends, static_points) < static_clearance, -np.inf, gap)
    best = int(np.argmax(gap))
    return None if not np.isfinite(gap[best]) else ends[best]


def plan_heading_change(heading_deg: float, here: Sequence[float], target: Sequence[float]) -> float:
    """Steering increment (degrees) that points the robot at ``target``; 0 when already there."""
    if dist(here, target) < 1e-9:
        return 0.0
    # the direction in [-180, 180] straight from atan2, not bearing_deg's [0, 360): wrapping to [0, 360)
    # first rounds a small negative angle (a + 360) and would change the recorded commands
    return wrap_180(atan2_deg(target[1] - here[1], target[0] - here[0]) - heading_deg)
