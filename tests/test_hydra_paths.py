"""Hydra settings that would make a run or a sweep write outside its folder, or a sweep into several folders, are
one line before anything runs (runners.configuration.hydra_paths); a job whose folder the command line's check
could not see (a key a sweep preset sweeps) fails alone, writing nothing (hostile review of the sweep)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from runners.configuration.precheck import precheck
from tests.conftest import ROOT

SWEEP = ["sweep=default", "scenario=head_on", "planner=auto,wait", "episodes=1"]


@pytest.mark.parametrize("overrides, expect", [
    (["hydra.sweep.dir=/tmp/x/by_${planner.strategy}"], "config: hydra.sweep.dir: resolves to another folder for each"),
    (["hydra.sweep.dir=/tmp/x/n_${hydra.job.num}"], "config: hydra.sweep.dir: cannot be resolved before the jobs run"),
    (["hydra.sweep.subdir=${hydra.job.override_dirname}", "scenario.description=x/../../../escaped"],
     "config: hydra.sweep.subdir: resolves to 'episodes=1,planner=auto,scenario.description=x/../../../escaped"),
    (["hydra.sweep.subdir=${hydra.job.override_dirname}", "hydra.job.config.override_dirname.kv_sep=/../../kv_"],
     "config: hydra.sweep.subdir: resolves to 'episodes/../../kv_1"),
    (["hydra.sweep.subdir=/abs/${hydra.job.num}"], "config: hydra.sweep.subdir: '/abs/${hydra.job.num}' is not a"),
    (["hydra.output_subdir=../hydra_outside"],
     "config: hydra.output_subdir: resolves to '../hydra_outside', outside the job's folder"),
    (["hydra.output_subdir=/tmp/abs"], "config: hydra.output_subdir: resolves to '/tmp/abs', outside the job's folder"),
    (["hydra.job.name=../x"], "config: hydra.job.name: '../x' is not a plain name"),
    (["hydra.job_logging.handlers.file.filename=/tmp/abs.log"],
     "config: hydra.job_logging.handlers.file.filename: '/tmp/abs.log' is outside the job's folder"),
    (["hydra.job_logging.root.level=NOPE"], "config: hydra.job_logging.root.level: 'NOPE' is not a logging level"),
    (["hydra.hydra_logging.root.level=NOPE"], "config: hydra.hydra_logging.root.level: 'NOPE' is not a logging"),
])
def test_a_setting_that_writes_outside_the_folder_is_one_line(overrides, expect):
    problem = precheck([*SWEEP, *overrides], multirun=True)
    assert problem is not None and problem.startswith(expect), problem


@pytest.mark.parametrize("overrides", [
    [], ["hydra.sweep.subdir=${hydra.job.num}_${planner.strategy}"], ["hydra.output_subdir=null"],
    ["hydra.sweep.dir=/tmp/x/${now:%Y}/fixed"], ["hydra.job_logging.root.level=DEBUG"],
    ["hydra.sweep.subdir=${hydra.job.override_dirname}"],
])
def test_settings_inside_the_folder_pass(overrides):
    assert precheck([*SWEEP, *overrides], multirun=True) is None


def test_a_single_runs_settings_are_checked_too():
    assert precheck(["hydra.output_subdir=../out"]).startswith(
        "config: hydra.output_subdir: resolves to '../out', outside")
    assert precheck(["hydra.job.name=a/b"]).startswith("config: hydra.job.name: 'a/b' is not a plain name")
    assert precheck([]) is None


def test_a_job_whose_sweep_folder_only_its_own_values_change_fails_alone(tmp_path):
    """The folder depends on a key the preset sweeps (not on the command line, so the check composed no job of
    another value): the jobs of other folders fail with one line each, nothing is written there, and the sweep
    says it is incomplete."""
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=head_on", "episodes=1",
                          f"hydra.sweep.dir={tmp_path}/p_${{planner.strategy}}"], cwd=ROOT, capture_output=True,
                         text=True, timeout=600)
    assert res.returncode != 0 and "Traceback" not in res.stderr, res.stderr
    assert "hydra.sweep.dir: resolves to" in res.stderr and "not the sweep's folder" in res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p_auto"]
    assert len(list((tmp_path / "p_auto").rglob("*.mcap"))) == 4  # the four auto(h) jobs
