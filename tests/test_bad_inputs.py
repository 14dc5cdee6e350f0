"""The bad-input corpus (tests/bad_inputs/cases.yaml): one readable line, non-zero exit, no traceback,
nothing left that looks like a result."""

from __future__ import annotations

import subprocess
import sys

import pytest
import yaml

from tests.conftest import ROOT

pytestmark = pytest.mark.long  # minutes: started first (tests/conftest.py)

CORPUS = ROOT / "tests" / "bad_inputs"
CASES = yaml.safe_load((CORPUS / "cases.yaml").read_text())


def test_corpus_has_at_least_30_cases():
    assert len(CASES) >= 30
    for case in CASES:
        if case["kind"] in ("scenario", "controller"):
            assert (CORPUS / case["kind"] / f"{case['name']}.yaml").exists(), case
        if case["kind"] == "log":
            assert (CORPUS / "logs" / case["name"]).exists(), case


@pytest.mark.parametrize("case", CASES, ids=[f"{c['kind']}-{c['name']}" for c in CASES])
def test_bad_input_fails_with_one_clear_line(case, tmp_path):
    kind, name = case["kind"], case["name"]
    if kind == "log":
        cmd = ["runners.replay", str(CORPUS / "logs" / name), "--verify"]
    else:
        cmd = ["runners.run", f"hydra.run.dir={tmp_path / 'out'}"]
        if kind == "override":
            cmd += name.split(" ")  # one or more overrides, separated by spaces
        else:
            cmd += [f"hydra.searchpath=[file://{CORPUS}]", f"{kind}={name}"]
    res = subprocess.run([sys.executable, "-m", *cmd], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode != 0
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("error: ") and case["expect"] in lines[0], lines[0]
    assert "Traceback" not in res.stderr
    assert not list(tmp_path.rglob("*.mcap")) and not list(tmp_path.rglob("report*"))


def test_scenario_files_are_never_code(tmp_path):
    from pathlib import Path

    marker = Path("/tmp/fuzzynav-bad-input-executed")  # what the file's python tag would create if run
    marker.unlink(missing_ok=True)
    evil = CORPUS / "scenario" / "bad_code_tag.yaml"
    assert "!!python/object/apply:os.system" in evil.read_text() and str(marker) in evil.read_text()
    res = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.searchpath=[file://{CORPUS}]",
                          "scenario=bad_code_tag", f"hydra.run.dir={tmp_path / 'o'}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=120, env={"PATH": "/usr/bin:/bin", "HOME": str(tmp_path)})
    assert res.returncode != 0 and not marker.exists()


def test_debug_shows_the_full_error(tmp_path):
    res = subprocess.run([sys.executable, "-m", "runners.run", "planner.h_wiat=2", "--debug",
                          f"hydra.run.dir={tmp_path}"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode != 0 and len(res.stderr.splitlines()) > 1
