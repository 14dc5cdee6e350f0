"""``python -m runners.tune --compare`` (issue #39): every study of a comparison file checked for the same budget
and seeds before any trial, run or resumed, and one comparison report; bad comparison files and studies that
cannot be compared are one line naming the file and the field; the comparison file fuzzed with hypothesis.

Tiny studies: one short scenario (head_on), two training seeds, two held-out seeds, two trials.
"""

from __future__ import annotations

import dataclasses
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import optuna
import pandas as pd
import pytest
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from analysis.log_inputs import find_logs
from analysis.logs import episode_summary
from analysis.objectives import objective_value
from runners.tuning import study_file as study_file_module
from runners.tuning.comparison_file import FIELDS, ComparisonFileError, load_comparison
from runners.tuning.episodes import EpisodeResults
from runners.tuning.heldout import Evaluated
from runners.tuning.storage import open_storage
from runners.tuning.study import counted
from tests.conftest import ROOT
from tests.fuzz_mutations import mutations
from tests.test_tune import TINY
from tests.test_tune_bad_inputs import one_line_error, run_main

# the default safety margin (10 cm) is outside this space: the tuned configuration is not the published one
PAPER = {**TINY, "space": ["planner.h_wait=int(range(1,4))", "planner.safety_margin_cm=interval(12,30)"],
         "heldout_seeds": {"start": 100, "count": 2}, "trials": 2}
DWA = {**PAPER, "name": "tiny_dwa", "base": ["navigator=dwa"], "space": ["navigator.margin_cm=interval(12,30)"]}
COMPARISON = {"name": "tiny_cmp", "description": "two tiny methods", "reference": "tiny",
              "studies": ["tiny.yaml", "studies/dwa.yaml"]}


def write(tmp_path: Path, paper: dict | None = None, dwa: dict | None = None, comparison: dict | None = None) -> Path:
    """The two study files and the comparison file (its studies named relative to its folder)."""
    (tmp_path / "studies").mkdir(exist_ok=True)
    (tmp_path / "tiny.yaml").write_text(yaml.safe_dump(paper or PAPER, sort_keys=False))
    (tmp_path / "studies" / "dwa.yaml").write_text(yaml.safe_dump(dwa or DWA, sort_keys=False))
    path = tmp_path / "cmp.yaml"
    path.write_text(yaml.safe_dump(comparison or COMPARISON, sort_keys=False))
    return path


def compare(*args, timeout=600) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "runners.tune", "--compare", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout, stdin=subprocess.DEVNULL)


def trials_of(study_dir: Path, name: str) -> list[optuna.trial.FrozenTrial]:
    return optuna.load_study(study_name=name, storage=open_storage(study_dir, "sqlite")).get_trials()


