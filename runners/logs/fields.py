"""Which values of a logged message are decisions, plans and outcomes, which are other discrete values, and
which are floating-point values; and the compact behaviour record of one episode that a dataset manifest keeps.

A difference between two logs of the same episode is one of three kinds, most serious first:

* ``behaviour`` — a decision, plan or outcome changed: on ``/planner/decision`` the mode, whether a plan was
  made and every non-float planning field (strategy, tc, tS, tG, waitTime, hWait, obstacle, tS', reason,
  number of path points), on ``/robot/state`` the contact flags, on ``/episode`` outcome, steps, contacts and
  reason, or a step that only one log has;
* ``discrete`` — another non-float value changed while every decision stayed the same: perception (track
  count and ids, beams attributed to moving obstacles, laser returns), the prediction table (its presence
  and collision flags), the scene's structure, the text of ``/log`` events;
* ``float`` — only floating-point values differ (the drift a different CPU, compiler or math library makes).

Two kinds of float are compared as what they mean, so that a tiny drift never looks large: headings (fields
ending in ``heading_deg``, in [0, 360)) on the circle (359.9999 and 0.0001 are 0.0002 apart), and quaternions
(``orientation``) up to sign (q and -q are the same rotation).

JSON keeps the distinction: the writer encodes every float with a ``.`` or an exponent and every count or
flag as an integer or boolean, so a value's JSON type says which it is. Numbers inside ``/log`` texts are
printed from floats (e.g. a waiting position in cm), so they count as float values of the field ``message``.
"""

from __future__ import annotations

import hashlib
import math
import re
from collections.abc import Callable, Iterable
from typing import Any

import orjson

BEHAVIOUR, DISCRETE, FLOAT = "behaviour", "discrete", "float"

# topic -> top-level fields whose non-float values are decisions, plans or outcomes (see the module docstring)
BEHAVIOUR_FIELDS: dict[str, frozenset[str]] = {
    "/planner/decision": frozenset({"mode", "new_plan", "planning"}),
    "/robot/state": frozenset({"contact_static", "contact_dynamic", "new_contacts"}),
    "/episode": frozenset({"outcome", "steps", "contacts", "reason"}),
}
STEP_TOPICS = ("/robot/state", "/planner/decision")  # written once per step: one log having a step more is behaviour
TIMING_FIELDS = ("compute_time_us",)  # wall-clock time: never reproducible, never compared
TEXT_FIELDS = {"/log": "message"}  # free text with numbers printed from floats
_NUMBER = re.compile(r"-?\d+(?:\.\d+)?")
_FLOAT_MASK = 0.0  # every float becomes this in the discrete view (a float, so None and integers stay distinct)
HEADING_SUFFIX = "heading_deg"
QUATERNION_FIELD = "orientation"
QUATERNION_KEYS = frozenset("xyzw")
# topics whose floats the manifest sums: fuzzynav's own (cm, cm/s, degrees, full precision); the Foxglove topics
# repeat the same quantities in m, rounded to 0.1 mm or 1 µm
SUMMED_TOPICS = ("/sonar", "/tracks", "/obstacles/truth", "/robot/state", "/tpt", "/planner/decision")


def kind_of(topic: str, path: str) -> str:
    """``behaviour`` or ``discrete``: the kind of a non-float difference at ``path`` (dotted, from the top-level
    field) of a ``topic`` message; a whole message present in one log only has the path ``""``."""
    if path == "":
        return BEHAVIOUR if topic in STEP_TOPICS or topic == "/episode" else DISCRETE
    return BEHAVIOUR if path.split(".", 1)[0] in BEHAVIOUR_FIELDS.get(topic, ()) else DISCRETE


def split_text(text: str) -> tuple[str, list[float]]:
    """A ``/log`` text as its words (numbers replaced by ``#``) and its numbers."""
    return _NUMBER.sub("#", text), [float(x) for x in _NUMBER.findall(text)]


