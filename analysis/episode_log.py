"""One episode loaded from its MCAP log into plain arrays (cm, s, degrees), for metrics, plots and replay.

Only the log is read: the static world comes from the first ``/scene`` message (walls, static obstacles,
goal and its tolerance), the robot from ``/robot/state``, the moving obstacles from ``/obstacles/truth``,
decisions from ``/planner/decision``, tables from ``/tpt``, the outcome from ``/episode`` and the run
parameters from the ``fuzzynav.run`` metadata.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import orjson
import shapely
from shapely.geometry import Point, Polygon, box

from analysis.episode_check import check_episode
from analysis.log_check import CheckError, check_message, check_metadata, messages_acceptable
from analysis.logs import LogError, LogFile, collector_paused, not_json

METRIC_TOPICS = ("/scene", "/robot/state", "/obstacles/truth", "/planner/decision", "/tpt", "/episode")


@dataclass
class EpisodeLog:
    """An episode as logged. ``positions`` has one row per step plus the final position (cm); ``dt``: the step
    length (s), from the config, else from the log times."""

    path: Path
    meta: dict[str, str]
    config: dict[str, Any]
    complete: bool
    dt: float
    bounds: tuple[float, float, float, float] | None = None
    static_polygons: list[Polygon] = field(default_factory=list)
    goal: tuple[float, float] | None = None
    goal_tolerance: float | None = None
    robot_radius: float = 20.0
    states: list[dict[str, Any]] = field(default_factory=list)
    truth: list[dict[str, Any]] = field(default_factory=list)
    decisions: list[dict[str, Any]] = field(default_factory=list)
    tpts: dict[int, dict[str, Any]] = field(default_factory=dict)
    tracks: list[dict[str, Any]] = field(default_factory=list)
    sonar: list[dict[str, Any]] = field(default_factory=list)
    laser: list[dict[str, Any]] = field(default_factory=list)
    logs: list[dict[str, Any]] = field(default_factory=list)
    episode: dict[str, Any] | None = None

    # -- derived arrays ---------------------------------------------------------------------------------
    @property
    def steps(self) -> int:
        return len(self.states)

    @property
    def positions(self) -> np.ndarray:
        """(steps + 1, 2) robot positions in cm: at each step, then after the last move."""
        if not self.states:
            return np.zeros((0, 2))
        pts = [(s["x_cm"], s["y_cm"]) for s in self.states]
        pts.append((self.states[-1]["next_x_cm"], self.states[-1]["next_y_cm"]))
        return np.array(pts, dtype=float)

    @property
    def headings(self) -> np.ndarray:
        """(steps + 1,) headings in degrees."""
        if not self.states:
            return np.zeros(0)
        return np.array([s["heading_deg"] for s in self.states] + [self.states[-1]["next_heading_deg"]])

    @property
    def outcome(self) -> str:
        """The logged outcome; ``incomplete`` when the log has no ``/episode`` message."""
        return self.episode["outcome"] if self.episode else "incomplete"

    def static_geometry(self) -> shapely.Geometry:
        """Static obstacles plus the solid frame outside the walls (cm), as the simulator sees them; prepared, and
        one shared (immutable) object for every log of the same world."""
        return _world_geometry(self.bounds, _wkbs(self.static_polygons), True)

    def static_obstacles(self) -> shapely.Geometry:
        """The union of the static obstacles (cm), walls excluded; prepared and shared as :meth:`static_geometry`."""
        return _world_geometry(None, _wkbs(self.static_polygons), False)


def _wkbs(polygons: list[Polygon]) -> tuple[bytes, ...]:
    """The polygons as WKB: their exact coordinates, the key of :func:`_world_geometry`."""
    return tuple(shapely.to_wkb(polygons).tolist()) if polygons else ()


@functools.lru_cache(maxsize=64)
def _world_geometry(bounds: tuple[float, float, float, float] | None, polygons: tuple[bytes, ...],
                    frame: bool) -> shapely.Geometry:
    """The union of the polygons (WKB, which keeps every coordinate exactly) and, with ``frame`` and ``bounds``,
    the solid frame outside the walls; made once per world: a sweep's logs of one scenario share it (building and
    preparing it was a twentieth of reading a log)."""
    parts = list(shapely.from_wkb(list(polygons))) if polygons else []
    if frame and bounds is not None:
        xmin, ymin, xmax, ymax = bounds
        parts.append(box(xmin - 1e4, ymin - 1e4, xmax + 1e4, ymax + 1e4).difference(box(xmin, ymin, xmax, ymax)))
    with np.errstate(divide="ignore", invalid="ignore"):
        geometry = shapely.union_all(parts) if parts else shapely.GeometryCollection()
    shapely.prepare(geometry)
    return geometry


def _cm(points: Iterable[dict[str, float]]) -> list[tuple[float, float]]:
    return [(p["x"] * 100.0, p["y"] * 100.0) for p in points]


def _read_scene(log: EpisodeLog, scene: dict[str, Any]) -> None:
    """The static world from the first ``/scene`` (already checked field by field): walls, static obstacles
    (valid polygons and circles) and the goal, each at most once."""
    seen: set[str] = set()
    for ent in scene["entities"]:
        eid = ent["id"]
        if eid in seen:
            raise CheckError(f"/scene entity {eid!r}", "appears twice in the first scene")
        seen.add(eid)
        if eid == "walls" and ent["lines"]:
            points = _cm(ent["lines"][0]["points"])
            if len(points) < 2:
                raise CheckError("/scene walls", f"{len(points)} point(s): not a boundary")
            xs, ys = zip(*points, strict=True)
            log.bounds = (min(xs), min(ys), max(xs), max(ys))
        elif eid.startswith("static/"):
            for line in ent["lines"]:
                points = _cm(line["points"])
                polygon = Polygon(points) if len(points) >= 3 else None
                if polygon is None or not polygon.is_valid:
                    raise CheckError(f"/scene {eid}", "not a valid polygon (fewer than 3 points or self-intersecting)")
                log.static_polygons.append(polygon)
            for cyl in ent["cylinders"]:
                c = cyl["pose"]["position"]
                # the simulator's circles are 64-gons (quad_segs=16): rebuild the same geometry
                log.static_polygons.append(Point(c["x"] * 100, c["y"] * 100).buffer(cyl["size"]["x"] * 50,
                                                                                     quad_segs=16))
        elif eid == "goal" and ent["cylinders"]:
            c = ent["cylinders"][0]
            log.goal = (c["pose"]["position"]["x"] * 100, c["pose"]["position"]["y"] * 100)
            log.goal_tolerance = c["size"]["x"] * 50


def _read_messages(log: EpisodeLog, messages: Iterable[tuple[str, int, bytes]], times: dict[str, list[int]]
                   ) -> None:
    """Decode each message, check the fields the analysis reads (:func:`check_message`) and file it into
    ``log``; ``times`` collects each topic's log times (ns) for :func:`check_episode`.

    The checks are decided per topic over the whole episode at once (:func:`messages_acceptable`); only when that
    says no are the messages checked one by one, in file order, so that the error names the first bad message
    and field exactly as a message-by-message reading would."""
    decoded: list[tuple[str, int, Any]] = []
    append, loads = decoded.append, orjson.loads  # decode()'s work without a call per message (a log has ~500)
    scene_seen = False
    topic = ""
    try:
        for topic, t, data in messages:
            if topic == "/scene":
                if scene_seen:
                    continue  # only the first scene (the static world) is read; the later ones are for Foxglove
                scene_seen = True
            append((topic, t, loads(data)))
    except orjson.JSONDecodeError as err:
        _check_each_and_file(log, decoded, times)  # a bad message before the undecodable one is named first
        raise not_json(log.path, topic, err) from None
    by_topic: dict[str, list[Any]] = {}
    for topic, _t, msg in decoded:
        by_topic.setdefault(topic, []).append(msg)
    if all(messages_acceptable(topic, msgs) for topic, msgs in by_topic.items()):
        for topic, t, msg in decoded:
            times[topic].append(t)
            _file(log, topic, msg)
    else:
        _check_each_and_file(log, decoded, times)


def _check_each_and_file(log: EpisodeLog, decoded: list[tuple[str, int, Any]], times: dict[str, list[int]]) -> None:
    """Check the messages one by one in file order (raising at the first bad one), filing each into ``log``."""
    for topic, t, msg in decoded:
        try:
            check_message(topic, msg)
        except CheckError as err:
            step = msg.get("step") if isinstance(msg, dict) else None
            at = f"at step {step}" if type(step) is int else f"number {len(times[topic])}"
            what = f"missing field '{err.where}'" if err.problem == "missing" else str(err)
            raise LogError(f"{log.path}: {topic} message {at} does not match its schema: {what}", "schema") from None
        times[topic].append(t)
        _file(log, topic, msg)


def _file(log: EpisodeLog, topic: str, msg: Any) -> None:
    """Put one checked message where the analysis reads it."""
    if topic == "/scene":
        _read_scene(log, msg)
    elif topic == "/tpt":
        if msg["step"] in log.tpts:
            raise CheckError(f"/tpt step {msg['step']}", "two tables for one step")
        log.tpts[msg["step"]] = msg
    elif topic == "/episode":
        if log.episode is not None:
            raise CheckError("/episode", "two outcome messages")
        log.episode = msg
    else:
        getattr(log, _TOPIC_LISTS[topic]).append(msg)


_TOPIC_LISTS = {"/robot/state": "states", "/obstacles/truth": "truth", "/planner/decision": "decisions",
                "/tracks": "tracks", "/sonar": "sonar", "/laser": "laser", "/log": "logs"}


def load_episode(path: str | Path, topics: Iterable[str] = METRIC_TOPICS) -> EpisodeLog:
    """Read the given topics of one log, verified and checked (:mod:`analysis.mcap_verify`,
    :mod:`analysis.log_check`). Raises :class:`LogError` naming the file and the problem; a truncated log loads
    what it has, with ``complete`` False and outcome ``incomplete``."""
    path = path if isinstance(path, Path) else Path(path)
    topics = tuple(topics)
    unknown = [t for t in topics if t not in _TOPIC_LISTS and t not in ("/scene", "/tpt", "/episode")]
    if unknown:
        raise ValueError(f"load_episode: no place for topic {unknown[0]!r}")
    source = LogFile(path, topics)
    meta = source.metadata()
    try:
        config, dt = check_metadata(meta)
    except CheckError as err:
        raise LogError(f"{path}: metadata {err}", "metadata") from None
    log = EpisodeLog(path=path, meta=meta, config=config, complete=source.complete, dt=math.nan)
    times: dict[str, list[int]] = {topic: [] for topic in topics}
    try:
        with collector_paused():
            _read_messages(log, source.raw_messages(topics), times)
        check_episode(log, times, dt)
    except CheckError as err:
        raise LogError(f"{path}: {err}", "episode") from None  # the messages together (check_episode)
    if log.states:
        log.robot_radius = float(log.states[0]["radius_cm"])
    return log
