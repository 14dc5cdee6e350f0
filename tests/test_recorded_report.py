"""Recorded people in the analysis (issue #38 items 3-4): the TPT's error per horizon step against the
constant-velocity baseline on the same predictions, computed from the log alone; the report's section for it (absent
for other logs); the episode identity holding the recording's SHA-256; the limit of recorded people."""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math

import numpy as np
import pandas as pd
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.episode_log import load_episode
from analysis.horizon_errors import column, count_column, horizon_errors, horizons_of_columns
from analysis.logs import LogFile, iter_messages
from analysis.metrics import column_unit, metrics_table
from analysis.recorded_people import horizon_table, shown_table
from analysis.report import build_report
from analysis.run_parameters import RECORDING_PARAMETER, find_grouping, parameters_of
from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode_identity import RECORDING, episode_key, episode_key_of
from fuzzynav.params import limits
from fuzzynav.scenarios.generators.recorded import recording_digest
from fuzzynav.scenarios.scenario import ScenarioError, scenario_from_dict
from runners.run import episode_metadata, run_episode
from tests.conftest import load_scenario
from tests.test_recorded import crossing_file, make, person

T = [0.4 * k for k in range(80)]  # 31.6 s of annotations every 0.4 s


def straight():
    """A person walking beside the robot (25 cm/s along y = 560, 160 cm from its path): constant velocity."""
    return person("straight", T, [[150 + 10 * k, 560] for k in range(80)], until_s=30)


def turning():
    """A person walking +x at 25 cm/s beside the robot, turning to +y after 6 s (annotation 15), back to +x
    after 12 s."""
    pts, x, y = [], 250.0, 150.0
    for k in range(80):
        pts.append([x, y])
        x, y = (x, y + 10) if 15 <= k < 30 else (x + 10, y)
    return person("turning", T, pts, until_s=30)


def world(people, max_steps=25):
    return scenario_from_dict({"name": "rec", "bounds": [0, 0, 1600, 1400],
                               "robot": {"start": [100, 400], "goal": [1500, 400]}, "max_steps": max_steps,
                               "dynamic_obstacles": people})


def episode_log(tmp_path, table1, people, perception="ground_truth", name="rec.mcap"):
    cfg = episode_config_from_dict({"perception": {"mode": perception}, "terminate_on_collision": False})
    path = tmp_path / name
    run_episode(world(people), FastEvaluator(table1), cfg, 0, path, f"perception:\n  mode: {perception}\n")
    return path


def test_constant_velocity_people_are_predicted_exactly_by_both(tmp_path, table1):
    log = load_episode(episode_log(tmp_path, table1, [straight()]))
    row = horizon_errors(log)
    horizons = horizons_of_columns(row)
    assert horizons == list(range(1, 10))  # n_traj = 9 rows ahead
    assert row[count_column(1)] > 10
    for k in horizons:
        if row[count_column(k)]:
            for predictor in ("tpt", "cv"):  # ground truth: the TPT's velocity is the recorded segment's slope
                assert row[column(predictor, "fde", k)] == pytest.approx(0.0, abs=1e-6)
                assert row[column(predictor, "ade", k)] == pytest.approx(0.0, abs=1e-6)


def _read(path):
    """The log's truth of its one obstacle per step, and its TPT tables."""
    return ([m["obstacles"][0] for _, _, m in iter_messages(path, ["/obstacles/truth"])],
            [m for _, _, m in iter_messages(path, ["/tpt"])])


def _oracle(path, track_t, track_xy, dt=1.0, read=None):
    """Per horizon: the TPT's and constant velocity's errors on the one person of the log, computed plainly from the
    log's tables and truth (one obstacle column, every step)."""
    truth, tables = read or _read(path)
    xs, ys = np.array([p[0] for p in track_xy]), np.array([p[1] for p in track_xy])
    errors: dict[tuple[str, int], list[float]] = {}
    for t in tables:
        s = t["step"]
        if not t["obstacle_radii_cm"] or s * dt - 0.4 < track_t[0]:
            continue
        here = np.array([np.interp(s * dt, track_t, xs), np.interp(s * dt, track_t, ys)])
        before = np.array([np.interp(s * dt - 0.4, track_t, xs), np.interp(s * dt - 0.4, track_t, ys)])
        v = (here - before) / 0.4
        for h in range(1, len(t["obstacles_cm"])):
            if s + h >= len(truth) or not truth[s + h]["present"]:
                break
            actual = np.array([truth[s + h]["x_cm"], truth[s + h]["y_cm"]])
            errors.setdefault(("tpt", h), []).append(float(np.hypot(*(np.array(t["obstacles_cm"][h][0]) - actual))))
            errors.setdefault(("cv", h), []).append(float(np.hypot(*(here + v * h * dt - actual))))
    return errors


