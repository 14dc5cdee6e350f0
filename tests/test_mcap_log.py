"""The MCAP log of an episode: every topic, the metadata, schemas, Foxglove conformance, determinism."""

from __future__ import annotations

import io
import json
import subprocess
import sys

import jsonschema
import pytest
from mcap.reader import make_reader

from analysis.log_format import FOXGLOVE_SCHEMAS, TOPICS
from analysis.logs import episode_summary, is_complete, iter_messages, read_metadata
from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from runners.run import run_episode
from tests.conftest import ROOT, load_controller, load_scenario


@pytest.fixture(scope="module")
def head_on_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("log") / "head_on.mcap"
    summary = run_episode(load_scenario("head_on"), FastEvaluator(load_controller("table1")),
                          episode_config_from_dict({"laser": {"noise_std_cm": 1.0}}), 3, path, "seed: 3\n")
    return path, summary


def test_log_has_every_topic_and_metadata(head_on_log):
    path, summary = head_on_log
    assert summary["outcome"] == "goal" and is_complete(path)
    with open(path, "rb") as f:
        reader = make_reader(f)
        info = reader.get_summary()
        topics = {ch.topic: info.schemas[ch.schema_id].name for ch in info.channels.values()}
        counts = {info.channels[cid].topic: n for cid, n in info.statistics.channel_message_counts.items()}
    assert topics == TOPICS
    steps = summary["steps"]
    for topic in ("/robot/pose", "/laser", "/sonar", "/tracks", "/obstacles/truth", "/robot/state",
                  "/planner/decision"):
        assert counts[topic] == steps, topic
    assert counts["/scene"] == steps + 1 and counts["/episode"] == 1
    assert 0 < counts["/tpt"] <= steps and counts["/log"] >= 3
    meta = read_metadata(path)
    for key in ("config", "seed", "scenario", "fuzzynav_version", "git_commit", "numpy_version",
                "scikit-fuzzy_version", "shapely_version", "mcap_version", "foxglove-sdk_version", "strategy",
                "h_wait"):
        assert key in meta, key
    assert meta["seed"] == "3" and meta["scenario"] == "head_on" and meta["config"] == "seed: 3\n"
    row = episode_summary(path)
    assert row["outcome"] == "goal" and row["steps"] == steps and row["strategy"] == "auto"


def test_every_message_matches_its_schema(head_on_log):
    path, _ = head_on_log
    with open(path, "rb") as f:
        reader = make_reader(f)
        validators = {}
        n = 0
        for schema, _channel, message in reader.iter_messages():
            if schema.id not in validators:
                validators[schema.id] = jsonschema.Draft202012Validator(json.loads(schema.data))
            validators[schema.id].validate(json.loads(message.data))
            n += 1
    assert n > 100


@pytest.mark.parametrize("name", sorted(FOXGLOVE_SCHEMAS))
def test_foxglove_topics_conform_to_foxglove_schemas(head_on_log, name):
    """Our Foxglove schema files are valid JSON schemas, and every message on a Foxglove topic conforms."""
    path, _ = head_on_log
    schema = FOXGLOVE_SCHEMAS[name]()
    jsonschema.Draft202012Validator.check_schema(schema)
    assert schema["title"] == name
    validator = jsonschema.Draft202012Validator(schema)
    topics = [t for t, s in TOPICS.items() if s == name]
    count = 0
    for _topic, _t, msg in iter_messages(path, topics):
        validator.validate(msg)
        count += 1
    assert count > 0


def test_scene_is_in_metres_and_static_entities_come_first(head_on_log):
    path, _ = head_on_log
    first = next(msg for _t, _n, msg in iter_messages(path, ["/scene"]))
    ids = [e["id"] for e in first["entities"]]
    assert ids[0] == "walls" and "goal" in ids
    walls = first["entities"][0]["lines"][0]["points"]
    assert max(p["x"] for p in walls) == pytest.approx(12.0)  # 1200 cm
    later = [msg for _t, _n, msg in iter_messages(path, ["/scene"])][5]
    robot = next(e for e in later["entities"] if e["id"] == "robot")
    assert robot["cylinders"][0]["size"]["x"] == pytest.approx(0.4)  # 2 * 20 cm


