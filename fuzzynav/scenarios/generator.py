"""The scenario-generator seam: plain parameters + seed -> a valid :class:`Scenario` (cm, s, degrees).

A generator is a function ``(params, seed, name) -> plain scenario data`` (the YAML form) registered with
``@register_generator("name")``; a scenario file uses it as ``{generator: name, params: {...}}``. fuzzynav's own
are the modules of :mod:`fuzzynav.scenarios.generators`, found without a list (:mod:`fuzzynav.registry`); another
package's is an entry point of group ``fuzzynav.generators``.

Each generator is valid by construction (start and goal free, obstacles clear of the robot's start and of
each other's start positions, moving obstacles starting outside the static ones) and deterministic: the same
parameters and seed give the same scenario.
The generator's random stream is ``numpy.random.default_rng((seed, 7))``, independent of the episode's.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping
from typing import Any

from fuzzynav.params import limits
from fuzzynav.params.checks import check_count, check_key, check_name, key_text, show
from fuzzynav.registry import load_plugins, one_line, source_digest
from fuzzynav.scenarios.scenario import ScenarioError, scenario_from_dict

ROBOT_RADIUS = 20.0
CLEAR_CM = 60.0  # free space kept around start and goal, beyond the robot radius


#: upper limits of the count parameters (fuzzynav.params.limits): the generator's work grows with them
_COUNT_LIMITS = {"n_static": (limits.MAX_STATIC_OBSTACLES, "obstacles"),
                 "n_dynamic": (limits.MAX_DYNAMIC_OBSTACLES, "obstacles"), "max_steps": (limits.MAX_STEPS, "steps"),
                 "n": (limits.MAX_DYNAMIC_OBSTACLES, "pedestrians"),
                 "n_groups": (limits.MAX_DYNAMIC_OBSTACLES, "groups"),
                 "group_size": (limits.MAX_DYNAMIC_OBSTACLES, "pedestrians")}


def param(params: Mapping[str, Any], key: str, default: Any, kind: type) -> Any:
    """Parameter ``key``: a ``[min, max]`` pair (``kind`` tuple), a count (int) or a length (float); finite,
    non-negative, |x| <= 1e9, counts at most their limit."""
    value = params.get(key, default)
    if kind is tuple:
        if not (isinstance(value, list | tuple) and len(value) == 2
                and all(_is_number(v) and 0 <= v <= limits.MAX_COORD_CM for v in value) and value[0] <= value[1]):
            raise ScenarioError(f"params.{key}: expected [min, max] with 0 <= min <= max <= "
                                f"{limits.MAX_COORD_CM:g}, got {show(value)}")
        return float(value[0]), float(value[1])
    if not _is_number(value) or not 0 <= value <= limits.MAX_COORD_CM:
        raise ScenarioError(f"params.{key}: expected a non-negative number (<= {limits.MAX_COORD_CM:g}), "
                            f"got {show(value)}")
    if kind is int:
        if value != int(value):
            raise ScenarioError(f"params.{key}: expected an integer, got {show(value)}")
        limit, what = _COUNT_LIMITS[key]
        check_count(int(value), f"params.{key}", limit, ScenarioError, what)
    return kind(value)


def _is_number(value: Any) -> bool:
    """A real, finite number (NaN fails every comparison, so it must be refused before them)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    if isinstance(value, int):  # math.isfinite overflows on a 400-digit integer
        return abs(value) <= limits.MAX_COORD_CM
    return math.isfinite(value)


Generator = Callable[[Mapping[str, Any], int, str], dict[str, Any]]
#: generator name -> function; filled by :func:`register_generator`
GENERATORS: dict[str, Generator] = {}
#: the entry-point group of generators from other installed packages (:mod:`fuzzynav.registry`)
ENTRY_POINT_GROUP = "fuzzynav.generators"


def register_generator(name: str) -> Callable[[Generator], Generator]:
    """Function decorator: make a generator available as ``generator: name`` (a name is registered once)."""

    def add(function: Generator) -> Generator:
        if not isinstance(name, str) or not limits.NAME_PATTERN.fullmatch(name):
            raise ValueError(f"generator name {name!r}: letters, digits and _ - . (at most "
                             f"{limits.NAME_MAX_CHARS} characters)")
        if name in GENERATORS and GENERATORS[name] is not function:
            raise ValueError(f"generator {name!r} is already registered ({GENERATORS[name]!r})")
        GENERATORS[name] = function
        return function

    return add


def registered_generators() -> dict[str, Generator]:
    """Every registered generator by name: fuzzynav's own and other packages' (their entry points)."""
    load_plugins("fuzzynav.scenarios.generators", ENTRY_POINT_GROUP, lambda n, f: register_generator(n)(f),
                 GENERATORS.get)
    return dict(GENERATORS)


def generator_source_digest(name: Any) -> str:
    """SHA-256 of the source of generator ``name``'s module when another package registered it ('' for fuzzynav's
    own and for unknown names and None, a scenario file): part of the identity of the episodes it generates the
    scenarios of."""
    if not isinstance(name, str):  # no generator: nothing to load (every episode of a scenario file asks)
        return ""
    generators = registered_generators()
    return source_digest(generators[name]) if name in generators else ""


def generate(data: Mapping[str, Any], seed: int):
    """Expand a scenario entry ``{generator: NAME, params: {...}, name: ...}`` into a validated Scenario."""
    generators = registered_generators()
    kind = data.get("generator")
    if not isinstance(kind, str) or kind not in generators:
        raise ScenarioError(f"generator: unknown generator {show(kind)} (known: {', '.join(generators)})")
    for key in data:
        check_key(key, "", ScenarioError)
        if key not in ("generator", "params", "name", "description"):
            raise ScenarioError(f"{key_text(key)}: unknown key for a generated scenario (allowed: generator, "
                                "params, name, description)")
    params = data.get("params") or {}
    if not isinstance(params, Mapping):
        raise ScenarioError("params: expected a mapping")
    name = check_name(data.get("name", kind), "name", ScenarioError)
    plain = _call_generator(kind, generators[kind], params, seed, name)
    if not isinstance(plain, Mapping):
        raise ScenarioError(f"generator {kind!r}: returned {type(plain).__name__}, expected the scenario's data "
                            "(a mapping, as in a scenario file)")
    return scenario_from_dict(plain), plain


def _call_generator(kind: str, function: Generator, params: Mapping[str, Any], seed: int, name: str) -> Any:
    """``function(params, seed, name)``, a call into generator ``kind``'s code, given its own copy of the
    parameters (a generator that changes them changes no other seed's scenario). Whatever it raises
    (``SystemExit`` included: a generator must not end a run or a sweep with exit status 0) is a
    :class:`ScenarioError` "generator 'kind': failed: Type: message"; a ``ScenarioError`` it raises itself
    (:func:`param`: "params.n: ...") already names the field and goes on as it is. ``KeyboardInterrupt`` goes on
    with a note naming the generator (a signal's stop request, or the code's own: the runner tells them apart)."""
    try:
        return function(copy.deepcopy(dict(params)), seed, name)
    except KeyboardInterrupt as err:
        err.add_note(f"generator {kind!r}: {kind}(params, seed, name)")
        raise
    except ScenarioError:
        raise
    except BaseException as err:
        raise ScenarioError(f"generator {kind!r}: failed: {one_line(err)}") from err
