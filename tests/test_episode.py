"""End-to-end episodes: head-on avoidance, determinism, outcomes, contacts."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from fuzzynav.config import episode_config_from_dict
from fuzzynav.episode import Episode, EpisodeConfig
from fuzzynav.planning.planner import PlannerConfig
from fuzzynav.sensing.perception import PerceptionConfig
from tests.conftest import load_scenario


def run(scenario, controller, seed=0, **cfg):
    ep = Episode(scenario, controller, episode_config_from_dict(cfg), seed=seed)
    records = list(ep.run())
    return ep, records


@pytest.mark.parametrize("mode", ["laser", "ground_truth"])
def test_head_on_is_avoided_with_auto_and_hit_with_none(mode, table1):
    s = load_scenario("head_on")
    ep, recs = run(s, table1, planner={"strategy": "auto"}, perception={"mode": mode})
    assert ep.outcome == "goal" and ep.contacts == 0
    assert any(r.decision.mode == "detour" for r in recs)
    ep, recs = run(s, table1, planner={"strategy": "none"}, perception={"mode": mode})
    assert ep.outcome == "collision" and recs[-1].contact_dynamic == ("walker",)
    assert all(r.decision.tpt is None for r in recs)


def test_records_are_deterministic(table1):
    s = load_scenario("head_on")
    cfg = EpisodeConfig(perception=PerceptionConfig(mode="ground_truth", position_noise_std_cm=2.0),
                        laser=dataclasses.replace(EpisodeConfig().laser, noise_std_cm=1.0))
    a = list(Episode(s, table1, cfg, seed=7).run())
    b = list(Episode(s, table1, cfg, seed=7).run())
    c = list(Episode(s, table1, cfg, seed=8).run())
    assert len(a) == len(b)
    for ra, rb in zip(a, b, strict=True):
        assert ra.state == rb.state and ra.next_state == rb.next_state and ra.decision.mode == rb.decision.mode
        np.testing.assert_array_equal(ra.scan.ranges, rb.scan.ranges)
        assert ra.tracks == rb.tracks
    assert any(not np.array_equal(x.scan.ranges, y.scan.ranges) for x, y in zip(a, c, strict=False))


def test_contacts_counted_when_not_terminating(table1):
    s = load_scenario("head_on")
    ep, recs = run(s, table1, planner={"strategy": "none"}, terminate_on_collision=False)
    assert ep.outcome in ("goal", "timeout")
    assert ep.contacts >= 1 and sum(r.new_contacts for r in recs) == ep.contacts


def test_every_episode_ends_with_a_defined_outcome(table1, listing):
    s = load_scenario("head_on")
    for controller in (table1, listing):
        for strategy in ("auto", "wait", "detour", "none"):
            ep, recs = run(s, controller, planner={"strategy": strategy})
            assert ep.outcome in ("goal", "collision", "timeout")
            assert recs[-1].outcome == ep.outcome and all(r.outcome is None for r in recs[:-1])


def test_wait_strategy_waits(table1):
    """A crossing obstacle with the wait-only strategy: the robot stands still at some step."""
    from fuzzynav.scenarios.scenario import scenario_from_dict
    s = scenario_from_dict({
        "bounds": [0, 0, 1200, 800], "robot": {"start": [100, 400], "goal": [1100, 400]},
        "dynamic_obstacles": [{"id": "x", "radius": 20, "start": [500, 20], "velocity": [0, 25]}],
        "max_steps": 100})
    ep, recs = run(s, table1, planner={"strategy": "wait"}, perception={"mode": "ground_truth"})
    assert ep.outcome == "goal"
    assert any(r.decision.mode == "wait" and r.decision.v_cm_s == 0 for r in recs)
    ep, _ = run(s, table1, planner={"strategy": "none"}, perception={"mode": "ground_truth"})
    assert ep.outcome == "collision"  # the wait was needed


def test_config_from_dict_rejects_unknown_and_wrong_types():
    with pytest.raises(ValueError, match=r"planner\.h_wiat: unknown key"):
        episode_config_from_dict({"planner": {"h_wiat": 2}})
    with pytest.raises(ValueError, match=r"planner\.h_wait: expected an integer"):
        episode_config_from_dict({"planner": {"h_wait": "two"}})
    assert episode_config_from_dict({"planner": {"successor_speeds": [10, 30]}}).planner.successor_speeds == (10, 30)
    # a planned speed the robot cannot drive (v_min 10) is refused, not clamped behind the table's back
    with pytest.raises(ValueError, match=r"planner\.successor_speeds\[0\]: 5 cm/s is outside the robot's speed range"):
        episode_config_from_dict({"planner": {"successor_speeds": [5, 10]}})
    assert episode_config_from_dict({"robot": {"v_min": 5.0}, "planner": {"successor_speeds": [5, 10]}})
    assert isinstance(PlannerConfig(), PlannerConfig)
