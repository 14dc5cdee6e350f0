"""``python -m runners.tune`` (issue #39): studies of real episodes, storage, resume, workers, held-out results.

Tiny studies: one short scenario (head_on, ~42 steps), two training seeds, a few trials.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import optuna
import pandas as pd
import pytest
import yaml

from analysis.log_inputs import find_logs
from analysis.logs import episode_summary
from runners.tuning.storage import open_storage
from runners.tuning.study import INTERRUPTED, SURPLUS, counted
from tests.conftest import ROOT

TINY = {
    "name": "tiny",
    "base": ["planner=auto"],
    "space": ["planner.h_wait=int(range(1,4))", "planner.safety_margin_cm=interval(0,30)"],
    "objectives": [{"name": "score", "direction": "maximize", "terms": {"success": 1.0, "time_to_goal_s": -0.005},
                    "fill": {"time_to_goal_s": 120}}],
    "scenarios": ["head_on"],
    "train_seeds": {"start": 0, "count": 2},
    "heldout_seeds": {"start": 100, "count": 3},
    "sampler": "tpe",
    "trials": 3,
}


def study_file(tmp_path: Path, **changes) -> Path:
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump({**TINY, **changes}, sort_keys=False))
    return path


def tune(*args, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "runners.tune", *map(str, args)], cwd=ROOT, capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def trials_of(study_dir: Path, kind: str = "sqlite") -> list[optuna.trial.FrozenTrial]:
    return optuna.load_study(study_name="tiny", storage=open_storage(study_dir, kind)).get_trials()


def test_study_runs_episodes_reports_and_writes_a_runnable_best(tmp_path):
    out = tmp_path / "study"
    # the default (safety margin 10 cm) is outside this space: the best trial is not the default
    space = ["planner.h_wait=int(range(1,4))", "planner.safety_margin_cm=interval(12,30)"]
    res = tune(study_file(tmp_path, space=space), "--out", out)
    assert res.returncode == 0, res.stderr
    trials = trials_of(out)
    assert [t.state.name for t in trials] == ["COMPLETE"] * 3
    for t in trials:  # each trial's episodes are ordinary logs of its parameters, on the training seeds
        logs = find_logs([out / "trials" / f"{t.number:05d}"])
        assert sorted(episode_summary(p)["seed"] for p in logs) == [0, 1]
        assert all(f"__h{t.params['planner.h_wait']}__" in p.name for p in logs)
    held = find_logs([out / "heldout"])
    assert sorted({int(episode_summary(p)["seed"]) for p in held}) == [100, 101, 102]  # never a training seed
    assert {p.parent.name for p in held} == {"default", "tuned"}
    report = out / "report"
    for name in ("study.md", "trials.csv", "heldout.csv", "history_score.png", "importance_score.png"):
        assert (report / name).stat().st_size > 0, name
    table = pd.read_csv(report / "heldout.csv")
    success = table[(table["metric"] == "success") & (table["configuration"] == "tuned")].iloc[0]
    assert success["n"] == 3 and 0 <= success["ci_low"] <= success["mean"] <= success["ci_high"] <= 1
    best = max(trials, key=lambda t: (t.value, -t.number))
    assert f"trial {best.number}" in (report / "study.md").read_text()
    # the best trial as a config that the normal run command runs
    run = subprocess.run([sys.executable, "-m", "runners.run", "--config-dir", str(out), "--config-name", "tuned",
                          f"hydra.run.dir={tmp_path / 'run'}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert f"h_wait={best.params['planner.h_wait']}" in run.stdout
    logged = yaml.safe_load((tmp_path / "run" / ".hydra" / "config.yaml").read_text())
    assert logged["planner"]["safety_margin_cm"] == best.params["planner.safety_margin_cm"]
    # the analysis reads the held-out logs as any sweep's
    rep = subprocess.run([sys.executable, "-m", "analysis.report", str(out / "heldout"), "--jobs", "1"], cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert rep.returncode == 0, rep.stderr


def test_rerun_resumes_and_stale_trials_run_again(tmp_path):
    out, path = tmp_path / "study", study_file(tmp_path)
    assert tune(path, "--out", out, "--trials", "2", "--no-heldout").returncode == 0
    first = trials_of(out)[0]  # the study starts from the default configuration
    assert first.user_attrs.get("default") and first.params == {"planner.h_wait": 2, "planner.safety_margin_cm": 10.0}
    # a trial left RUNNING, as a killed command leaves it
    study = optuna.load_study(study_name="tiny", storage=open_storage(out, "sqlite"))
    study.ask()
    res = tune(path, "--out", out, "--trials", "3", "--no-heldout")
    assert res.returncode == 0, res.stderr
    assert "2 of 3 trials done" in res.stdout and "trials 2 were left in flight" in res.stderr
    trials = trials_of(out)
    assert trials[2].state.name == "FAIL" and trials[2].user_attrs[INTERRUPTED]
    assert sum(map(counted, trials)) == 3 and trials[3].state.name == "COMPLETE"
    # the resumed command does not propose the points of the first run again
    assert trials[3].params != trials[1].params


def test_ctrl_c_loses_only_the_trial_in_flight(tmp_path):
    out, path = tmp_path / "study", study_file(tmp_path, train_seeds={"start": 0, "count": 6})
    proc = subprocess.Popen([sys.executable, "-m", "runners.tune", str(path), "--out", str(out), "--no-heldout",
                             "--trials", "50"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (out / "trials" / "00001").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "re-run the command to resume" in err and "Traceback" not in err
    trials = trials_of(out)
    assert trials[0].state.name == "COMPLETE"
    assert [t.user_attrs.get(INTERRUPTED) for t in trials if t.state.name != "COMPLETE"] == [True]
    res = tune(path, "--out", out, "--trials", "2", "--no-heldout")
    assert res.returncode == 0, res.stderr
    assert sum(map(counted, trials_of(out))) == 2


def test_workers_share_a_journal_study(tmp_path):
    out = tmp_path / "study"
    res = tune(study_file(tmp_path), "--out", out, "--workers", "2", "--storage", "journal", "--trials", "4",
               "--no-heldout")
    assert res.returncode == 0, res.stderr
    assert (out / "study.journal").exists() and not (out / "study.db").exists()
    trials = trials_of(out, "journal")
    assert sum(map(counted, trials)) == 4  # the budget, never exceeded
    ran = [t for t in trials if not t.user_attrs.get(SURPLUS)]
    assert len({(t.params["planner.h_wait"], t.params["planner.safety_margin_cm"]) for t in ran}) == len(ran)
    assert os.listdir(out / "trials")  # logs of both workers' trials


def test_two_objectives_give_a_pareto_front_and_each_evaluated_trial_a_config(tmp_path):
    out = tmp_path / "study"
    path = study_file(tmp_path, sampler="nsga2", trials=4, objectives=[
        {"metric": "min_clearance_dynamic_cm", "direction": "maximize"},
        {"name": "time", "terms": {"time_to_goal_s": 1.0}, "fill": {"time_to_goal_s": 120}, "direction": "minimize"}])
    res = tune(path, "--out", out)
    assert res.returncode == 0, res.stderr
    assert (out / "report" / "pareto_front.png").stat().st_size > 0
    front = optuna.load_study(study_name="tiny", storage=open_storage(out, "sqlite")).best_trials
    configs = sorted(p.stem for p in out.glob("trial_*.yaml"))
    assert configs and set(configs) <= {f"trial_{t.number}" for t in front}


def test_cmaes_sampler_runs(tmp_path):
    out = tmp_path / "study"
    res = tune(study_file(tmp_path, sampler="cmaes", space=["planner.safety_margin_cm=interval(0,30)",
                                                            "planner.n_traj=int(interval(5,12))"]),
               "--out", out, "--no-heldout")
    assert res.returncode == 0, res.stderr
    assert sum(map(counted, trials_of(out))) == 3


def test_a_trials_config_is_the_config_hydra_composes():
    from omegaconf import OmegaConf

    from runners.tuning.episodes import ConfigurationError, compose, hydra_conf, run_config
    from runners.tuning.study_file import Seeds

    overrides = ["planner=wait", "navigator=fuzzy_tpt", "planner.h_wait=3", "planner.safety_margin_cm=12.5",
                 "controller.inputs.front.terms.near.params=[0,0,25.5,61]"]
    with hydra_conf():
        for _ in range(2):  # composed, then from the cache
            fast = run_config(overrides, "crossing_right", Seeds(7, 3))
            full = compose([*overrides, "scenario=crossing_right", "seed=7", "episodes=3"])
            assert OmegaConf.to_yaml(fast, resolve=True) == OmegaConf.to_yaml(full, resolve=True)
        for bad in ("planner.h_wiat=3", "planner.h_wait=2.5", "planner.h_wait=abc"):
            with pytest.raises(ConfigurationError, match=r"planner\.h_w"):
                run_config([bad], "head_on", Seeds(0, 1))


def test_a_trial_asked_for_beyond_the_budget_is_surplus_and_never_runs(tmp_path):
    """Two workers both saw room for one more trial and both asked: the storage's numbering decides, the second
    is told FAIL as surplus before any parameter is asked, and it is not counted."""
    from runners.tuning.study import create_or_load, run_trial, within_budget
    from runners.tuning.study_file import load_study_file

    spec = load_study_file(study_file(tmp_path, trials=1))
    out = tmp_path / "study"
    out.mkdir()
    study = create_or_load(spec, open_storage(out, "sqlite"))
    first = study.ask()  # another worker's trial, in flight (the enqueued default)
    assert within_budget(study, first.number, 1)
    assert run_trial(study, spec, out, budget=1) is None
    trials = trials_of(out)
    assert [t.state.name for t in trials] == ["RUNNING", "FAIL"]
    assert trials[1].user_attrs == {SURPLUS: True} and trials[1].params == {} and not counted(trials[1])
    assert not (out / "trials").exists()  # no episode ran
    assert within_budget(study, first.number, 1) and not within_budget(study, 1, 1)


@pytest.mark.parametrize("name", sorted(p.stem for p in (ROOT / "conf" / "tune").glob("*.yaml")))
def test_every_shipped_study_file_checks(name):
    """conf/tune's studies (the suite_v2 comparison's baselines among them) load, and their base and every bound
    of their spaces compose and validate on each scenario before any trial."""
    from runners.tune import check_space
    from runners.tuning.study_file import find_study_file, load_study_file

    spec = load_study_file(find_study_file(name))
    check_space(spec)
    if name.startswith("suite_v2_"):  # the same budget and held-out seeds for every method
        ref = load_study_file(find_study_file("suite_v2_table1"))
        assert spec.scenarios == ("crowd_crossing", "crowd_crossing_invisible", "corridor_flow", "random_walkers",
                                  "groups")
        assert (spec.train, spec.heldout, spec.trials, spec.objectives) == (ref.train, ref.heldout, ref.trials,
                                                                            ref.objectives)
        assert spec.heldout.seeds == range(10)  # suite_v2's own seeds
