"""What the report's pictures need of an episode, read from its log: the robot's path, where it touched something,
the static world and the moving obstacles' paths (cm). Small and picklable, so that worker processes can read the
logs and send back only this.

A log is read (and verified, :func:`analysis.episode_log.load_episode`) once per report however many figures draw
it: :func:`load_traces` reads every log the figures need in one pass.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.episode_log import EpisodeLog, load_episode
from analysis.logs import LogError, read_logs

TRACE_TOPICS = ("/scene", "/robot/state", "/obstacles/truth")
MAX_SEEDS_PER_PANEL = 20
"""Trajectories drawn per group and scenario (the failed episodes first, then the lowest seeds); the panel's title
says when there are more (:mod:`analysis.plots`)."""


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
    return trace_of(load_episode(path, TRACE_TOPICS), path)


def first_contact_step(log: EpisodeLog) -> int | None:
    """The logged step number of the first step the simulator flagged as in contact (None: none flagged), as
    :attr:`Trace.first_contact_step`."""
    return next((int(s["step"]) for s in log.states if s["contact_static"] or s["contact_dynamic"]), None)


def trace_of(log: EpisodeLog, path: str | Path | None = None) -> Trace:
    """The :class:`Trace` of an episode already loaded (with at least :data:`TRACE_TOPICS`): the metrics pass makes
    the pictures' traces from the logs it reads, so that the report does not read them again. ``path``: the log's
    name as given (default ``log.path``)."""
    path = log.path if path is None else path
    flagged = [k for k, s in enumerate(log.states) if s["contact_static"] or s["contact_dynamic"]]
    paths: dict[str, list[tuple[float, float]]] = {}
    for message in log.truth:
        for o in message["obstacles"]:
            if o.get("present", True):  # a recorded person's path only while it is in the world
                paths.setdefault(o["id"], []).append((o["x_cm"], o["y_cm"]))
    world = World(bounds=log.bounds, polygons=tuple(np.asarray(p.exterior.coords) for p in log.static_polygons),
                  goal=log.goal, goal_tolerance=log.goal_tolerance)
    return Trace(log=str(path), positions=log.positions, contact_points=tuple(k + 1 for k in flagged),
                 first_contact_step=int(log.states[flagged[0]]["step"]) if flagged else None,
                 obstacle_paths=tuple(np.asarray(p, dtype=float) for p in paths.values()), world=world,
                 robot_radius_cm=log.robot_radius, outcome=log.outcome, steps=log.steps)


@dataclass
class KeptTraces:
    """What the report's pictures need of the logs, kept while the metrics pass reads them, so that the report does
    not read them again (:func:`analysis.metrics.analyse_logs` with ``traces=True``): per run configuration (the
    run-parameters text of an episode; a group of the report is one or more of them) the :class:`Trace` of its
    first ``per_run`` episodes in a trajectory panel's order (failed first, then by seed, then by log), which hold
    every episode a panel (:data:`MAX_SEEDS_PER_PANEL` per group) or the failures gallery pictures; and the first
    contact step of every failed episode (``failures.csv``). Its size is bounded whatever the number of logs, and
    it pickles (worker processes send theirs back, :meth:`merge` joins them). A log the report needs that is not
    here is read again: keeping less costs time, never a picture."""

    per_run: int = MAX_SEEDS_PER_PANEL
    runs: dict[str, list[tuple[tuple, Trace]]] = field(default_factory=dict)
    contacts: dict[str, int | None] = field(default_factory=dict)

    def offer(self, run: str, success: bool, seed: int | None, log: EpisodeLog, name: str) -> None:
        """One usable episode of run configuration ``run``, its log ``name`` loaded as ``log``."""
        if not success:
            self.contacts[name] = first_contact_step(log)
        self._insert(run, (bool(success), math.inf if seed is None else seed, name), None, log)

    def _insert(self, run: str, key: tuple, trace: Trace | None, log: EpisodeLog | None = None) -> None:
        kept = self.runs.setdefault(run, [])
        if len(kept) >= self.per_run and key >= kept[-1][0]:
            return  # not among the first: no Trace made
        bisect.insort(kept, (key, trace if trace is not None else trace_of(log, key[2])),  # type: ignore[arg-type]
                      key=lambda entry: entry[0])
        del kept[self.per_run:]

    def merge(self, other: KeptTraces) -> None:
        """Add what another part of the logs kept."""
        self.contacts.update(other.contacts)
        for run, entries in other.runs.items():
            for key, trace in entries:
                self._insert(run, key, trace)

    def traces(self) -> dict[str, Trace]:
        """Log -> :class:`Trace` of every kept episode."""
        return {trace.log: trace for entries in self.runs.values() for _key, trace in entries}


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
    worker processes (-1: every core; :func:`analysis.logs.read_logs`)."""
    unique = list(dict.fromkeys(paths))
    results = [r for part in read_logs(_read_traces, [Path(p) for p in unique], jobs) for r in part]
    traces = {p: r for p, r in zip(unique, results, strict=True) if isinstance(r, Trace)}
    problems = {p: r for p, r in zip(unique, results, strict=True) if isinstance(r, str)}
    return traces, problems
