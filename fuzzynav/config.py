"""Build the frozen config dataclasses from plain nested mappings (as composed by Hydra).

``episode_config_from_dict({"planner": {"strategy": "wait"}, "dt": 1.0})`` fills everything else with
defaults. An unknown key or a wrong type raises ``ValueError`` naming the dotted field.
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Mapping
from typing import Any

from fuzzynav.episode import EpisodeConfig


def from_dict(cls: type, data: Mapping[str, Any] | None, path: str = "") -> Any:
    """Instantiate dataclass ``cls`` from ``data`` recursively (lists become tuples)."""
    data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ValueError(f"{path or cls.__name__}: expected a mapping, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls)}
    kwargs = {}
    for key, value in data.items():
        where = f"{path}.{key}" if path else str(key)
        if key not in fields:
            raise ValueError(f"{where}: unknown key (allowed: {', '.join(fields)})")
        hint = hints[key]
        if dataclasses.is_dataclass(hint):
            kwargs[key] = from_dict(hint, value, where)
        else:
            kwargs[key] = _coerce(hint, value, where)
    try:
        return cls(**kwargs)
    except ValueError as err:
        msg = str(err)
        raise ValueError(msg if ":" in msg.split()[0] else f"{path}: {msg}") from None


def _coerce(hint: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ValueError(f"{where}: expected a list, got {value!r}")
        args = typing.get_args(hint)
        item = args[0] if args else float
        return tuple(_coerce(item, v, f"{where}[{i}]") for i, v in enumerate(value))
    if hint is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{where}: expected true or false, got {value!r}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{where}: expected an integer, got {value!r}")
        return value
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ValueError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ValueError(f"{where}: expected a string, got {value!r}")
        return value
    return value


def episode_config_from_dict(data: Mapping[str, Any] | None) -> EpisodeConfig:
    """An :class:`EpisodeConfig` from plain data (missing keys take their defaults)."""
    return from_dict(EpisodeConfig, data)
