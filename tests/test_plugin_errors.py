"""A broken plug-in of another package (an entry point that cannot be loaded) is one line naming the entry point,
exit 2, from every command that meets it: never a traceback from inside Hydra or the registry.

The entry points are declared by a ``*.dist-info`` folder on ``PYTHONPATH`` (what an installed package leaves), so
nothing is installed into the test environment."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT

CASES = {
    "fuzzynav.conf": ("no_such_pkg.conf", []),
    "fuzzynav.policies": ("no_such_mod:Policy", ["navigator.policy=dwa"]),
    "fuzzynav.pedestrians": ("no_such_mod:Model", ["scenario=crowd_crossing"]),
    "fuzzynav.generators": ("no_such_mod:generate", ["scenario=random_mixed"]),
}


def _broken_package(tmp_path: Path, group: str, value: str) -> dict[str, str]:
    info = tmp_path / "site" / "broken_plugin-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{group}]\nbroken = {value}\n")
    return {**os.environ, "PYTHONPATH": str(tmp_path / "site")}


@pytest.mark.parametrize("group", sorted(CASES))
@pytest.mark.parametrize("command", ["runners.run", "runners.sweep"])
def test_a_broken_entry_point_is_one_line(group, command, tmp_path):
    value, overrides = CASES[group]
    env = _broken_package(tmp_path, group, value)
    args = [*overrides, "episodes=1", f"hydra.run.dir={tmp_path / 'run'}", f"hydra.sweep.dir={tmp_path / 'sweep'}"]
    if command == "runners.sweep":
        args.append("sweep=quick")
    proc = subprocess.run([sys.executable, "-m", command, *args], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=300, stdin=subprocess.DEVNULL)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and len(lines) == 1, proc.stderr[-2000:]
    assert "entry point 'broken'" in lines[0] and group in lines[0], lines[0]
    assert not (ROOT / "outputs").exists() or not any((ROOT / "outputs").rglob(tmp_path.name))
