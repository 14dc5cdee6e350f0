"""A fuzzy controller as data: variables, terms and rules.

A controller definition is a plain mapping (it comes from YAML, e.g. ``conf/controller/table1.yaml``)::

    name: table1
    inputs:
      left:                       # variable name, used in rules
        source: left              # which observation feeds it: left | front | right | angle
        scale: 1.0                # input value = scale * observation (default 1)
        universe: [0, 130]        # [min, max], in the observation's unit times scale
        resolution: 1.0           # grid step of the sampled universe
        terms:
          near: {mf: trap, params: [0, 0, 30, 60]}
    outputs:
      dtheta:
        role: dtheta              # dtheta (steering increment, degrees) | v (speed, cm/s)
        universe: [-120, 120]
        resolution: 1.0
        terms:
          NB: {mf: trap, params: [-120, -120, -90, -45]}
    fallback: {dtheta: 0.0, v: 10.0}   # returned when no rule fires
    rules:
      - "left=near & front=near & right=near & angle=right -> dtheta=NB, v=slow"

Membership function types and their ``params``:

- ``trap``: ``[a, b, c, d]`` with a <= b <= c <= d (0 at a, 1 on [b, c], 0 at d; a == b is a left shoulder).
- ``tri``: ``[a, b, c]`` with a <= b <= c.
- ``gauss``: ``[mean, sigma]`` with sigma > 0 (note: MATLAB's ``gaussmf`` orders them ``[sigma, c]``).
- ``crisp``: ``[lo, hi]``: membership 1 on [lo, hi), 0 elsewhere (hi is included when it is the universe
  maximum). Inputs only. A crisp input is snapped to the midpoint of the interval it falls in before the
  reference evaluator sees it, so that scikit-fuzzy's linear interpolation cannot blur the boundary.

A rule is ``"<var>=<term> & <var>=<term> ... -> <out>=<term>, <out>=<term>"``: the antecedent is the
minimum (AND) of its memberships, each consequent term is cut at that level and several rules on the same
term are accumulated with the maximum (Mamdani min/max, centroid defuzzification).

Every error raises :class:`ControllerSpecError` naming the field, e.g.
``inputs.left.terms.near.params: breakpoints must be non-decreasing``.

Valid ranges (sizes in :mod:`fuzzynav.params.limits`): every number finite with |x| <= 1e6; the ``dtheta``
output's universe within [-180, 180] degrees and the ``v`` output's within [0, 1000] cm/s (a speed universe
below 0 would never move the robot); at most 10,000 grid steps per universe, 32 terms per variable, 16
variables, 1,000 rules; a gauss sigma at least the variable's ``resolution`` (a narrower bell falls between
the grid points and never fires); every term non-zero somewhere on its universe's grid (otherwise it can
never fire or has no area); ``name`` a safe file-name part, variable and term names identifiers (the rules
must be able to name them). Whether the speed universe fits the robot's limits is
:func:`check_fits_robot`.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from fuzzynav.numerics.portable_math import exp_array
from fuzzynav.params import limits
from fuzzynav.params.checks import check_count, check_key, check_name, check_text, key_text, kind_of, show

SOURCES = ("left", "front", "right", "angle")
ROLES = ("dtheta", "v")
MF_PARAM_COUNT = {"trap": 4, "tri": 3, "gauss": 2, "crisp": 2}


class ControllerSpecError(ValueError):
    """A controller definition is malformed; the message starts with the offending field."""


@dataclass(frozen=True)
class Term:
    """One linguistic term: a membership function type and its parameters (in the variable's unit)."""

    name: str
    mf: str
    params: tuple[float, ...]


@dataclass(frozen=True)
class Variable:
    """A fuzzy variable on a uniformly sampled universe ``[lo, hi]`` with step ``resolution``.

    For inputs ``source`` names the observation (``left``/``front``/``right``: sonar distance in cm;
    ``angle``: included angle in degrees) and ``scale`` converts it to the variable's unit. For outputs
    ``role`` says which command it is (``dtheta`` in degrees, ``v`` in cm/s).
    """

    name: str
    universe: tuple[float, float]
    resolution: float
    terms: tuple[Term, ...]
    source: str | None = None
    scale: float = 1.0
    role: str | None = None

    @property
    def grid(self) -> np.ndarray:
        """The sampled universe (shared by both evaluators)."""
        lo, hi = self.universe
        n = round((hi - lo) / self.resolution) + 1
        return np.linspace(lo, hi, n)

    @property
    def is_crisp(self) -> bool:
        return all(t.mf == "crisp" for t in self.terms)

    def term_index(self, name: str) -> int:
        for i, t in enumerate(self.terms):
            if t.name == name:
                return i
        raise KeyError(name)


@dataclass(frozen=True)
class Rule:
    """A parsed rule: antecedent and consequent as (variable, term) pairs; ``text`` is the source."""

    antecedent: tuple[tuple[str, str], ...]
    consequent: tuple[tuple[str, str], ...]
    text: str


@dataclass(frozen=True)
class ControllerSpec:
    """A complete controller definition (see the module docstring for the data format)."""

    name: str
    inputs: tuple[Variable, ...]
    outputs: tuple[Variable, ...]
    rules: tuple[Rule, ...]
    fallback_dtheta: float
    fallback_v: float

    @property
    def variables(self) -> dict[str, Variable]:
        return {v.name: v for v in (*self.inputs, *self.outputs)}

    def output_for(self, role: str) -> Variable:
        for v in self.outputs:
            if v.role == role:
                return v
        raise KeyError(role)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ControllerSpec:
        """Build and validate a definition from plain data; raises :class:`ControllerSpecError`."""
        return parse_controller(data)


#: the universe each output role must lie within (its unit: degrees, cm/s)
ROLE_UNIVERSE = {"dtheta": (-limits.MAX_STEER_DEG, limits.MAX_STEER_DEG), "v": (0.0, limits.MAX_SPEED_CM_S)}
_IDENTIFIER = re.compile(r"[A-Za-z_]\w{0,63}", re.ASCII)  # what a rule can name (see _CLAUSE)


def _number(value: Any, field: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ControllerSpecError(f"{field}: expected a number, got {show(value)}")
    x = float(value)
    if not math.isfinite(x):
        raise ControllerSpecError(f"{field}: must be finite, got {show(value)}")
    if abs(x) > limits.MAX_CONTROLLER_ABS:
        raise ControllerSpecError(f"{field}: {show(value)} is out of range (|x| <= {limits.MAX_CONTROLLER_ABS:g})")
    return x


def _mapping(value: Any, field: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise ControllerSpecError(f"{field or 'controller'}: expected a mapping, got {kind_of(value)}")
    for key in value:
        check_key(key, field, ControllerSpecError)
    return value


def _identifier(name: str, field: str) -> str:
    if not _IDENTIFIER.fullmatch(name):
        raise ControllerSpecError(f"{field}: {show(name)} is not a valid name (a letter or _, then letters, "
                                  "digits or _, at most 64 characters: rules must be able to name it)")
    return name


def _check_keys(data: Mapping[str, Any], allowed: set[str], required: set[str], field: str) -> None:
    for key in data:
        if key not in allowed:
            prefix = f"{field}." if field else ""
            raise ControllerSpecError(f"{prefix}{key_text(key)}: unknown key (allowed: {', '.join(sorted(allowed))})")
    for key in sorted(required):
        if key not in data:
            prefix = f"{field}." if field else ""
            raise ControllerSpecError(f"{prefix}{key}: missing")


def _parse_term(name: str, data: Any, field: str, universe: tuple[float, float], resolution: float,
                grid: np.ndarray, is_input: bool) -> Term:
    data = _mapping(data, field)
    _check_keys(data, {"mf", "params"}, {"mf", "params"}, field)
    mf = data["mf"]
    if not isinstance(mf, str) or mf not in MF_PARAM_COUNT:
        raise ControllerSpecError(f"{field}.mf: unknown membership function {show(mf)} "
                                  f"(known: {', '.join(MF_PARAM_COUNT)})")
    if mf == "crisp" and not is_input:
        raise ControllerSpecError(f"{field}.mf: crisp terms are for inputs only")
    raw = data["params"]
    if not isinstance(raw, list | tuple):
        raise ControllerSpecError(f"{field}.params: expected a list of numbers")
    if len(raw) != MF_PARAM_COUNT[mf]:
        raise ControllerSpecError(f"{field}.params: {mf} takes {MF_PARAM_COUNT[mf]} numbers, got {len(raw)}")
    params = tuple(_number(p, f"{field}.params[{i}]") for i, p in enumerate(raw))
    if mf in ("trap", "tri", "crisp") and any(b < a for a, b in itertools.pairwise(params)):
        raise ControllerSpecError(f"{field}.params: breakpoints must be non-decreasing, got {list(params)}")
    if mf == "gauss" and params[1] < resolution:
        raise ControllerSpecError(f"{field}.params: gauss sigma must be at least the resolution {resolution:g} "
                                  f"(a narrower bell falls between the grid points), got {params[1]:g}")
    if mf == "crisp" and params[0] == params[1]:
        raise ControllerSpecError(f"{field}.params: crisp interval is empty")
    term = Term(name=name, mf=mf, params=params)
    if not sample_membership(term, grid, universe[1]).max() > 0:  # also catches a NaN from the sampling
        raise ControllerSpecError(f"{field}.params: the term is zero everywhere on the universe {list(universe)} "
                                  "(sampled on its grid): it can never fire")
    return term


def _parse_variable(name: str, data: Any, field: str, is_input: bool) -> Variable:
    data = _mapping(data, field)
    allowed = {"universe", "resolution", "terms"} | ({"source", "scale"} if is_input else {"role"})
    _check_keys(data, allowed, {"universe", "terms"} | ({"source"} if is_input else set()), field)
    uni = data["universe"]
    if not isinstance(uni, list | tuple) or len(uni) != 2:
        raise ControllerSpecError(f"{field}.universe: expected [min, max]")
    lo, hi = (_number(u, f"{field}.universe[{i}]") for i, u in enumerate(uni))
    if not lo < hi:
        raise ControllerSpecError(f"{field}.universe: min must be < max, got [{lo}, {hi}]")
    role = None if is_input else data.get("role", name)
    if isinstance(role, str) and role in ROLE_UNIVERSE:
        r_lo, r_hi = ROLE_UNIVERSE[role]
        if not r_lo <= lo < hi <= r_hi:
            unit = "degrees" if role == "dtheta" else "cm/s"
            raise ControllerSpecError(f"{field}.universe: the {role} output must lie within [{r_lo:g}, {r_hi:g}] "
                                      f"{unit}, got [{lo:g}, {hi:g}]")
    res = _number(data.get("resolution", 1.0), f"{field}.resolution")
    steps = (hi - lo) / res if res > 0 else -1
    if res <= 0 or abs(steps - round(steps)) > 1e-9 * max(1.0, steps):
        raise ControllerSpecError(f"{field}.resolution: must be > 0 and divide the universe width {hi - lo:g}")
    if round(steps) > limits.MAX_UNIVERSE_STEPS:
        raise ControllerSpecError(f"{field}.resolution: too fine ({round(steps):,} steps; the limit is "
                                  f"{limits.MAX_UNIVERSE_STEPS:,})")
    terms_raw = _mapping(data["terms"], f"{field}.terms")
    if not terms_raw:
        raise ControllerSpecError(f"{field}.terms: at least one term is needed")
    check_count(len(terms_raw), f"{field}.terms", limits.MAX_TERMS, ControllerSpecError, "terms")
    grid = np.linspace(lo, hi, round(steps) + 1)  # as Variable.grid
    terms = tuple(_parse_term(_identifier(t, f"{field}.terms.{key_text(t)}"), d, f"{field}.terms.{t}", (lo, hi), res,
                              grid, is_input) for t, d in terms_raw.items())
    kinds = {t.mf == "crisp" for t in terms}
    if len(kinds) > 1:
        raise ControllerSpecError(f"{field}.terms: crisp and fuzzy terms cannot be mixed in one variable")
    source, scale = None, 1.0
    if is_input:
        source = data["source"]
        if not isinstance(source, str) or source not in SOURCES:
            raise ControllerSpecError(f"{field}.source: unknown source {show(source)} "
                                      f"(known: {', '.join(SOURCES)})")
        scale = _number(data.get("scale", 1.0), f"{field}.scale")
        if not scale >= 1.0 / limits.MAX_CONTROLLER_ABS:
            raise ControllerSpecError(f"{field}.scale: must be in [{1.0 / limits.MAX_CONTROLLER_ABS:g}, "
                                      f"{limits.MAX_CONTROLLER_ABS:g}], got {scale:g}")
    elif not isinstance(role, str) or role not in ROLES:
        raise ControllerSpecError(f"{field}.role: unknown role {show(role)} (known: {', '.join(ROLES)})")
    return Variable(name=name, universe=(lo, hi), resolution=res, terms=terms, source=source, scale=scale,
                    role=role)


_CLAUSE = re.compile(r"^\s*([A-Za-z_][\w]*)\s*=\s*([A-Za-z_][\w]*)\s*$")


def _parse_clauses(text: str, sep: str, field: str) -> tuple[tuple[str, str], ...]:
    clauses = []
    for part in text.split(sep):
        m = _CLAUSE.match(part)
        if not m:
            raise ControllerSpecError(f"{field}: cannot read {show(part.strip())} (expected var=term)")
        clauses.append((m.group(1), m.group(2)))
    return tuple(clauses)


def parse_rule(text: str, variables: Mapping[str, Variable], inputs: set[str], outputs: set[str],
               field: str) -> Rule:
    """Parse ``"a=x & b=y -> out=z, out2=w"`` and check every variable and term exists."""
    if not isinstance(text, str):
        raise ControllerSpecError(f"{field}: expected a string")
    if text.count("->") != 1:
        raise ControllerSpecError(f"{field}: expected exactly one '->' in {show(text)}")
    left, right = text.split("->")
    ante = _parse_clauses(left, "&", field)
    cons = _parse_clauses(right, ",", field)
    for group, names, what in ((ante, inputs, "input"), (cons, outputs, "output")):
        seen = set()
        for var, term in group:
            if var not in names:
                raise ControllerSpecError(f"{field}: unknown {what} variable {show(var)} in {show(text)}")
            if var in seen:
                raise ControllerSpecError(f"{field}: variable {show(var)} appears twice in {show(text)}")
            seen.add(var)
            if term not in {t.name for t in variables[var].terms}:
                raise ControllerSpecError(f"{field}: unknown term {show(term)} of variable {show(var)} in {show(text)}")
    return Rule(antecedent=ante, consequent=cons, text=text.strip())


def parse_controller(data: Mapping[str, Any]) -> ControllerSpec:
    """Validate and convert a controller definition mapping (see the module docstring)."""
    data = _mapping(data, "")
    _check_keys(data, {"name", "description", "inputs", "outputs", "rules", "fallback"},
                {"inputs", "outputs", "rules"}, "")
    name = check_name(data.get("name", "controller"), "name", ControllerSpecError)
    check_text(data.get("description", ""), "description", ControllerSpecError)
    inputs_raw, outputs_raw = _mapping(data["inputs"], "inputs"), _mapping(data["outputs"], "outputs")
    check_count(len(inputs_raw) + len(outputs_raw), "inputs/outputs", limits.MAX_CONTROLLER_VARIABLES,
                ControllerSpecError, "variables")
    inputs = tuple(_parse_variable(_identifier(n, f"inputs.{key_text(n)}"), d, f"inputs.{n}", True)
                   for n, d in inputs_raw.items())
    outputs = tuple(_parse_variable(_identifier(n, f"outputs.{key_text(n)}"), d, f"outputs.{n}", False)
                    for n, d in outputs_raw.items())
    if not inputs:
        raise ControllerSpecError("inputs: at least one input variable is needed")
    readers: dict[str, str] = {}
    for v in inputs:  # two inputs on one sonar leave another unread and weigh one obstacle twice
        if v.source in readers:
            raise ControllerSpecError(f"inputs.{v.name}.source: {v.source!r} is already read by "
                                      f"inputs.{readers[v.source]} (each observation feeds one input)")
        readers[str(v.source)] = v.name
    names = [v.name for v in (*inputs, *outputs)]
    for n in names:
        if names.count(n) > 1:
            raise ControllerSpecError(f"outputs.{n}: name used by both an input and an output variable")
    roles = [v.role for v in outputs]
    for role in ROLES:
        if roles.count(role) != 1:
            raise ControllerSpecError(f"outputs: exactly one output variable must have role {role!r} "
                                      f"(found {roles.count(role)})")
    variables = {v.name: v for v in (*inputs, *outputs)}
    rules_raw = data["rules"]
    if not isinstance(rules_raw, list | tuple) or not rules_raw:
        raise ControllerSpecError("rules: at least one rule is needed")
    check_count(len(rules_raw), "rules", limits.MAX_RULES, ControllerSpecError, "rules")
    rules = tuple(parse_rule(r, variables, {v.name for v in inputs}, {v.name for v in outputs}, f"rules[{i}]")
                  for i, r in enumerate(rules_raw))
    fb = _mapping(data.get("fallback", {}), "fallback")
    _check_keys(fb, set(ROLES), set(), "fallback")
    dtheta_var = next(v for v in outputs if v.role == "dtheta")
    v_var = next(v for v in outputs if v.role == "v")
    fb_dtheta = _number(fb.get("dtheta", 0.0), "fallback.dtheta")
    fb_v = _number(fb.get("v", v_var.universe[0]), "fallback.v")
    for value, var, key in ((fb_dtheta, dtheta_var, "dtheta"), (fb_v, v_var, "v")):
        if not var.universe[0] <= value <= var.universe[1]:
            raise ControllerSpecError(f"fallback.{key}: {value} is outside the universe {list(var.universe)}")
    return ControllerSpec(name=name, inputs=inputs, outputs=outputs, rules=rules,
                          fallback_dtheta=fb_dtheta, fallback_v=fb_v)


def check_fits_robot(spec: ControllerSpec, v_min: float, v_max: float) -> None:
    """The speed output must reach the robot's speed range ``[v_min, v_max]`` (cm/s): the robot clamps every
    commanded speed into it, so a universe entirely below or above it would silently command one speed."""
    var = spec.output_for("v")
    lo, hi = var.universe
    if hi < v_min or lo > v_max:
        raise ControllerSpecError(f"outputs.{var.name}.universe: [{lo:g}, {hi:g}] cm/s lies outside the robot's "
                                  f"speed range [{v_min:g}, {v_max:g}] cm/s (robot.v_min, robot.v_max)")


def sample_membership(term: Term, grid: np.ndarray, universe_max: float) -> np.ndarray:
    """Sample a term's membership function on ``grid`` (numpy only; independent of scikit-fuzzy)."""
    x = grid
    p = term.params
    if term.mf == "trap":
        a, b, c, d = p
        rise = np.ones_like(x) if b == a else np.clip((x - a) / (b - a), 0.0, 1.0)
        fall = np.ones_like(x) if d == c else np.clip((d - x) / (d - c), 0.0, 1.0)
        y = np.minimum(rise, fall)
        y[(x < a) | (x > d)] = 0.0
        return y
    if term.mf == "tri":
        return sample_membership(Term(term.name, "trap", (p[0], p[1], p[1], p[2])), grid, universe_max)
    if term.mf == "gauss":
        mean, sigma = p
        d = x - mean
        return exp_array(-(d * d) / (2.0 * (sigma * sigma)))
    lo, hi = p
    inside = (x >= lo) & ((x < hi) | ((hi >= universe_max) & (x <= hi)))
    return inside.astype(float)


def crisp_snap(var: Variable, values: np.ndarray) -> np.ndarray:
    """Replace each value of a crisp variable by the midpoint of the crisp interval it belongs to."""
    out = np.array(values, dtype=float, copy=True)
    lo_u, hi_u = var.universe
    clipped = np.clip(out, lo_u, hi_u)
    for term in var.terms:
        lo, hi = term.params
        inside = (clipped >= lo) & ((clipped < hi) | ((hi >= hi_u) & (clipped <= hi)))
        out = np.where(inside, 0.5 * (max(lo, lo_u) + min(hi, hi_u)), out)
    return out
