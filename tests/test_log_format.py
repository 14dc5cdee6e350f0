"""The log format is defined once (:mod:`analysis.log_format`) and the analysis's message checks come from it: on
mutated real messages of every topic (another type, a missing key or item, NaN, huge or negative numbers, an extra
key) the analysis's check and the JSON schema (``jsonschema``) agree, the analysis being stricter on ranges and
shapes only, and blind only to the fields it names as not read (``UNREAD``, ``LENIENT``) and to fields no schema
describes."""

from __future__ import annotations

import copy
import math
from typing import Any

import jsonschema
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from jsonschema import validators

from analysis.json_checks import number
from analysis.log_check import LENIENT, MESSAGE_CHECKS, RANGES, READ, TOPIC_SCHEMAS, UNREAD, CheckError, check_message
from analysis.log_format import SCHEMAS, TOPICS
from analysis.logs import LogFile
from analysis.schema_checks import Ranges, SchemaError, build_check
from fuzzynav.params import names as policy_names
from tests.log_surgery import message_paths
from tests.valid_logs import recorded_logs  # noqa: F401 - the session fixture

# JSON integers are written without a fraction: the analysis takes 7.0 as a number, not an integer (jsonschema
# by default takes it as both)
_INT_ONLY = jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("integer", lambda _checker, v: type(v) is int)
Validator = validators.extend(jsonschema.Draft202012Validator, type_checker=_INT_ONLY)
VALIDATORS = {topic: Validator(SCHEMAS[name]()) for topic, name in TOPICS.items()}

OTHER_VALUES: list[Any] = [None, True, "abc", 7, 1.5, [], {}, [1.5], {"x": 1}]
STRUCTURAL = ("missing", "expected ", "is not one of", "is not a string matching")  # what a JSON schema can say


def _structural(problem: str) -> bool:
    """A problem a JSON schema can state (missing, type, enum, pattern), not a range or a shape between fields."""
    return problem == "missing" or problem.startswith("expected ") or any(s in problem for s in STRUCTURAL[2:])


class Messages(dict):
    """Real messages by topic (a short repr: hypothesis prints the arguments of a failing example)."""

    def __repr__(self) -> str:
        return f"<{sum(map(len, self.values()))} real messages>"


@pytest.fixture(scope="module")
def messages(recorded_logs) -> Messages:  # noqa: F811
    """Per topic, a few real messages: the richest (lists filled, a plan), the first, the last (the first /scene:
    the one the analysis reads)."""
    out = Messages()
    for path in recorded_logs:
        by_topic: dict[str, list] = {}
        for topic, _t, msg in LogFile(path).messages():
            by_topic.setdefault(topic, []).append(msg)
        for topic, msgs in by_topic.items():
            picked = [msgs[0]] if topic == "/scene" else [max(msgs, key=lambda m: len(repr(m))), msgs[0], msgs[-1]]
            out.setdefault(topic, []).extend(picked)
    assert set(out) >= set(MESSAGE_CHECKS)
    return out


def test_real_messages_satisfy_both(messages):
    for topic, msgs in messages.items():
        for msg in msgs:
            VALIDATORS[topic].validate(msg)
            check_message(topic, msg)


def _dotted(path: tuple) -> str:
    return ".".join(str(k) for k in path if not isinstance(k, int))


def _under(dotted: str, fields: tuple[str, ...]) -> bool:
    """``dotted`` is one of ``fields`` or inside one."""
    return any(dotted == f or dotted.startswith(f"{f}.") for f in fields)


def _is_read(topic: str, dotted: str) -> bool:
    """The analysis reads this field, a field inside it or (the message itself: ``""``) the object holding it."""
    read = READ[topic]
    return dotted == "" or _under(dotted, read) or any(r.startswith(f"{dotted}.") for r in read)


def _analysis(topic: str, msg: Any) -> str | None:
    try:
        check_message(topic, msg)
    except CheckError as err:
        return err.problem
    return None


def _schema_at(schema: dict[str, Any], path: tuple) -> dict[str, Any]:
    """The schema of the value at ``path`` in a message (the object variant of a nullable object)."""
    node = schema
    for key in path:
        node = node["items"] if isinstance(key, int) else node["properties"][key]
        if "oneOf" in node:
            node = next((v for v in node["oneOf"] if v.get("type") == "object"), node)
    return node


def _mutate(msg: dict[str, Any], path: tuple, kind: str, value: Any) -> dict[str, Any] | None:
    out = copy.deepcopy(msg)
    if not path:
        return value if kind == "type" else None
    parent = out
    for key in path[:-1]:
        parent = parent[key]
    leaf = path[-1]
    if kind == "delete":
        del parent[leaf]
    elif kind == "extra":
        if not isinstance(parent[leaf], dict):
            return None
        parent[leaf]["unexpected_field"] = value
    else:
        parent[leaf] = value
    return out


