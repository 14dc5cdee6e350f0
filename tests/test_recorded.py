"""Recorded people in episodes (issue #38 item 2): the ``recorded`` obstacle model replays a recording exactly, the
``recorded`` generator makes a scenario of a window of a recording file (robot start and goal given or by the
busiest-crossing rule), and a run of the real command on a file the test writes in ETH's obsmat format."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.logs import iter_messages
from analysis.metrics import metrics_table
from fuzzynav.kinematics import RobotState
from fuzzynav.pedestrians.crowd import Crowd
from fuzzynav.scenarios.generator import generate
from fuzzynav.scenarios.generators.recorded import recording_windows
from fuzzynav.scenarios.recordings import parse
from fuzzynav.scenarios.scenario import ScenarioError, scenario_from_dict
from fuzzynav.scenarios.world import World
from tests.conftest import ROOT
from tests.test_recordings import obsmat

FAR = RobotState(-1e6, -1e6, 0.0, 0.0)


def person(pid: str, t_s, waypoints, **params):
    return {"id": pid, "radius": 25, "waypoints": [list(w) for w in waypoints], "speed": 50, "model": "recorded",
            "model_params": {"t_s": list(t_s), **params}}


def scene(people, **extra):
    return scenario_from_dict({"name": "rec", "bounds": [0, 0, 1200, 800],
                               "robot": {"start": [100, 400], "goal": [1100, 400]},
                               "dynamic_obstacles": people, "max_steps": 100, **extra})


def replay(s, dt, steps):
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds), 20.0)
    pos, vel = crowd.reset(0)
    out = [(pos.copy(), vel.copy(), crowd.present.copy())]
    for _ in range(steps):
        pos, vel = crowd.step(FAR, dt)
        out.append((pos.copy(), vel.copy(), crowd.present.copy()))
    return out, crowd


# -- the model ----------------------------------------------------------------------------------------------


def test_a_recorded_person_is_replayed_by_linear_interpolation_and_present_only_while_recorded():
    t = [-0.4, 0.0, 0.4, 0.8, 1.2]
    xy = [[500, 100], [500, 140], [520, 180], [560, 180], [600, 180]]
    s = scene([person("a", t, xy, until_s=10)])
    out, crowd = replay(s, 0.2, 10)
    assert len(crowd._models) == 1
    for k, (pos, vel, present) in enumerate(out):
        time = 0.2 * k
        if time <= 1.2 + 1e-9:
            expected = [np.interp(time, t, [p[0] for p in xy]), np.interp(time, t, [p[1] for p in xy])]
            np.testing.assert_allclose(pos[0], expected, atol=1e-9)
            assert present.tolist() == [True]
        else:  # left after its last annotation: absent, where it left, standing
            assert present.tolist() == [False] and pos[0].tolist() == [600, 180] and vel[0].tolist() == [0, 0]
    # the velocity is the recorded segment's: (520 - 500, 180 - 140) / 0.4 between 0.0 and 0.4 s
    np.testing.assert_allclose(out[1][1][0], [50, 100])


def test_a_person_appears_at_its_first_annotation_and_leaves_at_the_window_end():
    s = scene([person("late", [1.0, 1.4, 1.8, 2.2], [[300, 300], [340, 300], [380, 300], [420, 300]], until_s=2.0)])
    out, _ = replay(s, 0.5, 6)
    assert [bool(p[0]) for _, _, p in out] == [False, False, True, True, True, False, False]
    assert out[0][0][0].tolist() == [300, 300]  # before it appears: at its first annotation


def test_the_crop_limits_presence():
    s = scene([person("c", [0.0, 4.0], [[100, 200], [900, 200]], crop=[400, 0, 600, 800])])
    out, _ = replay(s, 1.0, 4)
    # x = 100, 300, 500, 700, 900 at t = 0..4: inside the crop [400, 600] only at t = 2
    assert [bool(p[0]) for _, _, p in out] == [False, False, True, False, False]


def test_the_replay_is_the_same_at_every_dt_on_common_times():
    s = scene([person("a", [0.0, 0.4, 0.8, 1.2, 1.6, 2.0], [[200, 200], [260, 230], [330, 230], [400, 260],
                                                              [420, 330], [480, 400]])])
    fine, _ = replay(s, 0.2, 10)
    coarse, _ = replay(s, 0.4, 5)
    for k in range(6):
        np.testing.assert_allclose(coarse[k][0], fine[2 * k][0], atol=1e-9)


def test_many_people_share_one_instance_and_may_start_overlapping():
    people = [person(f"p{i}", [0.0, 1.0], [[300 + 10 * i, 300], [300 + 10 * i, 500]]) for i in range(30)]
    s = scene(people)  # 10 cm apart with 25 cm radii: real couples walk so; reactive models would refuse it
    out, crowd = replay(s, 0.5, 3)
    assert len(crowd._models) == 1 and out[2][2].all() and not out[3][2].any()


@pytest.mark.parametrize("entry, message", [
    (person("a", [0.0, 1.0, 2.0], [[500, 100], [500, 200]]), "dynamic_obstacles[0].model_params.t_s: 3 times for 2 "
                                                              "waypoints"),
    (person("a", [0.0, 0.0], [[500, 100], [500, 200]]), "dynamic_obstacles[0].model_params.t_s[1]: 0.0 s is not "
                                                         "after"),
    (person("a", [0.0, 1.0], [[500, 100], [500, 200]], crop=[1, 2, 3]), "dynamic_obstacles[0].model_params.crop: "
                                                                         "expected [x0, y0, x1, y1]"),
    (person("a", [float("nan"), 1.0], [[500, 100], [500, 200]]), "dynamic_obstacles[0].model_params.t_s[0]: must be "
                                                                  "finite"),
    ({**person("a", [0.0], [[500, 100]]), "model_params": {}}, "dynamic_obstacles[0].model_params.t_s: missing"),
])
def test_a_bad_recorded_entry_is_one_line_naming_its_field(entry, message):
    with pytest.raises(ScenarioError) as err:
        scene([entry])
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


# -- the generator ------------------------------------------------------------------------------------------


def crossing_file(path, people=12, frames=300):
    """A synthetic obsmat recording (metres, 2.5 Hz): ``people`` walkers crossing a 12 x 8 m square, entering one
    after another, half along x and half along y."""
    rows = []
    for i in range(people):
        start = 20 * i  # annotations
        for k in range(60):
            frame = 10 * (start + k)
            if frame >= 10 * frames:
                break
            if i % 2:
                rows.append((frame, i + 1, 0.2 * k, 2.0 + 0.3 * i))
            else:
                rows.append((frame, i + 1, 1.0 + 0.5 * i, 0.13 * k))
    rows.sort()
    path.write_text(obsmat(rows))
    return path


@pytest.fixture()
def recording(tmp_path):
    return crossing_file(tmp_path / "obsmat.txt")


def make(params, seed=0):
    return generate({"generator": "recorded", "params": params}, seed)


def test_a_window_becomes_a_scenario_of_recorded_people(recording):
    s, plain = make({"recording": str(recording), "start_s": 8.0, "duration_s": 20.0})
    rec = parse(recording.read_text(), "obsmat", "x")
    assert s.max_steps == 20 and all(d.model == "recorded" for d in s.dynamic_obstacles)
    assert "sha256" in s.description and "busiest-crossing rule (seed 0)" in s.description
    for d in s.dynamic_obstacles:
        track = next(t for t in rec.tracks if f"p{t.id}" == d.id)
        t = np.array(d.model_params.t_s) + 8.0  # back to the recording's clock
        np.testing.assert_allclose(np.array(d.waypoints), track.xy_cm[np.searchsorted(track.t_s, t - 1e-9)],
                                   atol=1e-6)
        assert t[0] <= 8.0 + 1e-9 or t[0] == track.t_s[0]  # the annotation before the window is kept
        assert d.model_params.until_s == 20.0
    assert yaml.safe_load(yaml.safe_dump(plain)) == plain


def test_the_busiest_crossing_rule_is_seeded_and_clear_of_people(recording):
    a, _ = make({"recording": str(recording), "start_s": 8.0, "duration_s": 20.0}, seed=1)
    b, _ = make({"recording": str(recording), "start_s": 8.0, "duration_s": 20.0}, seed=1)
    c, _ = make({"recording": str(recording), "start_s": 8.0, "duration_s": 20.0}, seed=2)
    assert a.robot == b.robot and a.robot != c.robot
    for s in (a, c):
        length = np.hypot(*(np.array(s.robot.goal) - np.array(s.robot.start)))
        assert length == pytest.approx(1000.0)
        for d in s.dynamic_obstacles:
            assert np.hypot(*(np.array(d.waypoints[0]) - np.array(s.robot.start))) >= 20 + 25 + 60 - 1e-6


def test_a_given_start_and_goal_are_kept(recording):
    s, _ = make({"recording": str(recording), "duration_s": 20.0, "robot_start": [-50, 150],
                 "robot_goal": [1100, 500]})
    assert s.robot.start == (-50.0, 150.0) and s.robot.goal == (1100.0, 500.0) and "given" in s.description


def test_the_suite_of_windows(recording):
    rec = parse(recording.read_text(), "obsmat", "x")
    assert recording_windows(rec, 20.0) == [0, 1, 2, 3, 4]  # 111.6 s of people crossing, one at least in each
    # 10 s apart: people enter every 8 s and stay 23.6 s, so the first and last windows hold 3, the others more
    assert recording_windows(rec, 20.0, 10.0, min_people=4) == [1, 2, 3, 4, 5, 6, 7, 8]
    assert recording_windows(rec, 20.0, 10.0, min_people=3) == list(range(10))
    s, _ = make({"recording": str(recording), "window": 2, "duration_s": 20.0})
    assert "window 40-60 s" in s.description


@pytest.mark.parametrize("params, message", [
    ({"recording": "/nonexistent/obsmat.txt"}, "params.recording: /nonexistent/obsmat.txt: no such file"),
    ({}, "params.recording: expected the path of a recording file"),
    ({"start_s": 500.0}, "params.start_s: the window [500, 560] s is not inside the recording"),
    ({"duration_s": 301}, "params.duration_s: must be in [0.001, 300]"),
    ({"crop": [5, 5, 1, 1]}, "params.crop: expected [x0, y0, x1, y1]"),
    ({"crop": [5000, 5000, 6000, 6000]}, "params.start_s: nobody is recorded in the window"),
    ({"robot_start": [0, 0]}, "params.robot_start: give robot_start and robot_goal together"),
    ({"window": 1, "start_s": 3}, "params.window: give start_s or window, not both"),
    ({"speed": 3}, "params.speed: unknown parameter"),
    ({"path_length": 1e6}, "params.path_length: no start and goal"),
    ({"format": "csv"}, "params.format: unknown format 'csv'"),
])
def test_a_bad_parameter_is_one_line_naming_it(recording, params, message):
    base = {"recording": str(recording), "duration_s": 60.0}
    with pytest.raises(ScenarioError) as err:
        make({k: v for k, v in {**base, **params}.items() if not (k == "recording" and params == {})}
             if params else {"duration_s": 60.0})
    assert str(err.value).startswith(message) and "\n" not in str(err.value), str(err.value)


def test_a_corrupt_recording_names_the_file_and_line(tmp_path):
    bad = tmp_path / "obsmat.txt"
    bad.write_text(obsmat([(0, 1, 0.0, 0.0), (10, 1, 0.5, 0.0)]).replace("5.0000000e-01", "nan", 1))
    with pytest.raises(ScenarioError, match=rf"^params.recording: {bad}: line 2, column 3: nan is not a finite"):
        make({"recording": str(bad), "duration_s": 0.4})


def test_more_than_a_scenarios_people_is_refused(tmp_path):
    rows = sorted((10 * k, i, 0.1 * i, 0.05 * k) for i in range(301) for k in range(5))
    many = tmp_path / "obsmat.txt"
    many.write_text(obsmat(rows))
    with pytest.raises(ScenarioError, match=r"params\.duration_s: 301 people in the window, more than the limit"):
        make({"recording": str(many), "duration_s": 1.6})


def test_more_annotations_than_a_log_holds_are_refused(tmp_path):
    rows = sorted((10 * k, i, 0.1 * i, 0.05 * k) for i in range(200) for k in range(80))  # 16,000 annotations
    many = tmp_path / "obsmat.txt"
    many.write_text(obsmat(rows))
    with pytest.raises(ScenarioError, match=r"^params\.duration_s: the window's 200 people keep 16,000 annotations"):
        make({"recording": str(many), "duration_s": 31.6})


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(params=st.dictionaries(
    st.sampled_from(["start_s", "window", "stride_s", "duration_s", "crop", "robot_start", "robot_goal",
                     "robot_heading", "path_length", "radius", "max_steps", "max_gap", "annotation_hz", "format"]),
    st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True),
              st.text(max_size=4), st.lists(st.floats(-2000, 2000), max_size=5)), max_size=4))
def test_fuzz_generator_parameters(tmp_path_factory, params):
    """Any parameters: a valid scenario or one ScenarioError line naming a parameter — never another exception."""
    path = tmp_path_factory.getbasetemp() / "fuzz_obsmat.txt"
    if not path.exists():
        crossing_file(path)
    try:
        s, _ = make({"recording": str(path), **params})
    except ScenarioError as err:
        text = str(err)
        assert "\n" not in text and text.startswith(("params.", "robot.", "dynamic_obstacles")), text
        return
    assert s.dynamic_obstacles


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(alphabet="0123456789. -\tnaNe+\n#", max_size=300))
def test_fuzz_recording_file_contents(tmp_path_factory, text):
    """Any file contents: a scenario or one line naming the file (``params.recording: <file>: ...``)."""
    path = tmp_path_factory.getbasetemp() / "fuzz_contents.txt"
    path.write_text(text)
    try:
        make({"recording": str(path), "format": "xy", "duration_s": 0.4})
    except ScenarioError as err:
        assert "\n" not in str(err) and str(err).startswith("params."), str(err)


# -- the real command ---------------------------------------------------------------------------------------


def test_a_recorded_scenario_runs_end_to_end_and_its_log_verifies(recording, tmp_path):
    conf = tmp_path / "conf" / "scenario"
    conf.mkdir(parents=True)
    out = tmp_path / "run"  # the shipped scenario: the user names the recording
    res = subprocess.run([sys.executable, "-m", "runners.run", "scenario=recorded",
                          f"scenario.params.recording={recording}", "scenario.params.duration_s=20",
                          "navigator=fuzzy_tpt", f"hydra.run.dir={out}", "seed=3"],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    (log,) = out.glob("*.mcap")
    truth = [m for _, _, m in iter_messages(log, ["/obstacles/truth"])]
    assert all("present" in o and "next_present" in o for m in truth for o in m["obstacles"])
    assert any(not o["present"] for m in truth for o in m["obstacles"])  # people come and go
    table, left_out = metrics_table([str(log)])
    assert left_out.empty and len(table) == 1, left_out.to_dict("records")
    verify = subprocess.run([sys.executable, "-m", "runners.replay", str(log), "--verify"], cwd=ROOT,
                            capture_output=True, text=True, timeout=600)
    assert verify.returncode == 0, verify.stdout[-2000:] + verify.stderr[-2000:]
    (conf / "missing.yaml").write_text(yaml.safe_dump({"name": "missing", "generator": "recorded",
                                                      "params": {"recording": str(tmp_path / "nope.txt")}}))
    res = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.searchpath=[file://{tmp_path / 'conf'}]",
                          "scenario=missing", f"hydra.run.dir={tmp_path / 'run2'}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode != 0 and "Traceback" not in res.stderr
    assert f"params.recording: {tmp_path / 'nope.txt'}: no such file" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr
    res = subprocess.run([sys.executable, "-m", "runners.run", "scenario=recorded",
                          f"hydra.run.dir={tmp_path / 'run3'}"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 2 and res.stderr.startswith("error: ") and "Traceback" not in res.stderr
    assert "recorded.yaml: params.recording: missing: name your copy" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1, res.stderr


# -- reacting -----------------------------------------------------------------------------------------------


def _head_on(react_cm=0.0, model="social_force", y=400):
    """A person walking at 100 cm/s straight at a robot standing at (400, y)."""
    params = {"until_s": 30} | ({"react_cm": react_cm, "react_model": model} if react_cm else {})
    return scene([person("a", [0.4 * k for k in range(26)], [[1100 - 40 * k, 410] for k in range(26)], **params)],
                 robot={"start": [400, y], "goal": [100, 700]})


@pytest.mark.parametrize("model", ["social_force", "orca"])
def test_a_reacting_person_is_a_replay_until_the_robot_is_near_then_avoids_it(model):
    robot = RobotState(400, 400, 0, 0)

    def run(s):
        crowd = Crowd(s.dynamic_obstacles, World(s.bounds), 20.0)
        crowd.reset(0)
        out = []
        for _ in range(12):
            pos, _ = crowd.step(robot, 1.0)
            out.append((pos[0].copy(), bool(crowd.reacting[0]), bool(crowd.present[0])))
        return out, crowd

    replayed, crowd = run(_head_on())
    assert not crowd.has_reactions and not any(r for _, r, _ in replayed)
    reacting, crowd = run(_head_on(150.0, model))
    flags = [r for _, r, _ in reacting]
    first = flags.index(True)
    assert crowd.has_reactions and all(flags[first:])  # once it reacts, to the end
    for k in range(first):
        np.testing.assert_array_equal(reacting[k][0], replayed[k][0])
    # the replay walks through the robot's place (10 cm from its centre); the reacting person keeps off it (ORCA's
    # 1-s steps may graze it by a few mm: the sum of radii is 45 cm)
    assert min(np.hypot(*(p - [400, 400])) for p, _, _ in replayed) < 11
    assert min(np.hypot(*(p - [400, 400])) for p, _, _ in reacting) >= 44


def test_a_bad_reaction_is_one_line_naming_it():
    with pytest.raises(ScenarioError, match=r"^dynamic_obstacles\[0\]\.model_params\.react_model: unknown value"):
        _head_on(100.0, "teleport")
    with pytest.raises(ScenarioError, match=r"^dynamic_obstacles\[0\]\.model_params\.react_cm: must be in"):
        _head_on(-5.0)


def test_the_log_says_from_which_step_a_person_reacts(tmp_path, table1):
    from fuzzynav.config import episode_config_from_dict
    from fuzzynav.controller.fuzzy_fast import FastEvaluator
    from runners.run import run_episode
    from tests.handmade import rewrite_log

    cfg = episode_config_from_dict({"navigator": {"policy": "direct"}, "planner": {"strategy": "none"},
                                    "terminate_on_collision": False})
    s = scenario_from_dict({"name": "react", "bounds": [0, 0, 1200, 800],
                            "robot": {"start": [100, 400], "goal": [1100, 400]}, "max_steps": 40,
                            "dynamic_obstacles": [person("a", [0.4 * k for k in range(60)],
                                                         [[1150 - 19 * k, 410] for k in range(60)],
                                                         until_s=30, react_cm=100)]})
    log = tmp_path / "react.mcap"
    run_episode(s, FastEvaluator(table1), cfg, 0, log, "")
    flags = [m["obstacles"][0]["reacting"] for _, _, m in iter_messages(log, ["/obstacles/truth"])]
    assert True in flags and flags == [False] * flags.index(True) + [True] * (len(flags) - flags.index(True))
    table, left_out = metrics_table([str(log)])
    assert left_out.empty, left_out.to_dict("records")
    bad = tmp_path / "bad.mcap"
    last = len(flags) - 1
    rewrite_log(log, bad, lambda topic, m: m["obstacles"][0].update(reacting=False)
                if topic == "/obstacles/truth" and m["step"] == last else None)
    table, left_out = metrics_table([str(bad)])
    assert table.empty and f"/obstacles/truth step {last}" in left_out.iloc[0]["reason"]


def test_the_generator_passes_the_reaction_on(recording):
    s, _ = make({"recording": str(recording), "start_s": 8.0, "duration_s": 20.0, "react_cm": 120,
                 "react_model": "orca"})
    assert all(d.model_params.react_cm == 120 and d.model_params.react_model == "orca" for d in s.dynamic_obstacles)
    with pytest.raises(ScenarioError, match=r"^params\.react_model: unknown model"):
        make({"recording": str(recording), "duration_s": 20.0, "react_cm": 120, "react_model": "teleport"})


@settings(max_examples=150, deadline=None)
@given(params=st.dictionaries(
    st.sampled_from(["t_s", "until_s", "crop", "react_cm", "react_model", "speed"]),
    st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(), st.text(max_size=5),
              st.lists(st.one_of(st.floats(), st.integers(-3, 3)), max_size=6)), max_size=5),
    points=st.integers(1, 5))
def test_fuzz_recorded_model_params(params, points):
    """Any model_params of a recorded entry: a scenario whose replay runs, or one ScenarioError line naming
    ``dynamic_obstacles[0]`` — never another exception."""
    entry = {"id": "a", "radius": 25, "waypoints": [[500 + 10 * k, 300] for k in range(points)], "speed": 50,
             "model": "recorded", "model_params": params}
    try:
        s = scene([entry])
    except ScenarioError as err:
        assert str(err).startswith("dynamic_obstacles[0]") and "\n" not in str(err), str(err)
        return
    out, _ = replay(s, 0.5, 4)
    assert all(np.isfinite(pos).all() and np.isfinite(vel).all() for pos, vel, _ in out)


def test_a_replay_too_large_to_hold_is_refused_in_one_line():
    """Annotations 250 h apart at dt = 0.1 s would be 9 million positions: refused before any array is made (a run
    ends with outcome error and this reason), while the reset at t = 0 needs only one step."""
    s = scene([person("a", [0.0, 900_000.0], [[500, 100], [500, 140]])])
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds), 20.0)
    crowd.reset(0)
    with pytest.raises(ValueError, match=r"^recorded: 1 people x 9,000,001 steps of 0.1 s is more than 5,000,000"):
        crowd.step(FAR, 0.1)


@pytest.mark.parametrize("dt", [0.1, 0.7, 1.0, 2.5])
def test_the_reset_agrees_with_the_runs_grid_at_every_dt(dt):
    """A reset knows no dt: its positions at t = 0 (absent people included, at their first annotation) are those
    of the grid the first step builds at the run's dt, so that the log's first step continues into the second."""
    s = scene([person("late", [1.0, 1.4, 1.8], [[300, 300], [340, 300], [380, 300]]),
               person("now", [-0.4, 0.4, 1.2], [[600, 100], [600, 180], [600, 260]]),
               person("cropped", [0.0, 4.0], [[100, 500], [900, 500]], crop=[400, 0, 600, 800])])
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds), 20.0)
    at_reset, velocity = (a.copy() for a in crowd.reset(0))
    crowd.step(FAR, dt)
    for model, members, _ in crowd._models:  # the cropped person is a group of its own (another crop)
        np.testing.assert_array_equal(model._xy[:, 0], at_reset[members])
        np.testing.assert_array_equal(model._velocity[:, 0], velocity[members])
