"""Vectorised numpy Mamdani evaluator (single input and batch).

It computes exactly what scikit-fuzzy's ``skfuzzy.control`` computes for the same definition, without its
per-call graph walk:

1. fuzzification: linear interpolation of each term's sampled membership function at the (clipped) input,
   as ``skfuzzy.interp_membership`` does; crisp variables are evaluated exactly;
2. rule activation: minimum over the antecedent memberships (AND);
3. accumulation: per output term, the maximum activation over the rules that name it (the *cut*);
4. aggregation: the output membership is ``max_t min(cut_t, mf_t)`` sampled on the universe grid **plus**
   the points where each term's sampled membership crosses its cut level (scikit-fuzzy's upsampling);
5. defuzzification: centroid of that polyline: the trapezoid rule on the plain grid (precomputed weights),
   plus, for each inserted crossing point, the signed triangle it adds to the polyline.

Inputs and outputs are in the variables' own units (for the default controllers: cm, degrees, cm/s).
When no rule fires (zero output area) the definition's ``fallback`` output is returned.

Single decisions (floats) go through the scalar path ``_evaluate_scalar``, the one every episode takes; a batch
(arrays) through the numpy batch below, which agrees with the single decisions to ~1e-12 (its sums are grouped
differently).
"""

from __future__ import annotations

import bisect
import math
import operator
from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType

import numpy as np

from fuzzynav.controller.fuzzy_spec import ControllerSpec, Variable, sample_membership
from fuzzynav.numerics.portable_math import sequential_sum

_CHUNK = 1024  # batch rows per block (bounds memory at ~ chunk x grid floats per array)


@dataclass(frozen=True)
class _Output:
    grid: np.ndarray  # (G,)
    step: float
    mfs: np.ndarray  # (T, G) sampled memberships
    rising_end: np.ndarray  # (T,) first index of the maximum
    falling_start: np.ndarray  # (T,) last index of the maximum
    rule_mask: np.ndarray  # (T, R) True where rule r has this term as consequent
    fallback: float
    term_rules: tuple[tuple[int, ...], ...]  # rules naming each term (scalar path)
    weights: np.ndarray  # (2, G): area and first moment of the grid polyline = sum(weights[i] * y)
    rising: tuple[tuple[float, ...], ...]  # per term: samples up to the first maximum (non-decreasing)
    falling_neg: tuple[tuple[float, ...], ...]  # per term: negated samples from the last maximum (non-decreasing)
    mf_rows: tuple[tuple[float, ...], ...]  # per term: the sampled membership as plain floats (scalar path)
    grid_list: tuple[float, ...]  # the grid as plain floats (scalar path)
    support: tuple[tuple[int, int], ...]  # per term: grid slice [lo, hi) outside which the membership is 0


