"""How a regenerated episode differs from its recording: a changed decision, plan or outcome, another discrete
change, or floating-point values only (see :mod:`runners.logs.fields`), with the largest absolute difference
per numeric field.

Two sources: the recorded log itself (:func:`diff_logs`, message by message: every field is measured), or,
where only the manifest is kept, its digests, mode sequence and per-topic float sums (:func:`diff_records`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis.logs import iter_messages
from runners.logs.fields import BEHAVIOUR, DISCRETE, FLOAT, compare, expand_runs, kind_of, parse_sums

UNCLASSIFIED = "unclassified"
SUM_FIELD = "sum of floats"  # the field name of a difference measured on a manifest's per-topic float sum


@dataclass
class FloatDelta:
    """The differing values of one numeric field: the largest absolute difference (the field's unit), at
    which step (None: measured on the manifest's per-topic sum), and how many values differ."""

    max_abs: float
    step: int | None
    count: int = 1


@dataclass
class Change:
    """One differing non-float value."""

    kind: str  # BEHAVIOUR or DISCRETE
    topic: str
    step: int
    field: str  # dotted path ("" = the whole message, present in one log only)
    recorded: Any
    now: Any


@dataclass
class EpisodeDiff:
    """The classified difference of one episode. ``kind`` is the most serious kind found (``behaviour``,
    ``discrete``, ``float``) or ``unclassified`` (an old manifest without the behaviour record).
    ``floats`` maps (topic, field) to its :class:`FloatDelta`; ``first`` is the first change of the kind
    (None for float-only), ``first_message`` the first differing message (topic, step)."""

    kind: str
    source: str  # "log" (measured message by message) or "manifest" (digests, modes, float sums)
    first: Change | None = None
    first_message: tuple[str, int] | None = None
    counts: dict[str, int] = field(default_factory=dict)  # kind -> number of differing non-float values
    floats: dict[tuple[str, str], FloatDelta] = field(default_factory=dict)
    note: str = ""  # what the manifest could tell, when that is all there is

    def per_topic(self) -> list[tuple[str, str, FloatDelta]]:
        """The largest float difference of each topic, (topic, field, delta), largest first."""
        best: dict[str, tuple[str, FloatDelta]] = {}
        for (topic, name), delta in self.floats.items():
            if topic not in best or delta.max_abs > best[topic][1].max_abs:
                best[topic] = (name, delta)
        return sorted(((t, n, d) for t, (n, d) in best.items()), key=lambda x: -x[2].max_abs)


def _keyed(path: Path) -> Iterator[tuple[tuple[int, str, int], dict[str, Any]]]:
    """Messages keyed by (log time, topic, occurrence at that time), in log order."""
    seen: dict[tuple[int, str], int] = {}
    for topic, t, msg in iter_messages(path):
        n = seen.get((t, topic), 0)
        seen[(t, topic)] = n + 1
        yield (t, topic, n), msg


class _Collector:
    """Receives the differences of one message pair after another (see :func:`runners.logs.fields.compare`)."""

    def __init__(self, diff: EpisodeDiff) -> None:
        self.diff = diff
        self.firsts: dict[str, Change] = {}  # kind -> its first change
        self.topic, self.step = "", 0  # the message pair being compared

    def _seen(self) -> None:
        if self.diff.first_message is None:
            self.diff.first_message = (self.topic, self.step)

    def on_discrete(self, path: str, recorded: Any, now: Any) -> None:
        self._seen()
        kind = kind_of(self.topic, path)
        self.diff.counts[kind] = self.diff.counts.get(kind, 0) + 1
        self.firsts.setdefault(kind, Change(kind, self.topic, self.step, path, recorded, now))

    def on_float(self, path: str, delta: float) -> None:
        self._seen()
        cur = self.diff.floats.get((self.topic, path))
        if cur is None:
            self.diff.floats[(self.topic, path)] = FloatDelta(delta, self.step)
            return
        cur.count += 1
        if delta > cur.max_abs:
            cur.max_abs, cur.step = delta, self.step


def diff_logs(recorded: Path, fresh: Path) -> EpisodeDiff:
    """Compare two logs of one episode message by message, aligned by step and topic (so that a prediction
    table present in one log only does not shift the comparison of the rest)."""
    old = dict(_keyed(recorded))
    new = dict(_keyed(fresh))
    order = list(old) + [k for k in new if k not in old]
    order.sort(key=lambda k: k[0])  # stable: log order within a step
    # log time -> step, from the messages that state their step (log time is step * dt, and dt is configurable)
    steps = {t: m["step"] for (t, _, _), m in [*old.items(), *new.items()] if isinstance(m, dict) and "step" in m}
    diff = EpisodeDiff(kind=FLOAT, source="log")
    out = _Collector(diff)
    for key in order:
        a, b = old.get(key), new.get(key)
        if a == b:
            continue
        t, out.topic, _ = key
        out.step = steps.get(t, len(steps))  # a time without a stepped message: the end (/episode, last /log)
        if a is None or b is None:
            out.on_discrete("", "present" if a is not None else "absent", "present" if b is not None else "absent")
        else:  # (compare skips compute_time_us: a pair differing only there adds nothing)
            compare(out.topic, a, b, out.on_discrete, out.on_float)
    for kind in (BEHAVIOUR, DISCRETE):
        if kind in out.firsts:
            diff.kind, diff.first = kind, out.firsts[kind]
            break
    return diff


def _first_mode_change(old: str, new: str) -> str:
    """Where two run-length encoded mode sequences (recorded, now) first differ."""
    a, b = expand_runs(old), expand_runs(new)
    for k, (x, y) in enumerate(zip(a, b, strict=False)):
        if x != y:
            return f"first changed decision at step {k}: mode {x} -> {y}"
    if len(a) != len(b):
        return f"the same mode for {min(len(a), len(b))} steps, then {len(a)} vs {len(b)} steps"
    return "the same mode at every step (a plan, a contact or the outcome differs)"


def diff_records(expected: dict[str, Any], got: dict[str, Any]) -> EpisodeDiff:
    """Classify a difference from manifest entries only (the recorded log is not kept): ``expected`` from the
    manifest, ``got`` from the regenerated episode (both with ``outcome``, ``steps`` and, in manifests built
    since they exist, the fields of :class:`runners.logs.fields.BehaviourRecord`)."""
    if expected.get("outcome") != got.get("outcome") or expected.get("steps") != got.get("steps"):
        note = "" if "modes" not in expected else _first_mode_change(expected["modes"], got["modes"])
        return EpisodeDiff(kind=BEHAVIOUR, source="manifest", note=note)
    if "decision_digest" not in expected:
        return EpisodeDiff(kind=UNCLASSIFIED, source="manifest",
                           note="the manifest predates decision digests: rebuild it to classify")
    if expected["decision_digest"] != got["decision_digest"]:
        return EpisodeDiff(kind=BEHAVIOUR, source="manifest", note=_first_mode_change(expected["modes"], got["modes"]))
    if expected["discrete_digest"] != got["discrete_digest"]:
        return EpisodeDiff(kind=DISCRETE, source="manifest", note="decisions, plans and outcome the same")
    diff = EpisodeDiff(kind=FLOAT, source="manifest")
    old, new = parse_sums(expected.get("float_sums", "")), parse_sums(got.get("float_sums", ""))
    for topic in sorted(old.keys() & new.keys()):
        if old[topic] != new[topic]:
            diff.floats[(topic, SUM_FIELD)] = FloatDelta(abs(old[topic] - new[topic]), None)
    if not diff.floats:
        diff.note = "the float sums are equal (the drift is in topics not summed, or below the sums' resolution)"
    return diff
