"""Checks of decoded JSON values, built from small rules (``number(lo, hi)``, ``array(item)``, ``obj(**fields)``)
that raise :class:`CheckError` naming the field and the problem. Common cases are decided at C speed — the number
fields of one object that share a range with one ``itemgetter``, a set of types, ``min`` and ``max``; arrays of
numbers, of [x, y] pairs and of booleans likewise — and only a value that fails is walked item by item to say
what is wrong. Units are the caller's (the log checks use cm, cm/s, degrees, s).

Every rule also has a *batch* form, :func:`accepts_all` (``rule.batch(values) -> bool``): whether every value of a
list is acceptable, decided over the whole list at once — an episode's hundred ``/robot/state`` messages are one
``itemgetter`` per field group, one set of types, one ``min`` and one ``max``. It never says what is wrong: when it
says no, the caller runs the rule value by value, which names the first bad field. The batch form accepts exactly
what the rule accepts (a property test checks the two against each other on mutated messages)."""

from __future__ import annotations

import re
from collections.abc import Callable
from itertools import chain, repeat
from operator import eq, itemgetter
from typing import Any

MAX_CM = 1e9  # the scenario files' limit on coordinates (cm): the default magnitude bound of a number


class CheckError(ValueError):
    """A value the analysis would read is missing, of the wrong type, out of range or inconsistent.
    ``where``: the field's path (``x_cm``, ``obstacles[2].radius_cm``); ``problem``: what is wrong."""

    def __init__(self, where: str, problem: str) -> None:
        super().__init__(f"{where}: {problem}" if where else problem)
        self.where, self.problem = where, problem

    def inside(self, prefix: str) -> CheckError:
        """The same problem one level up (``prefix`` is the enclosing field or ``[index]``)."""
        joined = prefix if not self.where else f"{prefix}{self.where}" if self.where.startswith("[") \
            else f"{prefix}.{self.where}"
        return CheckError(joined, self.problem)


Check = Callable[[Any], None]  # raises CheckError (with an empty ``where``) if the value is not acceptable
Batch = Callable[[list[Any]], bool]  # True if every value of the list is acceptable


def accepts_all(rule: Check, values: list[Any]) -> bool:
    """Whether ``rule`` accepts every one of ``values``: its batch form when it has one, else value by value."""
    batch = getattr(rule, "batch", None)
    if batch is not None:
        try:
            return bool(batch(values))
        except (KeyError, TypeError, IndexError, AttributeError, ValueError, OverflowError):  # an unexpected shape
            return False
    try:
        for v in values:
            rule(v)
    except CheckError:
        return False
    return True


def with_batch(rule: Check, batch: Batch) -> Check:
    rule.batch = batch  # type: ignore[attr-defined]
    return rule


def _types_within(values: Any, allowed: frozenset) -> bool:
    return set(map(type, values)) <= allowed


def _numbers_within(values: list[Any], lo: float, hi: float) -> bool:
    """All ``values`` are JSON numbers (not booleans) in [lo, hi] (JSON has no NaN: orjson refuses it)."""
    return not values or (set(map(type, values)) <= NUMBER_TYPES and lo <= min(values) and max(values) <= hi
                          and _without_nan(values))


def _without_nan(values: list[Any]) -> bool:
    """No NaN among these numbers: min and max skip a NaN that is not first (every comparison with it is false),
    so the range test alone would pass one. ``eq`` pairwise keeps the loop in C."""
    return all(map(eq, values, values))


def are_booleans(values: list[Any]) -> bool:
    """All ``values`` (a list) are booleans."""
    return set(map(type, values)) <= BOOL_TYPES


def _integers_within(values: list[Any], lo: int, hi: int) -> bool:
    return not values or (set(map(type, values)) <= INT_TYPES and lo <= min(values) and max(values) <= hi)


def _lists(values: list[Any], min_items: int = 0, length: int | None = None) -> bool:
    """All ``values`` are lists of at least ``min_items`` (exactly ``length`` when given) items."""
    if not values:
        return True
    if not set(map(type, values)) <= LIST_TYPES:
        return False
    lengths = set(map(len, values))
    return min(lengths) >= min_items and (length is None or lengths == {length})


def kind_of(value: Any) -> str:
    """How an error message names the JSON type of ``value``."""
    return "null" if value is None else {bool: "a boolean", int: "an integer", float: "a number", str: "a string",
                                         list: "an array", dict: "an object"}.get(type(value), type(value).__name__)


def number(lo: float = -MAX_CM, hi: float = MAX_CM) -> Check:
    """A JSON number (not a boolean) in [lo, hi]; NaN and infinities fail the range test. The bounds are taken as
    floats (an int bound above 2**53 is not exactly a float: compared as given it would mean another range)."""
    lo, hi = float(lo), float(hi)

    def check(v: Any) -> None:
        t = type(v)
        if t is not float and t is not int:
            raise CheckError("", f"expected a number, got {kind_of(v)}")
        if not lo <= v <= hi:
            raise CheckError("", f"{v!r} is out of range [{lo:g}, {hi:g}]")
    check.bounds = (lo, hi)  # type: ignore[attr-defined]  # lets obj() check such fields together
    return with_batch(check, lambda vs: _numbers_within(vs, lo, hi))


