"""Reference evaluator: the same controller definition built with scikit-fuzzy's ``skfuzzy.control``.

Mamdani inference with min (AND), max (accumulation) and centroid defuzzification, as scikit-fuzzy does
by default. It is slow (scikit-fuzzy walks a networkx graph on every ``compute()``, ~15 ms per decision)
and exists to check :class:`fuzzynav.controller.fuzzy_fast.FastEvaluator`.

Do not share one evaluator between robots or threads: a ``ControlSystemSimulation`` holds state.
Units are the variables' own (for the default controllers: cm, degrees, cm/s).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import skfuzzy as fuzz
from skfuzzy import control as ctrl

from fuzzynav.controller.fuzzy_spec import ControllerSpec, Term, Variable, crisp_snap, sample_membership


def _skfuzzy_membership(term: Term, var: Variable) -> np.ndarray:
    grid = var.grid
    if term.mf == "trap":
        return fuzz.trapmf(grid, list(term.params))
    if term.mf == "tri":
        return fuzz.trimf(grid, list(term.params))
    if term.mf == "gauss":
        mean, sigma = term.params
        return fuzz.gaussmf(grid, mean, sigma)
    return sample_membership(term, grid, var.universe[1])  # crisp: a 0/1 step, no skfuzzy equivalent


class SkfuzzyEvaluator:
    """Evaluate a :class:`ControllerSpec` with ``skfuzzy.control.ControlSystemSimulation``.

    ``evaluate(inputs)`` mirrors :meth:`FastEvaluator.evaluate`: scalars give floats, 1-D arrays give
    arrays (computed with scikit-fuzzy's array mode). No rule firing gives the definition's fallback.
    """

    def __init__(self, spec: ControllerSpec) -> None:
        self.spec = spec
        self._vars: dict[str, ctrl.Antecedent | ctrl.Consequent] = {}
        for var in spec.inputs:
            ant = ctrl.Antecedent(var.grid, var.name)
            for term in var.terms:
                ant[term.name] = _skfuzzy_membership(term, var)
            self._vars[var.name] = ant
        for var in spec.outputs:
            con = ctrl.Consequent(var.grid, var.name, defuzzify_method="centroid")
            for term in var.terms:
                con[term.name] = _skfuzzy_membership(term, var)
            self._vars[var.name] = con
        rules = []
        for i, rule in enumerate(spec.rules):
            antecedent = None
            for vname, tname in rule.antecedent:
                clause = self._vars[vname][tname]
                antecedent = clause if antecedent is None else antecedent & clause
            consequent = [self._vars[v][t] for v, t in rule.consequent]
            rules.append(ctrl.Rule(antecedent, consequent, label=f"rule{i}"))
        self.system = ctrl.ControlSystem(rules)
        self._names = {role: spec.output_for(role).name for role in ("dtheta", "v")}
        self._fallback = {"dtheta": spec.fallback_dtheta, "v": spec.fallback_v}
        self._single = self._simulation()

    def _simulation(self) -> ctrl.ControlSystemSimulation:
        return ctrl.ControlSystemSimulation(self.system, clip_to_bounds=True, cache=False)

    def evaluate(self, inputs: Mapping[str, float | np.ndarray]) -> tuple:
        arrays = {k: np.asarray(v, dtype=float) for k, v in inputs.items()}
        scalar = all(a.ndim == 0 for a in arrays.values())
        if scalar:
            return self._evaluate_one({k: float(a) for k, a in arrays.items()})
        n = max(a.size for a in arrays.values())
        cols = {k: np.broadcast_to(a.reshape(-1), (n,)).copy() for k, a in arrays.items()}
        for var in self.spec.inputs:
            if var.is_crisp:
                cols[var.name] = crisp_snap(var, cols[var.name])
        sim = self._simulation()
        for var in self.spec.inputs:
            sim.input[var.name] = cols[var.name]
        try:
            sim.compute()
            return (np.asarray(sim.output[self._names["dtheta"]], dtype=float),
                    np.asarray(sim.output[self._names["v"]], dtype=float))
        except (ValueError, AssertionError):
            # some row fired no rule: scikit-fuzzy's array mode cannot return the others; go one by one
            out = [self._evaluate_one({k: float(c[i]) for k, c in cols.items()}) for i in range(n)]
            return np.array([o[0] for o in out]), np.array([o[1] for o in out])

    def _evaluate_one(self, inputs: Mapping[str, float]) -> tuple[float, float]:
        sim = self._single  # one simulation reused (cache=False: no state carries over between calls)
        for var in self.spec.inputs:
            value = inputs[var.name]
            if var.is_crisp:
                value = float(crisp_snap(var, np.array([value]))[0])
            sim.input[var.name] = value
        result = []
        try:
            sim.compute()
        except (ValueError, AssertionError):
            return self._fallback["dtheta"], self._fallback["v"]
        for role in ("dtheta", "v"):
            name = self._names[role]
            result.append(float(sim.output[name]) if name in sim.output else self._fallback[role])
        return result[0], result[1]
