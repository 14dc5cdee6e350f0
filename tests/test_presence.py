"""Obstacle presence (issue #38 item 1): moving obstacles that come and go. An absent obstacle is not sensed (laser,
sonar, ground truth), cannot be touched, is avoided by no pedestrian and is in no metric; the log records presence
(``present``/``next_present`` of ``/obstacles/truth``) only where a model has it, and the log check verifies it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.json_checks import CheckError
from analysis.log_check import check_message, messages_acceptable
from analysis.logs import iter_messages
from analysis.metrics import metrics_table
from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode import Episode
from fuzzynav.kinematics import RobotState
from fuzzynav.pedestrians.base import MODELS, CrowdView
from fuzzynav.pedestrians.crowd import Crowd
from fuzzynav.scenarios.scenario import scenario_from_dict
from fuzzynav.scenarios.world import World
from runners.run import run_episode
from tests.handmade import rewrite_log


@dataclass(frozen=True)
class BlinkConfig:
    """Present from step ``appear`` to step ``leave`` (excluded)."""

    appear: int = 0
    leave: int = 1_000_000


class Blink:
    """Stays at its start, reporting its scenario velocity (so that ground-truth perception reports it as moving);
    in the world only for steps appear .. leave - 1."""

    config_class = BlinkConfig

    def __init__(self, obstacles, config: BlinkConfig) -> None:
        self.start = np.array([o.start for o in obstacles], float)
        self.velocity = np.array([o.velocity for o in obstacles], float)
        self.config = config

    def reset(self, rng):
        return self.start.copy(), self.velocity.copy()

    def step(self, view, indices, dt):
        return self.start.copy(), self.velocity.copy()

    def presence(self, step: int) -> np.ndarray:
        return np.full(len(self.start), self.config.appear <= step < self.config.leave)


@pytest.fixture(autouse=True)
def blink_model(monkeypatch):
    monkeypatch.setitem(MODELS, "test_blink", Blink)


def _scene(appear: int, leave: int, max_steps: int = 60):
    """A person standing on the robot's straight path to the goal, present for steps appear .. leave - 1."""
    return scenario_from_dict({
        "name": "blink", "bounds": [0, 0, 1200, 800],
        "robot": {"start": [100, 400], "heading": 0, "goal": [1100, 400], "radius": 20},
        "dynamic_obstacles": [{"id": "person", "radius": 25, "start": [500, 400], "velocity": [0, 1],
                               "model": "test_blink", "model_params": {"appear": appear, "leave": leave}}],
        "max_steps": max_steps})


def _config(**extra):
    return episode_config_from_dict({"navigator": {"policy": "direct"},
                                     "perception": {"mode": "ground_truth", "confirm_frames": 1},
                                     "planner": {"strategy": "none"}, **extra})


def test_an_absent_person_is_not_sensed(table1):
    episode = Episode(_scene(1000, 2000), FastEvaluator(table1), _config(), seed=0)
    episode.state = RobotState(380, 400, 0.0, 0.0)  # the person 120 cm ahead, well within the sensors' reach
    obs, scan = episode.observe()
    assert not (scan.labels > 0).any() and obs.tracks == ()
    present = Episode(_scene(0, 2000), FastEvaluator(table1), _config(), seed=0)
    present.state = RobotState(380, 400, 0.0, 0.0)
    obs, scan = present.observe()
    assert (scan.labels > 0).any() and len(obs.tracks) == 1
    assert present.observe()[0].sonar[1] < episode.observe()[0].sonar[1]  # the front sonar sees only the present one


def test_an_absent_person_cannot_be_touched(table1):
    """The direct policy drives straight through the person's place: a collision while it is there, none while
    it is not."""
    hit = list(Episode(_scene(0, 2000), FastEvaluator(table1), _config(), seed=0).run())
    assert hit[-1].outcome == "collision" and hit[-1].contact_dynamic == ("person",)
    through = list(Episode(_scene(1000, 2000), FastEvaluator(table1), _config(), seed=0).run())
    assert through[-1].outcome == "goal"
    assert not any(r.contact_dynamic for r in through)
    assert through[0].obstacle_present.tolist() == [False]


def test_contacts_need_presence_at_both_ends_of_the_step(table1):
    """A person who leaves at step k is touchable over step k - 1 → k only if present at both ends: the robot
    reaching its place after it left drives through."""
    records = list(Episode(_scene(0, 6), FastEvaluator(table1), _config(), seed=0).run())
    assert records[-1].outcome == "goal"
    for r in records:
        assert r.obstacle_next_present.tolist() == [r.step + 1 < 6]
        assert r.obstacle_present.tolist() == [r.step < 6]


def test_pedestrians_do_not_avoid_absent_ones():
    view = CrowdView(World((0, 0, 100, 100)), RobotState(0, 0, 0, 0), 20.0,
                     np.array([[1.0, 1.0], [2.0, 2.0], [3.0, 3.0]]), np.zeros((3, 2)), np.array([10.0, 20.0, 30.0]),
                     0.0, 0, np.array([True, False, True]))
    pos, _, radii = view.others(np.array([0]), sees_robot=False)
    assert pos.tolist() == [[3.0, 3.0]] and radii.tolist() == [30.0]


