"""Small valid logs, recorded once per test session by the real command (``python -m runners.run``): two
14-step ``paper_fig5`` episodes (plans, prediction tables, a moving obstacle) with their full config, so that
``runners.replay --verify`` reproduces them. Import the fixture into a test module to use it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT


@pytest.fixture(scope="session")
def recorded_logs(tmp_path_factory) -> list[Path]:
    out = tmp_path_factory.mktemp("recorded")
    res = subprocess.run([sys.executable, "-m", "runners.run", "scenario=paper_fig5", "scenario.max_steps=14",
                          "episodes=2", f"hydra.run.dir={out}"], cwd=ROOT, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr
    logs = sorted(out.glob("*.mcap"))
    assert len(logs) == 2
    return logs
