"""A parameter of a part that is off changes nothing an episode does: h_wait under the strategies that do not read it
(wait, detour, none) and every planner parameter under ``planner=none``. That is why log file names and report
groups leave them out (:func:`fuzzynav.params.names.reads_h_wait`, :func:`analysis.run_parameters.parameters_of`):
pooling such episodes pools the same behaviour, not different settings."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, reject, settings
from hypothesis import strategies as st

from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode import Episode
from fuzzynav.params import limits
from fuzzynav.params.names import PLANNER_OFF, READS_H_WAIT, STRATEGIES, reads_h_wait
from tests.conftest import load_controller, load_scenario

EVALUATOR = FastEvaluator(load_controller("table1"))
SCENARIOS = ("head_on", "crossing_right", "overtaking", "multi_crossing", "mixed", "paper_fig5")
STEPS = 60  # enough for the wait/detour layer to act on each scenario


def behaviour(scenario: str, seed: int, planner: dict[str, Any]) -> list[tuple]:
    """Everything an episode does, step by step, as exact values: the robot's states, the command (mode, steering,
    speed), the plan's path, contacts and the outcome (not the logged copy of the config, which names h_wait)."""
    episode = Episode(load_scenario(scenario), EVALUATOR, episode_config_from_dict({"planner": planner}), seed=seed)
    out = []
    for record in episode.run():
        d = record.decision
        path = d.plan.path.tobytes() if d.plan is not None else b""
        out.append((dataclasses.astuple(record.next_state), d.mode, d.dtheta_deg, d.v_cm_s, path,
                    record.contact_static, record.contact_dynamic, record.outcome))
        if record.step >= STEPS:
            break
    return out


def test_the_names_agree_with_the_planner():
    assert set(READS_H_WAIT) < set(STRATEGIES) and PLANNER_OFF in STRATEGIES
    assert reads_h_wait("auto") and not reads_h_wait("wait") and not reads_h_wait("none")
    assert reads_h_wait("from_a_damaged_log")  # unknown: kept as a dimension


@settings(max_examples=24, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenario=st.sampled_from(SCENARIOS), seed=st.integers(0, 50),
       strategy=st.sampled_from([s for s in STRATEGIES if not reads_h_wait(s)]),
       h_wait=st.integers(0, 20))
def test_h_wait_changes_nothing_where_it_is_not_read(scenario, seed, strategy, h_wait):
    assert behaviour(scenario, seed, {"strategy": strategy, "h_wait": h_wait}) == \
        behaviour(scenario, seed, {"strategy": strategy, "h_wait": 2})


def _planner_values() -> st.SearchStrategy[dict[str, Any]]:
    """Any valid values of the planner's numeric parameters (their documented ranges)."""
    fields = {}
    for key, rng in limits.FIELD_RANGES.items():
        section, _, name = key.partition(".")
        if section != "planner" or key in limits.FIELD_MAX_ITEMS:
            continue
        hi = min(rng.hi, 200)  # beyond that the run only takes longer
        lo = rng.lo + (1e-3 if rng.lo_open else 0)
        fields[name] = st.integers(int(np.ceil(lo)), int(hi)) if rng.integer else st.floats(lo, hi)
    return st.fixed_dictionaries({}, optional=fields)


@settings(max_examples=24, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenario=st.sampled_from(SCENARIOS), seed=st.integers(0, 50), values=_planner_values(),
       switches=st.fixed_dictionaries({}, optional={
           "swept_tpt": st.booleans(), "fallbacks": st.booleans(), "recheck_plan": st.booleans(),
           "phi_low_rule": st.sampled_from(["paper", "target_side", "toward_goal"]),
           "detour_search": st.sampled_from(["greedy", "astar"])}))
def test_no_planner_parameter_changes_anything_under_planner_none(scenario, seed, values, switches):
    try:  # values the checks refuse (a cruise speed the robot cannot drive) are a config error, not an episode
        episode_config_from_dict({"planner": {"strategy": PLANNER_OFF, **values, **switches}})
    except ValueError:
        reject()
    assert behaviour(scenario, seed, {"strategy": PLANNER_OFF, **values, **switches}) == \
        behaviour(scenario, seed, {"strategy": PLANNER_OFF})