def integer(lo: int = 0, hi: int = 2**63 - 1) -> Check:
    def check(v: Any) -> None:
        if type(v) is not int:
            raise CheckError("", f"expected an integer, got {kind_of(v)}")
        if not lo <= v <= hi:
            raise CheckError("", f"{v!r} is out of range [{lo}, {hi}]")
    return with_batch(check, lambda vs: _integers_within(vs, lo, hi))


def boolean(v: Any) -> None:
    if type(v) is not bool:
        raise CheckError("", f"expected a boolean, got {kind_of(v)}")


boolean.batch = lambda vs: _types_within(vs, BOOL_TYPES)  # type: ignore[attr-defined]


def string(v: Any) -> None:
    if type(v) is not str:
        raise CheckError("", f"expected a string, got {kind_of(v)}")


string.batch = lambda vs: _types_within(vs, STR_TYPES)  # type: ignore[attr-defined]


def one_of(*values: str) -> Check:
    allowed = frozenset(values)

    def check(v: Any) -> None:
        if type(v) is not str or v not in allowed:
            raise CheckError("", f"{v!r} is not one of {', '.join(values)}")
    return with_batch(check, lambda vs: _types_within(vs, STR_TYPES) and set(vs) <= allowed)


def matching(pattern: re.Pattern[str], what: str) -> Check:
    """A string the whole of which matches ``pattern`` (``what`` says what it should be)."""
    def check(v: Any) -> None:
        if type(v) is not str or not pattern.fullmatch(v):
            raise CheckError("", f"{str(v)[:40]!r} is not {what}")
    return with_batch(check, lambda vs: _types_within(vs, STR_TYPES) and all(map(pattern.fullmatch, set(vs))))


def nullable(inner: Check) -> Check:
    def check(v: Any) -> None:
        if v is not None:
            inner(v)
    return with_batch(check, lambda vs: accepts_all(inner, [v for v in vs if v is not None]))


def array(item: Check, min_items: int = 0, length: int | None = None) -> Check:
    """A JSON array of ``item``s (at least ``min_items``; exactly ``length`` when given)."""
    def check(v: Any) -> None:
        if type(v) is not list:
            raise CheckError("", f"expected an array, got {kind_of(v)}")
        if len(v) < min_items or (length is not None and len(v) != length):
            raise CheckError("", f"{len(v)} items, expected {length if length is not None else f'>= {min_items}'}")
        i = 0
        try:
            for i, x in enumerate(v):  # noqa: B007 - i names the failing item
                item(x)
        except CheckError as err:
            raise err.inside(f"[{i}]") from None
    return with_batch(check, lambda vs: _lists(vs, min_items, length)
                       and accepts_all(item, list(chain.from_iterable(vs))))


class _Slow(Exception):
    """The fast path of :func:`obj` saw something wrong: the field-by-field path says what."""


def obj(**fields: Check) -> Check:
    """A JSON object with at least these fields (others are not read, so not checked). Number fields with the
    same range are checked together at C speed (one ``itemgetter``, a set of types, min and max); the rest, and
    any object the fast path refuses, field by field."""
    items = tuple(fields.items())
    by_range: dict[tuple[float, float], list[str]] = {}
    for name, field_check in items:
        bounds = getattr(field_check, "bounds", None)
        if bounds is not None:
            by_range.setdefault(bounds, []).append(name)
    groups = tuple((itemgetter(*names), lo, hi) for (lo, hi), names in by_range.items() if len(names) > 1)
    grouped = {name for (_lo, _hi), names in by_range.items() if len(names) > 1 for name in names}
    others = tuple((name, c) for name, c in items if name not in grouped)

    def field_by_field(v: Any) -> None:
        name = ""
        try:
            for name, field_check in items:
                field_check(v[name])
        except KeyError:
            raise CheckError(name, "missing") from None
        except CheckError as err:
            raise err.inside(name) from None

    def check(v: Any) -> None:
        if type(v) is not dict:
            raise CheckError("", f"expected an object, got {kind_of(v)}")
        try:
            for get, lo, hi in groups:
                if not _numbers_within(get(v), lo, hi):
                    raise _Slow
            for name, field_check in others:
                field_check(v[name])
        except (KeyError, CheckError, _Slow):
            field_by_field(v)
            raise CheckError("", "not acceptable") from None  # unreachable while the two paths agree

    def batch(vs: list[Any]) -> bool:
        if not vs:
            return True
        if not set(map(type, vs)) <= DICT_TYPES:
            return False
        for get, lo, hi in groups:
            if not _numbers_within(list(chain.from_iterable(map(get, vs))), lo, hi):
                return False
        return all(accepts_all(field_check, list(map(itemgetter(name), vs))) for name, field_check in others)
    return with_batch(check, batch)


