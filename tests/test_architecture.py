"""The import structure of the project: the contracts of ``[tool.importlinter]`` in pyproject.toml hold (the layers
runners > analysis > fuzzynav and fuzzynav's own, what the analysis may import, no circles among siblings), and no
module of fuzzynav, runners or analysis reaches itself again through its imports.

Imports under ``if TYPE_CHECKING:`` are left out (never executed); an import inside a function counts like any
other. Without import-linter (the ``dev`` extra) the tests are skipped, except in CI (``CI`` set), where they fail.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import networkx as nx
import pytest

from tests.conftest import ROOT

PACKAGES = ("fuzzynav", "runners", "analysis")
#: runners/hydra_sweeper/ is installed (and imported by runners.run and runners.sweep) under this name
SWEEPER_ALIAS, SWEEPER = "hydra_plugins.fuzzynav_sweeper", "runners.hydra_sweeper"


def _missing(what: str) -> None:
    message = f"{what} is not installed: pip install -e '.[dev]'"
    if os.environ.get("CI"):
        pytest.fail(message, pytrace=False)
    pytest.skip(message)


def test_import_contracts_hold():
    """``lint-imports`` (this environment's) passes every contract; its report is the failure message."""
    exe = Path(sys.executable).parent / ("lint-imports.exe" if os.name == "nt" else "lint-imports")
    if not exe.exists():
        _missing(f"lint-imports ({exe})")
    res = subprocess.run([str(exe), "--no-cache", "--no-logo"], cwd=ROOT, capture_output=True, text=True,
                         timeout=600, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert res.returncode == 0, f"lint-imports exited {res.returncode}:\n{res.stdout}\n{res.stderr}"


def import_graph() -> nx.DiGraph:
    """Module -> module it imports, over fuzzynav, runners and analysis (grimp; TYPE_CHECKING imports left out).
    An import of the installed Hydra sweeper by its plug-in name is an import of ``runners.hydra_sweeper``."""
    try:
        import grimp
    except ImportError:
        _missing("grimp (with import-linter)")
    graph = grimp.build_graph(*PACKAGES, include_external_packages=True, exclude_type_checking_imports=True,
                              cache_dir=None)
    ours = {m for m in graph.modules if m.split(".")[0] in PACKAGES}
    g = nx.DiGraph()
    g.add_nodes_from(ours)
    for importer in ours:
        for imported in graph.find_modules_directly_imported_by(importer):
            if imported in ours:
                g.add_edge(importer, imported)
            elif imported == SWEEPER_ALIAS.split(".")[0] and any(
                    SWEEPER_ALIAS in d["line_contents"]
                    for d in graph.get_import_details(importer=importer, imported=imported)):
                g.add_edge(importer, SWEEPER)
    return g


def test_no_module_imports_itself_round_a_circle():
    g = import_graph()
    assert {"fuzzynav.episode", "runners.run", "analysis.metrics", SWEEPER} <= set(g)  # the graph is the project's
    assert g.has_edge("runners.sweep", SWEEPER)  # the sweeper's plug-in name is followed
    try:
        cycle = nx.find_cycle(g)
    except nx.NetworkXNoCycle:
        return
    pytest.fail("import circle: " + " -> ".join([*(a for a, _ in cycle), cycle[0][0]]), pytrace=False)