def test_comparison_runs_every_study_reports_and_resumes(tmp_path):
    out = tmp_path / "out"
    res = compare(write(tmp_path), "--out", out)
    assert res.returncode == 0, res.stderr
    for name in ("tiny", "tiny_dwa"):
        assert sum(map(counted, trials_of(out / name, name))) == 2
        held = find_logs([out / name / "heldout"])
        assert {p.parent.name for p in held} == {"default", "tuned"}
        assert sorted({int(episode_summary(p)["seed"]) for p in held}) == [100, 101]  # never a training seed
        assert (out / name / "report" / "study.md").exists()
    report = out / "report"
    for name in ("comparison.md", "comparison.csv", "comparison_overall.csv", "comparison.png"):
        assert (report / name).stat().st_size > 0, name
    table = pd.read_csv(report / "comparison.csv")
    assert set(zip(table["study"], table["configuration"], strict=True)) == {
        ("tiny", "published"), ("tiny", "tuned"), ("tiny_dwa", "published"), ("tiny_dwa", "tuned")}
    assert set(table["scenario"]) == {"head_on"} and set(table["quantity"]) == {"score", "success", "time_to_goal_s"}
    assert (table["n"] == 2).all()
    assert ((table["ci_low"] <= table["mean"] + 1e-12) & (table["mean"] <= table["ci_high"] + 1e-12)).all()
    score = table[table["quantity"] == "score"].set_index(["study", "configuration"])
    reference = score.loc[("tiny", "published")]
    assert reference["vs_reference"] == 0 and reference["pairs"] == 2
    for key, row in score.iterrows():  # every seed paired: the mean difference is the difference of the means
        assert math.isclose(row["vs_reference"], row["mean"] - reference["mean"], abs_tol=1e-9), key
    # one scenario: the all-scenario score is that scenario's, and its interval that scenario's bootstrap
    overall = pd.read_csv(report / "comparison_overall.csv").set_index(["study", "configuration"])
    for key, row in score.iterrows():
        for column in ("mean", "ci_low", "ci_high", "vs_reference", "vs_reference_ci_low", "vs_reference_ci_high"):
            assert math.isclose(overall.loc[key, column], row[column], abs_tol=1e-12), (key, column)
    # the comparison's numbers are the studies' own held-out numbers (success, time to goal)
    for name in ("tiny", "tiny_dwa"):
        own = pd.read_csv(out / name / "report" / "heldout.csv").set_index(["metric", "configuration"])
        mine = table[(table["study"] == name) & (table["kind"] == "metric")]
        for _, row in mine.iterrows():
            label = "default" if row["configuration"] == "published" else row["configuration"]
            assert math.isclose(row["mean"], own.loc[(row["quantity"], label), "mean"]), (name, row["quantity"])
    text = (report / "comparison.md").read_text()
    assert "2 trials x 1 scenarios x 2 training seeds (0..1) = 4 episodes" in text and "### head_on" in text
    # re-running continues: no trial and no held-out episode again, the same report
    logs = {p: p.stat().st_mtime_ns for p in find_logs([out])}
    again = compare(tmp_path / "cmp.yaml", "--out", out)
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("already evaluated") == 2
    assert {p: p.stat().st_mtime_ns for p in find_logs([out])} == logs
    pd.testing.assert_frame_equal(pd.read_csv(report / "comparison.csv"), table)
    # a larger budget: one more trial per study, then the held-out evaluation again (the best may have changed)
    more = compare(tmp_path / "cmp.yaml", "--out", out, "--trials", "3")
    assert more.returncode == 0, more.stderr
    assert "already evaluated" not in more.stdout
    assert [sum(map(counted, trials_of(out / n, n))) for n in ("tiny", "tiny_dwa")] == [3, 3]


def test_ctrl_c_is_one_line_and_rerunning_continues(tmp_path):
    path, out = write(tmp_path, paper={**PAPER, "train_seeds": {"start": 0, "count": 6}},
                      dwa={**DWA, "train_seeds": {"start": 0, "count": 6}}), tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "runners.tune", "--compare", str(path), "--out", str(out),
                             "--trials", "50"], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not (out / "tiny" / "trials" / "00001").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    one_line_error(proc.returncode, err, "re-run the command to resume")
    assert not (out / "tiny_dwa").exists()  # the comparison stopped with the first study
    res = compare(path, "--out", out, "--trials", "2")
    assert res.returncode == 0, res.stderr
    assert (out / "report" / "comparison.md").exists()
    assert sum(map(counted, trials_of(out / "tiny_dwa", "tiny_dwa"))) == 2


def test_a_stopped_heldout_evaluation_runs_again_and_a_complete_one_does_not(tmp_path, monkeypatch):
    import runners.tuning.heldout as heldout

    path, out = write(tmp_path), tmp_path / "out"
    real, calls = heldout.run_configuration, []

    def stopped_in_the_second_study(overrides, *args):
        calls.append(list(overrides))
        if "navigator=dwa" in overrides:
            raise KeyboardInterrupt  # Ctrl-C while the second study's default runs on the held-out seeds
        return real(overrides, *args)

    monkeypatch.setattr(heldout, "run_configuration", stopped_in_the_second_study)
    code, _, err = run_main("--compare", str(path), "--out", str(out))
    one_line_error(code, err, "interrupted: comparison tiny_cmp stopped; re-run the command to resume")
    assert code == 130
    assert (out / "tiny" / "heldout" / "evaluated.json").exists()  # the first study's evaluation is complete
    assert not (out / "tiny_dwa" / "heldout" / "evaluated.json").exists() and not (out / "report").exists()
    calls.clear()
    monkeypatch.setattr(heldout, "run_configuration", lambda overrides, *args: calls.append(list(overrides))
                        or real(overrides, *args))
    code, stdout, err = run_main("--compare", str(path), "--out", str(out))
    assert code == 0, err
    assert "held-out: tiny already evaluated" in stdout
    assert calls and all("navigator=dwa" in c for c in calls)  # only the stopped study's configurations ran
    assert (out / "report" / "comparison.md").exists()


