"""Plane geometry shared by the simulation and the analysis: closest approach of straight motions over one
step, and angle wrapping.

Pure functions over floats and numpy arrays (arrays broadcast; points and vectors have a last axis of
length 2). Lengths in cm, angles in degrees (counter-clockwise from +x), the step's duration as the
fraction 0..1 of one time step. Built only on :mod:`fuzzynav.numerics.portable_math`'s primitives, with a fixed order
of operations, so every result is the same bits on every CPU (no BLAS, no reduction whose order numpy may
choose). The recorded logs depend on that order to the last bit: a call site whose inputs come in a
different order (e.g. :func:`fuzzynav.planning.tpt.build_tpt`'s relative positions) computes them itself and passes
them to :func:`closest_approach`, rather than rearranging them to fit a wrapper.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from fuzzynav.numerics.portable_math import dot2, norm2

Angle = TypeVar("Angle", float, np.ndarray)


def closest_approach_fraction(rel0: np.ndarray, rel_step: np.ndarray) -> np.ndarray:
    """Fraction s in [0, 1] of the step at which ``|rel0 + s·rel_step|`` is smallest: the time of closest
    approach in units of the step's duration, for a relative position ``rel0`` (cm) at the start of the
    step that changes by ``rel_step`` (cm) over it. 0 when ``rel_step`` is zero (nothing moves)."""
    dd = dot2(rel_step, rel_step)
    return np.clip(-dot2(rel0, rel_step) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)


def closest_approach(rel0: np.ndarray, rel_step: np.ndarray) -> np.ndarray:
    """Smallest length (cm) of the relative position ``rel0 + s·rel_step`` over s in [0, 1]: the exact
    minimum distance of two points that both move straight and uniformly during the step, given their
    relative position at the start (cm) and its change over the step (cm). Also the distance from the
    segment ``p + [0, 1]·rel_step`` to a point q when ``rel0 = p - q``."""
    s = closest_approach_fraction(rel0, rel_step)
    return norm2(rel0 + s[..., None] * rel_step)


def swept_distance(p0: np.ndarray, p1: np.ndarray, o0: np.ndarray, o1: np.ndarray) -> np.ndarray:
    """Closest distance (cm) between two points moving straight over the same step, one from ``p0`` to
    ``p1``, the other from ``o0`` to ``o1`` (positions in cm, broadcast against each other)."""
    return closest_approach(p0 - o0, (p1 - p0) - (o1 - o0))


def segment_point_distance(a: np.ndarray, b: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance (cm) from the segment ``a`` -> ``b`` to ``points`` (all in cm, broadcast against each
    other); the distance to ``a`` when ``a == b``."""
    return closest_approach(a - points, b - a)


def wrap_360(angle_deg: Angle) -> Angle:
    """An angle (degrees) wrapped to [0, 360)."""
    return angle_deg % 360.0


def wrap_180(angle_deg: Angle) -> Angle:
    """An angle (degrees) wrapped to [-180, 180): -180 for the half turn."""
    return (angle_deg + 180.0) % 360.0 - 180.0


def angle_difference_deg(a_deg: Angle, b_deg: Angle) -> Angle:
    """The turn (degrees, [-180, 180)) that brings angle ``b_deg`` to angle ``a_deg``."""
    return wrap_180(a_deg - b_deg)



def away_from_static(points: np.ndarray, segments: np.ndarray, circles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each point (n, 2) and each wall or polygon edge (M, 4: x0, y0, x1, y1) and static circle (C, 3: x,
    y, radius): the signed distance (cm) from the nearest point of that edge or circle rim (negative inside a
    circle), shape (n, M + C), and the unit vector pointing away from it, shape (n, M + C, 2). A point exactly
    on an edge, or at a circle's centre, gets a fixed direction (the edge's left normal; +x)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 1, 2)
    a, b = segments[None, :, 0:2], segments[None, :, 2:4]
    s = closest_approach_fraction(a - pts, b - a)
    off = pts - (a + s[..., None] * (b - a))
    gap_seg = norm2(off)
    edge = b - a
    edge_len = norm2(edge)
    normal = np.stack([-edge[..., 1], edge[..., 0]], axis=-1) / np.where(edge_len > 0.0, edge_len, 1.0)[..., None]
    away_seg = np.where((gap_seg > 0.0)[..., None], off / np.where(gap_seg > 0.0, gap_seg, 1.0)[..., None],
                        np.broadcast_to(normal, off.shape))
    centres, radii = circles[None, :, 0:2], circles[None, :, 2]
    from_centre = pts - centres
    d = norm2(from_centre)
    away_circ = np.where((d > 0.0)[..., None], from_centre / np.where(d > 0.0, d, 1.0)[..., None],
                         np.array([1.0, 0.0]))
    gaps = np.concatenate([gap_seg, d - radii], axis=1)
    return gaps, np.concatenate([away_seg, away_circ], axis=1)


def keep_inside(positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray,
                bounds: tuple[float, float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Discs (positions (n, 2) cm, radii (n,) cm) moved back inside the walls of ``bounds`` (xmin, ymin, xmax,
    ymax), with the velocity component (cm/s) into a wall they were stopped at set to 0: the walls are solid for
    reactive pedestrians, whatever force pushed them. A disc wider than the world keeps that coordinate."""
    x, v = positions.copy(), velocities.copy()
    r = radii[:, None]
    if (x >= np.array(bounds[:2]) + r).all() and (x <= np.array(bounds[2:]) - r).all():
        return x, v  # every disc inside (the usual case): the loop below would change nothing
    for axis, lo, hi in ((0, bounds[0], bounds[2]), (1, bounds[1], bounds[3])):
        lo_r, hi_r = lo + radii, hi - radii
        fits = lo_r <= hi_r
        below, above = fits & (x[:, axis] < lo_r), fits & (x[:, axis] > hi_r)
        x[:, axis] = np.where(below, lo_r, np.where(above, hi_r, x[:, axis]))
        v[:, axis] = np.where((below & (v[:, axis] < 0.0)) | (above & (v[:, axis] > 0.0)), 0.0, v[:, axis])
    return x, v