def is_float_pair(a: Any, b: Any) -> bool:
    """Two JSON numbers of which at least one is a float (booleans are flags, integers are counts or ids)."""
    numbers = all(isinstance(x, int | float) and not isinstance(x, bool) for x in (a, b))
    return numbers and (isinstance(a, float) or isinstance(b, float))


def compare(topic: str, a: Any, b: Any, on_discrete: Callable[[str, Any, Any], None],
            on_float: Callable[[str, float], None], path: str = "") -> None:
    """Walk two values of a ``topic`` message side by side: ``on_discrete(path, a, b)`` for every differing
    non-float value (a missing key, a list of another length, a changed string, integer or flag) and
    ``on_float(path, |a - b|)`` for every differing float. List indices are left out of ``path`` (the field
    ``tracks.heading_deg`` covers every track's)."""
    if path in TIMING_FIELDS:
        return
    if isinstance(a, dict) and isinstance(b, dict):
        if path.endswith(QUATERNION_FIELD) and a.keys() == b.keys() == QUATERNION_KEYS and \
                all(is_float_pair(a[k], b[k]) for k in a) and sum(a[k] * b[k] for k in a) < 0:
            b = {k: -v for k, v in b.items()}  # the same rotation: compare with the other sign
        for key in sorted(a.keys() | b.keys()):
            sub = f"{path}.{key}" if path else key
            if key not in a or key not in b:
                if sub not in TIMING_FIELDS:
                    on_discrete(sub, a.get(key), b.get(key))
            else:
                compare(topic, a[key], b[key], on_discrete, on_float, sub)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            on_discrete(path, f"{len(a)} items", f"{len(b)} items")
            return
        for x, y in zip(a, b, strict=True):
            compare(topic, x, y, on_discrete, on_float, path)
    elif is_float_pair(a, b):
        if type(a) is not type(b):  # 1 vs 1.0: the writer changed the field's type, not its value's rounding
            on_discrete(path, a, b)
        elif a != b:
            on_float(path, float_delta(path, float(a), float(b)))
    elif isinstance(a, str) and isinstance(b, str) and TEXT_FIELDS.get(topic) == path and a != b:
        (words_a, nums_a), (words_b, nums_b) = split_text(a), split_text(b)
        if words_a != words_b:
            on_discrete(path, a, b)
            return
        for x, y in zip(nums_a, nums_b, strict=True):
            if x != y:
                on_float(path, abs(x - y))
    elif a != b or type(a) is not type(b):
        on_discrete(path, a, b)


def _all_type(values: list, kind: type) -> bool:
    """Every item is exactly of ``kind`` (``bool`` is not ``int`` here: flags are not counts)."""
    return all(type(v) is kind for v in values)


def float_delta(path: str, a: float, b: float) -> float:
    """|a - b|, for headings the shorter way round the circle (degrees)."""
    d = abs(a - b)
    return 360.0 - d if path.endswith(HEADING_SUFFIX) and d > 180.0 else d


def _summand(key: str, value: float) -> float:
    """What a float adds to its topic's sum: a heading its angle from 0° (min(h, 360 - h), continuous round
    the circle, so a drift across 0° changes the sum by no more than the drift), any other value itself."""
    if key.endswith(HEADING_SUFFIX):
        h = value % 360.0
        return min(h, 360.0 - h)
    return value


def masked(topic: str, value: Any, path: str = "") -> Any:
    """``value`` with every float replaced by 0.0 and the numbers of ``/log`` texts by ``#``: what a
    float-only difference leaves unchanged."""
    if isinstance(value, dict):
        return {k: masked(topic, v, f"{path}.{k}" if path else k) for k, v in value.items()
                if (f"{path}.{k}" if path else k) not in TIMING_FIELDS}
    if isinstance(value, list):
        if _all_type(value, float):  # fast path for the long number arrays (laser ranges, tables)
            return [_FLOAT_MASK] * len(value)
        if _all_type(value, int):
            return value
        return [masked(topic, v, path) for v in value]
    if isinstance(value, float):
        return _FLOAT_MASK
    if isinstance(value, str) and TEXT_FIELDS.get(topic) == path:
        return split_text(value)[0]
    return value


