"""RVO2's linear program in velocity space (van den Berg, Guy, Lin & Manocha 2011, Sec. 5.2; the algorithm of
its authors' RVO2 library, ``linearProgram1/2/3``): ORCA half-planes and the velocity closest to a preferred one
that satisfies them, with the 3-D fallback of least penetration. Shared by the robot's ORCA policy
(:mod:`fuzzynav.policies.orca`) and the ORCA pedestrians (:mod:`fuzzynav.pedestrians.orca`).

The half-planes of static polygon edges (:func:`edge_lines`, the ORCA pedestrians' only) are the paper's
Sec. 5 "static obstacles" as RVO2's ``Agent::computeNewVelocity`` builds them: each edge's whole velocity
obstacle (its two end discs, their legs and the cut-off segment at 1/τ), not its nearest point.

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
# tolerance (cm/s) of the test whether earlier obstacle lines already keep a pedestrian off an edge (RVO2's
# RVO_EPSILON there, 1e-5 in single precision): the cut-off discs of a collinear or shared-vertex edge touch the
# earlier line exactly, up to rounding, which 1e-9 absorbs in double precision
_COVERED = 1e-9


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


# -- static polygon edges (the paper's Sec. 5 "static obstacles"; RVO2's obstacle lines) --------------------


@dataclass(frozen=True)
class ObstacleVertices:
    """Static obstacles as RVO2 keeps them: closed chains of vertices (cm) with the obstacle on the left of each
    edge — counter-clockwise round a polygon, clockwise along a world's walls seen from inside. Vertex ``k``
    starts the edge to vertex ``next[k]`` along the unit vector ``directions[k]``; ``previous[k]`` is the vertex
    before it; ``convex[k]``: the obstacle's corner at ``k`` is convex (at most 180° inside the obstacle; both
    ends of a lone segment). One entry per vertex in each field."""

    points: tuple[Vec, ...]
    directions: tuple[Vec, ...]
    next: tuple[int, ...]
    previous: tuple[int, ...]
    convex: tuple[bool, ...]


def _left_of(a: Vec, b: Vec, c: Vec) -> float:
    """Positive when ``c`` is left of the directed line from ``a`` to ``b`` (twice the triangle's signed area,
    cm²)."""
    return _det((a[0] - c[0], a[1] - c[1]), (b[0] - a[0], b[1] - a[1]))


def obstacle_vertices(chains: Sequence[Sequence[Vec]]) -> ObstacleVertices:
    """The :class:`ObstacleVertices` of ``chains``, each a closed chain of vertices (cm) in order, obstacle on the
    left. A vertex equal to the one before it (a closing repeat of the first vertex included) is dropped; a chain
    of two vertices is a lone segment, both of its sides edges (RVO2's two-vertex obstacle); a chain of fewer is
    left out."""
    points: list[Vec] = []
    directions: list[Vec] = []
    nxt: list[int] = []
    previous: list[int] = []
    convex: list[bool] = []
    for chain in chains:
        pts: list[Vec] = []
        for p in chain:
            q = (float(p[0]), float(p[1]))
            if not pts or q != pts[-1]:
                pts.append(q)
        while len(pts) > 1 and pts[-1] == pts[0]:
            pts.pop()
        k = len(pts)
        if k < 2:
            continue
        first = len(points)
        for i, p in enumerate(pts):
            after, before = pts[(i + 1) % k], pts[i - 1]
            points.append(p)
            directions.append(_unit((after[0] - p[0], after[1] - p[1])))
            nxt.append(first + (i + 1) % k)
            previous.append(first + (i - 1) % k)
            convex.append(k == 2 or _left_of(before, p, after) >= 0.0)
    return ObstacleVertices(tuple(points), tuple(directions), tuple(nxt), tuple(previous), tuple(convex))


def world_chains(bounds: Sequence[float], polygons: Sequence[Sequence[Vec]]) -> list[list[Vec]]:
    """The walls of ``bounds`` (xmin, ymin, xmax, ymax; cm) as a clockwise chain (the obstacle is outside) and
    each polygon counter-clockwise (reversed when given clockwise): the chains of :func:`obstacle_vertices`."""
    xmin, ymin, xmax, ymax = (float(b) for b in bounds)
    chains: list[list[Vec]] = [[(xmin, ymin), (xmin, ymax), (xmax, ymax), (xmax, ymin)]]
    for polygon in polygons:
        pts = [(float(p[0]), float(p[1])) for p in polygon]
        twice_area = math.fsum(a[0] * b[1] - b[0] * a[1] for a, b in zip(pts, pts[1:] + pts[:1], strict=True))
        chains.append(pts[::-1] if twice_area < 0.0 else pts)
    return chains


def _covered(lines: Sequence[Line], rel1: Vec, rel2: Vec, inv_tau: float, radius: float) -> bool:
    """Whether one of ``lines`` already excludes the cut-off discs of radius ``radius`` /τ (cm/s) round both ends
    of an edge at ``rel1``, ``rel2`` (cm, relative to the pedestrian; ``inv_tau`` = 1/τ in 1/s): then so is the
    edge's velocity obstacle, as RVO2 takes it (nearest edges first)."""
    margin = inv_tau * radius
    c1 = (inv_tau * rel1[0], inv_tau * rel1[1])
    c2 = (inv_tau * rel2[0], inv_tau * rel2[1])
    for line in lines:
        if _det((c1[0] - line.point[0], c1[1] - line.point[1]), line.direction) - margin >= -_COVERED and \
                _det((c2[0] - line.point[0], c2[1] - line.point[1]), line.direction) - margin >= -_COVERED:
            return True
    return False


def _leg_left(rel: Vec, dist_sq: float, radius: float) -> Vec:
    """The unit direction of the left tangent from the origin to the disc of ``radius`` at ``rel`` (cm),
    ``dist_sq`` = |rel|² (cm²) > 0. Rounding can leave a point just outside the disc by the edge's test a hair
    inside it by |rel|²: the leg is then the tangent of a disc through the origin (clamped at 0)."""
    leg = math.sqrt(max(dist_sq - radius * radius, 0.0))
    return (rel[0] * leg - rel[1] * radius) / dist_sq, (rel[0] * radius + rel[1] * leg) / dist_sq


def _leg_right(rel: Vec, dist_sq: float, radius: float) -> Vec:
    """As :func:`_leg_left`, the right tangent."""
    leg = math.sqrt(max(dist_sq - radius * radius, 0.0))
    return (rel[0] * leg + rel[1] * radius) / dist_sq, (-rel[0] * radius + rel[1] * leg) / dist_sq


def _through(centre: Vec, scale: float, direction: Vec) -> Line:
    """The line along the unit ``direction`` at ``scale`` (cm/s) to the left of ``centre`` (cm/s; on the side of the
    permitted velocities): the tangent of the cut-off disc of that radius round ``centre``."""
    return Line((centre[0] + scale * -direction[1], centre[1] + scale * direction[0]), direction)


def edge_lines(vertices: ObstacleVertices, edges: Sequence[int], position: Vec, velocity: Vec, radius: float,
               horizon_s: float) -> list[Line]:
    """The ORCA half-planes (cm/s) of a disc of ``radius`` (cm) at ``position`` (cm) moving at ``velocity`` (cm/s)
    for the polygon ``edges`` (each a vertex index: the edge from that vertex to the next), nearest first, time
    horizon ``horizon_s`` (s): RVO2's obstacle lines (module docstring), hard constraints for the linear program.

    Per edge, unless an earlier line already covers it (:func:`_covered`): overlapping the edge — the line
    through the origin that forbids moving towards it (at a concave end, nothing: the neighbouring edge takes
    it); otherwise the velocity obstacle of the segment swept by the disc over the horizon — the two legs (from
    one end disc when the edge is seen obliquely), a leg that would point into the neighbouring edge at a convex
    corner replaced by that edge's direction and then not a constraint of its own, the cut-off segment between
    the end discs shrunk by 1/τ — and the half-plane of the boundary part nearest the current velocity."""
    inv_tau = 1.0 / horizon_s
    r = radius
    r_sq = r * r
    pts, dirs, convex = vertices.points, vertices.directions, vertices.convex
    lines: list[Line] = []
    for k in edges:
        k1, k2 = k, vertices.next[k]
        rel1 = (pts[k1][0] - position[0], pts[k1][1] - position[1])
        rel2 = (pts[k2][0] - position[0], pts[k2][1] - position[1])
        if _covered(lines, rel1, rel2, inv_tau, r):
            continue
        dist_sq1 = _dot(rel1, rel1)
        dist_sq2 = _dot(rel2, rel2)
        edge = (pts[k2][0] - pts[k1][0], pts[k2][1] - pts[k1][1])
        # s: where along the edge (0 at vertex 1, 1 at vertex 2) the pedestrian's foot on its line falls
        s = -_dot(rel1, edge) / _dot(edge, edge)
        off = (-rel1[0] - s * edge[0], -rel1[1] - s * edge[1])
        dist_sq_line = _dot(off, off)
        if s < 0.0 and dist_sq1 <= r_sq:
            # overlapping vertex 1: only a convex corner constrains (at a concave one the other edge does)
            if convex[k1]:
                lines.append(Line((0.0, 0.0), _unit((-rel1[1], rel1[0]))))
            continue
        if s > 1.0 and dist_sq2 <= r_sq:
            # overlapping vertex 2: left to the next edge, which starts there, unless it faces away
            if convex[k2] and _det(rel2, dirs[k2]) >= 0.0:
                lines.append(Line((0.0, 0.0), _unit((-rel2[1], rel2[0]))))
            continue
        if 0.0 <= s <= 1.0 and dist_sq_line <= r_sq:
            # overlapping the edge between its ends: no velocity towards its line
            lines.append(Line((0.0, 0.0), (-dirs[k1][0], -dirs[k1][1])))
            continue
        if s < 0.0 and dist_sq_line <= r_sq:
            # seen obliquely past vertex 1: its disc alone is the velocity obstacle
            if not convex[k1]:
                continue
            k2, rel2 = k1, rel1
            left, right = _leg_left(rel1, dist_sq1, r), _leg_right(rel1, dist_sq1, r)
        elif s > 1.0 and dist_sq_line <= r_sq:
            # seen obliquely past vertex 2
            if not convex[k2]:
                continue
            k1, rel1 = k2, rel2
            left, right = _leg_left(rel2, dist_sq2, r), _leg_right(rel2, dist_sq2, r)
        else:
            # at a concave end the leg is the edge's own line: the cut-off segment extends to it
            left = _leg_left(rel1, dist_sq1, r) if convex[k1] else (-dirs[k1][0], -dirs[k1][1])
            right = _leg_right(rel2, dist_sq2, r) if convex[k2] else dirs[k1]
        # at a convex corner a leg cannot point into the neighbouring edge: that edge's direction instead, whose
        # own lines constrain there (a velocity projected on such a 'foreign' leg adds no line)
        before = dirs[vertices.previous[k1]]
        left_foreign = right_foreign = False
        if convex[k1] and _det(left, (-before[0], -before[1])) >= 0.0:
            left, left_foreign = (-before[0], -before[1]), True
        if convex[k2] and _det(right, dirs[k2]) <= 0.0:
            right, right_foreign = dirs[k2], True
        # the cut-off discs' centres (cm/s) and the velocity projected on the velocity obstacle's boundary
        left_cut = (inv_tau * rel1[0], inv_tau * rel1[1])
        right_cut = (inv_tau * rel2[0], inv_tau * rel2[1])
        cut = (right_cut[0] - left_cut[0], right_cut[1] - left_cut[1])
        from_left = (velocity[0] - left_cut[0], velocity[1] - left_cut[1])
        from_right = (velocity[0] - right_cut[0], velocity[1] - right_cut[1])
        one_vertex = k1 == k2
        t = 0.5 if one_vertex else _dot(from_left, cut) / _dot(cut, cut)
        t_left = _dot(from_left, left)
        t_right = _dot(from_right, right)
        scale = r * inv_tau
        if (t < 0.0 and t_left < 0.0) or (one_vertex and t_left < 0.0 and t_right < 0.0):
            w = _unit(from_left)
            lines.append(Line((left_cut[0] + scale * w[0], left_cut[1] + scale * w[1]), (w[1], -w[0])))
            continue
        if t > 1.0 and t_right < 0.0:
            w = _unit(from_right)
            lines.append(Line((right_cut[0] + scale * w[0], right_cut[1] + scale * w[1]), (w[1], -w[0])))
            continue
        if t < 0.0 or t > 1.0 or one_vertex:
            d_cut = math.inf
        else:
            on = (velocity[0] - (left_cut[0] + t * cut[0]), velocity[1] - (left_cut[1] + t * cut[1]))
            d_cut = _dot(on, on)
        if t_left < 0.0:
            d_left = math.inf
        else:
            on = (velocity[0] - (left_cut[0] + t_left * left[0]), velocity[1] - (left_cut[1] + t_left * left[1]))
            d_left = _dot(on, on)
        if t_right < 0.0:
            d_right = math.inf
        else:
            on = (velocity[0] - (right_cut[0] + t_right * right[0]),
                  velocity[1] - (right_cut[1] + t_right * right[1]))
            d_right = _dot(on, on)
        if d_cut <= d_left and d_cut <= d_right:
            lines.append(_through(left_cut, scale, (-dirs[k1][0], -dirs[k1][1])))
        elif d_left <= d_right:
            if left_foreign:
                continue
            lines.append(_through(left_cut, scale, left))
        else:
            if right_foreign:
                continue
            lines.append(_through(right_cut, scale, (-right[0], -right[1])))
    return lines
