"""`dataset verify` explains a difference: a changed decision/plan/outcome, other discrete values only, or
floating-point values only, with the largest |Δ| per topic; and `--seeds` that selects nothing is an error.

A two-episode dataset (paper_fig5 with h_wait 2, seeds 0-1, the log of seed 0 kept) is built in a temporary
directory, so these tests hold whatever the committed datasets say."""

from __future__ import annotations

import math
import re
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import orjson
import pytest
import yaml
from mcap.reader import make_reader
from mcap.writer import Writer

from runners import dataset
from runners.datasets.verify_report import summary_lines
from runners.logs.diff import SUM_FIELD, UNCLASSIFIED, diff_logs, diff_records
from runners.logs.fields import BEHAVIOUR, DISCRETE, FLOAT, SUMMED_TOPICS, compare, expand_runs, parse_sums
from tests.conftest import ROOT

TINY = {"name": "tiny", "description": "two short episodes for the verify tests", "version": 1,
        "sweep": {"scenarios": ["paper_fig5"], "variants": ["planner=auto_h2"], "seeds": [0, 2], "overrides": []},
        "keep_logs": [0]}
LOGGED, UNLOGGED = "paper_fig5__planner-auto_h2__s0.mcap", "paper_fig5__planner-auto_h2__s1.mcap"


@pytest.fixture(scope="module")
def root(tmp_path_factory) -> Path:
    """A datasets directory holding the built ``tiny`` dataset."""
    path = tmp_path_factory.mktemp("datasets")
    (path / "tiny").mkdir()
    (path / "tiny" / "manifest.yaml").write_text(yaml.safe_dump(TINY, sort_keys=False))
    dataset.build("tiny", n_jobs=2, root=path)
    return path


