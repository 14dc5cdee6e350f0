"""Libraries loaded on first use, so that the report's workers start before they are: ``pd = deferred("pandas")``.

``python -m analysis.report`` forks its log readers as early as it can (:mod:`analysis.forked`); the readers need
numpy and the log checks, not pandas or pyarrow (a third of a second of imports, more than the rest of the report's
imports together). With pandas deferred in the modules the report imports, the readers start without it and the
report's own process loads it (:func:`load`) while they read (issue #36). The stdlib's
:class:`importlib.util.LazyLoader` does the deferring: the module object is the real one, run on its first attribute
access.
"""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType


def deferred(name: str) -> ModuleType:
    """The top-level module ``name``, loaded on the first access to one of its attributes (or the module itself
    where it is loaded already)."""
    module = sys.modules.get(name)
    if module is not None:
        return module
    spec = importlib.util.find_spec(name)
    if spec is None or spec.loader is None:
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)
    spec.loader = importlib.util.LazyLoader(spec.loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


def load(module: ModuleType) -> None:
    """Load a :func:`deferred` module now (nothing for a loaded one)."""
    getattr(module, "__name__")  # noqa: B009 - the attribute access is what loads it
