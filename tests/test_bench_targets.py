"""runners.benchmarks.targets (issue #19's and issue #36's targets from one bench run) and
runners.benchmarks.baseline's refusal paths."""

from __future__ import annotations

import copy

import pytest

from runners.benchmarks import baseline as bench_baseline
from runners.benchmarks.targets import Target, main_job_targets, print_targets, targets

RESULTS = {
    "fuzzy": [{"controller": "table1", "peers": [{"engine": "ferrifuzz", "installed": True},
                                                 {"engine": "pyfuzzylite", "installed": True}],
               "single_over_ferrifuzz": 0.14, "batch_per_core_over_ferrifuzz": 0.13,
               "max_disagreement_dtheta_deg": 1.7e-13, "max_disagreement_v_cm_s": 3.5e-14}],
    "baseline": {"measured": True, "commit": bench_baseline.ISSUE_19_COMMIT, "logged_ratio": 2.2, "plain_ratio": 2.6},
    "crowd": [{"model": "scripted", "steps_per_s_with_logging": 1200.0},
              {"model": "social_force", "steps_per_s_with_logging": 760.0}],
    "analysis": {"episodes_per_s": 226.0},
    "report": {"synthetic": {"episodes": 10_000, "total_s_estimate": 23.2}},
    "memory": {"episodes": 1000, "growth": 0.0},
}


def by_name(rows: list[Target]) -> dict[str, Target]:
    return {t.name: t for t in rows}


def _with(results: dict, path: tuple, value: object) -> dict:
    """A copy of ``results`` with the figure at ``path`` (keys and indices) set to ``value``."""
    results = copy.deepcopy(results)
    node = results
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return results


def test_every_target_of_a_good_run_is_met():
    rows = targets(RESULTS)
    assert len(rows) == 9 and all(t.met for t in rows), [t.line() for t in rows if not t.met]
    assert "(target >= 2: 1.1 of it) — met" in by_name(rows)["3 logged step vs commit c90ff86 (side by side)"].line()


@pytest.mark.parametrize(("path", "value", "name"), [
    (("fuzzy", 0, "single_over_ferrifuzz"), 1.01, "2 single decision ours / ferrifuzz (table1)"),
    (("fuzzy", 0, "max_disagreement_v_cm_s"), 2e-9, "2 agreement with scikit-fuzzy (table1)"),
    (("baseline", "logged_ratio"), 1.99, "3 logged step vs commit c90ff86 (side by side)"),
    (("crowd", 1, "steps_per_s_with_logging"), 499.0, "3 crowds, 20 pedestrians, slowest model"),
    (("analysis", "episodes_per_s"), 199.9, "4 analysis, one process"),
    (("report", "synthetic", "total_s_estimate"), 60.5, "4 report of 10000 episodes"),
    (("memory", "growth"), 0.06, "4 RSS growth over 1000 episodes"),
])
def test_a_missed_target_is_reported_not_met(path, value, name):
    target = by_name(targets(_with(RESULTS, path, value)))[name]
    assert target.met is False and "NOT met" in target.line()


def test_a_missing_measurement_is_never_met():
    results = copy.deepcopy(RESULTS)
    results["baseline"] = {"measured": False, "commit": bench_baseline.ISSUE_19_COMMIT, "why": "no git"}
    results["fuzzy"][0]["peers"] = [{"engine": "ferrifuzz", "installed": False}]
    del results["fuzzy"][0]["single_over_ferrifuzz"], results["fuzzy"][0]["batch_per_core_over_ferrifuzz"]
    rows = by_name(targets(results))
    for name in ("3 logged step vs commit c90ff86 (side by side)", "1 peers in the table (table1)",
                 "2 single decision ours / ferrifuzz (table1)", "2 batch per core ours / ferrifuzz (table1)"):
        assert rows[name].met is None and "not measured" in rows[name].line(), name
    assert "no git" in rows["3 logged step vs commit c90ff86 (side by side)"].line()


def test_baseline_of_an_unknown_commit_is_not_measured():
    result = bench_baseline.bench_baseline("0" * 40, rounds=1, episodes=1, passes=1)
    assert result["measured"] is False and "0000000000" in result["why"]