def run(capsys, *args: str) -> tuple[int, str, str]:
    """``python -m runners.dataset ARGS`` in this process: exit code, stdout, stderr."""
    code = dataset.main([*args, "--jobs", "2"] if args[0] != "list" else list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


def episode_line(out: str, file: str) -> str:
    return next(ln for ln in out.splitlines() if ln.strip().startswith(f"{file}: "))


# -- build -------------------------------------------------------------------------------------------------
def test_build_writes_the_behaviour_record(root):
    manifest = dataset.load_manifest("tiny", root)
    assert sorted(p.name for p in (root / "tiny" / "logs").glob("*.mcap")) == [LOGGED]
    for entry in manifest["episodes"].values():
        assert re.fullmatch(r"[0-9a-f]{16}", entry["decision_digest"])
        assert re.fullmatch(r"[0-9a-f]{16}", entry["discrete_digest"])
        assert len(expand_runs(entry["modes"])) == entry["steps"]
        assert set(expand_runs(entry["modes"])) <= {"direct", "fuzzy", "wait", "detour", "evade", "stop"}
        assert list(parse_sums(entry["float_sums"])) == list(SUMMED_TOPICS)
    # the two seeds plan differently (seed 0 waits, seed 1 detours): the digests tell decisions apart
    a, b = manifest["episodes"][LOGGED], manifest["episodes"][UNLOGGED]
    assert a["decision_digest"] != b["decision_digest"] and a["modes"] != b["modes"]


# -- verify ------------------------------------------------------------------------------------------------
def test_verify_matches_its_own_build(root, capsys):
    code, out, _ = run(capsys, "verify", "tiny", "--root", str(root))
    assert code == 0, out
    assert out.strip() == "tiny: all episodes and the metrics table of the dataset match"


def test_a_tiny_float_perturbation_is_float_only(root, capsys):
    """Laser noise scaled by 1 + 1e-10 moves every track by ~1e-9 cm and changes no decision."""
    code, out, _ = run(capsys, "verify", "tiny", "sensors.laser.noise_std_cm=1.0000000001", "--root", str(root),
                       "--detail")
    assert code == 1
    logged = episode_line(out, LOGGED)  # measured message by message against the kept log
    # the laser ranges are logged at full precision: the scaled noise shows there first
    assert ": float-only; largest |Δ| per topic: " in logged and "first difference: topic /laser at step" in logged
    assert "/tracks tracks.x_cm: max |Δ| " in out  # --detail: one line per numeric field
    unlogged = episode_line(out, UNLOGGED)  # classified from the manifest's digests and float sums
    assert ": float-only; |Δ| of each topic's float sum: /t" in unlogged and "first differing step" in unlogged
    summary = next(ln for ln in out.splitlines() if ln.startswith("tiny: 2 of 2 episodes differ: "))
    m = re.search(r": 0 with a changed decision/plan/outcome, 2 float-only \(largest \|Δ\| (\S+) in /t", summary)
    assert m, summary
    assert 0 < float(m.group(1)) < 1e-6


def test_a_behaviour_change_is_named(root, capsys):
    """A larger safety margin changes seed 0's second wait into a detour and seed 1's detour plans."""
    code, out, _ = run(capsys, "verify", "tiny", "planner.safety_margin_cm=12", "--root", str(root))
    assert code == 1
    logged = episode_line(out, LOGGED)
    assert re.search(r": decision/plan/outcome changed at step \d+ /planner/decision \S+: recorded ", logged), logged
    assert "first difference: topic" in logged
    assert ": decision/plan/outcome changed; " in episode_line(out, UNLOGGED)
    assert "tiny: 2 of 2 episodes differ: 2 with a changed decision/plan/outcome, 0 float-only" in out


@pytest.mark.parametrize("seeds, problem", [
    ("50:60", "--seeds 50:60: selects no episode"),
    ("3:1", "--seeds 3:1: selects no seed"),
    ("1:1", "--seeds 1:1: selects no seed"),
    ("-1:1", "--seeds -1:1: FIRST must be 0 or more"),
    ("a:b", "--seeds: expected FIRST:END"),
    ("1:2:3", "--seeds: expected FIRST:END"),
])
def test_seeds_that_select_nothing_are_an_error(root, capsys, seeds, problem):
    code, out, err = run(capsys, "verify", "tiny", f"--seeds={seeds}", "--root", str(root))  # = for -1:1
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and err.startswith(f"error: {problem}"), err
    if seeds == "50:60":
        assert "has seeds 0:2" in err


@pytest.mark.parametrize(("override", "field"), [("planner.h_wait=abc", "planner.h_wait"),
                                                 ("planner.safety_margin_cm=nan", "planner.safety_margin_cm")])
def test_a_bad_override_is_one_line_before_anything_runs(root, capsys, override, field):
    code, out, err = run(capsys, "verify", "tiny", override, "--root", str(root))
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and field in err, err


@pytest.mark.parametrize(("override", "problem"), [
    ("seed=5", "seed: set by the dataset (each episode's seed is one of sweep.seeds; verify --seeds FIRST:END "),
    ("episodes=3", "episodes: set by the dataset"),
    ("hydra.run.dir=/tmp/x", "hydra.run.dir: hydra settings are not allowed in a dataset"),
    ("planner=auto,wait", "'planner=auto,wait' is a sweep"),
])
def test_an_override_of_what_the_dataset_decides_is_refused(root, capsys, monkeypatch, override, problem):
    """verify's own overrides follow the manifest's rules: ``seed=5`` was silently replaced by each seed."""
    monkeypatch.setattr(dataset, "record_all", lambda *a, **k: pytest.fail("episodes ran"))
    code, out, err = run(capsys, "verify", "tiny", override, "--root", str(root))
    assert code == 2 and out == ""
    assert err.startswith(f"error: command line: {problem}") and len(err.strip().splitlines()) == 1, err


def test_a_field_of_the_scenario_may_be_overridden(tmp_path):
    """``scenario.max_steps=5`` (one field of every scenario) is not the scenario group ``scenario=...``."""
    _bad_manifest(tmp_path, {"overrides": ["scenario.max_steps=5"]})
    manifest = dataset.load_manifest("bad", tmp_path)
    dataset.check_sweep(manifest, dataset.manifest_path("bad", tmp_path), ["scenario.max_steps=6"])


@pytest.mark.parametrize("jobs", ["0", "-5", "two"])
def test_bad_jobs_is_one_line(root, capsys, jobs):
    with pytest.raises(SystemExit) as exit_:
        dataset.main(["verify", "tiny", "--seeds", "0:1", "--root", str(root), "--jobs", jobs])
    err = capsys.readouterr().err
    assert exit_.value.code == 2
    assert len(err.strip().splitlines()) == 1 and err.startswith("error: argument --jobs: "), err


def _bad_manifest(root: Path, sweep: dict[str, Any] | None = None, text: str | None = None, **top: Any) -> None:
    """A manifest ``bad`` under ``root``: TINY with ``sweep`` entries and top-level fields replaced, or ``text``."""
    (root / "bad").mkdir(exist_ok=True)
    data = {**TINY, "name": "bad", "sweep": {**TINY["sweep"], **(sweep or {})}, **top}
    (root / "bad" / "manifest.yaml").write_text(text if text is not None else yaml.safe_dump(data, sort_keys=False))


ENTRY = {"outcome": "goal", "steps": 1, "sha256": "0" * 64, "topics": {"/episode": "0" * 8}, "step_digests": "0" * 8}
BAD_SWEEPS = [  # issue 14: each was a traceback from every worker, or silently accepted
    ({"scenarios": ["no_such_world"]}, "sweep.scenarios[0]: no config 'scenario/no_such_world'"),
    ({"scenarios": ["paper_fig5", "no_such_world"]}, "sweep.scenarios[1]: no config 'scenario/no_such_world'"),
    ({"scenarios": ["../x"]}, "sweep.scenarios[0]: '../x' is not a scenario name"),
    ({"overrides": ["planner.h_wait=nan"]}, "sweep.overrides[0]: planner.h_wait: "),
    ({"overrides": ["planner.safety_margin_cm=nan"]}, "sweep.overrides[0]: planner.safety_margin_cm: must be finite"),
    ({"variants": ["planner=auto,wait"]}, "sweep.variants[0]: 'planner=auto,wait' is a sweep"),
    ({"variants": ["planner=auto_h2", "planner=nope"]}, "sweep.variants[1]: no config 'planner/nope'"),
    ({"variants": ["hydra.run.dir=/tmp/x"]}, "sweep.variants[0]: hydra.run.dir: hydra settings are not allowed"),
    ({"overrides": ["hydra.sweep.dir=/tmp/x"]}, "sweep.overrides[0]: hydra.sweep.dir: hydra settings are not allowed"),
    ({"variants": [["planner=auto_h2", "hydra/launcher=basic"]]}, "sweep.variants[0][1]: hydra/launcher: hydra"),
    ({"seeds": [0, 9007199254740993]}, "sweep.seeds: end 9007199254740993 is beyond the largest seed"),
    ({"seeds": [0, 10_001]}, "sweep.seeds: [0, 10001) is 10,001 seeds, more than the limit of 10,000"),
    ({"seeds": [-1, 2]}, "sweep.seeds: -1: seeds are non-negative"),
    ({"overrides": ["scenario.max_steps=20", "planner=wait"]},
     "sweep.overrides[1]: planner is also set by the variants"),
    ({"variants": [["planner=auto_h2", "planner.h_wait=3"]], "overrides": ["planner.h_wait=4"]},
     "sweep.overrides[0]: planner.h_wait is also set by the variants"),
    ({"variants": ["planner=auto", "planner=auto_h2"]},
     "sweep.variants[1]: the same configuration as sweep.variants[0]"),
    ({"variants": ["planner=wait", "planner=auto_h2", "planner=auto_h2"]},
     "sweep.variants[2]: repeats sweep.variants[1]"),
    ({"scenarios": ["paper_fig5", "head_on", "paper_fig5"]}, "sweep.scenarios[2]: repeats sweep.scenarios[0]"),
    # dst_override_seed, dst_override_episodes: ignored (every episode ran its sweep.seeds seed) but recorded
    ({"overrides": ["seed=5"]}, "sweep.overrides[0]: seed: set by the dataset (each episode's seed is one of "),
    ({"overrides": ["episodes=3"]}, "sweep.overrides[0]: episodes: set by the dataset"),
    ({"overrides": ["planner.h_wait=3", "resume=true"]}, "sweep.overrides[1]: resume: set by the dataset"),
    ({"overrides": ["scenario=head_on"]}, "sweep.overrides[0]: scenario: set by the dataset (sweep.scenarios "),
    ({"overrides": ["sweep=quick"]}, "sweep.overrides[0]: sweep: a sweep preset is no part of a dataset"),
    ({"overrides": ["hydra.job.chdir=true"]}, "sweep.overrides[0]: hydra.job.chdir: hydra settings are not allowed"),
    ({"variants": [["planner=auto_h2", "seed=3"]]}, "sweep.variants[0][1]: seed: set by the dataset"),
    ({"variants": ["planner=auto_h2", "+episodes=2"]}, "sweep.variants[1]: episodes: set by the dataset"),
]


@pytest.mark.parametrize("command", ["build", "verify"])
@pytest.mark.parametrize("sweep, problem", BAD_SWEEPS, ids=[p for _, p in BAD_SWEEPS])
def test_a_bad_manifest_sweep_is_one_line_before_anything_runs(tmp_path, capsys, monkeypatch, command, sweep, problem):
    monkeypatch.setattr(dataset, "record_all", lambda *a, **k: pytest.fail("episodes ran"))
    _bad_manifest(tmp_path, sweep, episodes={"x.mcap": ENTRY})
    code, out, err = run(capsys, command, "bad", "--root", str(tmp_path))
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"error: {tmp_path / 'bad' / 'manifest.yaml'}: {problem}"), err


