"""Fuzzing the analysis with damaged logs (issue 14, item 7): hypothesis mutates valid logs — bytes (truncation,
bit flips, insertion, deletion, overwriting), the ``fuzzynav.run`` metadata (wrong types, NaN, huge, missing,
invalid YAML, alias bombs) and single messages (missing fields, wrong types, huge numbers, ragged arrays,
dropped or repeated messages) — and feeds each to the metrics reader, ``runners.replay --verify`` and the resume
check (``episode_summary``), in process, under a time limit. Each must give the unmutated log's result exactly
(the mutation hit nothing the analysis reads) or refuse the log with a reason: never a traceback, never a hang,
never a silently different metric.

A few hundred examples run in CI (derandomized); set ``FUZZNAV_FUZZ_EXAMPLES=2000`` for that many per class,
random, and ``FUZZNAV_FUZZ_STATS=file.json`` to write how many examples ran and how each ended.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import signal
from collections import Counter
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis import report
from analysis.log_format import SCHEMAS, TOPICS
from analysis.logs import LogError, episode_summary
from analysis.metrics import metrics_table
from runners import replay
from tests.log_surgery import DROP, Twice, message_paths, rewrite
from tests.valid_logs import recorded_logs  # noqa: F401 - the session fixture

EXAMPLES = int(os.environ.get("FUZZNAV_FUZZ_EXAMPLES", "0"))
TIME_LIMIT_S = 30  # per tool and example: a hang fails the example instead of the test run
STATS: Counter[str] = Counter()


def fuzz_settings(ci_examples: int) -> settings:
    return settings(max_examples=EXAMPLES or ci_examples, deadline=None, derandomize=not EXAMPLES,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                           HealthCheck.data_too_large], database=None)


@pytest.fixture(scope="module", autouse=True)
def write_stats():
    yield
    if os.environ.get("FUZZNAV_FUZZ_STATS"):
        Path(os.environ["FUZZNAV_FUZZ_STATS"]).write_text(json.dumps(dict(sorted(STATS.items())), indent=1))


class Hang(Exception):
    """A tool ran longer than ``TIME_LIMIT_S`` on one example."""


@contextlib.contextmanager
def time_limit(what: str):
    def expire(signum, frame):
        raise Hang(f"{what} ran longer than {TIME_LIMIT_S} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, TIME_LIMIT_S)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


# -- what the analysis says about one log ------------------------------------------------------------------
def _row(path: Path) -> tuple[dict[str, Any] | None, str | None]:
    """(metrics row without the path, None) or (None, the reason the log was left out)."""
    with time_limit("metrics_table"):
        df, left_out = metrics_table([path])
    if df.empty:
        assert len(left_out) == 1, left_out
        return None, str(left_out["reason"].iloc[0])
    assert len(df) == 1 and left_out.empty
    return {k: v for k, v in df.iloc[0].to_dict().items() if k != "log"}, None


def _replay(path: Path) -> tuple[int, str]:
    out, err = io.StringIO(), io.StringIO()
    with time_limit("replay --verify"), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = replay.main([str(path), "--verify"])
    return code, (out.getvalue() if code == 0 else err.getvalue()).strip()


def _summary(path: Path) -> dict[str, Any] | str:
    with time_limit("episode_summary"):
        try:
            return {k: v for k, v in episode_summary(path).items() if k != "log"}
        except LogError as err:
            return str(err)


def _same(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return a.keys() == b.keys() and all(
        x == y or (isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y))
        for x, y in ((a[k], b[k]) for k in a))


@pytest.fixture(scope="module")
def baselines(recorded_logs, tmp_path_factory):  # noqa: F811 - the fixture imported above
    """Per recorded log: its bytes, metrics row, replay answer and summary; the same for its re-written copy
    (the base of the metadata and message mutations)."""
    out = []
    for path in recorded_logs:
        copy = rewrite(path, tmp_path_factory.mktemp("rewritten") / path.name)
        row, why = _row(path)
        assert why is None, why
        code, said = _replay(path)
        assert code == 0 and said.endswith("decisions reproduced"), said
        copy_row, _ = _row(copy)
        assert copy_row is not None and _same(copy_row, row)
        assert _replay(copy) == (0, said.replace(str(path), str(copy)))
        out.append(Base({"path": path, "copy": copy, "bytes": path.read_bytes(), "row": row, "replay": said,
                         "summary": _summary(path)}))
    return out


class Base(dict):
    """A recorded log's baseline (short repr: hypothesis prints the examples it draws)."""

    def __repr__(self) -> str:
        return f"<baseline of {self['path'].name}>"