MUTATIONS = {"type": st.sampled_from(OTHER_VALUES), "delete": st.just(None),
             "nan": st.sampled_from([math.nan, math.inf, -math.inf]), "huge": st.sampled_from([1e300, -1e300, 2**64]),
             "negative": st.sampled_from([-1, -0.5]), "extra": st.sampled_from([1, "x", None])}


@settings(max_examples=1500, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=st.data())
def test_the_analysis_and_the_schema_agree_on_mutated_messages(messages, data):
    topic = data.draw(st.sampled_from(sorted(MESSAGE_CHECKS)))
    msg = data.draw(st.sampled_from(messages[topic]))
    path = data.draw(st.sampled_from([(), *message_paths(msg, last_item=True)]))
    kind = data.draw(st.sampled_from(sorted(MUTATIONS)))
    mutated = _mutate(msg, path, kind, data.draw(MUTATIONS[kind]))
    if mutated is None:
        return
    problem = _analysis(topic, mutated)
    schema_errors = [e.message for e in VALIDATORS[topic].iter_errors(mutated)]
    dotted = _dotted(path)
    event(f"{kind}: analysis {'refuses' if problem else 'accepts'}, schema {'refuses' if schema_errors else 'accepts'}")
    said = f"{topic} {kind} at {path}: analysis says {problem!r}, the schema {schema_errors[:2]}"
    # the analysis refuses for what a schema can state: so does the schema
    if problem is not None and _structural(problem):
        assert schema_errors, said
    # what the analysis does not read, or a field no schema describes, cannot change its verdict
    undescribed = kind == "extra" and not isinstance(_schema_at(SCHEMAS[TOPICS[topic]](), path).get(
        "additionalProperties"), dict)  # else a new entry of a map (a decision's policy_fields): a value
    if undescribed or (path and not _is_read(topic, dotted) and not _under(dotted, LENIENT.get(topic, ()))):
        assert undescribed or _under(dotted, UNREAD[topic]), said
        assert problem is None, said
    # the schema refuses a field the analysis reads: so does the analysis (LENIENT fields may be missing)
    elif schema_errors and not (kind == "delete" and _under(dotted, LENIENT.get(topic, ()))):
        assert problem is not None, said


def test_read_unread_and_lenient_fields_cover_each_schema_once():
    for topic, read in READ.items():
        schema = SCHEMAS[TOPIC_SCHEMAS[topic]]()
        top = set(schema["properties"])
        named = {p.split(".")[0] for p in (*read, *UNREAD[topic], *LENIENT.get(topic, ()))}
        assert named == top, topic
        assert not any(_under(u, read) or _is_read(topic, u) for u in UNREAD[topic]), topic


def test_the_topics_checked_declare_the_writers_schemas():
    assert {t: TOPICS[t] for t in MESSAGE_CHECKS} == TOPIC_SCHEMAS


def test_the_decision_mode_pattern_is_the_policies_name_pattern():
    mode = SCHEMAS["fuzzynav.Decision"]()["properties"]["mode"]["pattern"]
    assert mode == f"^{policy_names.NAME.pattern}$"


SCHEMA = {"type": "object", "properties": {"a_cm": {"type": "number"}, "n": {"type": "integer", "minimum": 1},
                                           "opt": {"type": "string"}}, "required": ["a_cm", "n"]}


@pytest.mark.parametrize(("paths", "ranges", "error"), [
    (("b_cm",), RANGES, "t b_cm: read, but the schema does not describe it"),
    (("opt",), RANGES, "t opt: read as always present, but the schema does not require it"),
    (("a_cm",), Ranges(numbers=[]), "t a_cm: a number without a range (add a rule)"),
    (("a_cm.x",), RANGES, "t a_cm: fields ['x'] read inside a number"),
    ((), RANGES, "t: no field read"),
])
def test_a_check_that_cannot_come_from_the_schema_is_refused_when_built(paths, ranges, error):
    with pytest.raises(SchemaError) as err:
        build_check("t", SCHEMA, paths, ranges)
    assert str(err.value) == error


def test_a_built_check_takes_the_schemas_minimum_and_the_rules_range():
    check = build_check("t", SCHEMA, ("a_cm", "n"), Ranges(numbers=[(r"_cm$", 0.0, 10.0)]))
    check({"a_cm": 10, "n": 1, "other": "not read"})
    for bad, said in (({"a_cm": 10.5, "n": 1}, "a_cm: 10.5 is out of range [0, 10]"),
                      ({"a_cm": 1.0, "n": 0}, "n: 0 is out of range [1, 9223372036854775807]"),
                      ({"a_cm": 1.0}, "n: missing"), ({"a_cm": "1", "n": 1}, "a_cm: expected a number, got a string")):
        with pytest.raises(CheckError) as err:
            check(bad)
        assert str(err.value) == said
    assert number(0.0, 10.0).bounds == (0.0, 10.0)