def _line(topic: str, t: int, value: Any) -> bytes:
    # orjson: several times faster than json here, and the masked views hold no float but 0.0, whose text
    # (unlike other floats') every JSON encoder writes alike
    return topic.encode() + b"|" + str(t).encode() + b"|" + orjson.dumps(value, option=orjson.OPT_SORT_KEYS) + b"\n"


def run_length(values: Iterable[str]) -> str:
    """``direct*12 detour*6 direct*28``: a sequence as runs of equal values."""
    runs: list[list[Any]] = []
    for v in values:
        if runs and runs[-1][0] == v:
            runs[-1][1] += 1
        else:
            runs.append([v, 1])
    return " ".join(f"{v}*{n}" for v, n in runs)


def expand_runs(text: str) -> list[str]:
    """The sequence of :func:`run_length`."""
    out: list[str] = []
    for run in text.split():
        value, _, count = run.rpartition("*")
        out.extend([value] * int(count))
    return out


class BehaviourRecord:
    """Accumulates, message by message, what a manifest keeps about an episode beyond its content hash:

    * ``decision_digest`` (16 hex): SHA-256 of the non-float values of the decision, plan and outcome
      fields (:data:`BEHAVIOUR_FIELDS`, plus which steps exist): it changes exactly when a decision, plan or
      outcome does;
    * ``discrete_digest`` (16 hex): SHA-256 of every message with its floats masked (:func:`masked`): it stays
      the same when only floats change;
    * ``modes``: the decision mode per step, run-length encoded (locates the first changed decision);
    * ``float_sums``: per topic of :data:`SUMMED_TOPICS`, the correctly rounded sum of all its float values
      (``math.fsum``, so independent of summation order; headings as their angle from 0°), as
      ``"topic sum topic sum ..."`` in shortest round-trip form (:func:`parse_sums` reads it back). Where the
      log is not kept, the change of a topic's sum sizes a float-only drift: a lower bound of the total
      change of its values, resolved to about 1e-16 of the sum.
    """

    def __init__(self) -> None:
        self._decisions = hashlib.sha256()
        self._discrete = hashlib.sha256()
        self._modes: list[str] = []
        self._floats: dict[str, list[float]] = {topic: [] for topic in SUMMED_TOPICS}

    def add(self, topic: str, t: int, message: dict[str, Any]) -> None:
        """One message (decoded JSON) at log time ``t`` (ns), in log order."""
        view = masked(topic, message)
        self._discrete.update(_line(topic, t, view))
        fields = BEHAVIOUR_FIELDS.get(topic)
        if fields is not None:
            self._decisions.update(_line(topic, t, {k: view.get(k) for k in sorted(fields)}))
        if topic == "/planner/decision":
            self._modes.append(str(message.get("mode")))
        if topic in self._floats:
            _collect_floats(message, self._floats[topic])

    def result(self) -> dict[str, Any]:
        """The manifest fields (see the class docstring)."""
        sums = " ".join(f"{topic} {math.fsum(values)!r}" for topic, values in self._floats.items())
        return {"decision_digest": self._decisions.hexdigest()[:16], "discrete_digest": self._discrete.hexdigest()[:16],
                "modes": run_length(self._modes), "float_sums": sums}


def _collect_floats(value: Any, out: list[float], key: str = "") -> None:
    """Append the summands (:func:`_summand`) of every float in ``value``; ``key``: the field holding it."""
    if isinstance(value, dict):
        for k, v in value.items():
            if k not in TIMING_FIELDS:
                _collect_floats(v, out, k)
    elif isinstance(value, list):
        if _all_type(value, float) and not key.endswith(HEADING_SUFFIX):
            out.extend(value)
            return
        for v in value:
            _collect_floats(v, out, key)
    elif isinstance(value, float):
        out.append(_summand(key, value))


def parse_sums(text: str) -> dict[str, float]:
    """Topic -> float sum of a ``float_sums`` field."""
    words = text.split()
    return {words[i]: float(words[i + 1]) for i in range(0, len(words) - 1, 2)}
