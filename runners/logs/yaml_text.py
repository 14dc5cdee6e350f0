"""YAML text of plain data (what ``yaml.safe_dump(data, sort_keys=False)`` writes), by libyaml's emitter where it
writes the same text as PyYAML's, which is four to ten times slower (a 20-pedestrian scenario: ~10 ms of an
episode's start, per episode, as every generated world is another text).

The two emitters differ in how they fold long double-quoted strings (escapes such as ``\\t`` or non-ASCII text),
in how they write an empty or a long key and in how they end a document that is a single scalar; on mappings and
lists of mappings (short keys), lists, numbers, booleans, None and non-empty printable-ASCII strings they write the
same text
(``tests/test_yaml_text.py`` compares them). So libyaml is used for such data only, and the text never depends
on whether this PyYAML was built with libyaml.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

_PRINTABLE_ASCII = re.compile(r"[ -~]+")
_KEY = re.compile(r"[ -~]{1,64}")  # PyYAML writes a key of 128 characters or more as "? key", libyaml does not
_FAST = getattr(yaml, "CSafeDumper", None)  # None when PyYAML was built without libyaml


def plain(value: Any, _seen: set[int] | None = None) -> bool:
    """Whether every string in ``value`` is non-empty printable ASCII, and every mapping key such a string of at most
    64 characters; False for data that holds one list or mapping twice (PyYAML writes it with anchors, and walking it
    again at every reference could take exponential time)."""
    if type(value) is str:
        return _PRINTABLE_ASCII.fullmatch(value) is not None
    if type(value) is dict or type(value) is list:
        seen = set() if _seen is None else _seen
        if id(value) in seen:
            return False
        seen.add(id(value))
        if type(value) is dict:
            return all(type(k) is str and _KEY.fullmatch(k) is not None and plain(v, seen) for k, v in value.items())
        return all(plain(v, seen) for v in value)
    return isinstance(value, int | float) or value is None


def dump(data: Any) -> str:
    """``yaml.safe_dump(data, sort_keys=False)``, by libyaml when it gives the same text (a mapping or list of
    :func:`plain` data)."""
    dumper = _FAST if _FAST is not None and type(data) in (dict, list) and plain(data) else yaml.SafeDumper
    return yaml.dump(data, Dumper=dumper, sort_keys=False)


def _omegaconf_dumpers() -> tuple[type, type | None]:
    """OmegaConf's dumper (what ``OmegaConf.to_yaml`` emits with: its quoting of strings) and the same representers on
    libyaml's emitter (None without libyaml)."""
    from omegaconf._utils import get_omega_conf_dumper

    python_dumper = get_omega_conf_dumper()
    base = getattr(yaml, "CDumper", None)
    if base is None:
        return python_dumper, None
    fast = type("OmegaConfCDumper", (base,), {})
    fast.add_representer(str, python_dumper.str_representer)
    return python_dumper, fast


def config_text(cfg: Any, *, resolve: bool = False) -> str:
    """``OmegaConf.to_yaml(cfg, resolve=resolve)``, the same text, by libyaml where it gives the same text
    (:func:`plain` data). A run's config takes ~10 ms by PyYAML's emitter and a sweep job writes three (its resolved
    text, part of each episode's identity, and Hydra's ``config.yaml`` and ``hydra.yaml``): more than an episode."""
    from omegaconf import OmegaConf

    global _OMEGACONF_DUMPERS
    if _OMEGACONF_DUMPERS is None:
        _OMEGACONF_DUMPERS = _omegaconf_dumpers()
    python_dumper, fast = _OMEGACONF_DUMPERS
    if not OmegaConf.is_config(cfg):
        cfg = OmegaConf.create(cfg)
    data = OmegaConf.to_container(cfg, resolve=resolve, enum_to_str=True)
    dumper = fast if fast is not None and plain(data) else python_dumper
    return yaml.dump(data, default_flow_style=False, allow_unicode=True, sort_keys=False, Dumper=dumper)


_OMEGACONF_DUMPERS: tuple[type, type | None] | None = None