@pytest.mark.parametrize("top, text, problem", [
    ({"episodes": {"a.mcap": 5}}, None, "manifest.yaml: episodes.a.mcap: expected a mapping, got 5"),
    ({"episodes": {"a.mcap": {"outcome": "goal"}}}, None, "manifest.yaml: episodes.a.mcap.steps: missing"),
    ({"episodes": [1, 2]}, None, "manifest.yaml: episodes: expected a mapping of log file names, got list"),
    ({"metrics_columns": ["spl"]}, None, "manifest.yaml: metrics_columns: expected a mapping of metrics column to "
                                         "digest"),
    ({"metrics_columns": {"spl": "abc"}}, None, "manifest.yaml: metrics_columns: spl: expected 16 lowercase hex "
                                                "digits, got 'abc'"),
    ({}, "name: x\nversion: !!python/object/apply:os.system [id]\n",
     "manifest.yaml:2: version: YAML tag 'tag:yaml.org,2002:python/object/apply:os.system' is not allowed"),
    ({}, "name: x\nversion: !!str 1\n", "manifest.yaml:2: version: YAML tag 'tag:yaml.org,2002:str' is not allowed"),
])
def test_a_malformed_manifest_is_one_line(tmp_path, capsys, monkeypatch, top, text, problem):
    monkeypatch.setattr(dataset, "record_all", lambda *a, **k: pytest.fail("episodes ran"))
    _bad_manifest(tmp_path, text=text, **top)
    code, out, err = run(capsys, "verify", "bad", "--root", str(tmp_path), "--seeds", "0:1")
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and problem in err, err


