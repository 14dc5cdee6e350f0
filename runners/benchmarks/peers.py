"""Other fuzzy engines built from the same :class:`ControllerSpec`, for the benchmark's peer table.

Each adapter builds the peer's Mamdani controller from our definition — the same membership functions
(trapezoid, triangle, Gaussian with the same parameters), the same 28 (or however many) rules, min (AND),
min implication, max aggregation, centroid defuzzification — and answers ``evaluate(inputs)`` like
:class:`fuzzynav.controller.fuzzy_fast.FastEvaluator` (scalars give floats, 1-D arrays give arrays; variables' units:
cm, degrees, cm/s). Rows where no rule fires give the definition's fallback, as ours do.

What a peer cannot express exactly (its agreement with scikit-fuzzy is measured and reported, not assumed):

- **crisp inputs** (the angle's right/left of Table 1): no peer has a half-open 0/1 interval; as the
  scikit-fuzzy reference does (:func:`fuzzynav.controller.fuzzy_spec.crisp_snap`), a crisp input is snapped to the
  midpoint of its interval first, where a rectangle (ferrifuzz: a trapezoid with vertical sides) is exact;
- **the centroid's discretisation**: scikit-fuzzy (and ours) integrate the polyline through the grid samples
  plus the points where each term crosses its cut level; ferrifuzz samples the aggregated set on
  ``resolution + 1`` points of each output's range with **one** resolution for all outputs (we give it the
  finest output's step count, 240 for dtheta; the speed output's grid is then 4x finer than ours);
  pyfuzzylite integrates with the midpoint rectangle rule on ``resolution`` divisions per output (we give it
  each output's own step count);
- **input memberships**: both peers evaluate the functions analytically; scikit-fuzzy interpolates their
  samples on the input grid (identical for trapezoids and triangles with breakpoints on the grid, slightly
  different for Gaussians).

Peers are optional (``pip install -e '.[bench]'``; pyfuzzylite separately, see ``pyproject.toml``): an
adapter's constructor raises :class:`PeerMissing` when its package is not installed.
"""

from __future__ import annotations

import importlib.metadata
from collections.abc import Mapping

import numpy as np

from fuzzynav.controller.fuzzy_spec import ControllerSpec, Term, Variable, crisp_snap


class PeerMissing(RuntimeError):
    """The peer's package is not installed."""


def peer_version(package: str) -> str | None:
    """Installed version of a distribution, or None."""
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def _prepare(spec: ControllerSpec, inputs: Mapping[str, float | np.ndarray]) -> tuple[dict[str, np.ndarray], bool]:
    """Inputs as 1-D float arrays clipped to their universes (crisp ones snapped), and whether all were scalars."""
    arrays = {k: np.asarray(v, dtype=float) for k, v in inputs.items()}
    scalar = all(a.ndim == 0 for a in arrays.values())
    n = max(a.size for a in arrays.values())
    cols = {}
    for var in spec.inputs:
        x = np.clip(np.broadcast_to(arrays[var.name].reshape(-1), (n,)), *var.universe)
        cols[var.name] = crisp_snap(var, x) if var.is_crisp else np.ascontiguousarray(x)
    return cols, scalar


def _crisp_bounds(term: Term, var: Variable) -> tuple[float, float]:
    lo, hi = term.params
    return max(lo, var.universe[0]), min(hi, var.universe[1])


class FerrifuzzEvaluator:
    """The definition as a ``ferrifuzz.FuzzySystem`` (Rust core; ``compute`` per decision, ``compute_batch``
    for arrays, which runs on all cores)."""

    package = "ferrifuzz"

    def __init__(self, spec: ControllerSpec) -> None:
        try:
            import ferrifuzz as ff
        except ImportError as e:
            raise PeerMissing(self.package) from e
        self.spec = spec
        # one resolution for every output: the finest output's number of grid steps
        steps = max(round((v.universe[1] - v.universe[0]) / v.resolution) for v in spec.outputs)
        system = ff.FuzzySystem(and_method="min", or_method="max", defuzz_method="centroid", resolution=steps,
                                type="type1", implication="mamdani", clamp_inputs=True)
        for var in (*spec.inputs, *spec.outputs):
            fv = ff.Variable(var.name, *var.universe)
            for term in var.terms:
                p = term.params
                if term.mf == "trap":
                    fv[term.name] = ff.mf.trapezoid(*p)
                elif term.mf == "tri":
                    fv[term.name] = ff.mf.triangle(*p)
                elif term.mf == "gauss":
                    fv[term.name] = ff.mf.gaussian(*p)
                else:  # crisp: exact at the snapped midpoints
                    lo, hi = _crisp_bounds(term, var)
                    fv[term.name] = ff.mf.trapezoid(lo, lo, hi, hi)
            (system.add_input if var in spec.inputs else system.add_output)(fv)
        for rule in spec.rules:
            system.add_rule("IF " + " AND ".join(f"{v} IS {t}" for v, t in rule.antecedent)
                            + " THEN " + " AND ".join(f"{v} IS {t}" for v, t in rule.consequent))
        system.check()
        self.system = system
        self._names = [spec.output_for(role).name for role in ("dtheta", "v")]
        self._fallback = [spec.fallback_dtheta, spec.fallback_v]
        self._crisp = [v for v in spec.inputs if v.is_crisp]

    def compute(self, inputs: Mapping[str, float]) -> tuple[float, float]:
        """One decision through ``FuzzySystem.compute`` (the timed call: crisp inputs must be snapped already)."""
        out = self.system.compute(inputs)
        d, v = out[self._names[0]], out[self._names[1]]
        return (self._fallback[0] if d != d else d), (self._fallback[1] if v != v else v)  # NaN: no rule fired

    def evaluate(self, inputs: Mapping[str, float | np.ndarray]) -> tuple:
        cols, scalar = _prepare(self.spec, inputs)
        if scalar:
            return self.compute({k: float(c[0]) for k, c in cols.items()})
        out = self.system.compute_batch(cols)
        d = np.where(np.isnan(out[self._names[0]]), self._fallback[0], out[self._names[0]])
        v = np.where(np.isnan(out[self._names[1]]), self._fallback[1], out[self._names[1]])
        return np.asarray(d, dtype=float), np.asarray(v, dtype=float)

    def snap(self, inputs: Mapping[str, float]) -> dict[str, float]:
        """The inputs :meth:`compute` takes: crisp ones snapped (done once, outside the timing)."""
        cols, _ = _prepare(self.spec, inputs)
        return {k: float(c[0]) for k, c in cols.items()}