MISMATCHES = [  # (change to the second study, words of the error)
    ({"trials": 3}, ["dwa.yaml: trials:", "3 x 2 episodes = 6 episodes differ", "tiny.yaml", "budget"]),
    ({"train_seeds": {"start": 0, "count": 3}}, ["dwa.yaml: train_seeds: 0..2 differ", "tiny.yaml's 0..1"]),
    ({"heldout_seeds": {"start": 200, "count": 2}}, ["dwa.yaml: heldout_seeds: 200..201 differ"]),
    ({"scenarios": ["crossing_right"]}, ["dwa.yaml: scenarios: 'crossing_right' differ", "tiny.yaml's 'head_on'"]),
    ({"objectives": [{"metric": "spl", "direction": "maximize"}]}, ["dwa.yaml: objectives:", "differ"]),
    ({"train_seeds": {"start": 100, "count": 2}, "heldout_seeds": {"start": 0, "count": 2}},
     ["tiny.yaml: train_seeds: 0..1 overlap the held-out seeds 0..1 of", "dwa.yaml"]),
]


@pytest.mark.parametrize(("change", "words"), MISMATCHES)
def test_studies_that_cannot_be_compared_are_one_line_before_any_trial(tmp_path, change, words):
    path = write(tmp_path, dwa={**DWA, **change})
    out = tmp_path / "out"
    code, _, err = run_main("--compare", str(path), "--out", str(out))
    one_line_error(code, err, *words, "cmp.yaml")
    assert code == 2 and not out.exists()  # nothing ran


@pytest.mark.parametrize(("comparison", "words"), [
    ({**COMPARISON, "studies": ["tiny.yaml", "nosuch.yaml"]}, ["cmp.yaml: studies[1]:", "nosuch.yaml"]),
    ({**COMPARISON, "studies": ["tiny.yaml", "tiny.yaml"]}, ["cmp.yaml: studies[1]:", "also studies[0]"]),
    ({**COMPARISON, "reference": "table9"}, ["cmp.yaml: reference:", "table9"]),
    ({**COMPARISON, "studies": []}, ["cmp.yaml: studies:"]),
    ({**COMPARISON, "studies": "tiny.yaml"}, ["cmp.yaml: studies:"]),
    ({**COMPARISON, "studies": ["tiny.yaml", 3]}, ["cmp.yaml: studies[1]:"]),
    ({**COMPARISON, "name": "a b"}, ["cmp.yaml: name:"]),
    ({**COMPARISON, "budget": 4}, ["cmp.yaml: 'budget': unknown field"]),
])
def test_bad_comparison_file_is_one_line_naming_file_and_field(tmp_path, comparison, words):
    path = write(tmp_path, comparison=comparison)
    code, _, err = run_main("--compare", str(path), "--out", str(tmp_path / "out"))
    one_line_error(code, err, *words)
    assert code == 2 and not (tmp_path / "out").exists()


def test_a_study_that_does_not_compose_is_refused_before_any_study_runs(tmp_path):
    # the second study's space reaches a key that does not exist: found before the first study's trials
    path, out = write(tmp_path, dwa={**DWA, "space": ["navigator.margin_cmm=interval(12,30)"]}), tmp_path / "out"
    code, _, err = run_main("--compare", str(path), "--out", str(out))
    one_line_error(code, err, "dwa.yaml: space[0] (navigator.margin_cmm=12", "cmp.yaml")
    assert code == 2 and not list(out.rglob("study.db"))


@pytest.mark.parametrize(("args", "words"), [
    (["tiny", "--compare", "suite_v2"], ["not both"]),
    ([], ["name a study"]),
    (["--compare", "suite_v2", "--no-heldout"], ["--no-heldout"]),
    (["--compare", "nosuch_comparison"], ["nosuch_comparison.yaml"]),
])
def test_bad_command_line_is_one_line(args, words):
    code, _, err = run_main(*args)
    one_line_error(code, err, *words)
    assert code == 2


def test_shipped_comparison_loads_with_one_budget():
    comparison = load_comparison(ROOT / "conf" / "tune" / "compare" / "suite_v2.yaml")
    assert [s.name for s in comparison.studies] == [f"suite_v2_{m}" for m in ("table1", "dwa", "apf", "vfh", "orca")]
    assert comparison.reference.name == "suite_v2_table1" and comparison.budget == 30 * 5 * 4


KNOWN_FIELDS = (*FIELDS, *study_file_module.FIELDS, "YAML", "expected a mapping")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), which=st.sampled_from(["comparison", "study"]),
       raw=st.one_of(st.none(), st.binary(max_size=200)))