# -- the classification, on edited copies of the kept log (no simulation) -----------------------------------
Edit = Callable[[str, int, dict[str, Any]], dict[str, Any] | None]


def rewrite(src: Path, dst: Path, edit: Edit) -> None:
    """Copy a log, passing every message through ``edit(topic, step_or_-1, message)`` (None drops it)."""
    with open(src, "rb") as f, open(dst, "wb") as out:
        reader = make_reader(f)
        summary = reader.get_summary()
        writer = Writer(out)
        writer.start()
        schemas = {sid: writer.register_schema(s.name, s.encoding, s.data) for sid, s in summary.schemas.items()}
        channels = {cid: writer.register_channel(c.topic, c.message_encoding, schemas[c.schema_id])
                    for cid, c in summary.channels.items()}
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, record.metadata)
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            msg = orjson.loads(message.data)
            msg = edit(channel.topic, msg.get("step", -1) if isinstance(msg, dict) else -1, msg)
            if msg is not None:
                writer.add_message(channels[channel.id], message.log_time, orjson.dumps(msg), message.publish_time)
        writer.finish()


def _nudge_x(topic, step, msg):
    if topic == "/robot/state" and step == 5:
        msg["x_cm"] += 1e-9
    return msg


class _FirstTable:
    """Edits the first prediction table only (a fresh instance per rewrite)."""

    def __init__(self) -> None:
        self.seen = False

    def __call__(self, topic, step, msg):
        if topic != "/tpt" or self.seen:
            return msg
        self.seen = True
        return self.edit(msg)

    def edit(self, msg):
        raise NotImplementedError


class _FlipACollisionFlag(_FirstTable):
    def edit(self, msg):
        msg["collide"][1][0] = not msg["collide"][1][0]
        return msg


class _DropATable(_FirstTable):
    def edit(self, msg):
        return None


def _change_a_mode(topic, step, msg):
    if topic == "/planner/decision" and step == 3:
        msg["mode"] = "fuzzy"
    return msg


def _change_a_plan_length(topic, step, msg):
    if topic == "/planner/decision" and msg["planning"] is not None:
        msg["planning"]["path_cm"] = msg["planning"]["path_cm"][:-1]
    return msg


def _change_a_printed_number(topic, step, msg):
    # every log line that prints a number (which lines exist depends on the episode's decisions)
    if topic == "/log" and re.search(r"\d", msg["message"]):
        msg["message"] = re.sub(r"\d+", lambda m: str(int(m.group()) + 1), msg["message"], count=1)
    return msg


