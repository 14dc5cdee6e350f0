"""The private parts of Hydra, OmegaConf and joblib the code uses are exactly those docs/sweeps.md lists, each with
its reason (issue #36: public APIs only, or a documented reason per exception)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PRIVATE = re.compile(r"^(hydra\._internal|hydra_plugins\.hydra_\w+\._|joblib\.externals|omegaconf\._)")


def _used(folders: tuple[Path, ...] = tuple(ROOT / f for f in ("fuzzynav", "runners", "analysis"))) -> set[str]:
    """Every imported name (``module.name``) or string naming a module path that starts with a private prefix."""
    found: set[str] = set()
    for folder in folders:
        for path in folder.rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if isinstance(node, ast.ImportFrom) and node.module and PRIVATE.match(node.module):
                    found |= {f"{node.module}.{a.name}" for a in node.names}
                elif isinstance(node, ast.Import):
                    found |= {a.name for a in node.names if PRIVATE.match(a.name)}
                elif isinstance(node, ast.Constant) and isinstance(node.value, str) and PRIVATE.match(node.value):
                    found.add(node.value)
    return found


def _documented() -> set[str]:
    text = (ROOT / "docs" / "sweeps.md").read_text()
    block = text.split("<!-- private-apis -->")[1].split("<!-- /private-apis -->")[0]
    return set(re.findall(r"^- `([^`]+)`", block, flags=re.M))


def test_every_private_api_used_is_documented_and_every_documented_one_used():
    assert _used() == _documented()


def test_the_scan_finds_each_form_of_use(tmp_path):
    (tmp_path / "m.py").write_text("from hydra._internal.utils import get_args_parser\nimport joblib.externals.loky\n"
                                   "NAME = 'hydra._internal.core_plugins.basic_launcher.BasicLauncher'\n"
                                   "from hydra.core.utils import run_job\n")
    assert _used((tmp_path,)) == {"hydra._internal.utils.get_args_parser", "joblib.externals.loky",
                                  "hydra._internal.core_plugins.basic_launcher.BasicLauncher"}