def test_fuzzed_comparison_is_a_comparison_or_one_line(tmp_path_factory, data, which, raw):
    tmp = tmp_path_factory.mktemp("fuzz")
    if which == "comparison":
        comparison, steps = data.draw(mutations(COMPARISON))
        path = write(tmp, comparison=comparison)
    else:  # the second study's numbers, names and structure: the checks between studies
        dwa, steps = data.draw(mutations(DWA))
        path = write(tmp, dwa=dwa)
    if raw is not None:
        path.write_bytes(raw)
    try:
        comparison = load_comparison(path)
    except ComparisonFileError as err:
        message = str(err)
        assert "\n" not in message, steps
        assert message.startswith((f"{path}:", f"{tmp / 'tiny.yaml'}:", f"{tmp / 'studies' / 'dwa.yaml'}:")), \
            (message, steps)
        # a file that is not YAML text is wrong as a whole; any other file's problem is in a field
        assert raw is not None or any(field in message for field in KNOWN_FIELDS), (message, steps)
        return
    ref = comparison.reference
    assert ref in comparison.studies and len({s.name for s in comparison.studies}) == len(comparison.studies)
    for spec in comparison.studies:  # a comparison is of studies with one budget and disjoint seeds
        assert (spec.train, spec.heldout, spec.trials, set(spec.scenarios), spec.objectives) == (
            ref.train, ref.heldout, ref.trials, set(ref.scenarios), ref.objectives)
        assert not set(spec.train.seeds) & set(spec.heldout.seeds)
    assert comparison.budget == ref.trials * len(ref.scenarios) * ref.train.count


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(trials=st.integers(1, 3), train=st.tuples(st.integers(0, 101), st.integers(1, 3)),
       heldout=st.tuples(st.integers(0, 101), st.integers(1, 3)))
@example(trials=2, train=(0, 2), heldout=(100, 2))  # the same as the first study: a comparison
@example(trials=3, train=(0, 2), heldout=(100, 2))
def test_fuzzed_budget_and_seeds_give_the_comparison_or_the_field_that_differs(tmp_path_factory, trials, train,
                                                                                 heldout):
    """The second study's trials and seeds drawn near the first's (trials 2, training 0..1, held-out 100..101):
    the comparison loads exactly when they are the same, else the one line names the field that differs."""
    tmp = tmp_path_factory.mktemp("budget")
    path = write(tmp, dwa={**DWA, "trials": trials, "train_seeds": {"start": train[0], "count": train[1]},
                           "heldout_seeds": {"start": heldout[0], "count": heldout[1]}})
    mine, held = set(range(train[0], sum(train))), set(range(heldout[0], sum(heldout)))
    if mine & held:
        expected = ["dwa.yaml: heldout_seeds:", "overlap train_seeds"]  # the study file's own check
    elif mine & set(range(100, 102)) or held & {0, 1}:
        expected = ["train_seeds:", "overlap the held-out seeds"]
    elif train != (0, 2):
        expected = ["dwa.yaml: train_seeds:"]
    elif heldout != (100, 2):
        expected = ["dwa.yaml: heldout_seeds:"]
    elif trials != 2:
        expected = ["dwa.yaml: trials:", "budget of episodes"]
    else:
        assert load_comparison(path).budget == 2 * 1 * 2
        return
    with pytest.raises(ComparisonFileError) as err:
        load_comparison(path)
    message = str(err.value)
    assert "\n" not in message and all(word in message for word in expected), message


def _evaluated(label: str, trial: int | None, episodes: pd.DataFrame, objective) -> Evaluated:
    return Evaluated(label, [], trial, EpisodeResults(episodes, pd.DataFrame(), []),
                     {objective.name: objective_value(episodes, objective)})