def recorded_entry(log: Path, like: dict[str, Any]) -> dict[str, Any]:
    """What ``verify`` records of a regenerated episode (outcome and steps come from the run, here unchanged)."""
    return {**dataset.content_digests(log), "outcome": like["outcome"], "steps": like["steps"]}


EDITS = [  # edit, kind from the log, kind from the manifest record, (topic, field) of the first change or float
    (_nudge_x, FLOAT, FLOAT, ("/robot/state", "x_cm")),
    (_change_a_printed_number, FLOAT, FLOAT, ("/log", "message")),
    (_FlipACollisionFlag, DISCRETE, DISCRETE, ("/tpt", "collide")),
    (_DropATable, DISCRETE, DISCRETE, ("/tpt", "")),
    (_change_a_mode, BEHAVIOUR, BEHAVIOUR, ("/planner/decision", "mode")),
    (_change_a_plan_length, BEHAVIOUR, BEHAVIOUR, ("/planner/decision", "planning.path_cm")),
]


@pytest.mark.parametrize("edit, from_log, from_manifest, where", EDITS, ids=[e[0].__name__ for e in EDITS])
def test_log_and_manifest_classify_an_edit_alike(root, tmp_path, edit, from_log, from_manifest, where):
    recorded = root / "tiny" / "logs" / LOGGED
    edited = tmp_path / LOGGED
    rewrite(recorded, edited, edit() if isinstance(edit, type) else edit)
    expected = dataset.load_manifest("tiny", root)["episodes"][LOGGED]
    got = recorded_entry(edited, expected)
    assert got["sha256"] != expected["sha256"]

    by_log = diff_logs(recorded, edited)
    assert by_log.kind == from_log
    if from_log == FLOAT:
        assert list(by_log.floats) == [where] and by_log.first is None
    else:
        assert (by_log.first.topic, by_log.first.field) == where
        assert by_log.kind == BEHAVIOUR or not by_log.counts.get(BEHAVIOUR)
    by_manifest = diff_records(expected, got)
    assert by_manifest.kind == from_manifest


def test_a_float_edit_is_measured_exactly(root, tmp_path):
    recorded = root / "tiny" / "logs" / LOGGED
    edited = tmp_path / LOGGED
    rewrite(recorded, edited, _nudge_x)
    delta = diff_logs(recorded, edited).floats[("/robot/state", "x_cm")]
    assert delta.step == 5 and delta.count == 1 and math.isclose(delta.max_abs, 1e-9, rel_tol=1e-4)
    expected = dataset.load_manifest("tiny", root)["episodes"][LOGGED]
    summed = diff_records(expected, recorded_entry(edited, expected)).floats
    assert list(summed) == [("/robot/state", SUM_FIELD)]
    assert math.isclose(summed[("/robot/state", SUM_FIELD)].max_abs, 1e-9, rel_tol=0.1)  # the sum is ~1.5e5


def test_unchanged_copy_has_no_difference(root, tmp_path):
    recorded = root / "tiny" / "logs" / LOGGED
    rewrite(recorded, tmp_path / LOGGED, lambda topic, step, msg: msg)
    diff = diff_logs(recorded, tmp_path / LOGGED)
    assert diff.first_message is None and not diff.floats and diff.kind == FLOAT


# -- units of the classification --------------------------------------------------------------------------
def collect(topic: str, a: Any, b: Any) -> tuple[list, list]:
    discrete, floats = [], []
    compare(topic, a, b, lambda p, x, y: discrete.append((p, x, y)), lambda p, d: floats.append((p, d)))
    return discrete, floats


def test_headings_and_quaternions_compare_as_what_they_mean():
    _, floats = collect("/robot/state", {"heading_deg": 359.9999999}, {"heading_deg": 1e-7})
    assert floats[0][0] == "heading_deg" and floats[0][1] == pytest.approx(2e-7)
    q = {"x": 0.0, "y": 0.0, "z": 1e-9, "w": 1.0}
    minus_q = {"x": -0.0, "y": -0.0, "z": -1e-9, "w": -1.0}
    assert collect("/robot/pose", {"orientation": q}, {"orientation": minus_q}) == ([], [])
    _, floats = collect("/robot/state", {"x_cm": 359.9999999}, {"x_cm": 1e-7})  # not a heading: no wrapping
    assert floats[0][1] == pytest.approx(360.0)