def check_refused_or_unchanged(path: Path, base: dict[str, Any], kind: str) -> None:
    """The oracle: every tool gives the unmutated answer, or refuses the log with a reason."""
    row, why = _row(path)
    code, said = _replay(path)
    summary = _summary(path)
    if row is None:
        assert why, "left out without a reason"
    else:
        assert _same(row, base["row"]), f"silently different metrics: {row} vs {base['row']}"
    if code == 0:
        assert row is not None, f"replay reproduces a log the analysis refused ({why})"
        assert said == base["replay"].replace(str(base["path"]), str(path)).replace(str(base["copy"]), str(path))
    elif code == 1:  # replay's own verdict: the log's decisions are not what this code decides
        assert said.startswith(f"{path}: decision differs at step ") and len(said.splitlines()) == 1, said
    else:
        assert code == 2, f"replay exit {code}: {said}"
        lines = said.splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"error: {path}"), said
    verdict = {0: "reproduced", 1: "differs", 2: "refused"}[code]
    STATS[f"{kind}: metrics {'refused' if row is None else 'unchanged'}, replay {verdict}"] += 1
    if isinstance(summary, dict):
        assert summary == base["summary"] or row is None, f"summary changed silently: {summary}"
    else:
        assert summary.startswith(f"{path}: "), summary


# -- byte mutations -------------------------------------------------------------------------------------------
@st.composite
def byte_mutation(draw, size: int) -> tuple[str, int, bytes | int]:
    kind = draw(st.sampled_from(["truncate", "flip", "insert", "delete", "overwrite"]))
    at = draw(st.integers(0, size - 1))
    if kind == "flip":
        return kind, at, draw(st.integers(0, 7))
    if kind in ("insert", "overwrite"):
        return kind, at, draw(st.binary(min_size=1, max_size=16))
    if kind == "delete":
        return kind, at, draw(st.integers(1, 64))
    return kind, at, 0


def apply_bytes(data: bytes, mutation: tuple[str, int, bytes | int]) -> bytes:
    kind, at, arg = mutation
    if kind == "truncate":
        return data[:at]
    if kind == "flip":
        return data[:at] + bytes([data[at] ^ (1 << arg)]) + data[at + 1:]  # type: ignore[operator]
    if kind == "insert":
        return data[:at] + arg + data[at:]  # type: ignore[operator]
    if kind == "delete":
        return data[:at] + data[at + arg:]  # type: ignore[operator]
    return data[:at] + arg + data[at + len(arg):]  # type: ignore[arg-type]


@fuzz_settings(150)
@given(data=st.data())
def test_damaged_bytes_are_refused(baselines, tmp_path, data):
    base = data.draw(st.sampled_from(baselines))
    mutation = data.draw(byte_mutation(len(base["bytes"])))
    mutated = apply_bytes(base["bytes"], mutation)
    if mutated == base["bytes"]:
        return
    path = tmp_path / f"bytes-{mutation[0]}.mcap"
    path.write_bytes(mutated)
    check_refused_or_unchanged(path, base, f"bytes/{mutation[0]}")


# -- metadata mutations ---------------------------------------------------------------------------------------
BAD_STRINGS = ["", "abc", "nan", "NaN", "inf", "-inf", "1e308", "-1", "1.5", "0x10", "null", "[1]", "{a: 1}",
               "../../escaped", "a\0b", "a\nb", "x" * 300, "٣", " 2", "2 ", "+2", "99999999999999999999999"]
BAD_VALUES = [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 0, -1, 0.0, "abc", None, [], {}, True,
              [1, 2, 3], {"a": 1}, 10**30]