def test_baseline_outside_a_checkout_is_not_measured(monkeypatch, tmp_path):
    monkeypatch.setattr(bench_baseline, "ROOT", tmp_path)
    result = bench_baseline.bench_baseline(rounds=1, episodes=1, passes=1)
    assert result["measured"] is False and "not a git checkout" in result["why"]


def test_baseline_child_refuses_modules_from_outside_its_tree(tmp_path):
    """A module the earlier tree lacks would be found in this checkout by the editable install's finder: the
    measurement would then time a mix of the two trees. The child imports from the tree alone and fails."""
    try:
        tree = bench_baseline.baseline_tree(bench_baseline.ISSUE_19_COMMIT, tmp_path)
    except bench_baseline.BaselineUnavailable as err:  # e.g. a shallow clone
        pytest.skip(str(err))
    (tree / "fuzzynav" / "kinematics.py").unlink()  # a module at the same place in this checkout
    with pytest.raises(RuntimeError, match=r"fuzzynav\.kinematics"):
        bench_baseline._measure(tree, 1, 1)


def test_baseline_that_cannot_run_is_not_measured_and_says_why(monkeypatch, tmp_path):
    """A tree that fails in its child (here: no conf) is a "not measured" line, not a crash that loses the bench's
    other results."""
    def broken_tree(commit, dest):
        for package in ("fuzzynav", "runners"):
            (dest / package).mkdir()
            (dest / package / "__init__.py").write_text("raise ImportError('this tree is broken')\n")
        return dest
    monkeypatch.setattr(bench_baseline, "baseline_tree", broken_tree)
    result = bench_baseline.bench_baseline(rounds=1, episodes=1, passes=1)
    assert result["measured"] is False and "this tree is broken" in result["why"]


@pytest.mark.parametrize("commit", ["--output=/tmp/x.tar", "-h", "", "a b", "HEAD;rm", "x" * 300])
def test_baseline_commit_is_never_an_option_of_git(commit, tmp_path):
    result = bench_baseline.bench_baseline(commit, rounds=1, episodes=1, passes=1)
    assert result["measured"] is False and "is not a commit name" in result["why"]
    assert not (tmp_path / "x.tar").exists()


@pytest.mark.parametrize(("args", "field"), [(["--rounds", "0"], "--rounds"), (["--rounds", "x"], "--rounds"),
                                             (["--episodes", "1e9"], "--episodes"), (["--passes", "-1"], "--passes"),
                                             (["--nope"], "--nope")])
def test_baseline_cli_refuses_bad_arguments_in_one_line(args, field, capsys):
    with pytest.raises(SystemExit) as stop:
        bench_baseline.main(args)
    err = capsys.readouterr().err.strip().splitlines()
    assert stop.value.code == 2 and len(err) == 1 and err[0].startswith("error: ") and field in err[0], err


def test_baseline_of_a_commit_with_kernels_builds_and_runs_them():
    """``--commit HEAD`` (a commit with compiled kernels) was "not measured: modules not from the tree": the tree had
    no built kernels and the editable install supplied this checkout's. Now the commit's own kernels are built
    from its sources, and the same code measures the same on both sides."""
    result = bench_baseline.bench_baseline("HEAD", rounds=1, episodes=1, passes=1)
    if not result["measured"] and "git" in result["why"]:
        pytest.skip(result["why"])
    assert result["measured"], result.get("why")
    earlier, this = (result["per_round"][0][name]["kernels"] for name in ("earlier", "this"))
    if result["kernels_not_built"]:  # no C compiler here: the earlier side ran its Python forms, and says so
        assert earlier == []
    else:
        assert earlier == this


# issue #36's targets (runners.benchmarks.targets.main_job_targets), read off the main job's sections

JOB = {"cores": 2, "sweep_efficiency": 0.85, "episodes_phase_efficiency": 0.9, "simulated_cores": 16,
       "simulated_sweep_efficiency": 0.82, "first_step_s": 0.3, "report_over_metrics": 0.6}
