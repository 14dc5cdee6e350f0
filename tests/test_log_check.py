"""The log checks (built from the schemas) agree with the JSON schemas the logs embed, and with the writer: every
field they demand is one the schema requires, of the schema's type; the config hash is the one ``runners.run``
computes; the verified reader reads a truncated log up to its last whole record and refuses damage in a closed one."""

from __future__ import annotations

import copy
import os
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

from analysis.log_check import MESSAGE_CHECKS, TOPIC_SCHEMAS, CheckError, check_message, config_hash
from analysis.log_format import SCHEMAS
from analysis.logs import LogFile
from analysis.mcap_verify import McapError, read_mcap
from tests.conftest import ROOT
from tests.log_surgery import chunk_payloads, message_paths, record_offsets
from tests.valid_logs import recorded_logs  # noqa: F401 - the session fixture

OTHER_TYPE = {"number": "text", "integer": "text", "string": 1.5, "boolean": 1, "array": {}, "object": []}


def _richest(log_path, topic: str) -> dict[str, Any]:
    """The message of ``topic`` with the most content (non-empty lists, a plan), the first scene for /scene."""
    messages = [m for _t, _n, m in LogFile(log_path, [topic]).messages()]
    return messages[0] if topic == "/scene" else max(messages, key=lambda m: len(repr(m)))


def _schema_at(schema: dict[str, Any], path: tuple) -> tuple[dict[str, Any], dict[str, Any]]:
    """(schema of the object holding the last key of ``path``, schema of its value)."""
    parent = schema
    for key in path:
        if "oneOf" in parent:  # nullable object: the object variant
            parent = next(s for s in parent["oneOf"] if s.get("type") == "object")
        holder = parent
        parent = parent["items"] if isinstance(key, int) else parent["properties"][key]
    return holder, parent


def _edit(msg: dict[str, Any], path: tuple, value: Any = None, delete: bool = False) -> dict[str, Any]:
    out = copy.deepcopy(msg)
    node = out
    for key in path[:-1]:
        node = node[key]
    if delete:
        del node[path[-1]]
    else:
        node[path[-1]] = value
    return out


def _rejects(topic: str, msg: dict[str, Any]) -> bool:
    try:
        check_message(topic, msg)
    except CheckError:
        return True
    return False


@pytest.mark.parametrize("topic", sorted(MESSAGE_CHECKS))
def test_every_field_the_check_demands_is_required_by_the_schema_and_typed_alike(topic, recorded_logs):  # noqa: F811
    schema = SCHEMAS[TOPIC_SCHEMAS[topic]]()
    msg = _richest(recorded_logs[0], topic)
    check_message(topic, msg)
    demanded = []
    for path in message_paths(msg):
        if isinstance(path[-1], int) or not _rejects(topic, _edit(msg, path, delete=True)):
            continue
        demanded.append(path)
        holder, value_schema = _schema_at(schema, path)
        assert path[-1] in holder.get("required", []), f"{topic} {path}: demanded but not required by the schema"
        kind = value_schema.get("type")
        if isinstance(kind, str):
            assert _rejects(topic, _edit(msg, path, OTHER_TYPE[kind])), f"{topic} {path}: accepts a non-{kind}"
    assert demanded, topic


def test_the_topics_schemas_are_the_writers():
    from runners.logs.mcap_log import TOPICS

    assert {t: s for t, s in TOPICS.items() if t in TOPIC_SCHEMAS} == TOPIC_SCHEMAS


def test_config_hash_is_the_runs():
    from runners.logs.provenance import provenance
    from runners.run import config_hash as run_hash

    text = "dt: 1.0\nresume: false\nplanner:\n  h_wait: 2\n"
    assert config_hash(text, "7", provenance()["fuzzynav_version"]) == run_hash(text, 7)


