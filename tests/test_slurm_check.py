"""``hydra/launcher=slurm`` where Slurm cannot be reached: one line saying what is missing and how to run locally,
before any job (it was "a worker process was lost (RuntimeError: Could not detect srun ...)")."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from runners.sweeping import slurm
from tests.conftest import ROOT


def _fake_commands(folder: Path, sinfo_body: str, names=("sbatch", "srun", "squeue")) -> None:
    folder.mkdir(exist_ok=True)
    for name in names:
        script = folder / name
        script.write_text("#!/bin/sh\nexit 0\n")
        script.chmod(script.stat().st_mode | stat.S_IEXEC)
    sinfo = folder / "sinfo"
    sinfo.write_text(f"#!/bin/sh\n{sinfo_body}\n")
    sinfo.chmod(sinfo.stat().st_mode | stat.S_IEXEC)


def test_missing_commands_are_named(tmp_path, monkeypatch):
    _fake_commands(tmp_path, "exit 0", names=("sbatch",))
    monkeypatch.setenv("PATH", str(tmp_path))
    problem = slurm.slurm_problem()
    assert problem.startswith("hydra/launcher=slurm: Slurm's srun, squeue not found on PATH")
    assert "hydra/launcher=all_cores" in problem


def test_a_controller_that_does_not_answer(tmp_path, monkeypatch):
    _fake_commands(tmp_path, 'echo "sinfo: error: Unable to contact slurm controller (connect failure)" >&2; exit 1')
    monkeypatch.setenv("PATH", str(tmp_path))
    assert slurm.slurm_problem() == (
        "hydra/launcher=slurm: Slurm does not answer (sinfo: error: Unable to contact slurm controller (connect "
        f"failure)); {slurm.RUN_LOCALLY}")


def test_a_controller_that_hangs(tmp_path, monkeypatch):
    _fake_commands(tmp_path, "exec sleep 30")
    monkeypatch.setenv("PATH", f"{tmp_path}:/usr/bin:/bin")
    assert "did not answer sinfo in 0.5 s" in slurm.slurm_problem(timeout_s=0.5)


def test_a_cluster_that_answers(tmp_path, monkeypatch):
    _fake_commands(tmp_path, 'echo "debug*"')
    monkeypatch.setenv("PATH", str(tmp_path))
    assert slurm.slurm_problem() is None


@pytest.mark.parametrize("target, slurm_launcher", [
    ("hydra_plugins.hydra_submitit_launcher.submitit_launcher.SlurmLauncher", True),
    ("hydra_plugins.hydra_submitit_launcher.submitit_launcher.LocalLauncher", False),
    ("hydra_plugins.hydra_joblib_launcher.joblib_launcher.JoblibLauncher", False)])
def test_which_launchers_are_slurm(target, slurm_launcher):
    assert slurm.is_slurm_launcher(target) is slurm_launcher


def test_the_sweep_says_it_before_any_job(tmp_path):
    bin_dir = tmp_path / "bin"
    _fake_commands(bin_dir, 'echo "sinfo: error: Unable to contact slurm controller" >&2; exit 1')
    env = {**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}"}
    out = subprocess.run([sys.executable, "-m", "runners.sweep", "sweep=quick", "hydra/launcher=slurm",
                          f"hydra.sweep.dir={tmp_path / 'sweep'}"], cwd=ROOT, capture_output=True, text=True,
                         timeout=300, env=env)
    assert out.returncode == 2, out.stderr
    assert out.stderr.strip().splitlines() == [
        "error: hydra/launcher=slurm: Slurm does not answer (sinfo: error: Unable to contact slurm controller); "
        + slurm.RUN_LOCALLY]
    assert not (tmp_path / "sweep").exists()