def test_a_turning_person_the_errors_are_those_computed_plainly(tmp_path, table1):
    p = turning()
    path = episode_log(tmp_path, table1, [p])
    row = horizon_errors(load_episode(path))
    oracle = _oracle(path, p["model_params"]["t_s"], p["waypoints"])
    assert oracle and max(oracle[("cv", 9)]) > 100  # the turn is missed
    for k in range(1, 10):
        if ("cv", k) not in oracle:
            assert row[count_column(k)] == 0
            continue
        n = len(oracle[("cv", k)])
        assert row[count_column(k)] == n
        for predictor in ("tpt", "cv"):
            fde = oracle[(predictor, k)]
            ade = [sum(oracle[(predictor, h)][i] for h in range(1, k + 1)) / k for i in range(n)]
            assert row[column(predictor, "fde", k)] == pytest.approx(sum(fde) / n, rel=1e-9, abs=1e-9)
            assert row[column(predictor, "ade", k)] == pytest.approx(sum(ade) / n, rel=1e-9, abs=1e-9)


def test_logs_without_recorded_people_have_no_columns(tmp_path, table1):
    cfg = episode_config_from_dict({})
    path = tmp_path / "head_on.mcap"
    run_episode(load_scenario("head_on"), FastEvaluator(table1), cfg, 0, path, "")
    assert horizon_errors(load_episode(path)) == {}
    table, _ = metrics_table([str(path)])
    assert not horizons_of_columns(table.columns) and horizon_table(table).empty


def test_units_of_the_columns():
    assert column_unit(column("tpt", "ade", 3)) == "cm" and column_unit(count_column(3)) == ""
    assert column_unit("rec_tpt_ade_cm_h0") == ""  # not a horizon


def test_the_table_means_episodes_with_intervals_and_never_pools_groups():
    rows = []
    for variant, base in (("laser", 100.0), ("ground_truth", 10.0)):
        for seed in range(4):
            rows.append({"scenario_label": "w0", "variant": variant, "seed": seed,
                         column("tpt", "fde", 1): base + seed, column("tpt", "ade", 1): base + seed,
                         column("cv", "fde", 1): 5.0, column("cv", "ade", 1): 5.0, count_column(1): 3.0,
                         column("tpt", "fde", 2): math.nan, column("tpt", "ade", 2): math.nan,
                         column("cv", "fde", 2): math.nan, column("cv", "ade", 2): math.nan, count_column(2): 0.0})
    table = horizon_table(pd.DataFrame(rows))
    assert set(table["horizon"]) == {1}  # no episode scored horizon 2
    laser = table[(table["variant"] == "laser") & (table["predictor"] == "tpt")].iloc[0]
    assert laser["fde_cm"] == pytest.approx(101.5) and laser["episodes"] == 4 and laser["predictions"] == 12
    assert laser["fde_lo"] <= 101.5 <= laser["fde_hi"] and laser["fde_lo"] < laser["fde_hi"]
    gt = table[(table["variant"] == "ground_truth") & (table["predictor"] == "tpt")].iloc[0]
    assert gt["fde_cm"] == pytest.approx(11.5)
    shown = shown_table(table)
    assert list(shown["variant"]) == ["laser", "ground_truth"] and "tpt FDE h1 (cm)" in shown.columns


def test_the_report_has_the_section_for_recorded_people_only(tmp_path, table1):
    logs = tmp_path / "logs"
    logs.mkdir()
    for perception in ("laser", "ground_truth"):
        episode_log(logs, table1, [straight(), turning()], perception, f"rec_{perception}.mcap")
    out = tmp_path / "report"
    build_report([str(logs)], out, jobs=1)
    text = (out / "report.md").read_text()
    assert "## Recorded people: the TPT against constant velocity" in text
    assert (out / "recorded_horizons.png").stat().st_size > 1000
    assert text.index("recorded_horizons.png") < text.index("## Trajectories")  # figures first
    csv = pd.read_csv(out / "recorded_horizons.csv")
    assert sorted(csv["variant"].unique()) == ["auto(h=2) · perception=ground_truth", "auto(h=2) · perception=laser"]
    assert set(csv["predictor"]) == {"tpt", "cv"}
    assert set(csv["horizon"]) <= set(range(1, 10)) and 1 in set(csv["horizon"])
    other = tmp_path / "other"
    other.mkdir()
    run_episode(load_scenario("head_on"), FastEvaluator(table1), episode_config_from_dict({}), 0,
                other / "head_on.mcap", "")
    out2 = tmp_path / "report2"
    build_report([str(other)], out2, jobs=1)
    assert "Recorded people" not in (out2 / "report.md").read_text()
    assert not (out2 / "recorded_horizons.csv").exists()