def test_types_decide_what_is_discrete():
    discrete, floats = collect("/tracks", {"tracks": [{"id": 1, "x_cm": 1.0}]}, {"tracks": [{"id": 2, "x_cm": 1.5}]})
    assert discrete == [("tracks.id", 1, 2)] and floats == [("tracks.x_cm", 0.5)]
    discrete, _ = collect("/episode", {"steps": 3}, {"steps": 3.0})  # a field's type changed: not a rounding
    assert discrete == [("steps", 3, 3.0)]
    assert collect("/planner/decision", {"compute_time_us": 1.0}, {"compute_time_us": 9.0}) == ([], [])


def test_old_manifests_classify_only_outcome_and_steps():
    old = {"outcome": "goal", "steps": 40, "sha256": "0" * 64}
    assert diff_records(old, {"outcome": "goal", "steps": 40}).kind == UNCLASSIFIED
    assert diff_records(old, {"outcome": "goal", "steps": 41}).kind == BEHAVIOUR
    diffs = {"a": diff_records(old, {"outcome": "goal", "steps": 40}),
             "b": diff_records(old, {"outcome": "collision", "steps": 40})}
    assert summary_lines(diffs, 5) == ["2 of 5 episodes differ: 1 with a changed decision/plan/outcome, "
                                       "0 float-only, 1 unclassified (rebuild the manifest to classify them)"]


@pytest.mark.parametrize("command", [["list"], ["verify", "tiny"], ["build", "tiny"]])
def test_a_missing_root_is_an_error(tmp_path, capsys, command):
    """dst_list_root_missing: ``list --root`` of a mistyped directory printed nothing, exit 0."""
    for root, problem in ((tmp_path / "nope", "no such directory"), (tmp_path / "f", "not a directory")):
        (tmp_path / "f").write_text("")
        code, out, err = run(capsys, *command, "--root", str(root))
        assert (code, out, err) == (2, "", f"error: --root {root}: {problem}\n")


def test_an_empty_root_says_so(tmp_path, capsys):
    code, out, err = run(capsys, "list", "--root", str(tmp_path))
    assert (code, out, err) == (0, f"no datasets in {tmp_path}\n", "")


def test_overrides_may_follow_the_options(root, capsys):
    """dst_verify_override_after_root: an override after ``--root DIR`` was 'unrecognized arguments'; both orders
    now verify the same thing, and the overrides keep their order (the last wins)."""
    seeds = ("--seeds", "0:1")
    before = run(capsys, "verify", "tiny", "planner.h_wait=1", "planner.h_wait=3", "--root", str(root), *seeds)[:2]
    after = run(capsys, "verify", "tiny", "--root", str(root), "planner.h_wait=1", *seeds, "planner.h_wait=3")[:2]
    assert before == after and before[0] == 1 and "1 of 1 episodes differ" in before[1], before
    same = run(capsys, "verify", "tiny", "--root", str(root), "planner.h_wait=3", "planner.h_wait=2", *seeds)[:2]
    assert same == (0, "tiny: seeds 0:1 of the dataset match\n"), same  # auto_h2's own h_wait, given last
    with pytest.raises(SystemExit) as exit_:
        dataset.main(["build", "tiny", "--root", str(root), "planner.h_wait=3"])  # build takes no overrides
    assert exit_.value.code == 2
    assert capsys.readouterr().err == "error: unrecognized arguments: planner.h_wait=3 (see --help)\n"


def test_root_option_lists_only_that_directory(root, capsys, tmp_path):
    shutil.copytree(root / "tiny", tmp_path / "tiny_copy")
    path = tmp_path / "tiny_copy" / "manifest.yaml"  # a manifest names its directory
    path.write_text(path.read_text().replace("name: tiny\n", "name: tiny_copy\n", 1))
    code, out, _ = run(capsys, "list", "--root", str(tmp_path))
    assert code == 0 and out.startswith("tiny_copy") and "2 episodes  built=True" in out
    assert "committed logs: 1" in out


# -- hostile14b ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("jobs, episodes", [(300, 1), (1024, 2), (-1, 1), (1, 5)])
def test_workers_are_capped_by_episodes_and_cores(tmp_path, monkeypatch, jobs, episodes):
    """d_jobs_300: ``--jobs 300`` for one episode started 300 workers (and hung)."""
    import os

    import joblib

    seen = {}

    class FakeParallel:
        def __init__(self, n_jobs, **_):
            seen["n_jobs"] = n_jobs

        def __call__(self, tasks):
            return iter(())

    monkeypatch.setattr(joblib, "Parallel", FakeParallel)
    manifest = {"sweep": {**TINY["sweep"], "seeds": [0, episodes]}}
    dataset.record_all(manifest, tmp_path / "out", n_jobs=jobs)
    assert seen["n_jobs"] == min(os.cpu_count() or 1, episodes, jobs if jobs > 0 else 10**6)


