"""The text ``dataset verify`` prints about differing episodes: one line per episode, optional per-field lines,
and a summary over all differing episodes. Float differences are in each field's own unit (cm, cm/s, degrees,
m on the Foxglove topics)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from runners.logs.diff import SUM_FIELD, UNCLASSIFIED, Change, EpisodeDiff
from runners.logs.fields import BEHAVIOUR, DISCRETE, FLOAT

LABELS = {BEHAVIOUR: "decision/plan/outcome changed", DISCRETE: "other discrete values changed, decisions the same",
          FLOAT: "float-only", UNCLASSIFIED: "unclassified"}
TOPICS_PER_LINE = 3  # float differences named per episode line (all of them with --detail)


def number(x: float) -> str:
    """A difference in two significant digits: ``2.1e-14``, ``0.5``, ``32``."""
    return f"{x:.2g}"


def _value(v: Any) -> str:
    return str(v)[:60]


def _change(c: Change) -> str:
    where = f"step {c.step} {c.topic}"
    if c.field == "":
        return f"{where}: message {c.recorded} in the recording, {c.now} now"
    return f"{where} {c.field}: recorded {_value(c.recorded)}, now {_value(c.now)}"


def _floats(diff: EpisodeDiff) -> str:
    topics = diff.per_topic()
    if not topics:
        return ""
    shown = ", ".join(f"{t} {number(d.max_abs)}" + ("" if name == SUM_FIELD else f" ({name})")
                      for t, name, d in topics[:TOPICS_PER_LINE])
    more = f" (+{len(topics) - TOPICS_PER_LINE} topics)" if len(topics) > TOPICS_PER_LINE else ""
    what = "|Δ| of each topic's float sum" if diff.source == "manifest" else "largest |Δ| per topic"
    return f"{what}: {shown}{more}"


def episode_line(file: str, expected: Mapping[str, Any], got: Mapping[str, Any], diff: EpisodeDiff,
                 location: str) -> str:
    """One line: the file, outcome and steps, the kind of difference, where it starts, the float sizes.
    ``location`` is where the first difference is (from the log or the per-step digests)."""
    parts = [f"{file}: content differs (outcome {expected['outcome']} -> {got['outcome']}, "
             f"steps {expected['steps']} -> {got['steps']}): {LABELS[diff.kind]}"]
    if diff.first is not None:
        parts[0] += f" at {_change(diff.first)}"
    if diff.note:
        parts.append(diff.note)
    if diff.kind in (BEHAVIOUR, DISCRETE) and diff.counts:
        parts.append(", ".join(f"{n} {'decision/plan/outcome' if k == BEHAVIOUR else 'other discrete'} value(s)"
                               for k, n in sorted(diff.counts.items())) + " differ")
    floats = _floats(diff)
    if floats:
        parts.append(floats)
    parts.append(location)
    return "; ".join(parts)


def detail_lines(diff: EpisodeDiff) -> list[str]:
    """Every differing numeric field: largest |Δ|, its step and how many values differ."""
    return [f"{topic} {name}: |Δ| {number(d.max_abs)}" if d.step is None else
            f"{topic} {name}: max |Δ| {number(d.max_abs)} at step {d.step} ({d.count} value(s))"
            for (topic, name), d in sorted(diff.floats.items())]


def _largest_per_topic(diffs: list[EpisodeDiff]) -> list[tuple[str, str, float]]:
    """(topic, field, largest |Δ|) over the episodes, one per topic, largest first."""
    best: dict[str, tuple[str, float]] = {}
    for d in diffs:
        for topic, name, delta in d.per_topic():
            if topic not in best or delta.max_abs > best[topic][1]:
                best[topic] = (name, delta.max_abs)
    return sorted(((t, n, v) for t, (n, v) in best.items()), key=lambda x: -x[2])


def summary_lines(diffs: Mapping[str, EpisodeDiff], compared: int) -> list[str]:
    """``7 of 7 episodes differ: 0 with a changed decision/plan/outcome, 7 float-only (largest |Δ| 2.1e-14 in
    /tracks heading_deg)``, and for float-only episodes the largest difference per topic. Sizes measured on
    committed logs come first; episodes without one have only their topics' float sums to show."""
    count = {k: sum(1 for d in diffs.values() if d.kind == k) for k in LABELS}
    line = (f"{len(diffs)} of {compared} episodes differ: {count[BEHAVIOUR]} with a changed decision/plan/outcome"
            + (f", {count[DISCRETE]} with other discrete changes only" if count[DISCRETE] else "")
            + f", {count[FLOAT]} float-only")
    floats = [d for d in diffs.values() if d.kind == FLOAT]
    measured = _largest_per_topic([d for d in floats if d.source == "log"])
    summed = _largest_per_topic([d for d in floats if d.source != "log"])
    notes = []
    if measured:
        topic, name, value = measured[0]
        notes.append(f"largest |Δ| {number(value)} in {topic} {name}")
    if summed:
        topic, _, value = summed[0]
        without = sum(1 for d in floats if d.source != "log")
        notes.append(f"{without} without a log: |Δ| of a topic's float sum up to {number(value)} in {topic}")
    if notes:
        line += f" ({'; '.join(notes)})"
    if count[UNCLASSIFIED]:
        line += f", {count[UNCLASSIFIED]} unclassified (rebuild the manifest to classify them)"
    lines = [line]
    if len(measured) > 1:
        lines.append("largest |Δ| per topic in float-only episodes: "
                     + ", ".join(f"{topic} {number(value)} ({name})" for topic, name, value in measured))
    return lines