# -- the episode's identity holds the recording's content ------------------------------------------------------


def test_two_recordings_of_one_name_are_two_episodes(tmp_path, table1):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    crossing_file(a / "obsmat.txt")
    crossing_file(b / "obsmat.txt", people=10)
    keys, digests = [], []
    for folder in (a, b):
        params = {"recording": str(folder / "obsmat.txt"), "start_s": 8.0, "duration_s": 20.0}
        scenario, _ = make(params)
        digest = hashlib.sha256((folder / "obsmat.txt").read_bytes()).hexdigest()
        assert recording_digest(scenario.description) == digest
        cfg = episode_config_from_dict({})
        meta = episode_metadata(scenario, FastEvaluator(table1), cfg, 0, "scenario: {recording: obsmat.txt}\n",
                                generator="recorded")
        assert meta[RECORDING] == digest
        keys.append(episode_key_of(meta))
        digests.append(digest)
    assert keys[0] != keys[1]
    # the same config and seed without a recording digest: the key as before (other scenarios keep theirs)
    assert episode_key("x: 1\n", 0, "1.0") == episode_key("x: 1\n", 0, "1.0", "", "")
    assert episode_key("x: 1\n", 0, "1.0", recording=digests[0]) != episode_key("x: 1\n", 0, "1.0")
    # a digest is a scenario parameter only where one recording path has two contents
    meta = {"scenario": "recorded", "strategy": "auto", "h_wait": "2", "controller": "table1",
            "perception": "laser", "config": "scenario:\n  params:\n    recording: obsmat.txt\n"}
    runs = [parameters_of({**meta, RECORDING: d}) for d in digests]
    assert all(r[RECORDING_PARAMETER] in digests for r in runs)
    assert RECORDING_PARAMETER in find_grouping(runs).dimensions
    other = {**meta, "config": "scenario:\n  params:\n    recording: other.txt\n"}
    runs = [parameters_of({**meta, RECORDING: digests[0]}), parameters_of({**other, RECORDING: digests[1]})]
    assert RECORDING_PARAMETER not in find_grouping(runs).dimensions


def test_a_log_of_a_recorded_scenario_records_the_digest(tmp_path, table1):
    crossing_file(tmp_path / "obsmat.txt")
    scenario, _ = make({"recording": str(tmp_path / "obsmat.txt"), "start_s": 8.0, "duration_s": 20.0})
    path = tmp_path / "rec.mcap"
    run_episode(scenario, FastEvaluator(table1), episode_config_from_dict({}), 0, path, "", generator="recorded")
    meta = LogFile(path).metadata()
    assert meta[RECORDING] == hashlib.sha256((tmp_path / "obsmat.txt").read_bytes()).hexdigest()
    table, left_out = metrics_table([str(path)])
    assert left_out.empty and len(table) == 1, left_out.to_dict("records")


# -- the limit of recorded people --------------------------------------------------------------------------------


def _people(n, model="recorded"):
    out = []
    for i in range(n):
        entry = person(f"{model}{i}", [0.0, 0.4], [[200 + 4.0 * i, 700.0], [240 + 4.0 * i, 700.0]], until_s=1)
        if model != "recorded":
            entry = {"id": f"{model}{i}", "radius": 25, "waypoints": [[200 + 4.0 * i, 700.0], [240 + 4.0 * i, 700.0]],
                     "speed": 50}
        out.append(entry)
    return out


