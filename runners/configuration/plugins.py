"""Config folders of other installed packages: a plug-in's YAML beside fuzzynav's own ``conf/`` groups.

A package that adds a policy (or a scenario, a controller, a sweep preset) ships its YAML in a package folder laid
out as ``conf/`` (``my_package/conf/navigator/wall_follow.yaml``) and names that package in the entry-point group
``fuzzynav.conf``::

    [project.entry-points."fuzzynav.conf"]
    my_package = "my_package.conf"

Every composition then searches it after fuzzynav's ``conf/`` (Hydra's search path, through the plugin
:class:`PluginConfigSearchPath`), so ``navigator=wall_follow,dwa`` sweeps it like a
built-in. A file whose group and name fuzzynav's ``conf/`` (or a package before it) already has would never be
composed (the first folder wins, as in Hydra): that is an error naming the entry point and the file, not a
silently ignored file.
"""

from __future__ import annotations

import importlib
import re
from functools import cache
from pathlib import Path

from hydra.core.config_search_path import ConfigSearchPath
from hydra.core.plugins import Plugins
from hydra.plugins.search_path_plugin import SearchPathPlugin

from fuzzynav.conf import CONF_DIR
from fuzzynav.registry import entry_points

ENTRY_POINT_GROUP = "fuzzynav.conf"
_PACKAGE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")


class PluginConfigError(ValueError):
    """An entry point of ``fuzzynav.conf`` that does not name an importable package folder (one line)."""


@cache
def plugin_config_dirs() -> tuple[tuple[str, Path], ...]:
    """(package, folder) of every ``fuzzynav.conf`` entry point, sorted by entry-point name (a fixed order, so
    that a composition does not depend on the order packages were installed in)."""
    found = []
    for entry in sorted(entry_points(ENTRY_POINT_GROUP), key=lambda e: (e.name, e.value)):
        package = entry.value.strip()
        where = f"entry point {entry.name!r} of group {ENTRY_POINT_GROUP!r}"
        if not _PACKAGE.fullmatch(package):
            raise PluginConfigError(f"{where}: expected a package name such as my_package.conf, got {package[:80]!r}")
        try:
            module = importlib.import_module(package)
        except Exception as err:  # another package's code: any failure is that entry point's error
            raise PluginConfigError(f"{where}: cannot import {package!r} ({type(err).__name__}: "
                                    f"{' '.join(str(err).split())[:160]})") from None
        paths = list(getattr(module, "__path__", []))
        if len(paths) != 1 or not Path(paths[0]).is_dir():
            raise PluginConfigError(f"{where}: {package!r} is not a package folder")
        folder = Path(paths[0]).resolve()
        earlier = [("fuzzynav's conf/", CONF_DIR), *((f"package {name}", f) for name, f in found)]
        for name in _config_names(folder):
            owner = next((who for who, f in earlier if (f / name).is_file()), None)
            if owner is not None:
                raise PluginConfigError(f"{where}: {name} is also in {owner} (searched first, so this file would "
                                        f"never be used): rename it")
        found.append((package, folder))
    return tuple(found)


def _config_names(folder: Path) -> list[str]:
    """The config files of a package folder laid out as ``conf/``, as paths relative to it (``navigator/x.yaml``);
    the top level holds no group's options."""
    return sorted(p.relative_to(folder).as_posix() for p in folder.glob("*/**/*.yaml") if p.is_file())


class PluginConfigSearchPath(SearchPathPlugin):
    """Hydra's search path plugin that adds the config folders of other installed packages after fuzzynav's own
    ``conf/`` (Hydra finds it in ``hydra_plugins.fuzzynav_sweeper``; :func:`register` registers it where Hydra's
    scan misses that package, as in an editable install)."""

    def manipulate_search_path(self, search_path: ConfigSearchPath) -> None:
        for package, _ in plugin_config_dirs():
            search_path.append(provider="fuzzynav-plugin", path=f"pkg://{package}")


def register() -> None:
    """Make every composition of this process search the plug-ins' config folders (idempotent)."""
    Plugins.instance().register(PluginConfigSearchPath)