LARGE = {"cores": 2, "sweep_efficiency": 0.88, "simulated_cores": 16, "simulated_sweep_efficiency": 0.81}
KERNELS = {"rounds": 2, "gain": {"default sweep": {"_raycast": 1.35, "_orca": 1.0, "all off": 1.4},
                                 "orca crowd sweep (docs/crowds.md)": {"_raycast": 1.1, "_orca": 3.7, "all off": 4.1}}}
MAIN_JOB = {"machine": {"kernels_built": {"_raycast": True, "_orca": True}}, "main_job": JOB, "large_sweep": LARGE,
            "kernels": KERNELS}
DEFAULT_SWEEP = "sweep efficiency, the default sweep as a whole command"
LARGE_SWEEP = "sweep efficiency, a 1,000-episode sweep as a whole command"
FIRST_STEP = "time to the first step of runners.run"
REPORT = "analysis.report / the metrics alone (episodes/s)"
DEFAULT_LOGS = "the default sweep's logs"


def by_key(rows: list[Target]) -> dict[tuple[str, str], Target]:
    return {(t.name, t.note): t for t in rows}


def test_issue_36_targets_of_a_good_run_are_met_with_their_thresholds():
    rows = main_job_targets(MAIN_JOB)
    assert all(t.met for t in rows), [t.line() for t in rows if not t.met]
    got = by_key(rows)
    assert got[(DEFAULT_SWEEP, "2 cores")].threshold == 0.8 and got[(DEFAULT_SWEEP, "2 cores")].higher
    assert got[(LARGE_SWEEP, "2 cores")].value == 0.88 and got[(LARGE_SWEEP, "2 cores")].threshold == 0.8
    assert got[(FIRST_STEP, "")].threshold == 0.5 and got[(FIRST_STEP, "")].sign == "<"
    assert got[(REPORT, DEFAULT_LOGS)].threshold == 0.5
    # a kernel's best gain is over the workloads, and names the workload; "all off" is not a kernel
    assert got[("kernel _raycast, best end-to-end gain", "default sweep")].value == 1.35
    assert got[("kernel _orca, best end-to-end gain", "orca crowd sweep (docs/crowds.md)")].value == 3.7
    assert [t.name for t in rows if t.name.startswith("kernel ")] == ["kernel _raycast, best end-to-end gain",
                                                                      "kernel _orca, best end-to-end gain"]
    assert "(target < 0.5: 0.6 of it) — met" in got[(FIRST_STEP, "")].line()


@pytest.mark.parametrize(("path", "value", "key"), [
    (("main_job", "sweep_efficiency"), 0.79, (DEFAULT_SWEEP, "2 cores")),
    (("main_job", "simulated_sweep_efficiency"), 0.5, (DEFAULT_SWEEP, "16 cores, simulated schedule")),
    (("large_sweep", "sweep_efficiency"), 0.799, (LARGE_SWEEP, "2 cores")),
    (("main_job", "first_step_s"), 0.5, (FIRST_STEP, "")),  # "under 0.5 s": 0.5 itself misses it
    (("main_job", "first_step_s"), 1.2, (FIRST_STEP, "")),
    (("main_job", "report_over_metrics"), 0.49, (REPORT, DEFAULT_LOGS)),
    (("kernels", "gain", "default sweep", "_raycast"), 1.29, ("kernel _raycast, best end-to-end gain",
                                                             "default sweep")),  # its best: 1.1 on the other
])
def test_an_issue_36_target_missed_is_not_met(path, value, key):
    target = by_key(main_job_targets(_with(MAIN_JOB, path, value)))[key]
    assert target.met is False and "NOT met" in target.line() and target.value == value


@pytest.mark.parametrize(("path", "value", "key"), [
    (("main_job", "sweep_efficiency"), 0.8, (DEFAULT_SWEEP, "2 cores")),  # ">= 0.8"
    (("large_sweep", "sweep_efficiency"), 0.8, (LARGE_SWEEP, "2 cores")),
    (("main_job", "first_step_s"), 0.4999, (FIRST_STEP, "")),
    (("main_job", "report_over_metrics"), 0.5, (REPORT, DEFAULT_LOGS)),
    (("kernels", "gain", "default sweep", "_raycast"), 1.3, ("kernel _raycast, best end-to-end gain",
                                                            "default sweep")),
])
def test_an_issue_36_target_at_its_threshold(path, value, key):
    assert by_key(main_job_targets(_with(MAIN_JOB, path, value)))[key].met is True