def test_recorded_people_have_a_limit_of_their_own():
    assert len(world(_people(limits.MAX_RECORDED_PEOPLE)).dynamic_obstacles) == limits.MAX_RECORDED_PEOPLE
    with pytest.raises(ScenarioError, match=r"^dynamic_obstacles: 301 obstacles of model recorded, more than"):
        world(_people(limits.MAX_RECORDED_PEOPLE + 1))
    with pytest.raises(ScenarioError, match=r"^dynamic_obstacles: 101 obstacles \(other than recorded people\)"):
        world(_people(limits.MAX_DYNAMIC_OBSTACLES + 1, model="scripted"))
    world(_people(limits.MAX_DYNAMIC_OBSTACLES, model="scripted") + _people(50))  # both kinds, each within


def test_a_window_of_150_people_is_a_scenario(tmp_path):
    from tests.test_recordings import obsmat

    rows = sorted((10 * k, i + 1, 0.3 * (i % 30), 0.3 * (i // 30) + 0.05 * k) for i in range(150) for k in range(8))
    many = tmp_path / "obsmat.txt"
    many.write_text(obsmat(rows))
    scenario, _ = make({"recording": str(many), "duration_s": 2.0, "robot_start": [-300, -300],
                        "robot_goal": [-300, 600]})
    assert len(scenario.dynamic_obstacles) == 150


@pytest.fixture(scope="module")
def turning_log(tmp_path_factory):
    from tests.conftest import load_controller

    p = turning()
    path = episode_log(tmp_path_factory.mktemp("turning"), load_controller("table1"), [p])
    return load_episode(path), path, p, _read(path)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(points=st.lists(st.tuples(st.floats(-5000, 5000), st.floats(-5000, 5000)), min_size=80, max_size=80),
       reacting_from=st.one_of(st.none(), st.integers(0, 30)))
def test_fuzz_the_baseline_follows_the_logged_annotations(turning_log, points, reacting_from):
    """Whatever annotations the logged scenario holds for the person (the TPT's tables and the truth unchanged), the
    baseline is the plain computation from them; a person reacting from a step is scored only before it."""
    log, path, p, read = turning_log
    world_ = yaml.safe_load(log.meta["scenario_yaml"])
    world_["dynamic_obstacles"][0]["waypoints"] = [list(q) for q in points]
    truth = copy.deepcopy(log.truth)
    if reacting_from is not None:
        for k, m in enumerate(truth):
            m["obstacles"][0]["reacting"] = k >= reacting_from
    mutated = dataclasses.replace(log, meta={**log.meta, "scenario_yaml": yaml.safe_dump(world_)}, truth=truth)
    row = horizon_errors(mutated)
    oracle = _oracle(path, p["model_params"]["t_s"], [list(q) for q in points], read=read)
    counts = [row.get(count_column(k), 0.0) for k in range(1, 10)]  # no column: nothing scored
    assert counts == sorted(counts, reverse=True)  # a prediction scored at k is scored at every shorter horizon
    for k in range(1, 10):
        if reacting_from is not None or ("cv", k) not in oracle:
            continue
        values = oracle[("cv", k)]
        assert row[count_column(k)] == len(values)
        assert row[column("cv", "fde", k)] == pytest.approx(sum(values) / len(values), rel=1e-9, abs=1e-6)
    if reacting_from is not None:
        tables = [t["step"] for t in log.tpts.values() if t["obstacle_radii_cm"]]
        scored = sum(1 for s in tables if s + 1 < reacting_from and s * log.dt - 0.4 >= 0 and s + 1 < len(truth))
        assert row.get(count_column(1), 0.0) <= scored


def test_a_resume_keeps_a_log_of_another_recording_as_another_world(tmp_path, table1):
    """A resume's restore tells the same episode run by other code (superseded: replaced by its re-run) from the
    same config and seed on another recording of the same file name (another world: a dimension of the report, so
    its log is kept beside the new one in ``earlier/``)."""
    from runners.sweeping.resume import _same_episode

    logs = {}
    for people in (4, 10, 4):
        folder = tmp_path / f"rec{len(logs)}"
        folder.mkdir()
        crossing_file(folder / "obsmat.txt", people=people)
        # one recording path, as a sweep's config names it, whose content changed between the runs
        scenario, _ = make({"recording": str(folder / "obsmat.txt"), "start_s": 8.0, "duration_s": 20.0})
        path = folder / "run.mcap"
        run_episode(scenario, FastEvaluator(table1), episode_config_from_dict({}), 0, path,
                    "scenario:\n  params:\n    recording: obsmat.txt\n", generator="recorded")
        logs[len(logs)] = path
    assert _same_episode(logs[0], logs[2])  # the same recording: the same episode
    assert not _same_episode(logs[0], logs[1])  # another recording of the same name: another world