class FastEvaluator:
    """Evaluate a :class:`ControllerSpec` with numpy.

    ``evaluate(inputs)`` takes a mapping from input-variable name to a scalar or 1-D array (variable units)
    and returns ``(dtheta_deg, v_cm_s)`` as floats or arrays.

    Immutable once built: one evaluator serves every episode of a worker process (and every policy, as
    ``context.controller``), so an attribute cannot be set or deleted (``AttributeError``), its tables are tuples
    and read-only arrays, and a policy cannot change what the controller computes for the next episode.
    """

    _built = False  # set (on the instance) at the end of __init__: from then on no attribute can change

    def __setattr__(self, name: str, value: object) -> None:
        if self._built:
            raise AttributeError(f"FastEvaluator is read-only (shared by every episode): cannot set {name!r}")
        object.__setattr__(self, name, value)

    def __delattr__(self, name: str) -> None:
        if self._built:
            raise AttributeError(f"FastEvaluator is read-only (shared by every episode): cannot delete {name!r}")
        object.__delattr__(self, name)

    def __reduce__(self) -> tuple:
        """Pickled (and copied) as its definition: built again from it on loading."""
        return type(self), (self.spec,)

    def __init__(self, spec: ControllerSpec) -> None:
        self.spec = spec
        self._inputs: list[tuple[Variable, np.ndarray, int]] = []  # variable, sampled mfs, offset
        offset = 0
        for var in spec.inputs:
            mfs = np.stack([sample_membership(t, var.grid, var.universe[1]) for t in var.terms])
            self._inputs.append((var, mfs, offset))
            offset += len(var.terms)
        self._n_terms_in = offset
        # antecedent index table: rules x max_clauses, padded with a constant-1 row
        width = max(len(r.antecedent) for r in spec.rules)
        one_row = offset
        table = np.full((len(spec.rules), width), one_row, dtype=np.intp)
        offsets = {var.name: off for var, _, off in self._inputs}
        variables = spec.variables
        for i, rule in enumerate(spec.rules):
            for j, (vname, tname) in enumerate(rule.antecedent):
                table[i, j] = offsets[vname] + variables[vname].term_index(tname)
        self._antecedents = table
        self._outputs: dict[str, _Output] = {}
        for var in spec.outputs:
            mfs = np.stack([sample_membership(t, var.grid, var.universe[1]) for t in var.terms])
            mask = np.zeros((len(var.terms), len(spec.rules)), dtype=bool)
            for r, rule in enumerate(spec.rules):
                for vname, tname in rule.consequent:
                    if vname == var.name:
                        mask[var.term_index(tname), r] = True
            peak = mfs.max(axis=1, keepdims=True)
            at_peak = mfs == peak
            fallback = spec.fallback_dtheta if var.role == "dtheta" else spec.fallback_v
            rising_end = at_peak.argmax(axis=1)
            falling_start = mfs.shape[1] - 1 - at_peak[:, ::-1].argmax(axis=1)
            self._outputs[var.role] = _Output(
                grid=var.grid, step=var.resolution, mfs=mfs, rising_end=rising_end, falling_start=falling_start,
                rule_mask=mask, fallback=fallback,
                term_rules=tuple(tuple(int(r) for r in np.nonzero(row)[0]) for row in mask),
                weights=np.stack(_grid_weights(var.grid)),
                rising=tuple(tuple(mfs[t, : rising_end[t] + 1].tolist()) for t in range(len(var.terms))),
                falling_neg=tuple(tuple((-mfs[t, falling_start[t]:]).tolist()) for t in range(len(var.terms))),
                mf_rows=tuple(tuple(row) for row in mfs.tolist()), grid_list=tuple(var.grid.tolist()),
                support=tuple(_support(row) for row in mfs))
        self._build_scalar_tables()
        # batch work buffers, allocated once: a fresh (grid x chunk) array per block would be a fresh mmap
        # whose page faults cost about as much as the arithmetic (not shared between threads: one evaluator
        # per thread for concurrent batches)
        self._grid_work = {role: np.empty((len(o.grid), _CHUNK)) for role, o in self._outputs.items()}
        self._term_work = np.empty((max(hi - lo for o in self._outputs.values() for lo, hi in o.support), _CHUNK))
        self._freeze()

    def _freeze(self) -> None:
        """Make every table read-only (tuples, read-only mappings and arrays), then refuse attribute assignment.
        The batch work buffers stay writable: each block fills them before it reads them."""
        self._inputs = tuple(self._inputs)
        for _, mfs, _ in self._inputs:
            mfs.flags.writeable = False
        for out in self._outputs.values():
            for f in fields(out):
                value = getattr(out, f.name)
                if isinstance(value, np.ndarray):
                    value.flags.writeable = False
        self._outputs = MappingProxyType(self._outputs)
        self._grid_work = MappingProxyType(self._grid_work)
        for array in (self._antecedents, self._stacked_mfs, self._stacked_weights, self._sum_rows):
            array.flags.writeable = False
        self._scalar_inputs = tuple(self._scalar_inputs)
        self._mu_zero = tuple(self._mu_zero)
        self._outs = tuple(self._outs)
        self._term_offset = tuple(self._term_offset)
        self._block_start = tuple(self._block_start)
        self._scalar_rules = tuple(self._scalar_rules)
        self._cross_tables = tuple(self._cross_tables)
        self._term_window = tuple(self._term_window)
        self._built = True

    # -- public API -------------------------------------------------------------------------------------
    def evaluate(self, inputs: Mapping[str, float | np.ndarray]) -> tuple:
        """Return ``(dtheta, v)`` for scalar inputs (floats) or 1-D arrays (arrays of the same length)."""
        if all(isinstance(v, float | int) for v in inputs.values()):
            return self._evaluate_scalar(inputs)
        arrays = {k: np.asarray(v, dtype=float) for k, v in inputs.items()}
        scalar = all(a.ndim == 0 for a in arrays.values())
        n = 1 if scalar else max(a.size for a in arrays.values())
        cols = {k: np.broadcast_to(a.reshape(-1), (n,)) if a.size == 1 else a.reshape(-1) for k, a in arrays.items()}
        for var in self.spec.inputs:
            if var.name not in cols:
                raise KeyError(f"missing input {var.name!r}")
        dtheta = np.empty(n)
        v = np.empty(n)
        for start in range(0, n, _CHUNK):
            sl = slice(start, min(n, start + _CHUNK))
            dtheta[sl], v[sl] = self._evaluate_block({k: c[sl] for k, c in cols.items()})
        if scalar:
            return float(dtheta[0]), float(v[0])
        return dtheta, v

    # -- internals ----------------------------------------------------------------------------------------
    def _memberships(self, cols: Mapping[str, np.ndarray]) -> np.ndarray:
        n = len(next(iter(cols.values())))
        mu = np.empty((self._n_terms_in + 1, n))
        mu[-1] = 1.0
        for var, mfs, off in self._inputs:
            x = np.clip(cols[var.name], var.universe[0], var.universe[1])
            k = len(var.terms)
            if var.is_crisp:
                for i, term in enumerate(var.terms):
                    lo, hi = term.params
                    upper = (x < hi) | ((hi >= var.universe[1]) & (x <= hi))
                    mu[off + i] = ((x >= lo) & upper).astype(float)
                continue
            pos = (x - var.universe[0]) / var.resolution
            idx = np.clip(np.floor(pos).astype(np.intp), 0, mfs.shape[1] - 2)
            frac = pos - idx
            mu[off:off + k] = mfs[:, idx] * (1.0 - frac) + mfs[:, idx + 1] * frac
        return mu

    def _activations(self, cols: Mapping[str, np.ndarray]) -> np.ndarray:
        mu = self._memberships(cols)
        return mu[self._antecedents].min(axis=1)  # (R, N)

    def _evaluate_block(self, cols: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
        act = self._activations(cols)
        return self._defuzz("dtheta", act), self._defuzz("v", act)

    def _defuzz(self, role: str, act: np.ndarray) -> np.ndarray:
        out = self._outputs[role]
        n = act.shape[1]
        # cut level of each output term: max over the rules naming it (0 when none fires)
        cuts = np.stack([act[list(rules)].max(axis=0) if rules else np.zeros(n) for rules in out.term_rules])
        grid, mfs = out.grid, out.mfs
        g = len(grid)
        # output membership on the grid, max_t min(cut_t, mf_t) (N, G): one term at a time, on its support
        # only (outside it min(cut, 0) = 0 and cuts are >= 0)
        y_t = self._grid_work[role][:, :n]  # grid-major, so that a term's support is one contiguous block
        y_t.fill(0.0)
        for t, (lo, hi) in enumerate(out.support):
            block, term = y_t[lo:hi], self._term_work[: hi - lo, :n]
            np.minimum(mfs[t, lo:hi, None], cuts[t], out=term)
            np.maximum(block, term, out=block)
        y = y_t.T
        # the polyline integral over the plain grid (trapezoid rule as precomputed weights)
        # elementwise products summed down the grid in a fixed order (a matrix product would go through BLAS)
        total_area = sequential_sum((out.weights[0][:, None] * y_t).T)
        total_moment = sequential_sum((out.weights[1][:, None] * y_t).T)
        # scikit-fuzzy adds the points where each term crosses its cut level; split those grid segments
        xs, segs = _cut_points(out, cuts)  # (N, K) positions, segment index (-1 = none)
        order = np.argsort(np.where(segs >= 0, xs, np.inf), axis=1, kind="stable")
        xs = np.take_along_axis(xs, order, axis=1)
        segs = np.take_along_axis(segs, order, axis=1)
        valid = segs >= 0
        if valid.any():
            ys = _polyline_at(out, cuts, xs, segs)
            seg_c = np.clip(segs, 0, g - 2)
            rows = np.arange(n)[:, None]
            # as in the scalar path: each point adds the triangle it forms with its left neighbour (the
            # previous point in the same segment, else the segment's start) and the segment's end
            prev_same = np.zeros_like(valid)
            prev_same[:, 1:] = valid[:, 1:] & valid[:, :-1] & (segs[:, 1:] == segs[:, :-1])
            xa = np.where(prev_same, np.roll(xs, 1, axis=1), grid[seg_c])
            ya = np.where(prev_same, np.roll(ys, 1, axis=1), y[rows, seg_c])
            xb, yb = grid[seg_c + 1], y[rows, seg_c + 1]
            triangle = np.where(valid, 0.5 * (ys * (xb - xa) - ya * (xb - xs) - yb * (xs - xa)), 0.0)
            total_area += sequential_sum(triangle)
            total_moment += sequential_sum(triangle * (xa + xs + xb)) / 3.0
        ok = total_area > 0
        result = np.full(n, out.fallback)
        result[ok] = total_moment[ok] / total_area[ok]
        return result

    # -- scalar path: the same computation with Python floats where arrays would be tiny ------------------
    # One decision is ~100 float operations on memberships and a few hundred on the output grids, so the
    # cost is the number of Python and numpy calls, not the arithmetic. The tables below, built once per
    # definition, cut those calls: per input grid segment the terms that can be non-zero there (the others
    # are exactly 0.0) and the rules that can fire (a bit mask), so only those rules are evaluated; both
    # outputs' grids go through one numpy call chain. Every result keeps the bits of the plain computation:
    # memberships are the same interpolation, activations and cuts are exact min/max, and the grid integrals
    # are the same products added strictly left to right from the same first grid point.
    def _build_scalar_tables(self) -> None:
        n_rules = len(self.spec.rules)
        all_rules = (1 << n_rules) - 1
        variables = self.spec.variables
        # rules (bit mask) whose antecedent accepts term k of an input, or does not name the input at all
        self._scalar_inputs: list[tuple] = []
        for var, mfs, off in self._inputs:
            accepts = []
            for k in range(len(var.terms)):
                mask = 0
                for r, rule in enumerate(self.spec.rules):
                    named = [t for v, t in rule.antecedent if v == var.name]
                    if not named or variables[var.name].term_index(named[0]) == k:
                        mask |= 1 << r
                accepts.append(mask)
            if var.is_crisp:
                terms = tuple((off + k, a, b, accepts[k]) for k, (a, b) in enumerate(t.params for t in var.terms))
                self._scalar_inputs.append((var.name, var.universe[0], var.universe[1], var.resolution, True,
                                            terms, None))
                continue
            segments = []  # per grid segment i: ((mu index, mf[i], mf[i+1]) of the terms non-zero there, mask)
            for i in range(mfs.shape[1] - 1):
                live = tuple((off + k, float(mfs[k, i]), float(mfs[k, i + 1])) for k in range(len(var.terms))
                             if mfs[k, i] != 0.0 or mfs[k, i + 1] != 0.0)
                mask = 0
                for k in range(len(var.terms)):
                    if mfs[k, i] != 0.0 or mfs[k, i + 1] != 0.0:
                        mask |= accepts[k]
                segments.append((live, mask))
            self._scalar_inputs.append((var.name, var.universe[0], var.universe[1], var.resolution, False,
                                        tuple(segments), None))
        self._all_rules = all_rules
        self._mu_zero = [0.0] * self._n_terms_in + [1.0]  # the last entry pads one-clause rules (see _antecedents)
        # the antecedent getter and the consequent terms (indices into the concatenated output terms) per rule
        table = self._antecedents if self._antecedents.shape[1] >= 2 else \
            np.hstack([self._antecedents, np.full_like(self._antecedents, self._n_terms_in)])
        self._outs = [self._outputs[role] for role in ("dtheta", "v")]
        term_offset, start = [], 0
        for out in self._outs:
            term_offset.append(start)
            start += out.mfs.shape[0]
        self._n_terms_out = start
        rule_terms = []
        for rule in self.spec.rules:
            terms = []
            for vname, tname in rule.consequent:
                block = ("dtheta", "v").index(variables[vname].role)
                terms.append(term_offset[block] + variables[vname].term_index(tname))
            rule_terms.append(tuple(terms))
        self._scalar_rules = [(operator.itemgetter(*(int(i) for i in row)), rule_terms[r])
                              for r, row in enumerate(table)]
        # both outputs' sampled terms side by side on one concatenated grid (dtheta first, zeros outside each
        # term's own output), and per output its area and moment weights on that grid (zeros elsewhere): y for
        # both outputs is one min and one max, the four integrals one product and one left-to-right sum
        sizes = [len(out.grid) for out in self._outs]
        stacked = np.zeros((self._n_terms_out, sum(sizes)))
        weights = np.zeros((2 * len(self._outs), sum(sizes)))
        column = 0
        for b, out in enumerate(self._outs):
            stacked[term_offset[b]:term_offset[b] + out.mfs.shape[0], column:column + sizes[b]] = out.mfs
            weights[2 * b:2 * b + 2, column:column + sizes[b]] = out.weights
            column += sizes[b]
        self._stacked_mfs, self._stacked_weights = stacked, weights
        self._term_offset = term_offset
        self._block_start = [0, sizes[0]]
        # the running sums read at each output's last grid point. dtheta's are exactly its own sums; v's start
        # from dtheta's block, whose products with v's zero weights are all +0.0, and +0.0 + p == p for v's
        # first product (v's grid is >= 0, so no product is -0.0): exactly v's own sums as well
        self._sum_rows = np.arange(4, dtype=np.intp)
        self._dtheta_last = sizes[0] - 1
        # per output, what the crossing points need as plain Python values: per term (rising samples,
        # negated falling samples, index of the last maximum, sampled row), the grid, its step, the fallback
        self._cross_tables = [(tuple((out.rising[t], out.falling_neg[t], int(out.falling_start[t]), out.mf_rows[t])
                                     for t in range(out.mfs.shape[0])), out.grid_list, out.step, out.fallback)
                              for out in self._outs]
        # grid window: y is zero outside the fired terms' supports, and so are the products there; the running
        # sums are read at dtheta's last point and at v's last fired point, so the window runs from the first
        # fired dtheta sample (dtheta's sums before it are -0.0 or +0.0 and adding them to the first product
        # changes nothing) to v's last fired sample (later products are +0.0: v's grid is >= 0)
        # (one sample wider each side: a crossing's segment can end on a zero sample just outside the support)
        self._term_window = [(max(lo - 1, 0) + self._block_start[b], min(hi + 1, len(out.grid)) + self._block_start[b])
                             for b, out in enumerate(self._outs) for lo, hi in out.support]

    def _evaluate_scalar(self, inputs: Mapping[str, float]) -> tuple[float, float]:
        mu = list(self._mu_zero)
        alive = self._all_rules
        for name, lo, hi, step, crisp, table, _ in self._scalar_inputs:
            x = min(max(float(inputs[name]), lo), hi)
            if crisp:
                inside = 0
                for k, a, b, accepts in table:
                    if a <= x < b or (b >= hi and a <= x <= b):
                        mu[k] = 1.0
                        inside |= accepts
                alive &= inside
                continue
            pos = (x - lo) / step
            i = min(max(math.floor(pos), 0), len(table) - 1)
            f = pos - i
            g = 1.0 - f
            live, accepts = table[i]
            for k, a, b in live:
                mu[k] = a * g + b * f
            alive &= accepts
        cuts = [0.0] * self._n_terms_out
        rules = self._scalar_rules
        while alive:  # the rules that can fire (any other has a zero antecedent: activation 0, no effect)
            low = alive & -alive
            alive ^= low
            antecedents, terms = rules[low.bit_length() - 1]
            act = min(antecedents(mu))
            for t in terms:
                if act > cuts[t]:
                    cuts[t] = act
        n_dtheta = self._term_offset[1]
        fired = [t for t, c in enumerate(cuts) if c > 0.0]
        if not fired:
            return self._cross_tables[0][3], self._cross_tables[1][3]
        window = self._term_window
        start = min([window[t][0] for t in fired if t < n_dtheta], default=self._block_start[1] - 1)
        end = max([window[t][1] for t in fired if t >= n_dtheta], default=self._block_start[1])
        y = np.minimum(np.array(cuts)[:, None], self._stacked_mfs[:, start:end]).max(axis=0)  # grid start..end
        # products and their left-to-right sums (np.add.accumulate: never SIMD- or BLAS-ordered): the same
        # operations as sequential_sum(out.weights * y) on each output alone (see _build_scalar_tables)
        cols = [self._dtheta_last - start, self._dtheta_last - start, end - 1 - start, end - 1 - start]
        sums = np.add.accumulate(self._stacked_weights[:, start:end] * y, axis=1)[self._sum_rows, cols].tolist()
        return (_centroid(self._cross_tables[0], cuts[:n_dtheta], y, -start, sums[0], sums[1]),
                _centroid(self._cross_tables[1], cuts[n_dtheta:], y, self._block_start[1] - start, sums[2], sums[3]))


def _centroid(table: tuple, cuts: list[float], y: np.ndarray, at: int, area: float, moment: float) -> float:
    """Centroid of one output from its grid integrals (area, first moment) plus the points where each term
    crosses its cut level, which scikit-fuzzy inserts into the polyline (``y[at + i]`` is the output
    membership at grid point i). In the output's unit."""
    terms, grid, h, fallback = table
    points = []  # (x, segment, term) where a term crosses its cut level, as scikit-fuzzy adds them
    higher = []  # (cut, sampled row) of the fired terms, to find the membership at a point
    for t, level in enumerate(cuts):
        if level <= 0.0:
            continue
        rise, fall, start, row = terms[t]
        higher.append((level, row))
        j = bisect.bisect_left(rise, level)
        if 1 <= j < len(rise):
            points.append((grid[j - 1] + (level - rise[j - 1]) * h / (rise[j] - rise[j - 1]), j - 1, t))
        cnt = bisect.bisect_right(fall, -level)
        if 1 <= cnt < len(fall):
            k = cnt - 1
            points.append((grid[start + k] + (level + fall[k]) * h / (fall[k] - fall[k + 1]), start + k, t))
    if not points:
        return moment / area if area > 0 else fallback
    # insert the crossing points into the grid polyline, left to right: each one adds the (signed)
    # triangle it forms with its neighbours on the polyline so far, whose centroid is the mean of its corners
    points.sort()
    seg_open = -1
    xa = ya = xb = yb = 0.0
    for x, seg, t in points:
        if seg != seg_open:
            seg_open = seg
            xa, ya, xb, yb = grid[seg], y.item(at + seg), grid[seg + 1], y.item(at + seg + 1)
        # the membership there: term t sits exactly at its cut; only a term with a higher cut can exceed it
        level = yx = cuts[t]
        f = (x - grid[seg]) / h
        for c, row in higher:
            if c > level:
                value = min(c, row[seg] * (1.0 - f) + row[seg + 1] * f)
                if value > yx:
                    yx = value
        triangle = 0.5 * (yx * (xb - xa) - ya * (xb - x) - yb * (x - xa))
        area += triangle
        moment += triangle * (xa + x + xb) / 3.0
        xa, ya = x, yx
    return moment / area if area > 0 else fallback


def _support(mf: np.ndarray) -> tuple[int, int]:
    """Grid slice [lo, hi) holding every non-zero sample of a sampled membership function."""
    nonzero = np.nonzero(mf > 0)[0]
    return (int(nonzero[0]), int(nonzero[-1]) + 1) if len(nonzero) else (0, 0)


def _grid_weights(grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weights w_a, w_m with area = sum(w_a * y) and first moment = sum(w_m * y) for the polyline through
    (grid, y)."""
    n = len(grid)
    eye = np.eye(n)
    area, moment = _trapezoids(grid[:-1, None], grid[1:, None], eye[:-1], eye[1:])
    return area.sum(axis=0), moment.sum(axis=0)


def _trapezoids(x1, x2, y1, y2):
    """Area and first moment of the straight segment(s) (x1, y1)-(x2, y2) above zero."""
    dx = x2 - x1
    area = 0.5 * dx * (y1 + y2)
    moment = 0.5 * dx * ((y1 + y2) * x1 + dx * (y1 + 2.0 * y2) / 3.0)
    return area, moment


def _cut_points(out: _Output, cuts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Crossing points of each term's sampled membership with its cut level (as scikit-fuzzy finds them).

    Returns positions and grid-segment indices, shape (N, 2T); segment -1 marks "no point". A term
    membership is unimodal, so it crosses a level at most once while rising and once while falling.
    """
    t_count, n = cuts.shape
    h, grid, mfs = out.step, out.grid, out.mfs
    xs = np.zeros((n, 2 * t_count))
    segs = np.full((n, 2 * t_count), -1, dtype=np.intp)
    for t in range(t_count):
        level = cuts[t]
        positive = level > 0.0  # a zero cut adds only grid points, which change nothing
        rise = mfs[t, : out.rising_end[t] + 1]
        j = np.searchsorted(rise, level, side="left")  # first index with mf >= level
        ok = positive & (j >= 1) & (j < len(rise))
        jj = np.clip(j, 1, len(rise) - 1)
        x_r = grid[jj - 1] + (level - rise[jj - 1]) * h / (rise[jj] - rise[jj - 1] + (~ok))
        xs[:, 2 * t] = np.where(ok, x_r, 0.0)
        segs[:, 2 * t] = np.where(ok, jj - 1, -1)
        start = out.falling_start[t]
        fall = mfs[t, start:]
        cnt = np.searchsorted(-fall, -level, side="right")  # number of leading samples >= level
        ok = positive & (cnt >= 1) & (cnt < len(fall))
        k = np.clip(cnt - 1, 0, max(len(fall) - 2, 0))
        if len(fall) >= 2:
            x_f = grid[start + k] + (level - fall[k]) * h / (fall[k + 1] - fall[k] - (~ok))
        else:
            x_f = np.zeros(n)
            ok = np.zeros(n, dtype=bool)
        xs[:, 2 * t + 1] = np.where(ok, x_f, 0.0)
        segs[:, 2 * t + 1] = np.where(ok, start + k, -1)
    return xs, segs


def _polyline_at(out: _Output, cuts: np.ndarray, xs: np.ndarray, segs: np.ndarray) -> np.ndarray:
    """Output membership ``max_t min(cut_t, interp(mf_t))`` at positions ``xs`` inside segments ``segs``."""
    seg = np.clip(segs, 0, len(out.grid) - 2)
    frac = (xs - out.grid[seg]) / out.step
    lo = out.mfs[:, seg]  # (T, N, K)
    hi = out.mfs[:, seg + 1]
    vals = lo * (1.0 - frac) + hi * frac
    return np.minimum(cuts[:, :, None], vals).max(axis=0)