@st.composite
def config_mutation(draw, config_text: str) -> str:
    """A changed config YAML text."""
    kind = draw(st.sampled_from(["leaf", "delete", "text", "bomb", "not_a_mapping", "deep"]))
    if kind == "text":
        return draw(st.sampled_from(["dt: [1.0\n", "dt: 1\n  x: 2\n", "{", "\t", "dt: !!python/object:os.system x\n",
                                     "? [a, b]\n: 1\n", "1: 2\n", "dt: 2020-01-01\n"]) | st.text(max_size=40))
    if kind == "bomb":
        return "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
            f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi", strict=True))
    if kind == "not_a_mapping":
        return draw(st.sampled_from(["- 1\n- 2\n", "3\n", "'text'\n", "null\n"]))
    if kind == "deep":
        return "a: " + "[" * 5000 + "]" * 5000 + "\n"
    config = yaml.safe_load(config_text)
    paths = []

    def walk(node: Any, prefix: tuple) -> None:
        if isinstance(node, dict):
            for k, v in node.items():
                paths.append((*prefix, k))
                walk(v, (*prefix, k))

    walk(config, ())
    preferred = [p for p in paths if p in (("dt",), ("planner", "h_wait"), ("planner", "strategy"),
                                           ("controller", "name"), ("perception", "mode"), ("scenario", "name"),
                                           ("sensors", "sonar", "left"), ("seed",))]
    path = draw(st.sampled_from(preferred) | st.sampled_from(paths))
    node = config
    for key in path[:-1]:
        node = node[key]
    if kind == "delete":
        del node[path[-1]]
    else:
        node[path[-1]] = draw(st.sampled_from(BAD_VALUES))
    return yaml.safe_dump(config, sort_keys=False)


@fuzz_settings(100)
@given(data=st.data())
def test_bad_metadata_is_refused(baselines, tmp_path, data):
    base = data.draw(st.sampled_from(baselines))
    keys = ["seed", "h_wait", "scenario", "strategy", "controller", "perception", "config", "config_hash",
            "fuzzynav_version", "git_commit", "scenario_yaml"]
    key = data.draw(st.sampled_from(keys))
    action = data.draw(st.sampled_from(["set", "delete"] + (["config"] * 3 if key == "config" else [])))

    def edit(meta: dict[str, str]) -> dict[str, str]:
        if action == "delete":
            meta.pop(key, None)
        elif action == "config":
            meta["config"] = data.draw(config_mutation(meta["config"]))
        else:
            meta[key] = data.draw(st.sampled_from(BAD_STRINGS) | st.text(max_size=30))
        return meta

    path = rewrite(base["copy"], tmp_path / "metadata.mcap", metadata=edit)
    check_refused_or_unchanged(path, base, f"metadata/{key}/{action}")


# -- message mutations ----------------------------------------------------------------------------------------
_BY_TYPE = {"string": "abc", "number": 1.5, "integer": 7, "boolean": True, "array": [1.5], "object": {"x": 1},
            "null": None}
# arrays whose length another array or the schema ties down: dropping an item makes the message inconsistent
# (other arrays, e.g. a step's contact ids, may be any length: a shorter one is a different valid message)
_TIED = ("robot_cm", "obstacles_cm", "collide", "obstacle_ids", "obstacle_radii_cm", "ranges", "intensities",
         "obstacles", "entities", "points")


def _types(schema: dict[str, Any]) -> set[str]:
    """JSON types a schema allows (``oneOf`` variants merged; a missing type: any)."""
    if "oneOf" in schema:
        return set().union(*(_types(v) for v in schema["oneOf"]))
    if "const" in schema:
        return {"integer" if isinstance(schema["const"], int) else "string"}
    t = schema.get("type")
    return set(t) if isinstance(t, list) else {t} if t else set(_BY_TYPE)


def _field_schema(schema: dict[str, Any], path: tuple) -> dict[str, Any] | None:
    """The schema of the value at ``path`` in a message (None where the schema says nothing)."""
    node = schema
    for key in path:
        if "oneOf" in node:
            node = next((v for v in node["oneOf"] if v.get("type") == "object"), node)
        node = node.get("items") if isinstance(key, int) else node.get("properties", {}).get(key)
        if node is None:
            return None
    return node


def invalid_values(schema: dict[str, Any] | None) -> list[Any]:
    """Values the schema forbids at a field: every other JSON type, a string outside an enum, -1 where the
    minimum is 0, and numbers beyond every documented range (±1e300; schemas leave numbers unbounded, the
    analysis bounds every number it reads)."""
    if schema is None:
        return [None, "abc", [], {}, 1e300]
    allowed = _types(schema)
    out = [v for t, v in _BY_TYPE.items() if t not in allowed and not (t == "integer" and "number" in allowed)]
    if allowed & {"number", "integer"}:
        out += [1e300, -1e300]
    if "integer" in allowed and schema.get("minimum") == 0:
        out.append(-1)
    if "enum" in schema:
        out.append("not-one-of-the-values")
    return out