def test_a_planning_step_is_logged_with_the_listing_quantities(head_on_log):
    path, _ = head_on_log
    plans = [m for _t, _n, m in iter_messages(path, ["/planner/decision"]) if m["planning"]]
    assert plans
    p = plans[0]["planning"]
    assert p["tS"] == p["tc"] - 1 and p["wait_time"] == p["tG"] - p["tS"] - 1 and p["h_wait"] == 2
    logs = [m["message"] for _t, _n, m in iter_messages(path, ["/log"])]
    assert any(s.startswith("collision predicted") for s in logs) and logs[-1].startswith("goal reached")


def _messages_without_timing(path):
    out = []
    for topic, t, msg in iter_messages(path):
        msg.pop("compute_time_us", None)
        out.append((topic, t, json.dumps(msg, sort_keys=True)))
    return out


def test_same_config_and_seed_give_the_same_messages_across_processes(tmp_path):
    logs = []
    for run in ("a", "b"):
        out = subprocess.run([sys.executable, "-m", "runners.run", f"hydra.run.dir={tmp_path / run}", "seed=4",
                              "scenario=crossing_right"], cwd=ROOT, capture_output=True, text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        logs.append(next((tmp_path / run).glob("*.mcap")))
    assert _messages_without_timing(logs[0]) == _messages_without_timing(logs[1])
    assert read_metadata(logs[0]) == read_metadata(logs[1])


def test_an_episode_that_raises_is_logged_as_error(tmp_path, monkeypatch):
    import fuzzynav.planning.layer as nav

    def broken(self, obs, active):
        raise RuntimeError("boom")

    monkeypatch.setattr(nav.PlanningLayer, "decide", broken)
    path = tmp_path / "err.mcap"
    summary = run_episode(load_scenario("head_on"), FastEvaluator(load_controller("table1")),
                          episode_config_from_dict({}), 0, path, "")
    assert summary["outcome"] == "error" and "boom" in summary["reason"]
    assert episode_summary(path)["outcome"] == "error"
    assert any("RuntimeError: boom" in m["message"] for _t, _n, m in iter_messages(path, ["/log"]))


def test_log_writes_to_any_binary_stream():
    from fuzzynav.episode import Episode
    from runners.logs.mcap_log import EpisodeLogWriter

    buf = io.BytesIO()
    ep = Episode(load_scenario("head_on"), load_controller("table1"))
    log = EpisodeLogWriter(buf, ep, {"seed": "0"}, "auto", "laser")
    for rec in ep.run():
        log.step(rec)
    log.finish(ep.outcome)
    assert buf.getvalue().endswith(b"\x89MCAP0\r\n")


def test_one_open_log_per_process():
    """The writer's channels are shared in a process: a second log cannot open until the first is finished."""
    from fuzzynav.episode import Episode
    from runners.logs.mcap_log import EpisodeLogWriter

    ep = Episode(load_scenario("head_on"), load_controller("table1"))
    first = EpisodeLogWriter(io.BytesIO(), ep, {"seed": "0"}, "auto", "laser")
    with pytest.raises(RuntimeError, match="already open"):
        EpisodeLogWriter(io.BytesIO(), ep, {"seed": "0"}, "auto", "laser")
    first.finish("interrupted")
    second_buf = io.BytesIO()
    second = EpisodeLogWriter(second_buf, ep, {"seed": "1"}, "auto", "laser")
    second.finish("interrupted")
    assert second_buf.getvalue().endswith(b"\x89MCAP0\r\n")


def test_unwritable_log_path_is_an_error_naming_it(tmp_path):
    scenario, controller = load_scenario("head_on"), FastEvaluator(load_controller("table1"))
    bad = tmp_path / "missing" / "x.mcap"
    with pytest.raises(FileNotFoundError, match=r"missing/x\.mcap"):
        run_episode(scenario, controller, episode_config_from_dict({}), 0, bad, "")
    good = tmp_path / "x.mcap"  # the failed open left no log open in the process
    assert run_episode(scenario, controller, episode_config_from_dict({}), 0, good, "")["outcome"] == "goal"
