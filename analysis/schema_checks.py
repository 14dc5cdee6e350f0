"""A topic's message check built from its JSON schema (:mod:`analysis.log_format`): the schema says which fields
exist, their JSON types, which are required, enums, patterns and integer minimums; the caller says which fields it
reads and the ranges of their numbers. Built once (at import), the check is a tree of :mod:`analysis.json_checks`
rules, so it is as fast as one written by hand: JSON type -> rule —

* ``number`` -> :func:`~analysis.json_checks.number` (its range from the caller's :class:`Ranges`),
* ``integer`` -> :func:`~analysis.json_checks.integer` (the schema's ``minimum``/``maximum`` and the caller's range,
  whichever is narrower; an enum of integer ``const`` s -> their span),
* ``boolean``, ``string`` -> :func:`~analysis.json_checks.boolean`, :func:`~analysis.json_checks.string`
  (``enum`` -> :func:`~analysis.json_checks.one_of`, ``pattern`` -> :func:`~analysis.json_checks.matching`),
* ``object`` -> :func:`~analysis.json_checks.obj` of the fields read, ``oneOf`` [X, null] or a type [X, "null"] ->
  :func:`~analysis.json_checks.nullable`,
* ``array`` -> :func:`~analysis.json_checks.array`, or the rules that check a whole array at C speed: of numbers
  -> :func:`~analysis.json_checks.numbers`, of [x, y] pairs -> :func:`~analysis.json_checks.points`, of arrays of
  [x, y] pairs -> :func:`~analysis.json_checks.point_rows`, of arrays of booleans ->
  :func:`~analysis.json_checks.boolean_rows`.

A field read that the schema does not describe or does not require, a number without a range, a schema construct
that has no rule here: each is an error when the check is built (so at import), never a silent difference.

Fields are named by dotted paths in which arrays are transparent (``obstacles.x_cm``: the ``x_cm`` of every item
of ``obstacles``); ranges are looked up by ``"<topic> <path>"`` with ``[]`` for an array's items
(``/obstacles/truth obstacles[].x_cm``, ``/tpt robot_cm[][]``).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from typing import Any

from analysis.json_checks import (
    MAX_CM,
    Check,
    array,
    boolean,
    boolean_rows,
    integer,
    matching,
    nullable,
    number,
    numbers,
    obj,
    one_of,
    point_rows,
    points,
    string,
)

__all__ = ["Ranges", "SchemaError", "build_check", "field_paths", "read_tree"]

MAX_INT = 2**63 - 1  # an int64 column


class SchemaError(Exception):
    """The check cannot be built as asked (a programming error, raised at import)."""


class Ranges:
    """Range rules: ``(pattern, lo, hi)`` for numbers, integers and array lengths (``lo``: the fewest items), the
    first rule whose pattern ``re.search`` es ``"<topic> <path>"`` applies. A number must match one; an integer or
    an array without one has [0, 2**63 - 1] or no least length."""

    def __init__(self, numbers: Iterable[tuple[str, float, float]], integers: Iterable[tuple[str, int, int]] = (),
                 min_items: Iterable[tuple[str, int]] = ()) -> None:
        self.numbers = tuple((re.compile(p), float(lo), float(hi)) for p, lo, hi in numbers)
        self.integers = tuple((re.compile(p), lo, hi) for p, lo, hi in integers)
        self.min_items = tuple((re.compile(p), n) for p, n in min_items)

    def number(self, where: str) -> tuple[float, float]:
        for pattern, lo, hi in self.numbers:
            if pattern.search(where):
                return lo, hi
        raise SchemaError(f"{where}: a number without a range (add a rule)")

    def integer(self, where: str) -> tuple[int, int]:
        return next(((lo, hi) for pattern, lo, hi in self.integers if pattern.search(where)), (0, MAX_INT))

    def least_items(self, where: str) -> int:
        return next((n for pattern, n in self.min_items if pattern.search(where)), 0)


def read_tree(paths: Iterable[str]) -> dict[str, Any]:
    """Dotted paths as a tree: ``{name: subtree}``, an empty subtree for a field read whole; in first-seen order."""
    tree: dict[str, Any] = {}
    for path in paths:
        node = tree
        for name in path.split("."):
            node = node.setdefault(name, {})
    return tree


def build_check(topic: str, schema: Mapping[str, Any], paths: Iterable[str], ranges: Ranges) -> Check:
    """The check of ``topic``'s messages (``schema``: the topic's message schema, an object) that demands each
    of ``paths`` (the fields read, dotted) and checks it as the schema types it, within ``ranges``."""
    tree = read_tree(paths)
    if not tree:
        raise SchemaError(f"{topic}: no field read")
    return _check(topic, "", schema, tree, ranges)


def _where(topic: str, path: str) -> str:
    return f"{topic} {path}"


def _nullable_variant(node: Mapping[str, Any]) -> Mapping[str, Any] | None:
    """X of ``{"oneOf": [X, {"type": "null"}]}`` or of ``{"type": [t, "null"]}`` (as ``{"type": t}``)."""
    variants = node.get("oneOf")
    if variants is not None:
        others = [v for v in variants if v.get("type") != "null"]
        return others[0] if len(variants) == 2 and len(others) == 1 else None
    kind = node.get("type")
    if isinstance(kind, list) and len(kind) == 2 and "null" in kind:
        return {**node, "type": next(k for k in kind if k != "null")}
    return None


def _check(topic: str, path: str, node: Mapping[str, Any], tree: dict[str, Any], ranges: Ranges) -> Check:
    where = _where(topic, path)
    inner = _nullable_variant(node)
    if inner is not None:
        return nullable(_check(topic, path, inner, tree, ranges))
    if "oneOf" in node:
        consts = [v.get("const") for v in node["oneOf"]]
        if consts and all(type(c) is int for c in consts):
            lo, hi = min(consts), max(consts)
            if set(consts) != set(range(lo, hi + 1)):
                raise SchemaError(f"{where}: an enum of integers with gaps")
            rule_lo, rule_hi = ranges.integer(where)
            return integer(max(lo, rule_lo), min(hi, rule_hi))
        raise SchemaError(f"{where}: a oneOf that is neither [X, null] nor integer constants")
    kind = node.get("type")
    if kind == "object":
        return _object(topic, path, node, tree, ranges)
    if kind == "array":
        return _array(topic, path, node, tree, ranges)
    if tree:
        raise SchemaError(f"{where}: fields {sorted(tree)} read inside a {kind}")
    if kind == "number":
        return number(*ranges.number(where))
    if kind == "integer":
        lo, hi = ranges.integer(where)
        return integer(max(lo, node.get("minimum", lo)), min(hi, node.get("maximum", hi)))
    if kind == "boolean":
        return boolean
    if kind == "string":
        if "enum" in node:
            return one_of(*node["enum"])
        if "pattern" in node:
            return matching(re.compile(node["pattern"]), f"a string matching {node['pattern']}")
        return string
    raise SchemaError(f"{where}: no rule for the schema {dict(node)}")


def _object(topic: str, path: str, node: Mapping[str, Any], tree: dict[str, Any], ranges: Ranges) -> Check:
    if not tree:
        raise SchemaError(f"{_where(topic, path)}: an object read whole (name the fields read)")
    properties, required = node.get("properties", {}), node.get("required", [])
    fields = {}
    for name, subtree in tree.items():
        sub = f"{path}.{name}" if path else name
        if name not in properties:
            raise SchemaError(f"{_where(topic, sub)}: read, but the schema does not describe it")
        if name not in required:
            raise SchemaError(f"{_where(topic, sub)}: read as always present, but the schema does not require it")
        fields[name] = _check(topic, sub, properties[name], subtree, ranges)
    return obj(**fields)


def _is_pair(node: Mapping[str, Any]) -> bool:
    """An [x, y] pair of numbers."""
    return node.get("type") == "array" and node.get("minItems") == node.get("maxItems") == 2 \
        and node.get("items", {}).get("type") == "number"


def _array(topic: str, path: str, node: Mapping[str, Any], tree: dict[str, Any], ranges: Ranges) -> Check:
    items, item_path = node["items"], f"{path}[]"
    least = max(node.get("minItems", 0), ranges.least_items(_where(topic, path)))
    length = node["maxItems"] if node.get("maxItems") is not None and node.get("minItems") == node["maxItems"] \
        else None
    if "maxItems" in node and length is None:
        raise SchemaError(f"{_where(topic, path)}: maxItems without the same minItems")
    if tree:  # fields of the items read
        return array(_check(topic, item_path, items, tree, ranges), least, length)
    if items.get("type") == "number" and "oneOf" not in items:
        return numbers(*ranges.number(_where(topic, item_path)), min_items=least, length=length)
    if length is None and _is_pair(items) and _cm_pairs(topic, f"{item_path}[]", ranges):
        return points(least)
    inner = items.get("items", {}) if items.get("type") == "array" and "maxItems" not in items else None
    if length is None and inner is not None and items.get("minItems", 0) == 0:
        if _is_pair(inner) and _cm_pairs(topic, f"{item_path}[][]", ranges):
            return point_rows(least)
        if inner.get("type") == "boolean":
            return boolean_rows(least)
    return array(_check(topic, item_path, items, {}, ranges), least, length)


def _cm_pairs(topic: str, coord_path: str, ranges: Ranges) -> bool:
    """The coordinates at ``coord_path`` have the range of :func:`~analysis.json_checks.points` (±MAX_CM)."""
    return ranges.number(_where(topic, coord_path)) == (-MAX_CM, MAX_CM)


def field_paths(node: Mapping[str, Any], path: str = "") -> list[str]:
    """The dotted paths of every field a schema describes, at every depth (arrays transparent)."""
    inner = _nullable_variant(node)
    if inner is not None:
        node = inner
    if node.get("type") == "array":
        return field_paths(node["items"], path)
    out = []
    for name, sub in node.get("properties", {}).items():
        here = f"{path}.{name}" if path else name
        out.append(here)
        out.extend(field_paths(sub, here))
    return out
