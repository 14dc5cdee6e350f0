"""Frozen config dataclasses from plain nested mappings (as composed by Hydra or loaded from YAML).

``from_dict(DWAConfig, {"margin_cm": 12})`` fills every other field with its default. An unknown key, a
non-string key, a wrong type or a list of the wrong length raises ``ValueError`` naming the dotted field; each
number is checked where it is parsed, so that the message names exactly this field, against its documented range
(the field's own, :func:`fuzzynav.params.limits.ranged`, else :data:`fuzzynav.params.limits.FIELD_RANGES`); then
the dataclass checks itself (``__post_init__``: relations between fields).
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Mapping
from typing import Any

from fuzzynav.params import limits
from fuzzynav.params.checks import check_key, check_number, field_name, kind_of, show


def from_dict(cls: type, data: Mapping[str, Any] | None, path: str = "") -> Any:
    """Instantiate dataclass ``cls`` from ``data`` recursively (lists become tuples)."""
    data = {} if data is None else data
    if isinstance(data, cls):  # already checked (a policy is given the config its configuration was read into)
        return data
    if not isinstance(data, Mapping):
        raise ValueError(f"{path or cls.__name__}: expected a mapping, got {kind_of(data)}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in data.items():
        check_key(key, path)
        where = field_name(path, key)
        if key not in fields:
            raise ValueError(f"{where}: unknown key (allowed: {', '.join(fields)})")
        hint = hints[key]
        if dataclasses.is_dataclass(hint):
            kwargs[key] = from_dict(hint, value, where)
        else:
            kwargs[key] = _coerce(hint, value, where, limits.field_range(fields[key], where))
    try:
        return cls(**kwargs)
    except ValueError as err:
        msg = str(err)
        named = bool(msg) and ":" in msg.split()[0]  # the dataclasses' messages start with the field
        raise ValueError(msg if named else f"{path or cls.__name__}: {msg or type(err).__name__}") from None


def _coerce(hint: Any, value: Any, where: str, rng: limits.Range | None) -> Any:
    origin = typing.get_origin(hint)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ValueError(f"{where}: expected a list, got {show(value)}")
        args = typing.get_args(hint)
        if args and Ellipsis not in args and len(value) != len(args):
            raise ValueError(f"{where}: expected a list of {len(args)} items, got {len(value)}")
        item = args[0] if args else float
        return tuple(_coerce(item, v, f"{where}[{i}]", rng) for i, v in enumerate(value))
    if hint is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{where}: expected true or false, got {show(value)}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{where}: expected an integer, got {show(value)}")
        check_number(value, where, rng)
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{where}: expected a number, got {show(value)}")
        check_number(value, where, rng)
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ValueError(f"{where}: expected a string, got {show(value)}")
        return value
    return value