def test_a_quick_run_has_issue_36_targets_not_measured_never_met(capsys):
    results = {**copy.deepcopy(MAIN_JOB), "quick": True}
    del results["large_sweep"], results["kernels"]
    rows = main_job_targets(results)
    absent = [t for t in rows if t.value is None]
    assert {t.name for t in absent} == {LARGE_SWEEP, "kernel _raycast, best end-to-end gain",
                                        "kernel _orca, best end-to-end gain"}
    assert all(t.met is None and "--quick" in t.note and "not measured" in t.line() for t in absent)
    assert all(t.met for t in rows if t.value is not None)
    print_targets(results)
    out = capsys.readouterr().out
    assert "issue #36 targets (the main job): 5 of 8 met in this run" in out
    assert f"  {LARGE_SWEEP}: not measured (no large_sweep in a --quick run: the full run measures it)" in out


def test_issue_36_targets_without_the_main_job_are_rows_not_measured():
    rows = main_job_targets({})
    assert [t.name for t in rows] == [DEFAULT_SWEEP, FIRST_STEP, REPORT, LARGE_SWEEP,
                                      "each kernel's best end-to-end gain"]
    assert all(t.value is None and t.met is None and "this run's results" in t.note for t in rows)


def test_a_kernel_not_built_is_not_measured_and_says_why():
    results = copy.deepcopy(MAIN_JOB)
    results["machine"]["kernels_built"]["_tracking"] = False  # no C compiler for it: the kernels' table lacks it
    target = by_key(main_job_targets(results))[("kernel _tracking, best end-to-end gain",
                                                "not built at install (no C compiler?)")]
    assert target.met is None and target.value is None


def test_a_target_as_bench_json_holds_it():
    strict = Target(FIRST_STEP, 0.5, 0.5, False, "s", strict=True)
    assert strict.as_dict() == {"name": FIRST_STEP, "value": 0.5, "threshold": 0.5, "higher_is_better": False,
                                "sign": "<", "unit": "s", "met": False, "note": ""}
    assert Target("x", None, 2.0, True, "").as_dict()["met"] is None
    assert [Target("x", 1.0, 1.0, h, "", strict=s).sign for h in (True, False) for s in (False, True)] == [
        ">=", ">", "<=", "<"]


@pytest.mark.parametrize("built, settings", [({"_orca": True}, ["_orca"]),
                                             ({"_orca": True, "_b": True, "_c": False}, ["_orca", "_b", "all off"])])
def test_the_kernels_table_times_all_off_only_when_it_differs_from_one_kernel_off(monkeypatch, built, settings):
    """With one kernel built, "all off" would be that kernel off timed twice; with several it is a setting of its
    own. A kernel not built is not timed. (A trivial command stands in for the documented workloads.)"""
    from fuzzynav.numerics import compiled
    from runners.benchmarks.main_job import bench_kernels

    monkeypatch.setattr(compiled, "built", lambda: built)
    result = bench_kernels(rounds=1, workloads=(("json help", ("json.tool", "--help")),))
    assert list(result["medians_s"]["json help"]) == ["all on", *settings]
    assert list(result["gain"]["json help"]) == settings


def test_the_report_on_the_1000_episode_sweeps_logs_is_a_target_row_of_its_own():
    large = {**LARGE, "episodes": 1008, "report_over_metrics": 0.7}
    got = by_key(main_job_targets({**MAIN_JOB, "large_sweep": large}))
    assert got[(REPORT, "the 1008 episodes' logs")].met and got[(REPORT, "the 1008 episodes' logs")].value == 0.7
    assert got[(REPORT, DEFAULT_LOGS)].value == 0.6  # the default sweep's row stays apart
    missed = by_key(main_job_targets({**MAIN_JOB, "large_sweep": {**large, "report_over_metrics": 0.49}}))
    assert missed[(REPORT, "the 1008 episodes' logs")].met is False
    assert (REPORT, "the 1008 episodes' logs") not in by_key(main_job_targets(MAIN_JOB))  # an earlier bench.json
