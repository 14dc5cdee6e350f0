"""The optional compiled kernels (C files built by the install when a C compiler is there).

Each kernel performs its Python or numpy counterpart's IEEE operations in the same order, so results are the same
bits with or without it (each kernel has a test that compares it with its counterpart).
``FUZZYNAV_KERNEL=python`` in the environment switches every kernel off: the runs then take the Python paths (to
check them, or to time them).
"""

from __future__ import annotations

import functools
import importlib
import os
from types import ModuleType

KERNEL_ENV = "FUZZYNAV_KERNEL"  # "python": never use a compiled kernel
# the modules pyproject.toml's ext-modules build
KERNELS = ("fuzzynav.sensing._raycast", "fuzzynav.sensing._tracking", "fuzzynav.pedestrians._social_force",
           "fuzzynav.pedestrians._orca", "fuzzynav.numerics._closest_approach")


def switched_off() -> bool:
    """Whether the environment asks for the Python paths (read at every call, so it follows ``os.environ``)."""
    env = os.environ
    data, encode = getattr(env, "_data", None), getattr(env, "encodekey", None)
    if type(data) is not dict or encode is None:  # not CPython's os._Environ
        return env.get(KERNEL_ENV, "").strip().lower() == "python"
    # CPython's os.environ keeps its variables in the dict _data: one lookup instead of Mapping.get's, which raises
    # and catches KeyError when the variable is not set (the usual case) and costs ~1 us; the kernels ask at every
    # call, up to ~10 times per simulation step
    value = data.get(encode(KERNEL_ENV))
    return value is not None and env.decodevalue(value).strip().lower() == "python"


#: kernels to leave unused in this process, by full or last name, comma-separated (``_orca,_raycast``): read when
#: a module loads its kernel; ``runners.bench`` times the commands with each kernel off in turn
KERNELS_OFF_ENV = "FUZZYNAV_KERNELS_OFF"


def kernels_off() -> set[str]:
    """The kernels :data:`KERNELS_OFF_ENV` names, as full module names (unknown names are an error: a typo must not
    time the wrong thing)."""
    names = {n.strip() for n in os.environ.get(KERNELS_OFF_ENV, "").split(",") if n.strip()}
    off = {k for k in KERNELS if k in names or k.rpartition(".")[2] in names}
    unknown = names - off - {k.rpartition(".")[2] for k in off}
    if unknown:
        raise ValueError(f"{KERNELS_OFF_ENV}: unknown kernel(s) {', '.join(sorted(unknown))} (known: "
                         f"{', '.join(k.rpartition('.')[2] for k in KERNELS)})")
    return off


def load(name: str) -> ModuleType | None:
    """The compiled module ``name`` (a full module name, one of :data:`KERNELS`), or None when it was not built
    (no C compiler at install) or :data:`KERNELS_OFF_ENV` names it."""
    if name in kernels_off():
        return None
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


@functools.cache
def built() -> dict[str, bool]:
    """Each kernel's short name and whether its compiled module can be imported (built at install)."""
    out = {}
    for name in KERNELS:
        try:
            importlib.import_module(name)
        except ImportError:
            out[name.rpartition(".")[2]] = False
        else:
            out[name.rpartition(".")[2]] = True
    return out


def in_use() -> str:
    """Which forms this process runs, as every log's metadata records it (``kernels``): ``compiled``, ``python``
    (no kernel built, e.g. no C compiler at install, or ``FUZZYNAV_KERNEL=python``) or ``python for _raycast, _orca``.
    Either way the results are the same bits; only the speed differs."""
    off = {k.rpartition(".")[2] for k in kernels_off()}
    python = [name for name, ok in built().items() if not ok or name in off]
    if switched_off() or len(python) == len(KERNELS):
        return "python"
    return "compiled" if not python else f"python for {', '.join(python)}"
