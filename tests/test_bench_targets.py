"""runners.benchmarks.targets (issue #19's targets from one bench run) and runners.benchmarks.baseline's refusal
paths."""

from __future__ import annotations

import copy

import pytest

from runners.benchmarks import baseline as bench_baseline
from runners.benchmarks.targets import Target, targets

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
    results = copy.deepcopy(RESULTS)
    node = results
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    target = by_name(targets(results))[name]
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
