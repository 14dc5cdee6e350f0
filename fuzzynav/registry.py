"""Plug-ins found without a central list: fuzzynav's own by their package, other packages' by entry points.

A kind of plug-in (navigation policies, pedestrian models, scenario generators) is a registry, a mapping from
name to factory that the plug-ins fill themselves: a module of fuzzynav's own registers on import (a decorator
such as ``@register_policy("dwa")``), and :func:`load_plugins` imports every public module of the kind's package
(``fuzzynav.policies``) the first time a name is looked up. A plug-in of another installed package declares an
entry point in the kind's group, in its ``pyproject.toml``::

    [project.entry-points."fuzzynav.policies"]
    wall_follow = "my_package.wall_follow:WallFollowPolicy"

and is used by that name (``navigator.policy=wall_follow``): the object the entry point names is registered
under the entry point's name (a module that registers itself on import may be named instead). Adding a plug-in
is therefore one module (plus its YAML); no list in fuzzynav names it.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import inspect
import pkgutil
import sys
from collections.abc import Callable
from importlib import metadata
from types import ModuleType
from typing import Any

_LOADED: set[tuple[str, str]] = set()


def one_line(err: BaseException, with_type: bool = True) -> str:
    """An exception as one short line (a plug-in, like any user code, may raise anything, with any message)."""
    text = " ".join(str(err).split())[:200]
    if not with_type:
        return text or type(err).__name__
    return f"{type(err).__name__}: {text}" if text else type(err).__name__


def source_digest(obj: Any) -> str:
    """SHA-256 of the source file of the module that defines plug-in ``obj`` ('' for fuzzynav's own, whose code the
    fuzzynav version identifies, and for a module without a readable source file): part of an episode's identity,
    so that a resumed sweep re-runs the episodes of a plug-in whose code changed instead of keeping their logs."""
    name = getattr(obj, "__module__", None)
    if not isinstance(name, str) or name == "fuzzynav" or name.startswith("fuzzynav."):
        return ""
    module = sys.modules.get(name)
    try:
        source = inspect.getsourcefile(module) if module is not None else None
        with open(source, "rb") as f:  # type: ignore[arg-type]
            data = f.read()
    except (OSError, TypeError):
        return ""
    return hashlib.sha256(data).hexdigest() if data else ""


@functools.cache
def _installed_entry_points() -> Any:  # EntryPoints (SelectableGroups on Python 3.11)
    return metadata.entry_points()


def entry_points(group: str) -> metadata.EntryPoints:
    """The entry points of ``group`` of every installed package, as ``importlib.metadata.entry_points(group=...)``
    gives them; the installed packages' metadata is read once per process (each reading opens every installed
    distribution's ``entry_points.txt``, ~3 ms, and a run's start looks up four groups)."""
    return _installed_entry_points().select(group=group)


def load_plugins(package: str, group: str, register: Callable[[str, Any], None],
                 registered: Callable[[str], Any]) -> None:
    """Import every public module of ``package`` (they register themselves), then load the entry points of
    ``group``: each one's object is registered under the entry point's name by ``register(name, factory)``
    unless ``registered(name)`` already returns it (a module that registered itself on import). Runs once per
    (package, group); a plug-in that fails to load raises ``ValueError`` naming the entry point."""
    key = (package, group)
    if key in _LOADED:
        return
    _LOADED.add(key)  # before loading: a plug-in's import may look a name up again
    try:
        pkg = importlib.import_module(package)
        for info in pkgutil.iter_modules(pkg.__path__):
            if not info.name.startswith("_"):
                importlib.import_module(f"{package}.{info.name}")
        for entry in entry_points(group):
            where = f"entry point {entry.name[:40]!r} of group {group!r} ({entry.value[:80]})"
            try:
                obj = entry.load()
            except KeyboardInterrupt:
                raise
            except BaseException as err:  # another package's code (SystemExit included): that plug-in's error
                raise ValueError(f"{where}: loading it failed: {one_line(err)}") from None
            if isinstance(obj, ModuleType) or registered(entry.name) is obj:
                continue
            if not callable(obj):
                raise ValueError(f"{where}: names {type(obj).__name__}, not a factory or a module")
            try:
                register(entry.name, obj)
            except ValueError as err:  # a bad or taken name, a config_class that is not a dataclass
                raise ValueError(f"{where}: {one_line(err, with_type=False)}") from None
    except BaseException:
        _LOADED.discard(key)  # a later lookup tries again and reports the same error
        raise
