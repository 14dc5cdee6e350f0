"""Every row of the paper's Table 1, and the controller-definition errors."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.controller.fuzzy_spec import ControllerSpec, ControllerSpecError, sample_membership
from tests.conftest import CONF, load_yaml

CORE = {"near": 15.0, "medium": 65.0, "far": 115.0}  # cm: membership 1 in exactly one term
ANGLE = {"right": 45.0, "left": 135.0}  # degrees

TABLE1 = [  # (left, front, right, angle or None) -> (dtheta term, v term), transcribed from the paper
    ("near", "near", "near", "right", "NB", "slow"), ("near", "near", "medium", None, "NS", "slow"),
    ("near", "near", "far", None, "NB", "slow"), ("near", "medium", "near", None, "ZE", "slow"),
    ("near", "medium", "medium", None, "NS", "medium"), ("near", "medium", "far", None, "NS", "medium"),
    ("near", "far", "near", None, "ZE", "medium"), ("near", "far", "medium", None, "ZE", "medium"),
    ("near", "far", "far", None, "NS", "medium"), ("medium", "near", "near", None, "PB", "slow"),
    ("medium", "near", "medium", None, "NB", "slow"), ("medium", "near", "far", None, "NB", "slow"),
    ("medium", "medium", "near", None, "PS", "medium"), ("medium", "medium", "medium", None, "ZE", "slow"),
    ("medium", "medium", "far", None, "NS", "medium"), ("medium", "far", "near", None, "ZE", "medium"),
    ("medium", "far", "medium", None, "ZE", "fast"), ("medium", "far", "far", None, "ZE", "fast"),
    ("far", "near", "near", None, "PB", "slow"), ("far", "near", "medium", None, "PB", "slow"),
    ("far", "near", "far", None, "NB", "slow"), ("far", "medium", "near", None, "PS", "medium"),
    ("far", "medium", "medium", None, "PS", "medium"), ("far", "medium", "far", None, "NS", "medium"),
    ("far", "far", "near", None, "PS", "medium"), ("far", "far", "medium", None, "ZE", "fast"),
    ("far", "far", "far", None, "ZE", "fast"), ("near", "near", "near", "left", "PB", "slow"),
]


def test_definition_has_the_28_rules_of_table1(table1):
    assert len(table1.rules) == 28
    got = set()
    for rule in table1.rules:
        a = dict(rule.antecedent)
        c = dict(rule.consequent)
        got.add((a["left"], a["front"], a["right"], a.get("angle"), c["dtheta"], c["v"]))
    assert got == set(TABLE1)


def _best_term(spec: ControllerSpec, role: str, value: float) -> str:
    var = spec.output_for(role)
    grid = np.array([value])
    mu = {t.name: float(sample_membership(t, grid, var.universe[1])[0]) for t in var.terms}
    return max(mu, key=mu.get)


@pytest.mark.parametrize("row", TABLE1, ids=[f"row{i + 1}" for i in range(28)])
def test_each_row_at_term_cores_gives_its_output_term(row, table1):
    left, front, right, angle, dterm, vterm = row
    angles = [ANGLE[angle]] if angle else list(ANGLE.values())
    ev = FastEvaluator(table1)
    for a in angles:
        if (left, front, right) == ("near", "near", "near") and angle is None:
            continue
        d, v = ev.evaluate({"left": CORE[left], "front": CORE[front], "right": CORE[right], "angle": a})
        assert _best_term(table1, "dtheta", d) == dterm, (row, d)
        assert _best_term(table1, "v", v) == vterm, (row, v)
        sign = {"NB": -1, "NS": -1, "ZE": 0, "PS": 1, "PB": 1}[dterm]
        if sign == 0:
            assert abs(d) < 1e-6
        else:
            assert np.sign(d) == sign
            big = dterm.endswith("B")
            assert (abs(d) > 60) if big else (10 < abs(d) < 60), (row, d)


def _table1_data() -> dict:
    return load_yaml(CONF / "controller" / "table1.yaml")


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d["rules"].__setitem__(0, "left=nearish & front=near -> dtheta=NB, v=slow"), "rules[0]"),
    (lambda d: d["inputs"]["left"]["terms"].__setitem__("near", {"mf": "trap", "params": [0, 30, 20, 60]}),
     "inputs.left.terms.near.params"),
    (lambda d: d["outputs"].__setitem__("left", d["outputs"].pop("v")), "outputs.left"),
    (lambda d: d.__setitem__("rules", []), "rules"),
    (lambda d: d["inputs"]["left"]["terms"]["near"].__setitem__("mf", "bell"), "inputs.left.terms.near.mf"),
    (lambda d: d["inputs"]["left"].__setitem__("sauce", "left"), "inputs.left.sauce"),
    (lambda d: d["rules"].__setitem__(3, "left=near -> dtheta=HUGE"), "rules[3]"),
])
def test_malformed_definitions_name_the_field(mutate, field):
    data = copy.deepcopy(_table1_data())
    # YAML anchors share the terms mapping between left/front/right: unshare before mutating
    for v in data["inputs"].values():
        v["terms"] = copy.deepcopy(v["terms"])
    mutate(data)
    with pytest.raises(ControllerSpecError) as err:
        ControllerSpec.from_dict(data)
    assert str(err.value).startswith(field), str(err.value)


def test_listing_controller_has_same_interface(listing, table1):
    assert {v.role for v in listing.outputs} == {"dtheta", "v"}
    ev = FastEvaluator(listing)
    d, v = ev.evaluate({"SL": 25.0, "SS": 1.0, "SR": 3.0})  # front blocked, left open -> hard left, slow
    assert d > 45 and v < 20
    d, v = ev.evaluate({"SL": 25.0, "SS": 25.0, "SR": 25.0})  # all open -> straight, fast
    assert abs(d) < 5 and v > 30
