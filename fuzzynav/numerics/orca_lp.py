"""RVO2's linear program in velocity space (van den Berg, Guy, Lin & Manocha 2011, Sec. 5.2; the algorithm of
its authors' RVO2 library, ``linearProgram1/2/3``): ORCA half-planes and the velocity closest to a preferred one
that satisfies them, with the 3-D fallback of least penetration. Shared by the robot's ORCA policy
(:mod:`fuzzynav.policies.orca`) and the ORCA pedestrians (:mod:`fuzzynav.pedestrians.orca`).

Units: positions in cm, velocities in cm/s, times in s. Plain Python floats, ``+ − × /`` and ``sqrt`` in a fixed
order (portable numerics).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from fuzzynav.numerics.portable_math import hypot

Vec = tuple[float, float]

# |sin| of the angle below which two lines count as parallel (RVO2 uses 1e-5 in single precision; in double
# precision 1e-9 keeps t = numerator/denominator finite and far from overflow at these speeds)
_PARALLEL = 1e-9
# widening (cm/s) of the fallback's second program beyond δ*, relative and absolute: δ* is exact up to
# rounding, and without slack the best velocity could sit a rounding error outside its own lines
_SLACK_REL = 1e-9
_SLACK_ABS = 1e-9


@dataclass(frozen=True)
class Line:
    """A half-plane in velocity space (cm/s): the velocities on the left of the directed line through
    ``point`` along the unit vector ``direction`` (RVO2's convention) are permitted."""

    point: Vec
    direction: Vec


@dataclass(frozen=True)
class OrcaResult:
    """The chosen velocity (cm/s), the half-planes it was chosen under (static ones first), whether the
    3-D fallback ran and the largest penetration into a track's half-plane it left (cm/s)."""

    velocity: Vec
    lines: tuple[Line, ...]
    fallback: bool
    penetration_cm_s: float


def _det(a: Vec, b: Vec) -> float:
    """The 2-D cross product a × b."""
    return a[0] * b[1] - a[1] * b[0]


def _dot(a: Vec, b: Vec) -> float:
    """The 2-D dot product a · b."""
    return a[0] * b[0] + a[1] * b[1]


def _unit(a: Vec) -> Vec:
    """``a`` scaled to length 1 (``a`` must not be zero)."""
    n = hypot(a[0], a[1])
    return a[0] / n, a[1] / n


def violation(line: Line, v: Vec) -> float:
    """How far (cm/s) ``v`` lies on the forbidden side of ``line`` (negative: inside the permitted side)."""
    return _det(line.direction, (line.point[0] - v[0], line.point[1] - v[1]))


def orca_line(rel_pos: Vec, rel_vel: Vec, combined_radius: float, horizon_s: float, dt: float,
              responsibility: float, velocity: Vec) -> Line:
    """The ORCA half-plane for an obstacle disc at ``rel_pos`` (cm, relative to the robot) of radius
    ``combined_radius`` (cm, the robot's radius included), with relative velocity ``rel_vel`` = robot −
    obstacle (cm/s), time horizon ``horizon_s`` (s), for a robot moving at ``velocity`` (cm/s) that takes
    ``responsibility`` (0.5–1) of the avoidance. Within the disc (overlap) the cut-off of ``dt`` (s) is
    used, so the separating velocity undoes the overlap in one step."""
    px, py = rel_pos
    dist_sq = px * px + py * py
    r = combined_radius
    r_sq = r * r
    if dist_sq > r_sq:
        inv_tau = 1.0 / horizon_s
        # w: from the cut-off circle's centre p/τ to the relative velocity
        w = (rel_vel[0] - inv_tau * px, rel_vel[1] - inv_tau * py)
        w_sq = w[0] * w[0] + w[1] * w[1]
        w_dot_p = _dot(w, rel_pos)
        if w_dot_p < 0.0 and w_dot_p * w_dot_p > r_sq * w_sq:
            # nearest boundary is the cut-off arc (the relative velocity points at the disc's near side)
            w_len = math.sqrt(w_sq)
            n = (w[0] / w_len, w[1] / w_len)
            direction = (n[1], -n[0])
            shift = r * inv_tau - w_len
            u = (shift * n[0], shift * n[1])
        else:
            # nearest boundary is a leg: the tangent from the origin to the disc on the side of w
            leg = math.sqrt(dist_sq - r_sq)
            if _det(rel_pos, w) > 0.0:
                direction = ((px * leg - py * r) / dist_sq, (px * r + py * leg) / dist_sq)
            else:
                direction = (-(px * leg + py * r) / dist_sq, -(-px * r + py * leg) / dist_sq)
            along = _dot(rel_vel, direction)
            u = (along * direction[0] - rel_vel[0], along * direction[1] - rel_vel[1])
    else:
        inv_dt = 1.0 / dt
        w = (rel_vel[0] - inv_dt * px, rel_vel[1] - inv_dt * py)
        w_len = hypot(w[0], w[1])
        if w_len == 0.0:
            # the relative velocity is the cut-off's centre: any direction away from the obstacle will do;
            # straight away from it (or +x for coincident centres) keeps the choice fixed
            d = math.sqrt(dist_sq)
            n = (-px / d, -py / d) if d > 0.0 else (1.0, 0.0)
        else:
            n = (w[0] / w_len, w[1] / w_len)
        direction = (n[1], -n[0])
        shift = r * inv_dt - w_len
        u = (shift * n[0], shift * n[1])
    return Line((velocity[0] + responsibility * u[0], velocity[1] + responsibility * u[1]), direction)


def static_point_line(rel_pos: Vec, combined_radius: float, horizon_s: float, dt: float,
                      velocity: Vec) -> Line | None:
    """The half-plane for a static return at ``rel_pos`` (cm) seen as a disc of ``combined_radius`` (cm):
    :func:`orca_line` with zero obstacle velocity and full responsibility; within the disc, RVO2's rule for
    obstacles in contact — no velocity component towards the return (the line through the origin). ``None``
    for a return at the robot's centre, which has no direction to avoid."""
    px, py = rel_pos
    if px * px + py * py > combined_radius * combined_radius:
        return orca_line(rel_pos, velocity, combined_radius, horizon_s, dt, 1.0, velocity)
    d = hypot(px, py)
    if d == 0.0:
        return None
    # the permitted side (left of the direction) is the half-plane of velocities with v·p <= 0
    return Line((0.0, 0.0), (-py / d, px / d))


def _lp1(lines: Sequence[Line], k: int, radius: float, opt: Vec, direction_opt: bool) -> Vec | None:
    """The best point on line ``k`` within the speed disc of ``radius`` (cm/s) and the half-planes of lines
    0..k−1: closest to ``opt``, or (``direction_opt``) farthest along the unit vector ``opt``; ``None``
    when nothing on line ``k`` satisfies them."""
    line = lines[k]
    p, d = line.point, line.direction
    along = _dot(p, d)
    disc = along * along + radius * radius - _dot(p, p)
    if disc < 0.0:
        return None
    root = math.sqrt(disc)
    t_left, t_right = -along - root, -along + root
    for i in range(k):
        other = lines[i]
        denominator = _det(d, other.direction)
        numerator = _det(other.direction, (p[0] - other.point[0], p[1] - other.point[1]))
        if abs(denominator) <= _PARALLEL:
            if numerator < 0.0:
                return None  # parallel and line k lies wholly on the forbidden side of line i
            continue
        t = numerator / denominator
        if denominator >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        t = t_right if _dot(opt, d) > 0.0 else t_left
    else:
        t = min(max(_dot(d, (opt[0] - p[0], opt[1] - p[1])), t_left), t_right)
    return p[0] + t * d[0], p[1] + t * d[1]


def solve_lp2(lines: Sequence[Line], radius: float, opt: Vec, direction_opt: bool = False) -> tuple[int, Vec]:
    """(index of the first line that made the program infeasible, or ``len(lines)``; the velocity in cm/s):
    the point of the speed disc of ``radius`` (cm/s) satisfying every half-plane that is closest to ``opt``
    (or farthest along the unit vector ``opt`` with ``direction_opt``), by the incremental algorithm over
    the lines in their given order. On failure the velocity is the optimum of the lines before that one."""
    if direction_opt:
        result = (opt[0] * radius, opt[1] * radius)
    elif _dot(opt, opt) > radius * radius:
        unit = _unit(opt)
        result = (unit[0] * radius, unit[1] * radius)
    else:
        result = opt
    for i, line in enumerate(lines):
        if violation(line, result) > 0.0:
            found = _lp1(lines, i, radius, opt, direction_opt)
            if found is None:
                return i, result
            result = found
    return len(lines), result


def solve_lp3(lines: Sequence[Line], hard: int, begin: int, radius: float, start: Vec) -> Vec:
    """RVO2's 3-D program: from ``start`` (the 2-D program's velocity when it failed on line ``begin``), the
    velocity in the speed disc of ``radius`` (cm/s) minimising the largest violation of lines ``hard``..end
    while satisfying lines 0..``hard``−1. Each line violated by more than the current worst is made the
    binding one: the problem is projected onto it (the bisectors with the earlier soft lines) and solved
    for the direction that reduces its violation."""
    result = start
    worst = 0.0
    for i in range(begin, len(lines)):
        line = lines[i]
        if violation(line, result) <= worst:
            continue
        projected = list(lines[:hard])
        d = line.direction
        for j in range(hard, i):
            other = lines[j]
            determinant = _det(d, other.direction)
            if abs(determinant) <= _PARALLEL:
                if _dot(d, other.direction) > 0.0:
                    continue  # same direction: line j binds wherever line i does
                point = (0.5 * (line.point[0] + other.point[0]), 0.5 * (line.point[1] + other.point[1]))
            else:
                t = _det(other.direction, (line.point[0] - other.point[0], line.point[1] - other.point[1])) \
                    / determinant
                point = (line.point[0] + t * d[0], line.point[1] + t * d[1])
            projected.append(Line(point, _unit((other.direction[0] - d[0], other.direction[1] - d[1]))))
        failed, found = solve_lp2(projected, radius, (-d[1], d[0]), direction_opt=True)
        # the previous result is feasible for the projected program by construction; a failure is rounding,
        # and the previous result is kept
        if failed == len(projected):
            result = found
        worst = violation(line, result)
    return result


def _deepest(lines: Sequence[Line], v: Vec) -> float:
    """The largest violation (cm/s) of ``lines`` by ``v``, 0 when it satisfies them all."""
    return max(0.0, max((violation(line, v) for line in lines), default=0.0))


def choose_velocity(lines: Sequence[Line], hard: int, radius: float, preferred: Vec) -> OrcaResult:
    """The velocity (cm/s) in the speed disc of ``radius`` closest to ``preferred`` under ``lines`` (the
    first ``hard`` of them never violated); when they have no common point, the least-penetrating velocity
    closest to ``preferred`` (module docstring, step 4)."""
    lines = tuple(lines)
    failed, velocity = solve_lp2(lines, radius, preferred)
    if failed == len(lines):
        return OrcaResult(velocity, lines, False, 0.0)
    least = solve_lp3(lines, hard, failed, radius, velocity)
    depth = _deepest(lines[hard:], least)
    slack = depth + depth * _SLACK_REL + _SLACK_ABS
    # the soft lines moved out by δ*: every velocity that penetrates no deeper than the fallback's optimum
    widened = lines[:hard] + tuple(Line((ln.point[0] + slack * ln.direction[1],
                                         ln.point[1] - slack * ln.direction[0]), ln.direction)
                                   for ln in lines[hard:])
    failed, closest = solve_lp2(widened, radius, preferred)
    chosen = closest if failed == len(widened) else least
    return OrcaResult(chosen, lines, True, _deepest(lines[hard:], chosen))
