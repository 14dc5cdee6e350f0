"""What the report's pictures need of an episode, read from its log: the robot's path, where it touched something,
the static world and the moving obstacles' paths (cm). Small and picklable, so that worker processes can read the
logs and send back only this.

A log is read (and verified, :func:`analysis.episode_log.load_episode`) once per report however many figures draw
it: :func:`load_traces` reads every log the figures need in one pass.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.episode_log import load_episode
from analysis.logs import LogError, read_logs

TRACE_TOPICS = ("/scene", "/robot/state", "/obstacles/truth")


@dataclass(frozen=True)
class World:
    """The static world of an episode (cm): walls' bounding box (xmin, ymin, xmax, ymax), static obstacles'
    outlines, the goal and its tolerance radius."""

    bounds: tuple[float, float, float, float] | None
    polygons: tuple[np.ndarray, ...]
    goal: tuple[float, float] | None
    goal_tolerance: float | None

    def key(self) -> tuple:
        """Equal for equal worlds (to draw a world shared by many episodes once)."""
        return (self.bounds, self.goal, self.goal_tolerance, tuple(p.round(3).tobytes() for p in self.polygons))


@dataclass(frozen=True)
class Trace:
    """One episode as drawn: ``positions`` (steps + 1, 2) robot centres in cm (each step's, then the final one);
    ``contact_points`` indices into ``positions`` of the ends of the steps the simulator flagged as in contact
    (static or moving obstacle); ``first_contact_step`` the logged step number of the first such step (None: no
    contact flagged); ``obstacle_paths`` each moving obstacle's true path (cm)."""

    log: str
    positions: np.ndarray
    contact_points: tuple[int, ...]
    first_contact_step: int | None
    obstacle_paths: tuple[np.ndarray, ...]
    world: World
    robot_radius_cm: float
    outcome: str
    steps: int


def read_trace(path: str | Path) -> Trace:
    """The :class:`Trace` of one log (:class:`analysis.logs.LogError` if it cannot be read)."""
    log = load_episode(path, TRACE_TOPICS)
    flagged = [k for k, s in enumerate(log.states) if s["contact_static"] or s["contact_dynamic"]]
    paths: dict[str, list[tuple[float, float]]] = {}
    for message in log.truth:
        for o in message["obstacles"]:
            paths.setdefault(o["id"], []).append((o["x_cm"], o["y_cm"]))
    world = World(bounds=log.bounds, polygons=tuple(np.asarray(p.exterior.coords) for p in log.static_polygons),
                  goal=log.goal, goal_tolerance=log.goal_tolerance)
    return Trace(log=str(path), positions=log.positions, contact_points=tuple(k + 1 for k in flagged),
                 first_contact_step=int(log.states[flagged[0]]["step"]) if flagged else None,
                 obstacle_paths=tuple(np.asarray(p, dtype=float) for p in paths.values()), world=world,
                 robot_radius_cm=log.robot_radius, outcome=log.outcome, steps=log.steps)


def _read_traces(paths: list[Path]) -> list[Trace | str]:
    """:func:`read_trace` of each path, or the one-line reason it could not be read (module level: it runs in
    worker processes)."""
    out: list[Trace | str] = []
    for path in paths:
        try:
            out.append(read_trace(path))
        except LogError as err:  # changed or removed since the analysis read it
            out.append(str(err))
    return out


def load_traces(paths: list[str], jobs: int = -1) -> tuple[dict[str, Trace], dict[str, str]]:
    """(log path -> :class:`Trace`, log path -> why it could not be read) for each distinct path; read in ``jobs``
    worker processes from :data:`analysis.logs.PARALLEL_MIN_LOGS` logs on (-1: every core)."""
    unique = list(dict.fromkeys(paths))
    results = [r for part in read_logs(_read_traces, [Path(p) for p in unique], jobs) for r in part]
    traces = {p: r for p, r in zip(unique, results, strict=True) if isinstance(r, Trace)}
    problems = {p: r for p, r in zip(unique, results, strict=True) if isinstance(r, str)}
    return traces, problems
