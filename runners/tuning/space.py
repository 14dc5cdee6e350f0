"""A study's search space, written in Hydra's override grammar and parsed by Hydra's own parser.

Each entry of a study file's ``space`` list is one override whose value is a sweep
(https://hydra.cc/docs/advanced/override_grammar/extended/):

- ``planner.h_wait=int(range(1,6))`` — the integers 1 … 5 (``range``'s stop is excluded, as in Python);
- ``planner.safety_margin_cm=interval(0,30)`` — any real number in [0, 30]; ``int(interval(0,30))``: an integer;
- ``planner.n_traj=tag(log,int(interval(3,27)))`` — sampled on a log scale (bounds > 0);
- ``planner=choice(auto,wait)`` or ``planner.phi_low_rule=choice(paper,toward_goal)`` — categories.

:func:`parse_space` turns them into :class:`Parameter` objects (Optuna distributions named by the override's key);
a trial's values become overrides again with :func:`overrides_of`. Every problem is a :class:`SpaceError` whose
message names the entry (``space[1]``) and says what is wrong.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import ChoiceSweep, IntervalSweep, OverrideType, RangeSweep
from optuna.distributions import BaseDistribution, CategoricalDistribution, FloatDistribution, IntDistribution

MAX_PARAMETERS = 64  # more is not a search a study of episodes can cover
MAX_CHOICES = 1_000
MAX_TEXT = 300  # characters of one entry
MAX_INT_BOUND = 10**15  # an integer parameter beyond this is no run parameter (and its value overflows an entry)


class SpaceError(ValueError):
    """An entry of the search space is not a search range (the message names the entry)."""


@dataclass(frozen=True)
class Parameter:
    """One searched config key: ``key`` as Hydra names it (``planner.h_wait``, ``planner`` for a config group),
    ``distribution`` Optuna's, ``text`` the entry as written."""

    key: str
    distribution: BaseDistribution
    text: str

    def contains(self, value: Any) -> bool:
        """Whether ``value`` is a point of this parameter's range (a default inside the space is enqueued)."""
        d = self.distribution
        if isinstance(d, CategoricalDistribution):
            return value in d.choices
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            return False
        if isinstance(d, IntDistribution) and (not float(value).is_integer() or (value - d.low) % d.step):
            return False
        return d.low <= value <= d.high


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise SpaceError(f"{where}: bound {value!r} is not a finite number")
    return value


def _int_bounds(where: str, *bounds: int) -> None:
    for b in bounds:
        if abs(b) > MAX_INT_BOUND:
            raise SpaceError(f"{where}: integer bound {b:.3g} is beyond +-{MAX_INT_BOUND:.0e}")


def _distribution(value: Any, where: str) -> BaseDistribution:
    tags = set(getattr(value, "tags", set()) or set())
    unknown = tags - {"log"}
    if unknown:
        raise SpaceError(f"{where}: unknown tag {sorted(unknown)[0]!r} (only 'log' is understood)")
    log = "log" in tags
    if isinstance(value, IntervalSweep):
        low, high = _number(value.start, where), _number(value.end, where)
        if not low < high:
            raise SpaceError(f"{where}: interval({low:g},{high:g}) is {'empty' if low == high else 'inverted'}: "
                             "the lower bound must be below the upper")
        if log and low <= 0:
            raise SpaceError(f"{where}: a log-scale interval needs a lower bound above 0, got {low:g}")
        if isinstance(value.start, int) and isinstance(value.end, int):
            _int_bounds(where, int(low), int(high))
            return IntDistribution(int(low), int(high), log=log)
        return FloatDistribution(float(low), float(high), log=log)
    if isinstance(value, RangeSweep):
        if value.shuffle:
            raise SpaceError(f"{where}: shuffle() orders a sweep; a search samples, so it means nothing here")
        start, stop, step = (_number(v, where) for v in (value.start, value.stop, value.step))
        if step <= 0:
            raise SpaceError(f"{where}: range step {step:g} must be above 0")
        if not start < stop:
            raise SpaceError(f"{where}: range({start:g},{stop:g}) is {'empty' if start == stop else 'inverted'}: "
                             "it has no value")
        if all(isinstance(v, int) for v in (value.start, value.stop, value.step)):
            _int_bounds(where, int(start), int(stop))
            last = start + (stop - 1 - start) // step * step
            if last == start:
                raise SpaceError(f"{where}: range({start},{stop}) has one value: set it in the study's base "
                                 "overrides instead")
            if log and (step != 1 or start <= 0):
                raise SpaceError(f"{where}: a log-scale integer range needs step 1 and a start above 0")
            return IntDistribution(int(start), int(last), step=1 if log else int(step), log=log)
        count = math.ceil((stop - start) / step)
        if count > MAX_CHOICES:
            raise SpaceError(f"{where}: range has {count} values, above the limit {MAX_CHOICES}")
        if count < 2:
            raise SpaceError(f"{where}: range has one value: set it in the study's base overrides instead")
        if log:
            raise SpaceError(f"{where}: log applies to interval() and integer range(), not to a real range")
        return CategoricalDistribution([start + k * step for k in range(count)])
    if isinstance(value, ChoiceSweep):
        if log:
            raise SpaceError(f"{where}: log applies to interval() and range(), not to choice()")
        choices = list(value.list)
        if len(choices) > MAX_CHOICES:
            raise SpaceError(f"{where}: choice has {len(choices)} values, above the limit {MAX_CHOICES}")
        for c in choices:
            if not (c is None or isinstance(c, bool | int | str) or (isinstance(c, float) and math.isfinite(c))):
                raise SpaceError(f"{where}: choice value {str(c)[:40]!r} is not a number, a string or a bool")
        if len(set(map(repr, choices))) != len(choices):
            raise SpaceError(f"{where}: choice lists a value twice")
        if len(choices) < 2:
            raise SpaceError(f"{where}: choice of one value is no search: set it in the study's base overrides")
        return CategoricalDistribution(choices)
    raise SpaceError(f"{where}: {type(value).__name__} is not a search range: use range(), interval() or choice()")