@fuzz_settings(150)
@given(data=st.data())
def test_bad_messages_are_refused(baselines, tmp_path, data):
    """Schema-invalid messages: a required field missing or of another type, a number out of every range, a
    string outside its enum, an array of a tied length shortened, a message replaced by a non-object, dropped
    or repeated. Extra fields are allowed by the analysis and change nothing."""
    base = data.draw(st.sampled_from(baselines))
    topic = data.draw(st.sampled_from(sorted(TOPICS)))
    schema = SCHEMAS[TOPICS[topic]]()
    target = data.draw(st.just(0) | st.integers(0, 20))  # the first message often: the first scene is the world
    action = data.draw(st.sampled_from(["value", "value", "value", "delete", "extra", "shorten", "whole",
                                        "drop", "repeat"]))
    if action == "drop" and topic == "/tpt":
        return  # a missing table on a step without a plan cannot be told from the messages read (README)
    done = []

    def edit(t: str, index: int, msg: Any) -> Any:
        if t != topic or index != min(target, _count(base, topic) - 1) or done:
            return msg
        done.append(True)
        if action == "drop":
            return DROP
        if action == "whole":
            return data.draw(st.sampled_from([None, [], "text", 7, [msg]]))
        if action == "repeat":
            return Twice(msg)
        paths = [p for p in message_paths(msg, last_item=True) if action in ("value", "extra") or (
            action == "delete" and not isinstance(p[-1], int)) or (
            action == "shorten" and isinstance(p[-1], str) and p[-1] in _TIED)]
        if not paths:
            return msg
        path = data.draw(st.sampled_from(paths))
        parent = msg
        for key in path[:-1]:
            parent = parent[key]
        leaf = path[-1]
        if action == "delete":
            del parent[leaf]
        elif action == "extra":
            if isinstance(parent, dict):
                parent["unexpected_field"] = 1
        elif action == "shorten":
            if isinstance(parent[leaf], list) and parent[leaf]:
                parent[leaf] = parent[leaf][:-1]
        else:
            parent[leaf] = data.draw(st.sampled_from(invalid_values(_field_schema(schema, path))))
        return msg

    path = rewrite(base["copy"], tmp_path / "message.mcap", message=edit)
    check_refused_or_unchanged(path, base, f"message/{topic}/{action}")


_COUNTS: dict[tuple[str, str], int] = {}


def _count(base: dict[str, Any], topic: str) -> int:
    """Messages of ``topic`` in the base log (at least 1, so that an index is always defined)."""
    key = (str(base["copy"]), topic)
    if key not in _COUNTS:
        from analysis.logs import LogFile

        _COUNTS[key] = max(1, sum(1 for _ in LogFile(base["copy"], [topic]).raw_messages()))
    return _COUNTS[key]


# -- the report, end to end ---------------------------------------------------------------------------------
@fuzz_settings(12)
@given(data=st.data())
def test_report_on_damaged_logs_lists_them_or_reports_them_unchanged(baselines, tmp_path_factory, data,
                                                                      monkeypatch_module):
    base = data.draw(st.sampled_from(baselines))
    mutation = data.draw(byte_mutation(len(base["bytes"])))
    tmp = tmp_path_factory.mktemp("report")
    path = tmp / "log.mcap"
    path.write_bytes(apply_bytes(base["bytes"], mutation))
    out, err = io.StringIO(), io.StringIO()
    with time_limit("analysis.report"), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = report.main([str(path), "--out", str(tmp / "rep"), "--jobs", "1"])
    assert code in (0, 1)  # 1: the only log was left out (the report says why)
    episodes = pd.read_csv(tmp / "rep" / "episodes.csv") if (tmp / "rep" / "episodes.csv").stat().st_size > 1 \
        else pd.DataFrame()
    md = (tmp / "rep" / "report.md").read_text()
    if episodes.empty:
        assert code == 1 and "0 episodes analysed, 1 left out" in md
        assert "error: none of the 1 log(s) could be analysed" in err.getvalue()
        STATS["report: refused"] += 1
    else:
        assert code == 0
        row = episodes.iloc[0]
        for key, value in base["row"].items():
            got = row[key]
            assert value == got or (pd.isna(value) and pd.isna(got)) or (
                isinstance(value, float) and math.isclose(value, got, rel_tol=1e-9)), (key, value, got)
        STATS["report: unchanged"] += 1


@pytest.fixture(scope="module")
def monkeypatch_module():
    """No PNGs in the report fuzz (matplotlib's time is not what is tested here)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(report.plots, "_save", lambda fig, path: report.plots.plt.close(fig) or path)
        yield mp