NUMBER_TYPES = frozenset({int, float})
INT_TYPES = frozenset({int})
LIST_TYPES = frozenset({list})
BOOL_TYPES = frozenset({bool})
STR_TYPES = frozenset({str})
DICT_TYPES = frozenset({dict})


def _fast(accept: Callable[[Any], bool], slow: Check) -> Check:
    """``accept`` decides the common case at C speed; when it says no, ``slow`` (the same rule, item by item)
    finds the item and says what is wrong."""
    def check(v: Any) -> None:
        if not accept(v):
            slow(v)
            raise CheckError("", "not acceptable")  # unreachable while the two rules agree
    return check


def numbers(lo: float = -MAX_CM, hi: float = MAX_CM, min_items: int = 0, length: int | None = None) -> Check:
    """An array of numbers in [lo, hi] (the large TPT and laser arrays: checked with set, min and max)."""
    def accept(v: Any) -> bool:
        if type(v) is not list or len(v) < min_items or (length is not None and len(v) != length):
            return False
        return _numbers_within(v, lo, hi)
    return with_batch(_fast(accept, array(number(lo, hi), min_items, length)),
                       lambda vs: _lists(vs, min_items, length) and _numbers_within(list(chain.from_iterable(vs)),
                                                                                    lo, hi))


def are_points(v: Any) -> bool:
    """An array of [x, y] number pairs within ±MAX_CM (map, set, min and max: no Python loop per pair)."""
    if type(v) is not list:
        return False
    if not v:
        return True
    if not set(map(type, v)) <= LIST_TYPES or set(map(len, v)) != {2}:
        return False
    coords = list(chain.from_iterable(v))
    return set(map(type, coords)) <= NUMBER_TYPES and min(coords) >= -MAX_CM and max(coords) <= MAX_CM \
        and _without_nan(coords)


def are_tables(tables: list[Any], rows: list[Any], ks: list[int], booleans: bool = False) -> bool:
    """Every ``tables[i]`` is a list of ``rows[i]`` lists of ``ks[i]`` cells each: [x, y] number pairs within
    ±MAX_CM (a TPT's ``obstacles_cm``), or booleans (its ``collide``). ``rows`` and ``ks``: exact ints, as a TPT's
    ``n_traj + 1`` and its obstacle count are (another count is refused, even for a table without rows).
    ``tables``, ``rows`` and ``ks``: lists of one length (TypeError, ValueError otherwise: the caller's mistake)."""
    if not (type(tables) is list and type(rows) is list and type(ks) is list):
        raise TypeError("are_tables: tables, rows and ks must be lists")
    if not len(tables) == len(rows) == len(ks):
        raise ValueError(f"are_tables: {len(tables)} tables, {len(rows)} row counts, {len(ks)} column counts")
    if not (set(map(type, tables)) <= LIST_TYPES and list(map(len, tables)) == rows):
        return False
    if not (set(map(type, rows)) <= INT_TYPES and set(map(type, ks)) <= INT_TYPES):
        return False
    if ks and min(ks) < 0:
        return False
    table_rows = list(chain.from_iterable(tables))
    if not (set(map(type, table_rows)) <= LIST_TYPES
            and list(map(len, table_rows)) == list(chain.from_iterable(map(repeat, ks, rows)))):
        return False
    cells = list(chain.from_iterable(table_rows))
    return are_booleans(cells) if booleans else are_points(cells)


def points(min_items: int = 0) -> Check:
    """An array of [x, y] pairs of numbers (cm)."""
    return with_batch(_fast(lambda v: are_points(v) and len(v) >= min_items,
                             array(array(number(), length=2), min_items)),
                       lambda vs: _lists(vs, min_items) and are_points(list(chain.from_iterable(vs))))


def point_rows(min_items: int = 0) -> Check:
    """An array of arrays of [x, y] pairs (the TPT's predicted obstacle positions, [row][obstacle])."""
    def accept(v: Any) -> bool:
        return type(v) is list and len(v) >= min_items and set(map(type, v)) <= LIST_TYPES \
            and are_points(list(chain.from_iterable(v)))
    def batch(vs: list[Any]) -> bool:
        rows = list(chain.from_iterable(vs)) if _lists(vs, min_items) else None
        return rows is not None and _lists(rows) and are_points(list(chain.from_iterable(rows)))
    return with_batch(_fast(accept, array(points(), min_items)), batch)


def boolean_rows(min_items: int = 0) -> Check:
    """An array of arrays of booleans (the TPT's collision matrix)."""
    def accept(v: Any) -> bool:
        return type(v) is list and len(v) >= min_items and set(map(type, v)) <= LIST_TYPES \
            and are_booleans(list(chain.from_iterable(v)))
    def batch(vs: list[Any]) -> bool:
        rows = list(chain.from_iterable(vs)) if _lists(vs, min_items) else None
        return rows is not None and _lists(rows) and are_booleans(list(chain.from_iterable(rows)))
    return with_batch(_fast(accept, array(array(boolean), min_items)), batch)