def parse_space(entries: Sequence[Any], field: str = "space") -> list[Parameter]:
    """The parameters of a study file's ``space`` list (strings in Hydra's override grammar), in order."""
    if isinstance(entries, str | bytes) or not isinstance(entries, Sequence):
        raise SpaceError(f"{field}: expected a list of overrides such as 'planner.h_wait=int(range(1,6))'")
    if not entries:
        raise SpaceError(f"{field}: is empty: name at least one parameter to search")
    if len(entries) > MAX_PARAMETERS:
        raise SpaceError(f"{field}: {len(entries)} parameters, above the limit {MAX_PARAMETERS}")
    parser = OverridesParser.create()
    parameters: list[Parameter] = []
    for i, text in enumerate(entries):
        where = f"{field}[{i}]"
        if not isinstance(text, str):
            raise SpaceError(f"{where}: expected an override string, got {type(text).__name__}")
        if len(text) > MAX_TEXT:
            raise SpaceError(f"{where}: {len(text)} characters, above the limit {MAX_TEXT}")
        try:
            (override,) = parser.parse_overrides([text])
        except Exception as err:  # Hydra's grammar error: its first line says where
            raise SpaceError(f"{where}: {text[:80]!r} does not parse: {' '.join(str(err).split())[:200]}") from None
        key = override.get_key_element()
        where = f"{where} ({key[:60]})"
        if override.type != OverrideType.CHANGE or override.package:
            raise SpaceError(f"{where}: only a plain key=sweep is searched (no +, ++, ~ or @package)")
        if key.startswith("hydra"):
            raise SpaceError(f"{where}: Hydra's own settings are not run parameters")
        if not override.is_sweep_override():
            raise SpaceError(f"{where}: {text.partition('=')[2][:60]!r} is one value, not a search range: use "
                             "range(), interval() or choice() (a fixed value goes in the study's base overrides)")
        if any(p.key == key for p in parameters):
            raise SpaceError(f"{where}: the key is searched twice")
        parameters.append(Parameter(key, _distribution(override.value(), where), text))
    return parameters


def format_value(value: Any) -> str:
    """A parameter value as an override's value: numbers exactly (``repr``), strings as Hydra reads them back."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if value is None:
        return "null"
    if isinstance(value, int | float):
        return repr(value)
    text = str(value)
    plain = text.replace("_", "").replace("-", "").replace("/", "").replace(".", "").isalnum()
    return text if plain else "'" + text.replace("\\", "\\\\").replace("'", "\\'") + "'"


def overrides_of(parameters: Sequence[Parameter], values: Mapping[str, Any]) -> list[str]:
    """The overrides that set each parameter to its value (``planner.h_wait=3``), in the space's order."""
    return [f"{p.key}={format_value(values[p.key])}" for p in parameters]


def suggest(trial: Any, parameters: Sequence[Parameter]) -> dict[str, Any]:
    """Ask an Optuna trial (its public ``suggest_*``) for a value of each parameter."""
    values: dict[str, Any] = {}
    for p in parameters:
        d = p.distribution
        if isinstance(d, IntDistribution):
            values[p.key] = trial.suggest_int(p.key, d.low, d.high, step=d.step, log=d.log)
        elif isinstance(d, FloatDistribution):
            values[p.key] = trial.suggest_float(p.key, d.low, d.high, log=d.log)
        else:
            values[p.key] = trial.suggest_categorical(p.key, list(d.choices))
    return values
