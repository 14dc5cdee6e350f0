"""The fuzzy controller's membership functions as a search space (issue #39): coordinates in which every point is
an ordered partition covering the universe, Table 1 as the starting point, a tuned controller file that runs."""

from __future__ import annotations

import itertools
import subprocess
import sys

import numpy as np
import optuna
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzynav.conf import CONF_DIR
from fuzzynav.controller.fuzzy_spec import ControllerSpec, ControllerSpecError, Term, sample_membership
from fuzzynav.controller.partition import MIN_OVERLAP, PartitionError, coordinates_of, partition_terms
from runners.tuning.storage import open_storage
from tests.conftest import ROOT
from tests.test_tune import study_file, tune
from tests.test_tune_bad_inputs import one_line_error, run_main

TABLE1 = yaml.safe_load((CONF_DIR / "controller" / "table1.yaml").read_text())
VARIABLES = [TABLE1["inputs"]["front"], TABLE1["outputs"]["dtheta"], TABLE1["outputs"]["v"]]


@pytest.mark.parametrize("var", VARIABLES, ids=["distance", "dtheta", "v"])
def test_table1_comes_back_exactly_from_its_coordinates(var):
    coords = coordinates_of(var["terms"], var["universe"])
    assert partition_terms(var["terms"], var["universe"], coords) == {
        name: {"mf": t["mf"], "params": [float(p) for p in t["params"]]} for name, t in var["terms"].items()}


def coordinate_values(var):
    names = list(coordinates_of(var["terms"], var["universe"]))
    return st.fixed_dictionaries({n: st.floats(MIN_OVERLAP if n.startswith("overlap") else 0.0, 1.0) for n in names})


@settings(max_examples=150, deadline=None)
@given(data=st.data(), index=st.integers(0, len(VARIABLES) - 1))
def test_every_point_is_an_ordered_covering_partition(data, index):
    var = VARIABLES[index]
    coords = data.draw(coordinate_values(var))
    if not sum(v for k, v in coords.items() if k.startswith("gap")) > 0:
        with pytest.raises(PartitionError):
            partition_terms(var["terms"], var["universe"], coords)
        return
    terms = partition_terms(var["terms"], var["universe"], coords)
    u0, u1 = var["universe"]
    params = [t["params"] for t in terms.values()]
    for p in params:  # each term's breakpoints in order, inside the universe
        assert p == sorted(p) and u0 <= p[0] and p[-1] <= u1
    assert params[0][:2] == [u0, u0] and params[-1][-2:] == [u1, u1]  # the shoulders stay
    for left, right in itertools.pairwise(params):  # terms in order, neighbours overlap
        assert left[0] <= right[0] and left[-1] <= right[-1] and right[0] <= left[-1]
    grid = np.linspace(u0, u1, 2001)
    top = np.max([sample_membership(Term(n, t["mf"], tuple(t["params"])), grid, u1) for n, t in terms.items()], axis=0)
    assert top.min() > 0  # no hole: some term is above zero everywhere
    section = "inputs" if var is VARIABLES[0] else "outputs"
    name = {0: "front", 1: "dtheta", 2: "v"}[index]
    changed = {**TABLE1, section: {**TABLE1[section], name: {**var, "terms": terms}}}
    try:  # the controller's own checks accept it, unless a term is narrower than the grid (a trial fails then)
        ControllerSpec.from_dict(changed)
    except ControllerSpecError as err:
        assert "can never fire" in str(err)
        assert any(t["params"][-1] - t["params"][0] < var["resolution"] for t in terms.values())


def controller_study(tmp_path, out, **controller) -> list[optuna.trial.FrozenTrial]:
    """Run a two-trial random study of the controller alone (no ``space``) into ``out``; its trials."""
    path = study_file(tmp_path, **controller, sampler="random", trials=2)
    text = yaml.safe_load(path.read_text())
    del text["space"]
    path.write_text(yaml.safe_dump(text))
    res = tune(path, "--out", out)
    assert res.returncode == 0, res.stderr
    return optuna.load_study(study_name="tiny", storage=open_storage(out, "sqlite")).get_trials()