@pytest.mark.parametrize("seeds, said", [
    ("1:9007199254740993", "tiny: seeds 1:2 of the dataset match (--seeds 1:9007199254740993: the dataset has only "
                           "these)"),
    ("1:2", "tiny: seeds 1:2 of the dataset match"),
])
def test_verify_says_the_seeds_it_checked(root, capsys, seeds, said):
    """d_seeds_huge: --seeds 0:9007199254740993 checked the dataset's seeds and said all 9e15 matched."""
    code, out, err = run(capsys, "verify", "tiny", "--seeds", seeds, "--root", str(root))
    assert code == 0, err
    assert out.strip() == said


@pytest.mark.parametrize("field, value, said", [("steps", 999, "steps 999 -> "),
                                                ("outcome", "timeout", "outcome 'timeout' -> ")])
def test_a_wrong_manifest_steps_or_outcome_is_a_difference(root, tmp_path, capsys, field, value, said):
    """d_verify_steps_wrong: an entry's steps edited 20 -> 999 still verified as matching."""
    shutil.copytree(root / "tiny", tmp_path / "tiny")
    path = tmp_path / "tiny" / "manifest.yaml"
    manifest = yaml.safe_load(path.read_text())
    assert manifest["episodes"][UNLOGGED][field] != value
    manifest["episodes"][UNLOGGED][field] = value
    path.write_text(yaml.safe_dump(manifest, sort_keys=False, width=200))
    code, out, err = run(capsys, "verify", "tiny", "--seeds", "1:2", "--root", str(tmp_path))
    assert code == 1, (out, err)
    line = episode_line(out, UNLOGGED)
    assert "the manifest entry differs from the regenerated episode" in line and said in line, out


