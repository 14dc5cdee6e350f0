"""The optional compiled kernels (C files built by the install when a C compiler is there).

One kernel is left: ``fuzzynav.pedestrians._orca``, the orca pedestrians' velocities, kept because it makes the ORCA
crowd sweep of docs/crowds.md at least 1.3x faster end to end (issue #36; ``python -m runners.bench`` measures it).
A kernel performs its Python counterpart's IEEE operations in the same order, so results are the same bits with or
without it (tests/test_orca_kernel.py and tests/test_orca_boundaries.py compare the two forms).
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
KERNELS = ("fuzzynav.pedestrians._orca",)


def switched_off() -> bool:
    """Whether the environment asks for the Python paths (read at every call, so it follows ``os.environ``; the orca
    model asks once per step)."""
    return os.environ.get(KERNEL_ENV, "").strip().lower() == "python"


#: kernels to leave unused in this process, by full or last name, comma-separated (``_orca``): read when
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
    (no kernel built, e.g. no C compiler at install, or ``FUZZYNAV_KERNEL=python``) or, with several kernels of which
    only some run, ``python for`` the others (``python for _a, _b``).
    Either way the results are the same bits; only the speed differs."""
    off = {k.rpartition(".")[2] for k in kernels_off()}
    python = [name for name, ok in built().items() if not ok or name in off]
    if switched_off() or len(python) == len(KERNELS):
        return "python"
    return "compiled" if not python else f"python for {', '.join(python)}"
