"""Logs are verified before they are believed (issue 14, item 3): the damaged and malformed logs of
tests/bad_inputs/logs/cases.yaml, non-regular files, the same log or episode given twice, and the argument checks
of ``analysis.report`` and ``runners.replay``."""

from __future__ import annotations

import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from analysis import report
from analysis.log_inputs import find_logs
from analysis.logs import RejectedLog
from analysis.metrics import metrics_table
from runners import replay
from tests.conftest import ROOT, one_error_line
from tests.log_surgery import rewrite
from tests.valid_logs import recorded_logs  # noqa: F401 - the session fixture

LOGS = ROOT / "tests" / "bad_inputs" / "logs"
CASES = yaml.safe_load((LOGS / "cases.yaml").read_text())


@pytest.fixture
def good(recorded_logs) -> Path:  # noqa: F811 - the fixture imported above
    """A complete, valid log (replay --verify reproduces it)."""
    return recorded_logs[0]


def test_every_log_case_is_a_file():
    assert len(CASES) >= 16
    for case in CASES:
        assert (LOGS / case["name"]).is_file(), case


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_replay_refuses_a_bad_log_in_one_line(case, capsys):
    log = LOGS / case["name"]
    assert replay.main([str(log), "--verify"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert line.startswith(f"error: {log}: ") and case["expect"] in line, line


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_the_analysis_leaves_a_bad_log_out_with_its_reason(case):
    df, left_out = metrics_table([LOGS / case["name"]])
    assert df.empty and len(left_out) == 1
    assert case["expect"] in left_out["reason"].iloc[0]


def test_a_truncated_log_is_left_out_as_truncated():
    df, left_out = metrics_table([LOGS / "truncated_mid_chunk.mcap"])
    assert df.empty and left_out["reason"].iloc[0].startswith("truncated:")


def test_a_log_cut_before_its_metadata_is_truncated_not_a_foreign_file(good, tmp_path, capsys):
    """The writer puts the run's metadata first (after the header); a copy cut inside it was "no 'fuzzynav.run'
    metadata (not a fuzzynav log)", kind metadata, where it is a fuzzynav log cut short. A complete file without
    the metadata is still not a fuzzynav log (cases.yaml: no_run_metadata.mcap)."""
    import struct

    data = good.read_bytes()
    header_end = 8 + 9 + struct.unpack_from("<Q", data, 9)[0]  # magic, then the header record (opcode, length)
    assert data[header_end] == 0x0C  # the metadata record follows
    metadata_end = header_end + 9 + struct.unpack_from("<Q", data, header_end + 1)[0]
    for cut in (8, 20, header_end, header_end + 100, metadata_end - 1):
        log = tmp_path / f"cut{cut}.mcap"
        log.write_bytes(data[:cut])
        df, left_out = metrics_table([log])
        assert df.empty and list(left_out["kind"]) == ["truncated"], cut
        reason = left_out["reason"].iloc[0]
        assert reason.startswith(f"{log}: truncated: the file ends before the MCAP summary, with no 'fuzzynav.run' "
                                 "metadata"), reason
        assert replay.main([str(log), "--verify"]) == 2
        assert one_error_line(capsys.readouterr().err) == f"error: {reason}"


@pytest.mark.parametrize("field, edit", [
    ("collide[1][0]", lambda t: t["collide"][1].__setitem__(0, not t["collide"][1][0])),
    ("obstacles_cm[2][0]", lambda t: t["obstacles_cm"][2][0].__setitem__(0, t["obstacles_cm"][2][0][0] + 0.5)),
    ("robot_cm[1]", lambda t: t["robot_cm"][1].__setitem__(1, t["robot_cm"][1][1] + 1e-4)),
])
def test_a_tpt_that_is_not_what_its_first_row_makes_is_left_out(field, edit, good, tmp_path):
    """A table's rows and marks follow from its first row (fuzzynav.numerics.prediction.table_rows); an edited flag or
    position changed tpt_collisions_predicted and tpt_ade_cm and was analysed as good."""
    edited = []

    def change(topic, i, msg):
        if topic == "/tpt" and not edited and msg["obstacle_ids"]:
            edit(msg)
            edited.append(msg["step"])
        return msg

    log = rewrite(good, tmp_path / "edited.mcap", message=change)
    assert edited, "the log has no TPT with an obstacle"
    df, left_out = metrics_table([log])
    assert df.empty and list(left_out["kind"]) == ["episode"]
    assert f"/tpt step {edited[0]} {field}: " in left_out["reason"].iloc[0], left_out["reason"].iloc[0]
    df, left_out = metrics_table([rewrite(good, tmp_path / "same.mcap")])  # the same log, re-written unedited
    assert len(df) == 1 and left_out.empty


@pytest.mark.parametrize("field, edit, expect", [
    ("n_traj", None, "/tpt step {step} n_traj: 3, the config's planner.n_traj is 9"),
    ("safety_margin_cm", None, "/tpt step {step} safety_margin_cm: 40.0, the config's planner.safety_margin_cm is 10"),
    ("robot_radius_cm", None, "/tpt step {step} robot_radius_cm: 60.0, the robot's radius is 20.0"),
    ("robot_cm", None, "/tpt step {step} robot_cm[0]: "),
])
def test_a_tpt_consistent_in_itself_but_not_with_its_run_is_left_out(field, edit, expect, good, tmp_path):
    """An edit that keeps the table consistent with its first row (every row and mark recomputed) changed the
    metrics: the table's n_traj and margin are the config's, its robot the logged robot's at that step."""
    import numpy as np

    from fuzzynav.numerics.prediction import table_rows

    edited = []

    def change(topic, i, msg):
        if topic != "/tpt" or edited or not msg["obstacle_ids"]:
            return msg
        t = dict(msg, **{"n_traj": 3} if field == "n_traj" else {},
                 **{"safety_margin_cm": 40.0} if field == "safety_margin_cm" else {},
                 **{"robot_radius_cm": 60.0} if field == "robot_radius_cm" else {})
        start = np.array(t["robot_cm"][0]) + (50.0 if field == "robot_cm" else 0.0)
        k = len(t["obstacle_ids"])
        rows, columns, marks = table_rows(start, (1100.0, 250.0), t["robot_speed_cm_s"],
                                          np.array(t["obstacles_cm"][0]), np.array(t["obstacle_velocities_cm_s"]),
                                          np.array(t["obstacle_radii_cm"]), t["robot_radius_cm"], t["n_traj"],
                                          t["dt_s"], t["safety_margin_cm"], True)
        t.update(robot_cm=rows.tolist(), obstacles_cm=columns.reshape(-1, k, 2).tolist(), collide=marks.tolist())
        edited.append(msg["step"])
        return t

    log = rewrite(good, tmp_path / "edited.mcap", message=change)
    df, left_out = metrics_table([log])
    assert df.empty and list(left_out["kind"]) == ["episode"], left_out["reason"].tolist()
    assert expect.format(step=edited[0]) in left_out["reason"].iloc[0], left_out["reason"].iloc[0]


@pytest.fixture(scope="module")
def generated_log(tmp_path_factory) -> Path:
    """A log of a scenario generated per seed (a small crowd)."""
    out = tmp_path_factory.mktemp("generated")
    res = subprocess.run([sys.executable, "-m", "runners.run", "scenario=crowd_crossing", "scenario.params.n=3",
                          "scenario.params.max_steps=6", "episodes=1", f"hydra.run.dir={out}"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    (log,) = out.glob("*.mcap")
    return log


@pytest.mark.parametrize("world", [None, "", "robot: [\n", "- 1\n", "robot: null\n"])
def test_a_generated_scenarios_log_without_its_world_is_left_out(world, generated_log, tmp_path):
    """Every run logs the world its generator made (metadata scenario_yaml); without it the checks against the
    scenario (start, goal, outcome, the TPTs) were skipped, and a cleared collision mark went unnoticed."""
    log = generated_log
    assert len(metrics_table([log])[0]) == 1

    def without_world(meta):
        if world is None:
            return {k: v for k, v in meta.items() if k != "scenario_yaml"}
        return dict(meta, scenario_yaml=world)

    edited = rewrite(log, tmp_path / "edited.mcap", metadata=without_world)
    df, left_out = metrics_table([edited])
    assert df.empty and list(left_out["kind"]) == ["episode"]
    assert "metadata scenario_yaml: missing or not a scenario, but the config's scenario is made by generator " \
           "'crowd_crossing'" in left_out["reason"].iloc[0], left_out["reason"].iloc[0]


def test_tables_of_fuzzynav_before_the_present_marked_step_1_are_accepted():
    """Before 752785e a pass that started inside the margin (row 0 marked) did not mark step 1; logs of that code
    (still version 0.2.0) are checked against that rule too, and any other mark is still refused."""
    import numpy as np

    from analysis.episode_check import _check_tpt_prediction
    from analysis.json_checks import CheckError
    from fuzzynav.numerics.prediction import table_rows

    # the robot 25 cm from an obstacle (within radii + margin, 40 cm) that leaves at 100 cm/s
    args = ((0.0, 0.0), (1000.0, 0.0), 40.0, np.array([[25.0, 0.0]]), np.array([[0.0, 100.0]]), np.array([10.0]),
            20.0, 9, 1.0, 10.0)
    rows, columns, marks = table_rows(*args, True)
    sampled = table_rows(*args, False)[2]
    assert marks[0, 0] and marks[1, 0] and not sampled[1, 0]  # step 1 marked by the present's pass alone
    table = {"n_traj": 9, "dt_s": 1.0, "robot_speed_cm_s": 40.0, "robot_radius_cm": 20.0, "safety_margin_cm": 10.0,
             "obstacle_ids": [1], "obstacle_radii_cm": [10.0], "obstacle_velocities_cm_s": [[0.0, 100.0]],
             "robot_cm": rows.tolist(), "obstacles_cm": columns.tolist(), "collide": marks.tolist()}
    _check_tpt_prediction(table, (1000.0, 0.0), (True,))
    earlier = marks.copy()
    earlier[1, 0] = False
    _check_tpt_prediction(dict(table, collide=earlier.tolist()), (1000.0, 0.0), (True,))
    earlier[5, 0] = True
    with pytest.raises(CheckError, match=r"collide\[5\]\[0\]"):
        _check_tpt_prediction(dict(table, collide=earlier.tolist()), (1000.0, 0.0), (True,))


@pytest.mark.parametrize("schema, expect", [
    (None, "/robot/state declares no schema, expected 'fuzzynav.RobotState'"),
    (("fuzzynav.Sonar", "jsonschema"), "/robot/state declares schema 'fuzzynav.Sonar', expected 'fuzzynav.RobotState'"),
    (("fuzzynav.RobotState", "protobuf"), "/robot/state declares a 'protobuf' schema, expected 'jsonschema'"),
])
def test_a_topic_without_its_schema_is_refused_and_left_out(schema, expect, tmp_path, capsys, good):
    """A /robot/state channel with no schema record (schema id 0) was replayed ("all 14 decisions reproduced") and
    analysed as good; fuzzynav's writer declares the schema of every topic."""
    log = rewrite(good, tmp_path / "bad.mcap", schemas={"/robot/state": schema})
    assert replay.main([str(log), "--verify"]) == 2
    assert one_error_line(capsys.readouterr().err) == f"error: {log}: {expect}"
    df, left_out = metrics_table([log])
    assert df.empty and list(left_out["kind"]) == ["schema"] and list(left_out["reason"]) == [f"{log}: {expect}"]
    # the only log is left out: the report lists why, and exits 1 (there is no result)
    assert report.main([str(log), "--out", str(tmp_path / "rep"), "--jobs", "1"]) == 1
    assert "none of the 1 log(s) could be analysed (1 schema)" in capsys.readouterr().err
    assert expect in (tmp_path / "rep" / "report.md").read_text()


def test_a_log_re_written_with_its_own_schemas_is_still_good(tmp_path, capsys, good):
    """The surgery above changes nothing but the schema: the same copy with the schemas kept is replayed."""
    log = rewrite(good, tmp_path / "same.mcap", schemas={"/robot/state": ("fuzzynav.RobotState", "jsonschema")})
    assert replay.main([str(log), "--verify"]) == 0
    assert "decisions reproduced" in capsys.readouterr().out


# -- which files are read -----------------------------------------------------------------------------------
@pytest.fixture
def sweep_dir(tmp_path, good):
    """A directory with one good log in a subdirectory, as a sweep's job directory holds it."""
    (tmp_path / "0").mkdir()
    shutil.copy(good, tmp_path / "0" / good.name)
    return tmp_path


def test_the_same_file_through_several_paths_is_read_once(sweep_dir, good):
    log = sweep_dir / "0" / good.name
    (sweep_dir / "link.mcap").symlink_to(log)
    os.link(log, sweep_dir / "hard.mcap")
    paths = [sweep_dir, sweep_dir / "0", log, log, sweep_dir / "link.mcap"]
    assert find_logs(paths) == [sweep_dir / "0" / good.name]
    df, left_out = metrics_table(paths)
    assert len(df) == 1 and left_out.empty


def test_hidden_directories_and_files_are_not_looked_into(sweep_dir, good):
    (sweep_dir / ".fuzzynav" / "resume").mkdir(parents=True)
    shutil.copy(good, sweep_dir / ".fuzzynav" / "resume" / "held.mcap")
    shutil.copy(good, sweep_dir / "0" / ".in-flight.mcap")
    assert find_logs([sweep_dir]) == [sweep_dir / "0" / good.name]
    assert find_logs([sweep_dir / ".fuzzynav" / "resume"]) == [sweep_dir / ".fuzzynav" / "resume" / "held.mcap"]


def test_a_copy_of_an_episode_is_counted_once_and_listed(sweep_dir, good):
    shutil.copy(good, sweep_dir / "copy.mcap")
    df, left_out = metrics_table([sweep_dir])
    assert len(df) == 1 and len(left_out) == 1
    assert "a copy of" in left_out["reason"].iloc[0] and "counted once" in left_out["reason"].iloc[0]


def test_two_different_logs_of_one_episode_are_both_left_out(sweep_dir, good):
    def nudge(topic, index, msg):  # same config hash and seed, different content
        if topic == "/planner/decision" and index == 2:
            msg["left_cm"] -= 1.0  # (its speed is the robot's move: the analysis checks it)
        return msg

    rewrite(good, sweep_dir / "other.mcap", message=nudge)
    df, left_out = metrics_table([sweep_dir])
    assert df.empty and len(left_out) == 2
    assert all("different content: none of them is counted" in r for r in left_out["reason"])


def test_a_re_run_differing_only_in_compute_times_is_a_copy(sweep_dir, good):
    def slower(topic, index, msg):
        if topic == "/planner/decision":
            msg["compute_time_us"] *= 2
        return msg

    rewrite(good, sweep_dir / "rerun.mcap", message=slower)
    df, left_out = metrics_table([sweep_dir])
    assert len(df) == 1 and "a copy of" in left_out["reason"].iloc[0]


def test_non_regular_files_are_skipped_without_being_opened(sweep_dir):
    os.mkfifo(sweep_dir / "x.mcap")
    (sweep_dir / "d.mcap").mkdir()
    (sweep_dir / "dangling.mcap").symlink_to(sweep_dir / "nowhere")
    found = find_logs([sweep_dir, "/dev/null"])
    rejected = {p.name: p.reason for p in found if isinstance(p, RejectedLog)}
    assert rejected == {"x.mcap": "a FIFO, not a regular file: skipped, not opened",
                        "d.mcap": "a directory, not a regular file: skipped, not opened",
                        "dangling.mcap": "cannot read: No such file or directory",
                        "null": "a character device, not a regular file: skipped, not opened"}
    df, left_out = metrics_table([sweep_dir])
    assert len(df) == 1 and len(left_out) == 3


def test_a_fifo_named_mcap_blocks_neither_report_nor_replay(sweep_dir):
    fifo = sweep_dir / "x.mcap"
    os.mkfifo(fifo)
    res = subprocess.run([sys.executable, "-m", "analysis.report", str(sweep_dir), str(fifo), "--jobs", "1",
                          "--out", str(sweep_dir / "rep")], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "1 log(s) left out" in res.stdout, res.stderr
    assert "a FIFO, not a regular file" in (sweep_dir / "rep" / "report.md").read_text()
    res = subprocess.run([sys.executable, "-m", "runners.replay", str(fifo), "--verify"], cwd=ROOT,
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "a FIFO, not a regular file" in one_error_line(res.stderr)


# -- arguments ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("args, expect", [
    (["--turn-threshold-deg", "nan"], "--turn-threshold-deg: 'nan' is not a finite number in (0, 180] degrees"),
    (["--turn-threshold-deg", "-5"], "--turn-threshold-deg: '-5' is not a finite number"),
    (["--turn-threshold-deg", "inf"], "--turn-threshold-deg: 'inf' is not a finite number"),
    (["--jobs", "0"], "--jobs: 0: expected -1 (every core) or 1 to 1024"),
    (["--no-such-option"], "unrecognized arguments: --no-such-option"),
])
def test_report_options_are_checked(args, expect, capsys, tmp_path, good):
    with pytest.raises(SystemExit) as stop:
        report.main([str(good), "--out", str(tmp_path / "rep"), *args])
    assert stop.value.code == 2 and expect in one_error_line(capsys.readouterr().err)
    assert not (tmp_path / "rep").exists()


def test_an_unwritable_report_directory_is_one_line_before_any_work(capsys, tmp_path, good):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert report.main([str(good), "--out", str(blocker / "rep")]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert line == f"error: {blocker / 'rep'}: cannot write: Not a directory", line


def test_a_report_that_cannot_be_written_completely_exits_non_zero(capsys, tmp_path, monkeypatch, good):
    def disk_full(rep, out, *args):
        raise OSError(errno.ENOSPC, "No space left on device", str(out / "report.md"))

    monkeypatch.setattr(report, "_write", disk_full)
    monkeypatch.setattr(report.plots, "_save", lambda fig, path: report.plots.plt.close(fig) or path)
    assert report.main([str(good), "--out", str(tmp_path / "rep"), "--jobs", "1"]) == 1
    line = one_error_line(capsys.readouterr().err)
    assert f"{tmp_path / 'rep' / 'report.md'}: cannot write the report: No space left on device" in line


@pytest.mark.parametrize("args, expect", [
    (["--steps", "a,b"], "--steps: 'a' is not a step number"),
    (["--steps", "3,-1"], "--steps: '-1' is not a step number"),
    (["--steps", "5,4000"], "--steps: step 4000 is beyond the episode's"),
    (["planner.h_wait"], "override 'planner.h_wait': expected key=value"),
    (["dt.x=1"], "override dt.x: no such key in the recorded config"),
    (["planner.h_wait=[1"], "override planner.h_wait: not a value Hydra can read"),
    (["--controller", "/dev/null"], "/dev/null: a character device, not a controller file"),
    (["--controller", "no_such_controller"], "controller 'no_such_controller': no such file"),
    (["--nope"], "unrecognized arguments: --nope"),
])
def test_replay_arguments_are_checked(args, expect, capsys, tmp_path, good):
    try:
        draws = not any(a == "--controller" or "=" in a for a in args)  # (the others draw no picture)
        code = replay.main([str(good), *(["--out", str(tmp_path / "x")] if draws else []), *args])
    except SystemExit as stop:
        code = stop.code
    assert code == 2 and expect in one_error_line(capsys.readouterr().err)
    assert not list(tmp_path.iterdir())


def test_replay_names_an_unwritable_picture(capsys, tmp_path, good):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert replay.main([str(good), "--quiet", "--out", str(blocker / "x")]) == 2
    assert one_error_line(capsys.readouterr().err) == f"error: --out: {blocker / 'x'}: {blocker} is not a directory"


def test_rejected_paths_keep_their_reason_in_worker_processes(sweep_dir, monkeypatch):
    import pickle

    import analysis.logs

    rejected = RejectedLog.with_reason(sweep_dir / "x.mcap", "a FIFO, not a regular file: skipped, not opened")
    assert pickle.loads(pickle.dumps(rejected)).reason == rejected.reason
    os.mkfifo(sweep_dir / "x.mcap")
    monkeypatch.setattr(analysis.logs, "PARALLEL_MIN_LOGS", 1)  # 2 paths over 2 workers
    df, left_out = metrics_table([sweep_dir], jobs=2)
    assert len(df) == 1 and list(left_out["reason"]) == [f"{rejected}: {rejected.reason}"]


@pytest.fixture
def mount(tmp_path):
    from tests.tmpfs import tmpfs_mounter

    yield from tmpfs_mounter(tmp_path)


def test_report_into_a_read_only_or_full_file_system_is_one_line(mount, good):
    read_only, full = mount("64k", read_only=True), mount("24k")
    for out, code, expect in ((read_only / "rep", 2, "cannot write: Read-only file system"),
                              (full / "rep", 1, "cannot write the report: No space left on device (nothing written)")):
        res = subprocess.run([sys.executable, "-m", "analysis.report", str(good), "--jobs", "1", "--out", str(out)],
                             cwd=ROOT, capture_output=True, text=True, timeout=300)
        assert res.returncode == code and expect in one_error_line(res.stderr), res.stderr
        assert str(out) in res.stderr
        assert not list(out.rglob("*")) if out.exists() else True  # whole or nothing: no plots of a lost report


def _zero_chunks(log: Path, out: Path, chunks: int) -> Path:
    """``log``'s data section, then a channel and ``chunks`` chunks that each decompress to 64 MB of zeros (a few
    kB each on disk), without the file's end: what a decompression bomb looks like to the reader."""
    import struct

    import zstandard

    data = log.read_bytes()
    pos, data_end = 8, None
    while pos < len(data):
        opcode, length = struct.unpack_from("<BQ", data, pos)
        if opcode == 0x0F:
            data_end = pos
            break
        pos += 9 + length
    assert data_end is not None

    def record(opcode: int, body: bytes) -> bytes:
        return struct.pack("<BQ", opcode, len(body)) + body

    def text(s: str) -> bytes:
        return struct.pack("<I", len(s)) + s.encode()

    size = 64 * 2**20
    inner = struct.pack("<BQ", 5, size - 9) + struct.pack("<HIQQ", 99, 0, 0, 0) + bytes(size - 9 - 22)
    packed = zstandard.ZstdCompressor(level=3).compress(inner)
    chunk = record(6, struct.pack("<QQQI", 0, 0, size, 0) + text("zstd") + struct.pack("<Q", len(packed)) + packed)
    channel = record(4, struct.pack("<HH", 99, 0) + text("/junk") + text("json") + struct.pack("<I", 0))
    out.write_bytes(data[:data_end] + channel + chunk * chunks)
    return out


def test_chunks_that_decompress_to_more_than_any_log_are_refused_at_once(tmp_path, good):
    """Chunks of zeros that each declare 64 MB (each within the per-chunk bound): the file is left out as too large
    once its chunks pass the bound on all of them, instead of being decompressed chunk after chunk (a 5 MB file of
    them kept the report busy for minutes)."""
    from analysis.mcap_verify import MAX_DECOMPRESSED_BYTES

    bomb = _zero_chunks(good, tmp_path / "bomb.mcap", MAX_DECOMPRESSED_BYTES // (64 * 2**20) + 1)
    assert bomb.stat().st_size < 200_000
    df, left_out = metrics_table([bomb])
    assert df.empty and left_out["kind"].tolist() == ["too-large"]
    assert "the chunks decompress to more than 1024 MB" in left_out["reason"].iloc[0]
    assert replay.main([str(bomb)]) == 2


def _other_world(meta: dict[str, str]) -> dict[str, str]:
    """The ``scenario_yaml`` of another scenario (head_on's), the config left as it was."""
    world = yaml.safe_load(meta["scenario_yaml"])
    world.update(name="head_on", robot={"start": [100.0, 300.0], "goal": [1100.0, 300.0], "heading": 0.0,
                                        "radius": 20.0})
    return {**meta, "scenario_yaml": yaml.safe_dump(world, sort_keys=False)}


def _moved_start(meta: dict[str, str]) -> dict[str, str]:
    world = yaml.safe_load(meta["scenario_yaml"])
    world["robot"]["start"] = [world["robot"]["start"][0] + 1.0, world["robot"]["start"][1]]
    return {**meta, "scenario_yaml": yaml.safe_dump(world, sort_keys=False)}


@pytest.mark.parametrize("edit, expect", [
    (lambda m: {k: v for k, v in m.items() if k != "scenario_yaml"}, "metadata scenario_yaml: missing or not a "
                                                                      "scenario"),
    (lambda m: {**m, "scenario_yaml": "a placeholder"}, "metadata scenario_yaml: missing or not a scenario"),
    (_other_world, "metadata scenario_yaml robot.start"),
    (_moved_start, "metadata scenario_yaml robot.start"),
], ids=["deleted", "placeholder", "another_scenario", "moved_start"])
def test_a_fixed_scenarios_logged_world_is_its_configs(edit, expect, tmp_path, good):
    """``scenario_yaml`` is not covered by ``config_hash``: deleted, the checks against the scenario were skipped (a
    collision relabelled a goal counted as a success); replaced, an episode was counted in another scenario's
    group. For a fixed scenario (the config's ``scenario`` has its robot) it must be the config's scenario."""
    reason = _left_out_episode(rewrite(good, tmp_path / "bad.mcap", metadata=edit))
    assert expect in reason, reason


def _left_out_episode(log: Path) -> str:
    """The reason the analysis leaves ``log`` out, asserting that it does, as an episode that fails its checks."""
    df, left_out = metrics_table([log])
    assert df.empty and list(left_out["kind"]) == ["episode"], left_out.to_dict("records")
    return str(left_out["reason"].iloc[0])


@pytest.mark.parametrize("next_v, expect", [
    (39.0, "/robot/state step 5: moves ("),
    (55.0, "/robot/state step 5 next_v_cm_s: 55.0 is not 0 and outside the config's robot speed limits [10, 40]"),
])
def test_a_robot_that_does_not_move_as_the_simulator_moves_it_is_refused(next_v, expect, tmp_path, good):
    """The robot's moves are the simulator's kinematics (``next_v_cm_s`` × dt along ``next_heading_deg``, within the
    config's robot limits): a robot moved 490 cm in one step of 25 cm/s was counted as a faster success."""
    def edit(topic, index, msg):
        if topic == "/robot/state" and index == 5:
            assert msg["next_v_cm_s"] not in (0.0, next_v)
            msg["next_v_cm_s"] = next_v
        return msg

    reason = _left_out_episode(rewrite(good, tmp_path / "bad.mcap", message=edit))
    assert expect in reason, reason


def test_a_decision_that_is_not_the_robots_move_is_refused(tmp_path, good):
    """Decisions rewritten to wait (v 0) while the robot kept moving were counted as waiting steps."""
    def edit(topic, index, msg):
        if topic == "/planner/decision" and index == 5:
            assert msg["v_cm_s"] > 0
            msg["v_cm_s"] = 0.0
        return msg

    reason = _left_out_episode(rewrite(good, tmp_path / "bad.mcap", message=edit))
    assert "/robot/state step 5 next_v_cm_s" in reason and "decision v_cm_s 0.0" in reason, reason


def test_a_moving_obstacle_of_another_size_than_the_scenarios_is_refused(tmp_path, good):
    """A walker logged at 5 cm instead of the scenario's 20 moved every clearance, near miss and intrusion time."""
    def edit(topic, index, msg):
        if topic == "/obstacles/truth" and index == 3:
            msg["obstacles"][0]["radius_cm"] = 5.0
        return msg

    reason = _left_out_episode(rewrite(good, tmp_path / "bad.mcap", message=edit))
    assert "/obstacles/truth step 3" in reason and "radius_cm: 5.0 is not the scenario's" in reason, reason


def test_the_line_of_a_report_of_no_episode_names_the_log(tmp_path, capsys):
    """An episode that raised is left out with its own reason ("episode raised: ..."), which names no file: the
    command's last line did not say which log it was."""
    from tests.handmade import write_log

    log = write_log(tmp_path / "raised.mcap", [(0, 0, 0), (50, 0, 0)], outcome="error")
    assert report.main([str(log), "--out", str(tmp_path / "rep"), "--jobs", "1"]) == 1
    line = one_error_line(capsys.readouterr().err)
    assert line.startswith(f"error: none of the 1 log(s) could be analysed (1 error): {log}: "), line


def test_a_scenario_that_leaves_keys_to_their_defaults_is_analysed(tmp_path):
    """The check of the logged world against the config's scenario compared a key the scenario leaves out (None)
    with the default the run used (heading 0, radius 20, max_steps 300, name 'unnamed'): every such log, a tuning
    study's whole, was left out."""
    res = subprocess.run([sys.executable, "-m", "runners.run", "scenario=head_on", "~scenario.robot.heading",
                          "~scenario.robot.radius", "~scenario.max_steps", "~scenario.name",
                          f"hydra.run.dir={tmp_path}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    df, left_out = metrics_table([tmp_path])
    assert len(df) == 1 and left_out.empty, left_out.to_dict("records")
    assert df["scenario"].iloc[0] == "unnamed"