class FuzzyliteEvaluator:
    """The definition as a pyfuzzylite ``Engine`` (pure Python on numpy; ``process()`` per decision, and
    on arrays for a batch)."""

    package = "pyfuzzylite"

    def __init__(self, spec: ControllerSpec) -> None:
        try:
            import fuzzylite as fl
        except ImportError as e:
            raise PeerMissing(self.package) from e
        self.spec = spec

        def term(t: Term, var: Variable):
            p = t.params
            if t.mf == "trap":
                return fl.Trapezoid(t.name, *p)
            if t.mf == "tri":
                return fl.Triangle(t.name, *p)
            if t.mf == "gauss":
                return fl.Gaussian(t.name, *p)
            return fl.Rectangle(t.name, *_crisp_bounds(t, var))  # exact at the snapped midpoints

        inputs = [fl.InputVariable(name=v.name, minimum=v.universe[0], maximum=v.universe[1], lock_range=True,
                                   terms=[term(t, v) for t in v.terms]) for v in spec.inputs]
        fallback = {"dtheta": spec.fallback_dtheta, "v": spec.fallback_v}
        outputs = [fl.OutputVariable(name=v.name, minimum=v.universe[0], maximum=v.universe[1],
                                     aggregation=fl.Maximum(), default_value=fallback[v.role],
                                     # the midpoint rule on as many divisions as the output's grid has steps
                                     defuzzifier=fl.Centroid(round((v.universe[1] - v.universe[0]) / v.resolution)),
                                     terms=[term(t, v) for t in v.terms]) for v in spec.outputs]
        rules = [fl.Rule.create("if " + " and ".join(f"{v} is {t}" for v, t in r.antecedent)
                                + " then " + " and ".join(f"{v} is {t}" for v, t in r.consequent))
                 for r in spec.rules]
        self.engine = fl.Engine(name=spec.name, input_variables=inputs, output_variables=outputs,
                                rule_blocks=[fl.RuleBlock(conjunction=fl.Minimum(), implication=fl.Minimum(),
                                                          activation=fl.General(), rules=rules)])
        self._in = [(self.engine.input_variable(v.name), v.name) for v in spec.inputs]
        self._out = [self.engine.output_variable(spec.output_for(role).name) for role in ("dtheta", "v")]

    def compute(self, inputs: Mapping[str, float]) -> tuple[float, float]:
        """One decision through ``Engine.process`` (crisp inputs must be snapped already)."""
        for variable, name in self._in:
            variable.value = inputs[name]
        self.engine.process()
        # a value is an array (shape () or (1,) depending on the previous call): its one element
        return np.asarray(self._out[0].value).item(0), np.asarray(self._out[1].value).item(0)

    def evaluate(self, inputs: Mapping[str, float | np.ndarray]) -> tuple:
        cols, scalar = _prepare(self.spec, inputs)
        if scalar:
            return self.compute({k: float(c[0]) for k, c in cols.items()})
        for variable, name in self._in:
            variable.value = cols[name]
        self.engine.process()
        return (np.asarray(self._out[0].value, dtype=float).reshape(-1),
                np.asarray(self._out[1].value, dtype=float).reshape(-1))

    def snap(self, inputs: Mapping[str, float]) -> dict[str, float]:
        """The inputs :meth:`compute` takes: crisp ones snapped (done once, outside the timing)."""
        cols, _ = _prepare(self.spec, inputs)
        return {k: float(c[0]) for k, c in cols.items()}


#: the peers of the benchmark's table, in its order
PEERS = {"ferrifuzz": FerrifuzzEvaluator, "pyfuzzylite": FuzzyliteEvaluator}