def _flip_a_byte(log: Path) -> None:
    data = bytearray(log.read_bytes())
    data[len(data) // 2] ^= 0x01
    log.write_bytes(bytes(data))


def _another_episode(log: Path) -> None:
    """Replaced by another valid episode: seed 1 of the same configuration, from the committed paper_fig5 dataset."""
    shutil.copyfile(ROOT / "datasets" / "paper_fig5" / "logs" / UNLOGGED, log)


def _a_folder(log: Path) -> None:
    log.unlink()
    log.mkdir()


@pytest.mark.parametrize("damage, said", [
    (_flip_a_byte, "the committed log"),
    (_another_episode, "is not the episode the manifest records"),
    (_a_folder, "is not a regular file"),
], ids=["bit_flip", "replaced", "a_folder"])
def test_a_damaged_or_replaced_committed_log_fails_verify(root, tmp_path, capsys, damage, said):
    """The committed logs were looked at only when a regenerated episode differed: one replaced by another episode
    (or damaged, or a folder in its place) verified as matching."""
    shutil.copytree(root / "tiny", tmp_path / "tiny")
    damage(tmp_path / "tiny" / "logs" / LOGGED)
    code, out, err = run(capsys, "verify", "tiny", "--seeds", "0:1", "--root", str(tmp_path))
    assert code == 1, (out, err)
    line = episode_line(out, LOGGED)
    assert f"{LOGGED}: the committed log" in line and said in line, out


# -- metrics hashed per column --------------------------------------------------------------------------------
def test_build_hashes_each_metrics_column(root):
    manifest = dataset.load_manifest("tiny", root)
    assert "metrics_sha256" not in manifest
    columns = manifest["metrics_columns"]
    assert {"path_length_cm", "success", "spl", "min_ttc_s", "seed"} <= set(columns)
    assert not any(c.startswith("compute_time") for c in columns) and "log" not in columns
    assert all(re.fullmatch(r"[0-9a-f]{16}", d) for d in columns.values())
    assert list(manifest)[-2:] == ["metrics_columns", "episodes"]  # the documented order of the fields


def _edit_metrics(monkeypatch, edit: Callable[[Any], Any]) -> None:
    """Make the metrics table that verify computes go through ``edit`` (as a new version of analysis would)."""
    real = dataset.metrics_table

    def edited(paths, *args, **kwargs):
        table, bad = real(paths, *args, **kwargs)
        return edit(table.copy()), bad

    monkeypatch.setattr(dataset, "metrics_table", edited)


def test_a_new_metric_column_passes_and_is_named(root, capsys, monkeypatch):
    def add(table):
        table["new_metric_cm"] = 1.5
        table["another_s"] = 2.0
        return table

    _edit_metrics(monkeypatch, add)
    code, out, err = run(capsys, "verify", "tiny", "--root", str(root))
    assert code == 0, (out, err)
    assert "tiny: all episodes and the metrics table of the dataset match" in out
    assert ("tiny: new metrics, not in the manifest: new_metric_cm, another_s (behaviour unchanged; to record "
            "them: python -m runners.dataset build tiny)") in out


def test_a_changed_metric_column_fails_naming_it(root, capsys, monkeypatch):
    def change(table):
        table.loc[0, "path_length_cm"] += 0.5
        return table

    _edit_metrics(monkeypatch, change)
    code, out, err = run(capsys, "verify", "tiny", "--root", str(root))
    assert code == 1, (out, err)
    problems = [ln.strip() for ln in out.splitlines() if "metrics column" in ln]
    assert len(problems) == 1 and problems[0].startswith("metrics column path_length_cm: values differ from the "
                                                         "manifest ("), out


def test_a_removed_metric_column_fails_naming_it(root, capsys, monkeypatch):
    _edit_metrics(monkeypatch, lambda table: table.drop(columns=["turn_count"]))
    code, out, err = run(capsys, "verify", "tiny", "--root", str(root))
    assert code == 1, (out, err)
    assert "metrics column turn_count: in the manifest but no longer computed" in out


@pytest.mark.parametrize("same", [True, False])
def test_an_old_manifest_with_one_metrics_digest_says_to_rebuild(root, tmp_path, capsys, monkeypatch, same):
    """Manifests built before per-column hashing have ``metrics_sha256`` of the whole table: still read, and verify
    says what to run."""
    shutil.copytree(root / "tiny", tmp_path / "tiny")
    path = tmp_path / "tiny" / "manifest.yaml"
    manifest = yaml.safe_load(path.read_text())
    del manifest["metrics_columns"]
    manifest["metrics_sha256"] = "0" * 64
    path.write_text(yaml.safe_dump(manifest, sort_keys=False, width=200))
    if same:  # the regenerated table's whole-table digest is the recorded one
        monkeypatch.setattr(dataset, "metrics_digest", lambda table: "0" * 64)
    code, out, err = run(capsys, "verify", "tiny", "--root", str(tmp_path))
    if same:
        assert code == 0, (out, err)
        assert ("tiny: the metrics table matches the manifest's metrics_sha256; metrics are now hashed per column "
                "(a new metric then needs no rebuild): run python -m runners.dataset build tiny") in out
    else:
        assert code == 1, (out, err)
        assert "metrics table differs from the manifest's metrics_sha256" in out
        assert "if a metric was added, record a digest per column with python -m runners.dataset build tiny" in out



def test_verifications_assembled_configs_are_the_configs_hydra_composes(tmp_path):
    """``verify`` makes most episodes' configs from a few composed ones (runners.datasets.episode_recording); each is
    Hydra's composition of the episode's overrides, to the last character of its resolved YAML, over scenarios,
    variants that choose other groups' options (a navigator with its planner), plain values, a variant of two
    overrides, a common override and seeds."""
    from runners.datasets import episode_recording
    from runners.logs import yaml_text

    manifest = {"sweep": {"scenarios": ["head_on", "crowd_crossing"],
                          "variants": ["planner=wait", "navigator=dwa", "planner.h_wait=3",
                                       ["navigator=fuzzy_tpt", "planner=auto_h4"]],
                          "seeds": [0, 2], "overrides": ["terminate_on_collision=false"]}}
    todo = dataset.jobs(manifest)
    state = tmp_path / "configs.pickle"
    token = episode_recording.prepare_assembly(todo, 1, state)
    assert token is not None
    try:
        for job in todo:
            got = yaml_text.config_text(episode_recording.run_config(job, token, str(state)), resolve=True)
            assert got == yaml_text.config_text(episode_recording.run_config(job, None), resolve=True), job
        # each variant sets other keys: four references (a variant's first episode) and, with each, the other
        # scenario's first seed are composed up front; the second seed of each is assembled
        assert episode_recording._ASSEMBLED[token].assembled == 4 * 2
    finally:
        episode_recording.forget_assembled()