def assert_controller_runs(study_dir, controller, tmp_path) -> None:
    """The tuned controller file runs with ``controller=<name>`` and its episodes carry its name."""
    run = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.searchpath=[file://{study_dir}]",
                          f"controller={controller.stem}", f"hydra.run.dir={tmp_path / 'run'}"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert f"__{controller.stem}__" in run.stdout


def test_controller_study_tunes_membership_functions_and_writes_a_runnable_controller(tmp_path):
    out = tmp_path / "study"
    trials = controller_study(tmp_path, out, controller_space=[["left", "front", "right"], ["v"]])
    assert trials[0].user_attrs["default"]  # Table 1 first
    assert "controller.inputs.front.terms.near.params=[0.0,0.0,30.0,60.0]" in trials[0].user_attrs["overrides"]
    assert any(o.startswith("controller.outputs.v.terms.fast.params=") for o in trials[1].user_attrs["overrides"])
    assert (out / "report" / "membership.png").stat().st_size > 0
    (controller,) = (out / "controller").glob("*.yaml")
    assert_controller_runs(out, controller, tmp_path)


@pytest.mark.parametrize(("field", "value", "words"), [
    ("controller_space", [["left", "sideways"]], ["controller_space[0]", "sideways", "not a variable"]),
    ("controller_space", [["angle"]], ["crisp terms are not tuned"]),
    ("controller_space", [["left", "dtheta"]], ["controller_space[0]", "other terms"]),
    ("controller_space", [["left"], ["left"]], ["controller_space[1]", "named twice"]),
    ("controller_space", "left", ["controller_space", "expected a list"]),
    ("controller_rules", ["steer"], ["controller_rules", "steer", "not an output"]),
    ("controller_rules", ["v", "v"], ["controller_rules", "named twice"]),
    ("controller_rules", "v", ["controller_rules", "expected a list"]),
])
def test_bad_controller_space_or_rules_is_one_line(tmp_path, field, value, words):
    path = study_file(tmp_path, **{field: value})
    code, _, err = run_main(str(path), "--out", str(tmp_path / "study"))
    one_line_error(code, err, str(path), *words)
    assert code == 2


def table1_rule_outputs() -> dict[str, str]:
    """Table 1's rule outputs as the rule space's parameter values, read from conf/controller/table1.yaml."""
    out = {}
    for i, rule in enumerate(TABLE1["rules"]):
        for clause in rule.split("->")[1].split(","):
            var, term = (s.strip() for s in clause.split("="))
            out[f"rule~{i}.{var}"] = term
    return out


def test_rule_study_searches_rule_outputs_from_table1_and_writes_a_runnable_controller(tmp_path):
    out = tmp_path / "study"
    trials = controller_study(tmp_path, out, controller_rules=["dtheta", "v"])
    start = table1_rule_outputs()
    assert len(start) == 2 * len(TABLE1["rules"])
    assert trials[0].user_attrs["default"] and trials[0].params == start  # Table 1 as published first
    dists = trials[1].distributions
    assert list(dists["rule~0.dtheta"].choices) == list(TABLE1["outputs"]["dtheta"]["terms"])
    assert list(dists["rule~5.v"].choices) == list(TABLE1["outputs"]["v"]["terms"])
    assert trials[1].params != start  # a random point of 56 categories is not Table 1
    (rules,) = [o for o in trials[1].user_attrs["overrides"] if o.startswith("controller.rules=")]
    assert rules.count("->") == len(TABLE1["rules"])
    (controller,) = (out / "controller").glob("*.yaml")
    written = yaml.safe_load(controller.read_text())
    best = max((t for t in trials if t.state.name == "COMPLETE"), key=lambda t: t.values[0])
    for i, rule in enumerate(written["rules"]):  # the tuned rules: the antecedents of Table 1, the best outputs
        ante, _, cons = rule.partition(" -> ")
        assert ante == TABLE1["rules"][i].split("->")[0].strip()
        assert cons == f"dtheta={best.params[f'rule~{i}.dtheta']}, v={best.params[f'rule~{i}.v']}"
    assert written["inputs"]["front"]["terms"] == TABLE1["inputs"]["front"]["terms"]
    report = (out / "report" / "study.md").read_text()
    if best.params != start:  # the report lists the changed rules beside Table 1's
        assert "## Rule outputs beside the base controller's" in report
    assert_controller_runs(out, controller, tmp_path)