def test_all_scenario_score_has_a_stratified_interval_and_a_paired_difference(tmp_path):
    """The methods table's all-scenario score from held-out episodes made by hand (two scenarios of unequal size):
    its mean is the mean of the scenarios' means, its interval the scenario-stratified bootstrap; the difference
    from the reference is paired by scenario and seed; an identical configuration differs by exactly 0."""
    from analysis.objectives import episode_values
    from analysis.stats import stratified_bootstrap_mean
    from runners.tuning.comparison_report import overall_table, write_comparison_report

    two = {**PAPER, "scenarios": ["head_on", "crossing_left"]}
    comparison = load_comparison(write(tmp_path, two, {**DWA, "scenarios": two["scenarios"]}))
    paper, dwa = comparison.studies
    objective = paper.objectives[0]  # success - 0.005 x time to goal (120 s when not reached)
    rng = np.random.default_rng(4)

    def episodes(shift: float, nan_time: bool = False) -> pd.DataFrame:
        rows = [{"scenario": scenario, "seed": 100 + i, "success": float(i % 2 == 0 or i % 3 == 0),
                 "time_to_goal_s": 20.0 + 3 * i + shift} for scenario, n in (("head_on", 3), ("crossing_left", 6))
                for i in range(n)]
        frame = pd.DataFrame(rows)
        frame["time_to_goal_s"] += rng.integers(0, 4, size=len(frame))
        if nan_time:
            frame.loc[1, "time_to_goal_s"] = math.nan
        return frame

    ref_eps = episodes(0.0)
    tuned_eps = ref_eps.copy()
    tuned_eps["time_to_goal_s"] -= 10.0  # 10 s faster on every episode: 0.05 better, paired
    dwa_eps = episodes(5.0)
    results = [(paper, optuna.create_study(), [_evaluated("default", None, ref_eps, objective),
                                               _evaluated("tuned", 3, tuned_eps, objective)]),
               (dwa, optuna.create_study(), [_evaluated("default", None, ref_eps.copy(), objective),
                                             _evaluated("tuned", 1, dwa_eps, objective)])]
    table = overall_table(comparison, results).set_index(["study", "configuration"])
    assert len(table) == 4 and (table["scenarios"] == 2).all() and (table["n"] == 9).all()
    for (study, configuration), row in table.iterrows():
        assert row["ci_low"] <= row["mean"] <= row["ci_high"], (study, configuration)
        assert row["pairs"] == 9
    ref = table.loc[("tiny", "published")]
    by_scenario = [episode_values(ref_eps[ref_eps["scenario"] == s], objective) for s in ("head_on", "crossing_left")]
    assert math.isclose(ref["mean"], (by_scenario[0].mean() + by_scenario[1].mean()) / 2)
    assert (ref["ci_low"], ref["ci_high"]) == stratified_bootstrap_mean([v.tolist() for v in by_scenario])[1:]
    assert ref["ci_low"] < ref["mean"] < ref["ci_high"]
    # the published DWA is here the same episodes as the reference: difference 0, degenerate interval
    same = table.loc[("tiny_dwa", "published")]
    assert (same["vs_reference"], same["vs_reference_ci_low"], same["vs_reference_ci_high"]) == (0.0, 0.0, 0.0)
    tuned = table.loc[("tiny", "tuned")]
    for key in ("vs_reference", "vs_reference_ci_low", "vs_reference_ci_high"):
        assert math.isclose(tuned[key], 0.05, abs_tol=1e-12), key
    assert math.isclose(tuned["mean"] - ref["mean"], 0.05, abs_tol=1e-12)
    other = table.loc[("tiny_dwa", "tuned")]
    assert other["vs_reference_ci_low"] <= other["vs_reference"] <= other["vs_reference_ci_high"]
    assert math.isclose(other["vs_reference"], other["mean"] - ref["mean"], abs_tol=1e-12)  # every seed paired
    # the report: the CSV is the table, the methods table shows each all-scenario score with its interval
    report = write_comparison_report(comparison, tmp_path / "out", results)
    written = pd.read_csv(report.parent / "comparison_overall.csv", keep_default_na=False, na_values=[""])
    written["note"] = written["note"].astype(object).fillna("")
    pd.testing.assert_frame_equal(written.set_index(["study", "configuration"]), table, check_dtype=False)
    text = report.read_text()
    assert f"| {ref['mean']:.4g} [{ref['ci_low']:.4g}, {ref['ci_high']:.4g}] | (reference) |" in text
    assert f"| {0.05:.4g} [{0.05:.4g}, {0.05:.4g}] |" in text
    # an undefined term (no fill) in some episode: the score is the study's, without an interval, and says why
    unfilled = dataclasses.replace(objective, fill=())
    gap = episodes(0.0, nan_time=True)
    comparison_nofill = dataclasses.replace(comparison, reference=dataclasses.replace(paper, objectives=(unfilled,)))
    results = [(comparison_nofill.reference, optuna.create_study(), [_evaluated("default", None, gap, unfilled)])]
    row = overall_table(comparison_nofill, results).iloc[0]
    assert math.isfinite(row["mean"]) and math.isnan(row["ci_low"]) and "undefined" in row["note"]
