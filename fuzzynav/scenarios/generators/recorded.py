"""``recorded``: a time window of a pedestrian recording (ETH/BIWI, UCY, the benchmarks' 4-column files) replayed
around the robot (:mod:`fuzzynav.pedestrians.recorded`), its people as obstacles of model ``recorded``.

Parameters (``scenario.params``; cm, s):

- ``recording``: the file (read with :func:`fuzzynav.scenarios.recordings.read_recording`: a path, relative to the
  working directory); ``format`` (``obsmat`` | ``xy``; default by the file's name), ``max_gap`` (0),
  ``annotation_hz`` (2.5);
- the window: ``start_s`` (s after the recording's first annotation; default 0) or ``window`` (k: the k-th window,
  starting at k × ``stride_s``; ``stride_s`` defaults to ``duration_s``), and ``duration_s`` (60; at most 300);
  ``crop`` [x0, y0, x1, y1] cm in the recording's frame: people are present only inside it (default: everywhere);
- the robot: ``robot_start`` and ``robot_goal`` [x, y] cm (both or neither) and ``robot_heading`` (degrees;
  default: towards the goal); when not given they are chosen by the *busiest-crossing rule*, below, with
  ``path_length`` (cm between start and goal; 1000);
- ``react_cm`` (0: a replay throughout) and ``react_model`` (``social_force`` | ``orca``): people react to the robot
  within ``react_cm`` (:mod:`fuzzynav.pedestrians.recorded`);
- ``radius`` (25: a person's disc, cm), ``static_obstacles`` (the scene's static map where one is known, in the
  recording's frame, as a scenario's), ``max_steps`` (default: ``duration_s`` — one step a second, the paper's dt).

The window's people are those present in it (inside the crop) at the annotations' resolution; each keeps its
annotations in the window plus the one before and the one after it (so that it is where the recording has it
from t = 0), with their times from the window's start (``model_params.t_s``), and is absent after the window
(``until_s``). At most 300 people (the scenarios' limit of recorded people): a busier window is an error naming
``duration_s``.
The world's walls are the box of every kept annotation, the crop and the robot's start and goal, 100 cm wider on
each side (people never walk through a wall; outside the crop they are absent).

The busiest-crossing rule: count the window's present people on a 100 cm grid at every whole second of the
window; the busiest cell (the most person-seconds; on a tie the first in x-major then y order) is the crossing
point. From the generator's random stream (``default_rng((seed, 7))``) draw a direction θ uniformly in [0, 360)
degrees; the robot's straight path of ``path_length`` along θ passes through the crossing point, which lies as
near its middle as start and goal allow: both must be inside the crop (without a crop: inside the walls), 20 cm +
the robot's radius from its edges. A draw is kept when such a path exists and its start is 60 cm (beyond both
radii) clear of every person present at t = 0 and of every person's first kept annotation; otherwise another θ
is drawn, at most 64 times (then an error naming ``path_length``). So the seed
chooses the crossing's direction and the window chooses where: the robot always crosses the window's densest
place.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from fuzzynav.numerics.portable_math import bearing_deg, dist, norm2, sin_cos_deg
from fuzzynav.numerics.portable_random import uniform
from fuzzynav.params import limits
from fuzzynav.params.checks import check_key, key_text, show
from fuzzynav.pedestrians.recorded import REACT_MODELS
from fuzzynav.pedestrians.recording import Recording, resample
from fuzzynav.scenarios.generator import CLEAR_CM, ROBOT_RADIUS, register_generator
from fuzzynav.scenarios.recordings import ANNOTATION_HZ, FORMATS, RecordingError, read_recording
from fuzzynav.scenarios.scenario import ScenarioError

MAX_DURATION_S = 300.0  # 750 annotations a person at 2.5 Hz: within a scenario's waypoint limit (1000)
MARGIN_CM = 100.0  # the walls' distance from the box of the annotations
GRID_CM = 100.0  # the busiest-crossing rule's cell
EDGE_CM = 20.0  # the robot's start and goal stay this far (beyond its radius) inside the crop
TRIES = 64
DIGEST = re.compile(r"\(sha256 ([0-9a-f]{64})\)")  # the recording's digest in the scenario's description

_KNOWN = {"recording", "format", "max_gap", "annotation_hz", "start_s", "window", "stride_s", "duration_s", "crop",
          "robot_start", "robot_goal", "robot_heading", "path_length", "radius", "static_obstacles", "max_steps",
          "react_cm", "react_model"}


def _number(params: Mapping[str, Any], key: str, default: Any, lo: float, hi: float) -> float:
    value = params.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int | float) or not (
            (isinstance(value, float) and math.isfinite(value)) or (isinstance(value, int) and abs(value) < 1e15)):
        raise ScenarioError(f"params.{key}: expected a number, got {show(value)}")
    if not lo <= value <= hi:
        raise ScenarioError(f"params.{key}: must be in [{lo:g}, {hi:g}], got {show(value)}")
    return float(value)


def _integer(params: Mapping[str, Any], key: str, default: int, hi: int) -> int:
    value = params.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= hi:
        raise ScenarioError(f"params.{key}: expected a whole number in [0, {hi}], got {show(value)}")
    return value


def _point(params: Mapping[str, Any], key: str) -> np.ndarray | None:
    value = params.get(key)
    if value is None:
        return None
    if not (isinstance(value, list | tuple) and len(value) == 2 and all(
            not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
            and abs(v) <= limits.MAX_COORD_CM for v in value)):
        raise ScenarioError(f"params.{key}: expected [x, y] cm, got {show(value)}")
    return np.array(value, dtype=float)


def _crop(params: Mapping[str, Any]) -> tuple[float, float, float, float] | None:
    value = params.get("crop")
    if value is None:
        return None
    if not (isinstance(value, list | tuple) and len(value) == 4 and all(
            not isinstance(v, bool) and isinstance(v, int | float) and math.isfinite(v)
            and abs(v) <= limits.MAX_COORD_CM for v in value) and value[0] < value[2] and value[1] < value[3]):
        raise ScenarioError(f"params.crop: expected [x0, y0, x1, y1] cm with x0 < x1 and y0 < y1, got {show(value)}")
    return tuple(float(v) for v in value)  # type: ignore[return-value]


def read_window_recording(params: Mapping[str, Any]) -> tuple[Recording, str]:
    """The recording ``params.recording`` names, and its SHA-256 (``ScenarioError`` naming the parameter)."""
    path = params.get("recording")
    if path == "???":  # Hydra's mark of a value conf/scenario/recorded.yaml leaves to the command line
        raise ScenarioError("params.recording: missing: name your copy of the recording "
                            "(scenario.params.recording=PATH; docs/recordings.md says where to get them)")
    if not isinstance(path, str) or not path or "\0" in path:
        raise ScenarioError(f"params.recording: expected the path of a recording file, got {show(path)}")
    fmt = params.get("format")
    if fmt is not None and not (isinstance(fmt, str) and fmt in FORMATS):
        raise ScenarioError(f"params.format: unknown format {show(fmt)} (known: {', '.join(FORMATS)})")
    max_gap = _integer(params, "max_gap", 0, 1000)
    hz = _number(params, "annotation_hz", ANNOTATION_HZ, 1e-3, 1000.0)
    try:
        return read_recording(Path(path), fmt, hz, max_gap)
    except RecordingError as err:
        raise ScenarioError(f"params.recording: {err}") from None


def window_start(params: Mapping[str, Any], duration_s: float) -> float:
    """The window's start (s after the recording's first annotation): ``start_s``, or ``window`` × ``stride_s``."""
    if "window" in params and "start_s" in params:
        raise ScenarioError("params.window: give start_s or window, not both")
    if "window" in params:
        stride = _number(params, "stride_s", duration_s, 1e-3, 1e6)
        return _integer(params, "window", 0, 1_000_000) * stride
    return _number(params, "start_s", 0.0, 0.0, 1e6)


def recording_windows(recording: Recording, duration_s: float, stride_s: float | None = None,
                      crop: tuple[float, float, float, float] | None = None, min_people: int = 1,
                      max_people: int = limits.MAX_RECORDED_PEOPLE) -> list[int]:
    """The suite of windows of a recording: the indices k of the windows [k·stride, k·stride + duration] s (stride
    default: ``duration_s``, windows side by side) that lie wholly in the recording and have from ``min_people``
    to ``max_people`` people in them (inside ``crop``) — what ``params.window`` takes."""
    stride = duration_s if stride_s is None else stride_s
    if not (math.isfinite(duration_s) and 0 < duration_s <= MAX_DURATION_S and math.isfinite(stride)
            and stride > 0):
        raise RecordingError(f"{recording.source}: windows need 0 < duration_s <= {MAX_DURATION_S:g} and a "
                             f"positive stride, got {duration_s!r}, {stride!r}")
    out = []
    k = 0
    while k * stride + duration_s <= recording.duration_s + 1e-9 and k < 1_000_000:
        people = len(resample(recording, recording.annotation_dt_s, k * stride, duration_s, crop).ids)
        if min_people <= people <= max_people:
            out.append(k)
        k += 1
    return out


@register_generator("recorded")
def recorded(params: Mapping[str, Any], seed: int, name: str = "recorded") -> dict[str, Any]:
    """A window of a recording around the robot (module docstring)."""
    for key in params:
        check_key(key, "params", ScenarioError)
        if key not in _KNOWN:
            raise ScenarioError(f"params.{key_text(key)}: unknown parameter (known: {', '.join(sorted(_KNOWN))})")
    duration = _number(params, "duration_s", 60.0, 1e-3, MAX_DURATION_S)
    start_s = window_start(params, duration)
    crop = _crop(params)
    radius = _number(params, "radius", 25.0, 1.0, 200.0)
    path_length = _number(params, "path_length", 1000.0, 2 * CLEAR_CM, limits.MAX_COORD_CM)
    max_steps = _integer(params, "max_steps", max(1, math.ceil(duration)), limits.MAX_STEPS)
    if max_steps < 1:
        raise ScenarioError("params.max_steps: must be at least 1")
    start, goal = _point(params, "robot_start"), _point(params, "robot_goal")
    if (start is None) != (goal is None):
        raise ScenarioError("params.robot_start: give robot_start and robot_goal together, or neither")
    statics = params.get("static_obstacles") or []
    if not isinstance(statics, list | tuple):
        raise ScenarioError(f"params.static_obstacles: expected a list of static obstacles, got {show(statics)}")
    react_cm = _number(params, "react_cm", 0.0, 0.0, 1e5)
    react_model = params.get("react_model", "social_force")
    if not (isinstance(react_model, str) and react_model in REACT_MODELS):
        raise ScenarioError(f"params.react_model: unknown model {show(react_model)} (known: {', '.join(REACT_MODELS)})")
    reaction = {"react_cm": react_cm, "react_model": react_model} if react_cm > 0 else {}
    recording, digest = read_window_recording(params)
    if start_s + duration > recording.duration_s + 1e-9:
        raise ScenarioError(f"params.start_s: the window [{start_s:g}, {start_s + duration:g}] s is not inside the "
                            f"recording ({recording.duration_s:g} s long)")
    adt = recording.annotation_dt_s
    inside = resample(recording, adt, start_s, duration, crop)
    people = set(inside.ids)
    if not people:
        raise ScenarioError(f"params.start_s: nobody is recorded in the window [{start_s:g}, {start_s + duration:g}] "
                            "s" + (" inside the crop" if crop else ""))
    if len(people) > limits.MAX_RECORDED_PEOPLE:
        raise ScenarioError(f"params.duration_s: {len(people)} people in the window, more than the limit of "
                            f"{limits.MAX_RECORDED_PEOPLE} (a shorter window or a smaller crop)")
    end_s = start_s + duration
    dynamics, kept = [], []
    for track in recording.tracks:
        if track.id not in people:
            continue
        index = np.nonzero((track.t_s >= start_s - 1e-9) & (track.t_s <= end_s + 1e-9))[0]
        lo = int(index[0]) if len(index) else int(np.searchsorted(track.t_s, start_s)) - 1
        hi = int(index[-1]) if len(index) else lo
        lo, hi = max(lo - 1, 0), min(hi + 1, len(track.t_s) - 1)  # the annotation before and after the window
        t = track.t_s[lo:hi + 1] - start_s
        xy = track.xy_cm[lo:hi + 1]
        length = math.fsum(float(dist(a, b)) for a, b in itertools.pairwise(xy))
        span = float(t[-1] - t[0])
        entry = {"id": f"p{track.id}", "radius": radius,
                 "waypoints": [[round(float(x), 6), round(float(y), 6)] for x, y in xy],
                 # the mean recorded speed (informative: the replay follows the recorded times)
                 "speed": round(length / span, 6) if span > 0 and length > 0 else 1e-3,
                 "model": "recorded",
                 "model_params": {"t_s": [round(float(v), 9) for v in t], "until_s": round(duration, 9),
                                  **({"crop": list(crop)} if crop else {}), **reaction}}
        dynamics.append(entry)
        kept.append(xy)
    annotations = sum(len(xy) for xy in kept)
    if annotations > limits.MAX_RECORDED_ANNOTATIONS:
        raise ScenarioError(f"params.duration_s: the window's {len(dynamics)} people keep {annotations:,} annotations, "
                            f"more than the limit of {limits.MAX_RECORDED_ANNOTATIONS:,} (a shorter window or a "
                            "smaller crop)")
    points = np.concatenate(kept)
    box = [float(points[:, 0].min()), float(points[:, 1].min()), float(points[:, 0].max()),
           float(points[:, 1].max())]
    # where the robot's start and goal may be: the crop, else the world inside its walls
    area = crop or (box[0] - MARGIN_CM, box[1] - MARGIN_CM, box[2] + MARGIN_CM, box[3] + MARGIN_CM)
    now = resample(recording, adt, start_s, 0.0, crop)
    at_zero = now.xy_cm[:, 0][now.present[:, 0]]
    firsts = np.array([d["waypoints"][0] for d in dynamics])
    clear = ROBOT_RADIUS + radius + CLEAR_CM
    chosen = start is None
    if chosen:
        start, goal = _busiest_crossing(recording, start_s, duration, crop, area, path_length, seed,
                                        np.concatenate([at_zero, firsts]), clear)
    assert start is not None and goal is not None
    heading = params.get("robot_heading")
    if heading is None:
        heading = bearing_deg(float(start[0]), float(start[1]), float(goal[0]), float(goal[1]))
    else:
        heading = _number(params, "robot_heading", 0.0, -1e6, 1e6)
    for p in (start, goal):
        box = [min(box[0], p[0], area[0]), min(box[1], p[1], area[1]), max(box[2], p[0], area[2]),
               max(box[3], p[1], area[3])]
    bounds = [box[0] - MARGIN_CM, box[1] - MARGIN_CM, box[2] + MARGIN_CM, box[3] + MARGIN_CM]
    source = Path(str(params["recording"])).name
    how = f"start and goal by the busiest-crossing rule (seed {seed})" if chosen else "start and goal given"
    return {"name": name, "bounds": [round(b, 6) for b in bounds],
            "description": (f"{source} (sha256 {digest}), window {start_s:g}-{end_s:g} s"
                            f"{', crop ' + str(list(crop)) if crop else ''}, {len(dynamics)} people; {how}"),
            "robot": {"start": [round(float(v), 6) for v in start], "goal": [round(float(v), 6) for v in goal],
                      "heading": round(float(heading), 9), "radius": ROBOT_RADIUS},
            "static_obstacles": list(statics), "dynamic_obstacles": dynamics, "max_steps": max_steps}


def recording_digest(description: str) -> str:
    """The SHA-256 of the recording a scenario of this generator was made from, as its description records it
    ('' when the description names none)."""
    found = DIGEST.search(description)
    return found.group(1) if found else ""


def _busiest_crossing(recording: Recording, start_s: float, duration: float,
                      crop: tuple[float, float, float, float] | None, area: tuple[float, ...], path_length: float,
                      seed: int, people: np.ndarray, clear: float) -> tuple[np.ndarray, np.ndarray]:
    """The robot's start and goal by the busiest-crossing rule (module docstring)."""
    seconds = resample(recording, 1.0, start_s, duration, crop)
    xy = seconds.xy_cm[seconds.present]
    if not len(xy):  # people in the window, but none at a whole second: the annotations' times instead
        fine = resample(recording, recording.annotation_dt_s, start_s, duration, crop)
        xy = fine.xy_cm[fine.present]
    cells = np.floor((xy - np.array([area[0], area[1]])) / GRID_CM).astype(np.int64)
    keys, counts = np.unique(cells, axis=0, return_counts=True)  # sorted x-major: ties go to the first
    best = keys[int(np.argmax(counts))]
    centre = np.array([area[0], area[1]]) + (best + 0.5) * GRID_CM
    rng = np.random.default_rng((int(seed), 7))
    edge = ROBOT_RADIUS + EDGE_CM
    lo = np.array([area[0] + edge, area[1] + edge])
    hi = np.array([area[2] - edge, area[3] - edge])
    for _ in range(TRIES):
        sin_t, cos_t = sin_cos_deg(uniform(rng, 0.0, 360.0))
        u = np.array([cos_t, sin_t])
        before = _offset(centre, u, path_length, lo, hi)
        if before is None:
            continue
        start, goal = centre - before * u, centre + (path_length - before) * u
        if len(people) and float(norm2(people - start).min()) < clear:
            continue
        return start, goal
    raise ScenarioError(f"params.path_length: no start and goal {path_length:g} cm apart through the busiest place "
                        f"({centre[0]:.0f}, {centre[1]:.0f}) cm fit inside the {'crop' if crop else 'recorded area'} "
                        f"clear of the people in {TRIES} directions (a shorter path_length, or robot_start and "
                        "robot_goal)")


def _offset(centre: np.ndarray, u: np.ndarray, length: float, lo: np.ndarray, hi: np.ndarray) -> float | None:
    """How far before ``centre`` along direction ``u`` the start lies: the offset a in [0, length] nearest to
    length / 2 for which the start (centre − a·u) and the goal (centre + (length − a)·u) are both in the box
    [lo, hi] (an interval of a, the box being convex); None when no offset fits."""
    a_lo, a_hi = 0.0, length
    for j in (0, 1):
        if not lo[j] <= centre[j] <= hi[j]:
            return None
        if abs(u[j]) < 1e-12:
            continue
        # start: lo <= c - a u <= hi; goal: lo <= c + (length - a) u <= hi; each bounds a on both sides
        for shift in (0.0, length):
            bound_1 = (centre[j] + shift * u[j] - lo[j]) / u[j]
            bound_2 = (centre[j] + shift * u[j] - hi[j]) / u[j]
            a_lo = max(a_lo, min(bound_1, bound_2))
            a_hi = min(a_hi, max(bound_1, bound_2))
    if a_lo > a_hi:
        return None
    return min(max(length / 2, a_lo), a_hi)
