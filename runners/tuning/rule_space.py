"""The fuzzy controller's rule outputs as a search space (``controller_rules:`` in a study file; issue #39 item 2).

``controller_rules: [dtheta, v]`` names output variables; for each rule of the base configuration's controller
(Table 1's 28 by default) whose consequent sets one of them, the term it sets is one categorical parameter over
that variable's terms (``rule~3.dtheta`` in {NB, NS, ZE, PS, PB}). The antecedents stay as they are. The base
controller's rules are the study's first trial; a trial's rules become one ordinary override
(``controller.rules=['left=near & ... -> dtheta=NS, v=slow', ...]``), recorded in its logs and written into the
tuned controller file.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from optuna.distributions import CategoricalDistribution

from runners.tuning.space import Parameter

PREFIX = "rule~"  # Optuna parameter names of the rule outputs (not Hydra keys)
_CLAUSE = re.compile(r"^\s*([A-Za-z_]\w*)\s*=\s*([A-Za-z_]\w*)\s*$")


class RuleSpaceError(ValueError):
    """``controller_rules`` names what the controller does not have (the message names it)."""


@dataclass(frozen=True)
class RuleSpace:
    """The rules of the base controller, split at ``->``, and the searched outputs with their terms."""

    antecedents: tuple[str, ...]
    consequents: tuple[tuple[tuple[str, str], ...], ...]  # per rule: (output, term) in the rule's order
    terms: tuple[tuple[str, tuple[str, ...]], ...]  # searched output -> its term names

    def searched(self) -> list[tuple[int, str, str]]:
        """(rule index, output, base term) of every searched rule output."""
        outputs = dict(self.terms)
        return [(i, out, term) for i, cons in enumerate(self.consequents) for out, term in cons if out in outputs]


def check_entries(data: Any, field: str = "controller_rules") -> tuple[str, ...]:
    """The study file's ``controller_rules`` as output names (checked for form only)."""
    if data is None:
        return ()
    if not isinstance(data, list) or not data or not all(isinstance(n, str) and n for n in data):
        raise RuleSpaceError(f"{field}: expected a list of output variable names such as [dtheta, v]")
    if len(set(data)) != len(data):
        raise RuleSpaceError(f"{field}: an output is named twice")
    return tuple(data)


def resolve(outputs: Sequence[str], controller: Mapping[str, Any], field: str = "controller_rules") -> RuleSpace:
    """The rule space of the composed config's ``controller`` section."""
    known = controller.get("outputs") or {}
    for name in outputs:
        if name not in known:
            raise RuleSpaceError(f"{field}: {name[:40]!r} is not an output of controller {controller.get('name')} "
                                 f"(outputs: {', '.join(known)})")
    antecedents, consequents = [], []
    for i, text in enumerate(controller.get("rules") or []):
        if not isinstance(text, str) or text.count("->") != 1:
            raise RuleSpaceError(f"{field}: controller rules[{i}] is not 'antecedent -> out=term, ...'")
        left, right = text.split("->")
        clauses = []
        for part in right.split(","):
            m = _CLAUSE.match(part)
            if m is None:
                raise RuleSpaceError(f"{field}: controller rules[{i}]: cannot read {part.strip()[:40]!r}")
            clauses.append((m.group(1), m.group(2)))
        antecedents.append(left.strip())
        consequents.append(tuple(clauses))
    space = RuleSpace(tuple(antecedents), tuple(consequents),
                      tuple((name, tuple(known[name]["terms"])) for name in outputs))
    if not space.searched():
        raise RuleSpaceError(f"{field}: no rule of controller {controller.get('name')} sets {', '.join(outputs)}")
    return space


def parameters(space: RuleSpace | None) -> list[Parameter]:
    """One categorical parameter per searched rule output, over its variable's terms."""
    if space is None:
        return []
    terms = dict(space.terms)
    return [Parameter(f"{PREFIX}{i}.{out}", CategoricalDistribution(list(terms[out])),
                      f"rule {i} ({space.antecedents[i][:60]}): {out}") for i, out, _ in space.searched()]


def start_values(space: RuleSpace | None) -> dict[str, str]:
    """The base controller's rule outputs (Table 1), as parameter values."""
    return {} if space is None else {f"{PREFIX}{i}.{out}": term for i, out, term in space.searched()}


def rules(space: RuleSpace, values: Mapping[str, Any]) -> list[str]:
    """The rules with the searched outputs at ``values``."""
    out = []
    for i, (ante, cons) in enumerate(zip(space.antecedents, space.consequents, strict=True)):
        terms = [f"{o}={values.get(f'{PREFIX}{i}.{o}', t)}" for o, t in cons]
        out.append(f"{ante} -> {', '.join(terms)}")
    return out


def overrides(space: RuleSpace | None, values: Mapping[str, Any]) -> list[str]:
    """The one override that sets the controller's rules to those at ``values`` (none without a rule space)."""
    if space is None:
        return []
    return ["controller.rules=[" + ",".join(f"'{r}'" for r in rules(space, values)) + "]"]
