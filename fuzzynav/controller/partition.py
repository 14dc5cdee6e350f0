"""A fuzzy variable's terms as an ordered partition of its universe, and coordinates that keep it one.

Tuning membership functions point by point breaks them: terms change order, leave holes in the universe where no
rule can fire, or turn inside out. Here a variable's terms ``T1 … Tn`` (left to right; ``T1`` a left shoulder
``trap [u0, u0, c, d]``, ``Tn`` a right shoulder ``trap [a, b, u1, u1]``, the others ``tri`` or ``trap``) are
described by coordinates in which every point is such a partition:

- ``gap0 … gapm`` (each >= 0, not all 0): the cores (the plateau of a trap, the peak of a tri) in order,
  ``p_1 <= … <= p_m``, placed by the gaps' shares of the universe: ``p_j = u0 + span * (gap0 + … + gap(j-1)) /
  sum(gaps)``;
- for each pair of neighbours ``T(i-1), T(i)``, with ``c`` the end of ``T(i-1)``'s core and ``b`` the start of
  ``T(i)``'s: ``rise_i`` in [0, 1] places ``T(i)``'s left foot ``a = c + rise_i * (b - c)`` and ``overlap_i`` in
  (0, 1] places ``T(i-1)``'s right foot ``d = a + overlap_i * (b - a)``, so ``c <= a <= d <= b``: the feet lie
  between the cores and the two terms overlap (every point of the universe has a term above zero).

:func:`coordinates_of` gives the coordinates of a partition (Table 1's terms, the starting point of a study);
:func:`partition_terms` the terms of coordinates (rounded to :data:`DIGITS` decimals). Units are the variable's
(cm, degrees, cm/s).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

MIN_OVERLAP = 0.05  # neighbours overlap over at least this share of the space between their cores
DIGITS = 6  # breakpoints are rounded to 1e-6 of the unit: Table 1's come back exactly (not 99.99999999999999)


class PartitionError(ValueError):
    """The terms are not an ordered partition of shoulders and tri/trap terms (the message says which)."""


def _terms(terms: Mapping[str, Any], universe: Sequence[float], where: str) -> list[tuple[str, str, list[float]]]:
    out = []
    for name, term in terms.items():
        mf, params = term.get("mf"), [float(p) for p in term.get("params", [])]
        if mf not in ("tri", "trap"):
            raise PartitionError(f"{where}.{name}: {mf} terms are not tuned as a partition (tri and trap only)")
        out.append((name, mf, params))
    if len(out) < 2:
        raise PartitionError(f"{where}: a partition needs two terms or more")
    u0, u1 = float(universe[0]), float(universe[1])
    first, last = out[0], out[-1]
    if first[1] != "trap" or first[2][0] != u0 or first[2][1] != u0:
        raise PartitionError(f"{where}.{first[0]}: the first term must be a left shoulder trap [{u0:g}, {u0:g}, c, d]")
    if last[1] != "trap" or last[2][2] != u1 or last[2][3] != u1:
        raise PartitionError(f"{where}.{last[0]}: the last term must be a right shoulder trap [a, b, {u1:g}, {u1:g}]")
    return out


def _cores(terms: list[tuple[str, str, list[float]]]) -> list[tuple[int, int]]:
    """For each term, the indices (start, end) of its core among the ordered core points."""
    spans, k = [], 0
    for i, (_, mf, _) in enumerate(terms):
        width = 1 if i in (0, len(terms) - 1) or mf == "tri" else 2
        spans.append((k, k + width - 1))
        k += width
    return spans


def coordinates_of(terms: Mapping[str, Any], universe: Sequence[float], where: str = "terms") -> dict[str, float]:
    """The coordinates of an ordered partition (see the module docstring); :class:`PartitionError` if the terms
    are not one (out of order, not overlapping, no shoulders)."""
    parsed = _terms(terms, universe, where)
    u0, u1 = float(universe[0]), float(universe[1])
    points: list[float] = []
    for i, (_, mf, p) in enumerate(parsed):
        if i == 0:
            points.append(p[2])
        elif i == len(parsed) - 1:
            points.append(p[1])
        else:
            points.extend([p[1]] if mf == "tri" else [p[1], p[2]])
    if any(b < a for a, b in zip([u0, *points], [*points, u1], strict=True)):
        raise PartitionError(f"{where}: the terms' cores are not in order along the universe")
    span = u1 - u0
    coords = {f"gap{j}": (b - a) / span for j, (a, b) in enumerate(zip([u0, *points], [*points, u1], strict=True))}
    cores = _cores(parsed)
    for i in range(1, len(parsed)):
        c, b = points[cores[i - 1][1]], points[cores[i][0]]
        a = parsed[i][2][0]
        d = parsed[i - 1][2][-1]
        name = parsed[i][0]
        if not c <= a <= d <= b or (b > c and d == a):
            raise PartitionError(f"{where}.{name}: its left foot and its neighbour's right foot must lie between the "
                                 f"two cores and overlap (c <= a < d <= b), got c={c:g} a={a:g} d={d:g} b={b:g}")
        coords[f"rise{i}"] = 0.0 if b == c else (a - c) / (b - c)
        coords[f"overlap{i}"] = 1.0 if b == a else (d - a) / (b - a)
    return coords


def partition_terms(terms: Mapping[str, Any], universe: Sequence[float], coords: Mapping[str, float],
                    where: str = "terms") -> dict[str, dict[str, Any]]:
    """The terms (same names and kinds as ``terms``) at ``coords``: an ordered, overlapping partition."""
    parsed = _terms(terms, universe, where)
    u0, u1 = float(universe[0]), float(universe[1])
    cores = _cores(parsed)
    m = cores[-1][1] + 1
    gaps = [float(coords[f"gap{j}"]) for j in range(m + 1)]
    if any(not math.isfinite(g) or g < 0 for g in gaps) or not math.fsum(gaps) > 0:
        raise PartitionError(f"{where}: gaps must be finite, >= 0 and not all 0, got {gaps}")
    total, run, points = math.fsum(gaps), 0.0, []
    for g in gaps[:-1]:
        run += g
        points.append(min(u1, u0 + (u1 - u0) * run / total))
    feet: dict[int, tuple[float, float]] = {}
    for i in range(1, len(parsed)):
        rise, overlap = float(coords[f"rise{i}"]), float(coords[f"overlap{i}"])
        if not (0.0 <= rise <= 1.0 and MIN_OVERLAP <= overlap <= 1.0):
            raise PartitionError(f"{where}: rise{i} must be in [0, 1] and overlap{i} in [{MIN_OVERLAP}, 1], got "
                                 f"{rise}, {overlap}")
        c, b = points[cores[i - 1][1]], points[cores[i][0]]
        a = c + rise * (b - c)
        feet[i] = (a, a + overlap * (b - a))  # (left foot of T(i), right foot of T(i-1))
    out: dict[str, dict[str, Any]] = {}
    for i, (name, mf, _) in enumerate(parsed):
        start, end = points[cores[i][0]], points[cores[i][1]]
        left = u0 if i == 0 else feet[i][0]
        right = u1 if i == len(parsed) - 1 else feet[i + 1][1]
        if i == 0:
            params = [u0, u0, end, right]
        elif i == len(parsed) - 1:
            params = [left, start, u1, u1]
        else:
            params = [left, start, right] if mf == "tri" else [left, start, end, right]
        out[name] = {"mf": mf, "params": [round(p, DIGITS) + 0.0 for p in params]}  # rounding keeps the order
    return out