def test_a_crowd_without_presence_has_everyone_always():
    s = scenario_from_dict({"name": "t", "bounds": [0, 0, 1200, 800],
                            "robot": {"start": [100, 400], "goal": [1100, 400]},
                            "dynamic_obstacles": [{"id": "a", "radius": 20, "start": [600, 100],
                                                   "velocity": [0, 10]}]})
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds), 20.0)
    crowd.reset(0)
    crowd.step(RobotState(0, 0, 0, 0), 1.0)
    assert not crowd.has_presence and crowd.present.tolist() == [True]


@pytest.fixture()
def blink_log(tmp_path, table1):
    path = tmp_path / "blink.mcap"
    cfg = _config(terminate_on_collision=False)
    run_episode(_scene(3, 9, max_steps=40), FastEvaluator(table1), cfg, 0, path, "")
    return path


def test_the_log_records_presence_and_the_metrics_leave_absent_people_out(blink_log):
    truth = [msg for _, _, msg in iter_messages(blink_log, ["/obstacles/truth"])]
    flags = [(m["obstacles"][0]["present"], m["obstacles"][0]["next_present"]) for m in truth]
    assert flags[:10] == [(k in range(3, 9), k + 1 in range(3, 9)) for k in range(10)]
    table, left_out = metrics_table([str(blink_log)])
    assert left_out.empty, left_out.to_dict("records")
    row = table.iloc[0]
    # the robot passes the person's place (x = 500) after step 9, when it has left: no contact, and the nearest
    # approach counts only the steps it was there (the robot then still far to the left of it)
    assert row["outcome"] == "goal"
    xs = [m["x_cm"] for _, _, m in iter_messages(blink_log, ["/robot/state"])]
    nearest_present = min(500 - x for x in xs[3:9]) - 20 - 25
    assert row["min_clearance_dynamic_cm"] == pytest.approx(nearest_present, abs=1.0)


def test_foxglove_draws_an_absent_person_as_an_empty_entity(blink_log):
    drawn = []
    for _, _, msg in iter_messages(blink_log, ["/scene"]):
        for ent in msg["entities"]:
            if ent["id"] == "obstacle/person":
                drawn.append(len(ent["cylinders"]))
    assert drawn[:10] == [int(k in range(3, 9)) for k in range(10)]


def test_a_log_whose_presence_does_not_continue_is_refused(blink_log, tmp_path):
    def edit(topic, msg):
        if topic == "/obstacles/truth" and msg["step"] == 4:
            msg["obstacles"][0]["present"] = False
    bad = tmp_path / "bad.mcap"
    rewrite_log(blink_log, bad, edit)
    table, left_out = metrics_table([str(bad)])
    assert table.empty and "does not continue step 3" in left_out.iloc[0]["reason"]


def _truth(**fields):
    o = {"id": "a", "x_cm": 1.0, "y_cm": 2.0, "vx_cm_s": 0.0, "vy_cm_s": 0.0, "radius_cm": 20.0, "next_x_cm": 1.0,
         "next_y_cm": 2.0, **fields}
    return {"timestamp": {"sec": 0, "nsec": 0}, "step": 0, "obstacles": [o]}


def test_the_check_reads_presence_when_given():
    check_message("/obstacles/truth", _truth())  # an older log: no presence
    check_message("/obstacles/truth", _truth(present=True, next_present=False))
    with pytest.raises(CheckError, match="one of present and next_present"):
        check_message("/obstacles/truth", _truth(present=True))
    with pytest.raises(CheckError, match="true or false"):
        check_message("/obstacles/truth", _truth(present=1, next_present=True))
    check_message("/obstacles/truth", _truth(present=True, next_present=True, reacting=True))
    with pytest.raises(CheckError, match=r"obstacles\[0\]\.reacting: must be true or false"):
        check_message("/obstacles/truth", _truth(reacting="yes"))
    assert not messages_acceptable("/obstacles/truth", [_truth(reacting=0)])


@settings(max_examples=200, deadline=None)
@given(st.dictionaries(st.sampled_from(["present", "next_present"]),
                       st.one_of(st.booleans(), st.none(), st.integers(), st.floats(), st.text(max_size=3))))
def test_fuzz_presence_fields_are_accepted_or_refused_in_one_line(fields):
    """Any values of the presence fields: accepted exactly when both or neither are booleans, refused with a
    CheckError (never another exception), and the whole-episode check agrees with the message check."""
    msg = _truth(**fields)
    ok = not fields or (len(fields) == 2 and all(type(v) is bool for v in fields.values()))
    try:
        check_message("/obstacles/truth", msg)
        accepted = True
    except CheckError as err:
        accepted = False
        assert "\n" not in str(err)
    assert accepted == ok == messages_acceptable("/obstacles/truth", [msg])