def test_a_log_cut_after_any_record_is_truncated_and_inside_any_record_too(recorded_logs):  # noqa: F811
    data = recorded_logs[0].read_bytes()
    full = read_mcap(data)
    assert full.complete
    for _opcode, offset, length in record_offsets(data):
        for cut in (offset, offset + 9 + length // 2):
            content = read_mcap(data[:cut])
            assert not content.complete and len(content.messages) <= len(full.messages)
            assert content.messages == full.messages[:len(content.messages)]


def test_a_killed_runs_last_chunk_whose_sizes_are_not_filled_in_is_where_the_log_stops(recorded_logs):  # noqa: F811
    """The writer fills in a chunk's sizes once its records are written: a run killed in between (seen in CI, a
    SIGKILL) left a log whose last chunk fits in the file but cannot be read, and the whole log was refused as
    damaged. Cut after any chunk with that chunk's records length not filled in, the log reads up to the chunk
    before; the same damage anywhere but at the end of an unclosed file is still refused."""
    data = recorded_logs[0].read_bytes()
    full = read_mcap(data)
    chunks = chunk_payloads(data)
    assert len(chunks) > 3
    for offset, first, end in chunks:
        cut = bytearray(data[:end])
        cut[first - 8:first] = b"\xff" * 8  # the records length, as before the writer fills it in
        content = read_mcap(bytes(cut))
        assert not content.complete and content.stopped_at == offset
        assert content.messages == full.messages[:len(content.messages)]
        with pytest.raises(McapError):  # followed by anything, or in a closed file: damaged
            read_mcap(bytes(cut) + data[end:end + 1])
    offset, first, end = chunks[1]
    closed = bytearray(data)
    closed[first - 8:first] = b"\xff" * 8
    with pytest.raises(McapError):
        read_mcap(bytes(closed))


def test_a_closed_log_with_a_changed_byte_is_refused_wherever_the_byte_is(recorded_logs):  # noqa: F811
    data = recorded_logs[0].read_bytes()
    for at in range(0, len(data), max(1, len(data) // 997)):  # ~1,000 positions spread over the file
        damaged = data[:at] + bytes([data[at] ^ 0x04]) + data[at + 1:]
        try:
            content = read_mcap(damaged)
        except McapError:
            continue
        assert not content.complete, f"a changed byte at {at} went unnoticed"  # the closing magic itself


@pytest.mark.parametrize("compression", ["LZ4", "NONE"])
def test_a_log_with_other_chunk_compression_reads_the_same_and_damage_is_still_refused(compression, tmp_path,
                                                                                        recorded_logs):  # noqa: F811
    """MCAP allows lz4 and uncompressed chunks (``mcap compress`` and other tools write them): the same messages,
    the same episode, and a changed byte is still refused. lz4 logs were all refused as damaged until the reader
    checked the frame's end inside the decompressor's ``with`` block (leaving it resets the decompressor)."""
    from mcap.writer import CompressionType

    from analysis.episode_log import load_episode
    from tests.log_surgery import rewrite

    zstd = rewrite(recorded_logs[0], tmp_path / "zstd.mcap")
    other = rewrite(recorded_logs[0], tmp_path / "other.mcap", compression=getattr(CompressionType, compression))
    data = other.read_bytes()
    assert data != zstd.read_bytes()
    assert read_mcap(data).messages == read_mcap(zstd.read_bytes()).messages
    a, b = load_episode(zstd), load_episode(other)
    assert (a.states, a.tpts, a.decisions, a.episode) == (b.states, b.tpts, b.decisions, b.episode)
    # the chunks' compressed records (this writer leaves the data-section CRC at 0: outside the chunks, bytes the
    # analysis does not read, such as a schema's text, may change unnoticed). A changed byte there is refused, or
    # decompresses to the very same records (an lz4 match can point at another copy of the same bytes: the chunk's
    # CRC then holds), never to other messages
    expected = read_mcap(data).messages
    payload = [at for _chunk, first, end in chunk_payloads(data) for at in range(first, end)]
    assert payload
    refused = 0
    for at in payload[::max(1, len(payload) // 199)]:
        damaged = data[:at] + bytes([data[at] ^ 0x04]) + data[at + 1:]
        try:
            content = read_mcap(damaged)
        except McapError as err:
            assert "chunk at byte" in str(err)
            refused += 1
            continue
        assert content.messages == expected, f"a changed byte at {at} gave other messages"
    assert refused > 150  # most changes are refused: the comparison above is the exception


def test_the_data_section_crc_stands_in_for_the_chunk_crcs_only_where_it_matches(recorded_logs):  # noqa: F811
    """A closed log whose data-section CRC matches has its chunks' bytes as written: their own CRCs are not
    computed again. A changed byte in a chunk breaks the data-section CRC, and the chunk's error names it, as
    when every chunk CRC is checked."""
    from analysis import mcap_verify

    data = recorded_logs[0].read_bytes()
    at = mcap_verify._intact_data_section(data)
    assert at > 0 and data[at] == 0x0F  # the DataEnd record
    assert read_mcap(data).messages == read_mcap(data[:-1]).messages  # not closed: every chunk CRC checked
    chunk_at, first, end = chunk_payloads(data)[0]
    inside = (first + end) // 2  # a byte in the middle of the compressed records
    damaged = data[:inside] + bytes([data[inside] ^ 0x10]) + data[inside + 1:]
    assert mcap_verify._intact_data_section(damaged) == 0
    with pytest.raises(McapError, match=f"chunk at byte {chunk_at}"):
        read_mcap(damaged)
    for summary_start in (0, 1, 9, at, len(data), 2**64 - 1):  # a footer pointing anywhere: no shortcut, no error
        footer = len(data) - 8 - 29
        bent = data[:footer + 9] + summary_start.to_bytes(8, "little") + data[footer + 17:]
        assert mcap_verify._intact_data_section(bent) in (0, at)


BAD_LOGS = ROOT / "tests" / "bad_inputs" / "logs"
BAD_LOG_KINDS = {"empty.mcap": "not-mcap", "random_bytes.mcap": "not-mcap", "no_run_metadata.mcap": "metadata",
                 "message_off_schema.mcap": "schema", "x_cm_null.mcap": "schema", "outcome_unknown.mcap": "schema",
                 "chunk_crc_digit.mcap": "crc", "data_crc.mcap": "crc", "summary_crc.mcap": "crc",
                 "trailing_bytes.mcap": "damaged", "config_bad_yaml.mcap": "metadata", "h_wait_abc.mcap": "metadata",
                 "tpt_ragged.mcap": "schema", "truncated_mid_chunk.mcap": "truncated"}


def test_left_out_logs_carry_the_kind_of_check_that_failed(tmp_path, recorded_logs, capsys):  # noqa: F811
    """Each left-out log says what it is (a copy, not a regular file) or which check it failed, in the table and
    in the report's counts, not just "unreadable"."""
    from analysis import report
    from analysis.metrics import analyse_logs

    logs = tmp_path / "logs"
    logs.mkdir()
    for name in BAD_LOG_KINDS:
        shutil.copy(BAD_LOGS / name, logs / name)
    shutil.copy(recorded_logs[0], logs / "good.mcap")
    shutil.copy(recorded_logs[0], logs / "good_copy.mcap")
    os.mkfifo(logs / "fifo.mcap")
    analysis = analyse_logs([logs])
    left_out = analysis.excluded.assign(name=[Path(p).name for p in analysis.excluded["log"]]).set_index("name")
    assert left_out["kind"].to_dict() == {**BAD_LOG_KINDS, "good_copy.mcap": "duplicate",
                                          "fifo.mcap": "not-regular-file"}
    assert left_out.loc["good_copy.mcap", "outcome"] == left_out.loc["fifo.mcap", "outcome"] == "skipped"
    assert left_out.loc["chunk_crc_digit.mcap", "outcome"] == "unreadable"
    assert len(analysis.episodes) == 1
    assert report.main([str(logs), "--out", str(tmp_path / "report")]) == 0
    assert ("16 log(s) left out (4 schema, 3 crc, 3 metadata, 2 not-mcap, 1 damaged, 1 duplicate, "
            "1 not-regular-file, 1 truncated)") in capsys.readouterr().out
    markdown = (tmp_path / "report" / "report.md").read_text()
    assert re.search(r"\|\s*log\s*\|\s*kind\s*\|", markdown) and "not-regular-file" in markdown


@pytest.mark.parametrize(("forged", "expect"), [
    ("goal", "/episode outcome: 'goal', but the robot ends "),
    ("collision", "/episode outcome: 'collision', but the last step (step 13) has no contact")])
def test_an_outcome_its_last_step_contradicts_is_left_out(tmp_path, recorded_logs, forged, expect, capsys):  # noqa: F811
    """/episode outcome rewritten from timeout to goal (the robot 470+ cm short of the goal) was counted as a success
    by the report and passed replay --verify (hostile14b l_forged_goal)."""
    from analysis.metrics import analyse_logs
    from runners import replay
    from tests.log_surgery import rewrite

    def forge(topic, _index, msg):
        if topic == "/episode":
            assert msg["outcome"] == "timeout"
            return {**msg, "outcome": forged}
        return msg

    log = rewrite(recorded_logs[0], tmp_path / "forged.mcap", message=forge)
    analysis = analyse_logs([log])
    assert analysis.episodes.empty and len(analysis.excluded) == 1
    row = analysis.excluded.iloc[0]
    assert row["kind"] == "episode" and expect in row["reason"], row["reason"]
    assert replay.main([str(log), "--verify", "--quiet"]) == 2
    assert expect in capsys.readouterr().err
    # the true outcome still passes
    analysis = analyse_logs([rewrite(recorded_logs[0], tmp_path / "same.mcap", message=lambda _t, _i, m: m)])
    assert len(analysis.episodes) == 1 and analysis.excluded.empty


def test_logs_named_in_upper_case_are_read_and_deduplicated(tmp_path, recorded_logs):  # noqa: F811
    """``a.mcap`` and ``b.MCAP`` (another episode) in one folder: b.MCAP was skipped without a word, '1 episodes
    analysed, 0 left out' (hostile14b r_upper_ext). A copy of a.mcap named ``C.Mcap`` is still a duplicate."""
    from analysis.metrics import analyse_logs

    shutil.copy(recorded_logs[0], tmp_path / "a.mcap")
    shutil.copy(recorded_logs[1], tmp_path / "b.MCAP")
    analysis = analyse_logs([tmp_path])
    assert sorted(Path(p).name for p in analysis.episodes["log"]) == ["a.mcap", "b.MCAP"]
    assert analysis.excluded.empty
    shutil.copy(recorded_logs[0], tmp_path / "C.Mcap")
    analysis = analyse_logs([tmp_path])
    assert len(analysis.episodes) == 2
    assert analysis.excluded["kind"].tolist() == ["duplicate"]


def test_a_log_that_grows_while_it_is_read_is_read_whole_up_to_the_limit(tmp_path, monkeypatch):
    """read_log_bytes reads the size fstat reports, and on when the file has grown since: all of it, and never more
    than the limit plus one byte (so that the size check refuses a file grown past it)."""
    import analysis.logs as logs

    path = tmp_path / "grown.mcap"
    content = bytes(range(256)) * 40
    path.write_bytes(content)
    assert logs.read_log_bytes(path) == content
    real_fstat = os.fstat

    def stale_fstat(fd):  # the size before the file grew
        st = real_fstat(fd)
        return os.stat_result((*st[:6], 100, *st[7:]))

    monkeypatch.setattr(logs.os, "fstat", stale_fstat)
    assert logs.read_log_bytes(path) == content
    monkeypatch.setattr(logs, "MAX_FILE_BYTES", 5000)
    assert logs.read_log_bytes(path) == content[:5001]


@pytest.mark.parametrize("fault", ["deleted", "damaged"])
def test_a_counted_copy_lost_while_the_report_runs_is_replaced_by_another_copy(
        tmp_path, recorded_logs, fault, monkeypatch):  # noqa: F811
    """Three copies of one episode: the one chosen to be counted was deleted (or damaged) after it was chosen and
    before its metrics were read; its copies stayed marked as duplicates and the episode counted zero times,
    exit 0 (issue 37, hostile corpus)."""
    import analysis.metrics as metrics
    from analysis.log_inputs import find_logs

    for name in ("a.mcap", "b.mcap", "c.mcap"):
        shutil.copy(recorded_logs[0], tmp_path / name)

    def find_then_lose(paths):
        found = find_logs(paths)
        chosen = next(p for p in found if not hasattr(p, "kind"))
        if fault == "deleted":
            chosen.unlink()
        else:
            data = bytearray(chosen.read_bytes())
            data[len(data) // 2] ^= 0xFF
            chosen.write_bytes(bytes(data))
        return found

    monkeypatch.setattr(metrics, "find_logs", find_then_lose)
    analysis = metrics.analyse_logs([tmp_path])
    assert len(analysis.episodes) == 1  # counted once, from a copy
    kinds = analysis.excluded["kind"].tolist()
    assert kinds.count("duplicate") == 1 and len(kinds) == 2
    lost = analysis.excluded[analysis.excluded["kind"] != "duplicate"].iloc[0]
    assert "is counted instead" in lost["reason"] and Path(lost["log"]).name == "a.mcap"
    assert Path(analysis.episodes["log"].iloc[0]).name == "b.mcap"


def test_a_config_text_parsed_once_gives_each_caller_its_own_copy():
    from analysis import log_check

    text = "a: {b: [1, {c: 2.5}], d: x}\nn: null\n"
    first = log_check._parse_config(text)
    first["a"]["b"][1]["c"] = 99  # a caller that changes its config changes no other caller's
    second = log_check._parse_config(text)
    assert second == {"a": {"b": [1, {"c": 2.5}], "d": "x"}, "n": None} and second is not first
    deep = "a: " + "[" * 400 + "]" * 400 + "\n"  # deeper than the recursion limit allows a recursive copy
    value = log_check._parse_config(deep)["a"]
    for _ in range(399):
        value = value[0]
    assert value == []


@pytest.mark.parametrize("factor", [5.0, 0.0, 1.01])
def test_a_goal_disc_other_than_the_scenarios_tolerance_is_left_out(tmp_path, recorded_logs, factor):  # noqa: F811
    """The scene's goal disc re-sized (the metrics measure the time to the goal with it): the log contradicts its
    scenario's goal tolerance and is left out, as a moved goal is; the disc as written passes."""
    from analysis.metrics import analyse_logs
    from tests.log_surgery import rewrite

    def resize(topic, index, msg):
        if topic != "/scene" or index != 0:
            return msg
        msg = copy.deepcopy(msg)
        goal = next(e for e in msg["entities"] if e.get("id") == "goal")
        for cylinder in goal["cylinders"]:
            cylinder["size"]["x"] *= factor
            cylinder["size"]["y"] *= factor
        return msg

    analysis = analyse_logs([rewrite(recorded_logs[0], tmp_path / "goal.mcap", message=resize)])
    assert analysis.episodes.empty and analysis.excluded["kind"].tolist() == ["episode"]
    assert "/scene goal: a disc of radius" in analysis.excluded["reason"].iloc[0]


@pytest.mark.parametrize(("edit", "field"), [
    (lambda m: m.pop("config_hash"), "config_hash"),
    (lambda m: m.update(config_hash="not-a-digest"), "config_hash"),
    (lambda m: m.update(config_hash="0" * 64), "config_hash"),
    (lambda m: m.pop("fuzzynav_version"), "fuzzynav_version"),
    (lambda m: m.update(fuzzynav_version="9.9.9"), "config_hash"),
])
def test_the_record_cannot_be_unchecked_by_deleting_or_spoiling_its_hash(edit, field):
    """A log whose config was edited (another run's parameters: it was pooled into the wrong group) and whose
    ``config_hash`` or ``fuzzynav_version`` was deleted or spoiled is refused, naming the field: every log
    ``runners.run`` writes has both, so their absence is no reason to skip the check."""
    from analysis.log_check import check_metadata

    log = ROOT / "datasets" / "paper_fig5" / "logs" / "paper_fig5__planner-auto_h2__s0.mcap"
    meta = dict(LogFile(log).metadata())
    check_metadata(meta)  # the log as written passes
    meta["config"] = meta["config"].replace("safety_margin_cm: 10", "safety_margin_cm: 20")
    assert "safety_margin_cm: 20" in meta["config"]
    edit(meta)
    with pytest.raises(CheckError) as err:
        check_metadata(meta)
    assert err.value.where == field, str(err.value)
