"""Write an episode's record stream to an MCAP log (zstd chunks, JSON messages with JSON schemas).

One file per episode, written with the Foxglove SDK's MCAP writer (Rust: per message about half the time of
the pure-Python ``mcap`` writer, which the analysis uses to read) on channels of a context of our own, so one
log is open at a time per process. Foxglove topics use metres and radians (true scale in the 3D panel);
fuzzynav topics use cm, cm/s and degrees (said in their field names). The topics and their schemas:
:mod:`analysis.log_format` (the one definition of the log format, which the analysis's checks come from).

Messages are deterministic: the same config and seed give the same bytes, except the ``compute_time_us``
field of ``/planner/decision``. Log time is simulation time (step * dt) in nanoseconds from 0. Messages are
encoded with orjson (compact JSON; numpy arrays are written directly, floats in shortest round-trip form).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import json
import logging
import math
import os
import re
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, BinaryIO

import foxglove
import numpy as np
import orjson
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

from analysis.log_format import SCHEMAS, TOPICS
from fuzzynav.episode import Episode, StepRecord
from fuzzynav.episode_identity import same_episode_config
from fuzzynav.numerics.portable_math import dist
from fuzzynav.params.names import DEFAULT_MODEL
from runners.logs.foxglove_scene import FRAME, StepScenes, pose, stamp, static_scene

RUN_METADATA = "fuzzynav.run"
LOG_INFO, LOG_WARNING, LOG_ERROR = 2, 3, 4
CHUNK_BYTES = 32 * 1024  # small chunks: a killed run loses at most the last ~32 KB of messages
# one thread: a sweep already runs one episode per core. zstd level 1, not the default 3: compressing the chunks
# was most of the time of writing a log (a 20-pedestrian step writes ~30 KB), level 1 takes about half of it, and
# on these JSON messages its files are the same size to within 0.1 % (the messages themselves do not change)
ZSTD_LEVEL = 1
_WRITE_OPTIONS = MCAPWriteOptions(chunk_size=CHUNK_BYTES, compression=MCAPCompression.Zstd, compression_threads=0,
                                  compression_level=ZSTD_LEVEL)

def _r(x: float) -> float:
    """Full precision: replay --verify feeds these numbers back to the planning layer, and a rounded input can flip
    a decision that sits on a boundary (e.g. the crisp included angle at exactly 90°)."""
    return float(x)


def _array(values, *shape: int) -> np.ndarray:
    """A float64 C-ordered array of ``shape`` (orjson writes it as nested JSON lists, full precision); empty
    inputs keep the shape (e.g. no obstacles: ``[[], [], ...]`` rows)."""
    return np.ascontiguousarray(values, dtype=np.float64).reshape(shape or (-1,))


def _compact(schema: Any) -> Any:
    """A schema without its descriptions, for embedding: every log carries each schema twice (data section
    and summary), and the full Foxglove texts would triple the size of a short episode's log."""
    if isinstance(schema, dict):
        return {k: _compact(v) for k, v in schema.items() if not (k == "description" and isinstance(v, str))}
    if isinstance(schema, list):
        return [_compact(v) for v in schema]
    return schema


@functools.cache
def _channels() -> tuple[foxglove.Context, dict[str, foxglove.Channel]]:
    """fuzzynav's topics as Foxglove SDK channels on a context of their own, made once per process; the log
    being written subscribes to them (so only one can be open at a time)."""
    context = foxglove.Context()
    channels = {topic: foxglove.Channel(topic, message_encoding="json", context=context, schema=foxglove.Schema(
        name=schema_name, encoding="jsonschema", data=_schema_bytes(schema_name)))
        for topic, schema_name in TOPICS.items()}
    return context, channels


@functools.cache
def _writes() -> dict[str, Callable[[bytes, int, None], None]]:
    """For each topic, the function that writes encoded bytes at a log time (ns), called as ``write(data, ns,
    None)``: the channel's ``base.log`` (what ``Channel.log`` calls for bytes after checking the message's type;
    ~0.4 us less per message, ~10 messages a step), or ``Channel.log`` on an SDK without it."""
    writes = {}
    for topic, channel in _channels()[1].items():
        base_log = getattr(getattr(channel, "base", None), "log", None)
        writes[topic] = base_log if callable(base_log) else (
            lambda data, ns, _sink, channel=channel: channel.log(data, log_time=ns))
    return writes


_OPEN: list[EpisodeLogWriter] = []  # the log being written in this process, if any

# The SDK does not raise when writing a message fails (disk full, I/O error): it reports a warning on this
# logger for every message after the failure, and only ``close`` raises. The writer watches it instead.
SDK_LOGGER = "foxglove.log_sink_set"
_OS_CODE = re.compile(r"(?:code: |os error )(\d+)")  # "Os { code: 28, ..." or "(os error 28)"


class LogWriteError(OSError):
    """A log file could not be written (disk full, read-only, I/O error); ``filename`` is the log's final path,
    ``errno``/``strerror`` the operating system's error when known. ``str()`` is one line naming the file."""

    def __init__(self, path: Path, errno: int | None, detail: str) -> None:
        super().__init__(f"{path}: cannot write the log: {detail}")
        self.errno, self.strerror, self.filename = errno, detail, str(path)

    def __str__(self) -> str:
        return str(self.args[0])

    def __reduce__(self):  # type: ignore[override]  # travels from a sweep's worker to its launcher
        return LogWriteError, (Path(self.filename), self.errno, self.strerror)


def partial_path(path: Path) -> Path:
    """Where the log of ``path`` is written until it is finished: a hidden ``.<name>.partial`` next to it, renamed
    to ``path`` by :meth:`EpisodeLogWriter.finish`. No ``*.mcap`` file is ever incomplete: a killed run leaves
    only the partial file (readable up to its last chunk, e.g. by ``runners.replay``)."""
    return path.with_name(f".{path.name}.partial")


@functools.cache
def _schema_bytes(schema_name: str) -> bytes:
    """The JSON schema embedded in every log for ``schema_name`` (encoded once per process)."""
    schema = SCHEMAS[schema_name]()
    if schema_name.startswith("foxglove."):
        schema = _compact(schema)  # ours keep their descriptions: they carry the units
    return json.dumps(schema, separators=(",", ":")).encode()


class EpisodeLogWriter:
    """Writes one episode to ``destination``: a file path or an open binary stream with ``write``, ``seek`` and
    ``flush``. Use :meth:`step` per record, then :meth:`finish`. A path is written as :func:`partial_path` (the
    SDK writes the file itself, which is cheaper than through a Python stream) and atomically renamed to the
    path (created or replaced) when finished. A failed write raises :class:`LogWriteError` from the next
    :meth:`step` (or :meth:`finish`), and the partial file is removed."""

    def __init__(self, destination: str | Path | BinaryIO, episode: Episode, metadata: Mapping[str, str], strategy: str,
                 perception_mode: str) -> None:
        self.episode = episode
        self.scenario = episode.scenario
        self.dt = episode.config.dt
        self.strategy = strategy
        self.h_wait = episode.config.planner.h_wait
        self.perception_mode = perception_mode
        if _OPEN:
            raise RuntimeError("an episode log is already open in this process: finish it first "
                               f"(episode seed {_OPEN[0].episode.seed})")
        context, self.channels = _channels()
        self._writes = _writes()
        self.steps = 0
        self.finished = False
        self._last_time = 0.0
        self._radii = [float(r) for r in episode.crowd.radii]  # moving obstacles' radii (cm)
        # a moving obstacle of a reactive model shows where it is heading (scripted ones are drawn as they always
        # were, so their logs stay byte for byte what they were before obstacle models)
        self._scenes = StepScenes(self.scenario.robot.radius, episode.obstacle_ids, self._radii,
                                  [model != DEFAULT_MODEL for model in episode.crowd.models_of])
        self.path = Path(destination) if isinstance(destination, str | Path) else None
        self._identity = (metadata.get("config"), metadata.get("seed"))
        self._partial = partial_path(self.path) if self.path is not None else None
        self._failures: list[str] = []  # the SDK's reports of failed writes (see SDK_LOGGER)
        try:
            self.writer = foxglove.open_mcap(self._partial or destination, context=context,
                                             writer_options=_WRITE_OPTIONS, allow_overwrite=True)
        except OSError as err:  # the SDK's message does not name the file
            failed = type(err)(f"{destination}: cannot write the log: {err}")
            failed.errno, failed.filename = err.errno or _errno_of(str(err)), str(destination)
            raise failed from None
        logging.getLogger(SDK_LOGGER).addFilter(self._capture_failure)
        try:
            self.writer.write_metadata(RUN_METADATA, dict(metadata))
            self.log(0.0, LOG_INFO, f"episode started: scenario {self.scenario.name}, strategy {strategy}, "
                                    f"h_wait {self.h_wait}, seed {episode.seed}")
            self._write_static_scene()
            self._raise_if_failed()
        except BaseException:
            self._abandon()
            raise
        _OPEN.append(self)

    # -- write failures -----------------------------------------------------------------------------------
    def _capture_failure(self, record: logging.LogRecord) -> bool:
        """Logging filter on the SDK's logger: keep the first failure reports, drop the records (a full disk
        would otherwise print one warning per message, each failing again in a log file on that disk)."""
        if len(self._failures) < 8:
            self._failures.append(record.getMessage())
        return False

    def _raise_if_failed(self) -> None:
        if self._failures:
            raise self._error()

    def _error(self, err: BaseException | None = None) -> LogWriteError:
        """The write failure as one :class:`LogWriteError` naming the log: the operating system's error when the
        SDK reported one (its first report names it) or writing to the file again shows it (when the last writes
        fail in ``close``, the SDK says only "I/O error from writing"), else the SDK's own words."""
        text = self._failures[0] if self._failures else str(err or "unknown error")
        code = _errno_of(text)
        if code is None and self._partial is not None:
            code = _write_errno(self._partial)
        detail = os.strerror(code) if code is not None else text.removeprefix("error logging message: ")
        return LogWriteError(self.path or Path("<stream>"), code, detail)

    def _abandon(self) -> None:
        """After a failure: close the writer (its error is ours already) and remove the partial file."""
        logging.getLogger(SDK_LOGGER).removeFilter(self._capture_failure)
        with contextlib.suppress(Exception):
            self.writer.close()
        if self._partial is not None:
            with contextlib.suppress(OSError):
                self._partial.unlink()

    # -- writing helpers --------------------------------------------------------------------------------
    def _write(self, topic: str, t: float, message: dict) -> None:
        self._writes[topic](orjson.dumps(message, option=orjson.OPT_SERIALIZE_NUMPY), round(t * 1e9), None)

    def log(self, t: float, level: int, text: str) -> None:
        """A human-readable event on ``/log``."""
        self._write("/log", t, {"timestamp": stamp(t), "level": level, "message": text, "name": "fuzzynav",
                                "file": "", "line": 0})

    def _write_static_scene(self) -> None:
        self._write("/scene", 0.0, static_scene(self.scenario))

    # -- per step ---------------------------------------------------------------------------------------
    def step(self, rec: StepRecord) -> None:
        """Write every topic for one step."""
        t = rec.time_s
        self._last_time = t + self.dt
        s, n = rec.state, rec.next_state
        d = rec.decision
        k = rec.step
        radius = self.scenario.robot.radius
        when = stamp(t)  # one (read-only) timestamp object shared by this step's messages
        self._write("/robot/pose", t, {"timestamp": when, "frame_id": FRAME, "pose": pose(s.x, s.y, s.heading)})
        self._write_laser(rec, when)
        self._write("/sonar", t, {"timestamp": when, "step": k, "left_cm": _r(rec.sonar[0]),
                                  "front_cm": _r(rec.sonar[1]), "right_cm": _r(rec.sonar[2]),
                                  "range_cm": _r(self.episode.config.sonar.range_cm)})
        self._write("/tracks", t, {"timestamp": when, "step": k, "mode": self.perception_mode,
                                   "moving_beams": np.nonzero(rec.moving_beams)[0].tolist(), "tracks": [
            {"id": tr.id, "x_cm": _r(tr.x), "y_cm": _r(tr.y), "vx_cm_s": _r(tr.vx), "vy_cm_s": _r(tr.vy),
             "speed_cm_s": _r(tr.speed), "heading_deg": _r(tr.moving_angle_deg), "radius_cm": _r(tr.radius)}
            for tr in rec.tracks]})
        truth = [{"id": oid, "x_cm": x, "y_cm": y, "vx_cm_s": vx, "vy_cm_s": vy, "radius_cm": r, "next_x_cm": qx,
                  "next_y_cm": qy}
                 for oid, (x, y), (vx, vy), r, (qx, qy) in zip(
                     self.episode.obstacle_ids, rec.obstacle_positions.tolist(), rec.obstacle_velocities.tolist(),
                     self._radii, rec.obstacle_next_positions.tolist(), strict=True)]
        if rec.obstacle_present is not None:
            # only where a model says who is present (recorded people): every other log stays what it was
            for o, now, after in zip(truth, rec.obstacle_present.tolist(), rec.obstacle_next_present.tolist(),
                                     strict=True):
                o["present"], o["next_present"] = now, after
        if rec.obstacle_reacting is not None:  # only where recorded people may react to the robot
            for o, reacting in zip(truth, rec.obstacle_reacting.tolist(), strict=True):
                o["reacting"] = reacting
        self._write("/obstacles/truth", t, {"timestamp": when, "step": k, "obstacles": truth})
        self._write("/robot/state", t, {
            "timestamp": when, "step": k, "x_cm": _r(s.x), "y_cm": _r(s.y), "heading_deg": _r(s.heading),
            "v_cm_s": _r(s.v), "next_x_cm": _r(n.x), "next_y_cm": _r(n.y), "next_heading_deg": _r(n.heading),
            "next_v_cm_s": _r(n.v), "radius_cm": _r(radius), "contact_static": rec.contact_static,
            "contact_dynamic": list(rec.contact_dynamic), "new_contacts": rec.new_contacts,
            "distance_to_goal_cm": _r(rec.distance_to_goal)})
        if d.tpt is not None:
            self._write_tpt(t, when, k, d.tpt)
        self._write_decision(t, when, k, rec)
        self._write_scene(t, when, rec)
        self._write_events(t, rec)
        self.steps += 1
        if self._failures:
            raise self._error()

    def _write_laser(self, rec: StepRecord, when: dict[str, int]) -> None:
        scan, s = rec.scan, rec.state
        n = len(scan.ranges)
        returned = scan.ranges < scan.range_cm
        self._write("/laser", rec.time_s, {
            "timestamp": when, "frame_id": FRAME, "pose": pose(s.x, s.y, s.heading, 0.1),
            "start_angle": 0.0, "end_angle": 2 * math.pi * (n - 1) / n,
            # full precision: replay --verify rebuilds the static returns from these ranges, and policies that
            # read every return (VFH's histogram cells, ORCA's constraints) can turn on a micrometre
            "ranges": scan.ranges / 100.0, "intensities": returned.astype(np.int64)})

    def _write_tpt(self, t: float, when: dict[str, int], k: int, tpt) -> None:
        self._write("/tpt", t, {
            "timestamp": when, "step": k, "n_traj": tpt.n_traj, "dt_s": tpt.dt,
            "robot_speed_cm_s": _r(tpt.robot_speed), "robot_radius_cm": _r(tpt.robot_radius),
            "safety_margin_cm": _r(tpt.safety_margin), "robot_cm": _array(tpt.robot, -1, 2),
            "obstacle_ids": list(tpt.obstacle_ids), "obstacle_radii_cm": _array(tpt.obstacle_radii),
            "obstacle_velocities_cm_s": _array(tpt.obstacle_velocities, -1, 2),
            "obstacles_cm": _array(tpt.obstacles, len(tpt.robot), len(tpt.obstacle_ids), 2),
            "collide": np.ascontiguousarray(tpt.collide, dtype=bool)})

    def _write_decision(self, t: float, when: dict[str, int], k: int, rec: StepRecord) -> None:
        d = rec.decision
        planning = None
        if d.new_plan and d.plan is not None:
            p = d.plan
            planning = {"strategy": p.strategy, "tc": p.tc, "tS": p.tS, "tG": p.tG, "wait_time": p.wait_time,
                        "h_wait": self.h_wait, "obstacle_id": p.obstacle_id, "detour_start": p.detour_start,
                        "phi_low_deg": None if p.phi_low_deg is None else _r(p.phi_low_deg), "reason": p.reason,
                        "path_cm": [[_r(x), _r(y)] for x, y in p.path]}
        left, front, right, angle = d.inputs
        self._write("/planner/decision", t, {
            "timestamp": when, "step": k, "mode": d.mode, "new_plan": d.new_plan, "left_cm": _r(left),
            "front_cm": _r(front), "right_cm": _r(right), "angle_deg": _r(angle), "dtheta_deg": _r(d.dtheta_deg),
            "v_cm_s": _r(d.v_cm_s), "strategy": self.strategy, "planning": planning,
            "policy": d.policy, "policy_fields": _policy_fields(d.fields),
            "compute_time_us": round(rec.compute_time_us, 1)})

    def _write_scene(self, t: float, when: dict[str, int], rec: StepRecord) -> None:
        s, d = rec.state, rec.decision
        self._writes["/scene"](self._scenes.message(
            when, s.x, s.y, s.heading, rec.obstacle_positions, rec.obstacle_velocities, d.tpt, d.plan, d.new_plan,
            rec.obstacle_present), round(t * 1e9), None)

    def _write_events(self, t: float, rec: StepRecord) -> None:
        d = rec.decision
        if d.new_plan and d.plan is not None:
            p = d.plan
            self.log(t, LOG_WARNING, f"collision predicted with obstacle {p.obstacle_id} at step +{p.tc} "
                                     f"(tS={p.tS}, tG={p.tG}, waitTime={p.wait_time}, hWait={self.h_wait})")
            if p.strategy == "wait":
                waiting = int(sum(1 for q in p.path if dist(q, p.path[-1]) < 1e-9))
                self.log(t, LOG_INFO, f"wait started: {waiting} step(s) at ({p.path[-1][0]:.0f}, "
                                      f"{p.path[-1][1]:.0f}) cm — {p.reason}")
            elif p.strategy == "detour":
                self.log(t, LOG_INFO, f"detour planned: {len(p.path)} step(s) from tS'={p.detour_start} — {p.reason}")
            else:
                self.log(t, LOG_WARNING, f"stop: {p.reason}")
        if rec.contact_static:
            self.log(t + self.dt, LOG_ERROR, "contact with a static obstacle or wall")
        for oid in rec.contact_dynamic:
            self.log(t + self.dt, LOG_ERROR, f"contact with moving obstacle {oid}")

    # -- end ----------------------------------------------------------------------------------------------
    def finish(self, outcome: str, reason: str = "") -> None:
        """Write ``/episode`` and the summary, then rename the partial file to the log's path: the file is complete
        afterwards, or :class:`LogWriteError` is raised and no file is left."""
        if self.finished:
            return
        t = self._last_time
        level = LOG_INFO if outcome == "goal" else LOG_ERROR if outcome == "error" else LOG_WARNING
        text = {"goal": "goal reached", "collision": "collision", "timeout": "timeout: step limit reached",
                "error": "error", "interrupted": "interrupted"}.get(outcome, outcome)
        try:
            self.log(t, level, f"{text} after {self.steps} step(s)" + (f": {reason}" if reason else ""))
            self._write("/episode", t, {"timestamp": stamp(t), "outcome": outcome, "steps": self.steps,
                                        "time_s": _r(self.steps * self.dt), "contacts": self.episode.contacts,
                                        "reason": reason})
        finally:  # whatever happens, the file is closed and the process can open the next log
            try:
                self._close()
            finally:
                _OPEN.remove(self)
                self.finished = True

    def _close(self) -> None:
        """Close the writer and move the finished file into place (an atomic rename: a reader sees the whole
        log or none); any failure removes the partial file and raises :class:`LogWriteError`."""
        try:
            self.writer.close()
        except Exception as err:  # the SDK raises RuntimeError for I/O errors
            failure = self._error(err)
            self._abandon()
            raise failure from None
        logging.getLogger(SDK_LOGGER).removeFilter(self._capture_failure)
        if self._failures:
            failure = self._error()
            self._abandon()
            raise failure
        if self._partial is not None and self.path is not None:
            other = _other_episode(self.path, self._identity)
            if other:
                self._abandon()
                raise LogWriteError(self.path, errno.EEXIST, f"{other} is already there and would be replaced (choose "
                                    "another output directory; in a sweep, a hydra.sweep.subdir per job)")
            try:
                os.replace(self._partial, self.path)
            except OSError as err:
                self._abandon()
                raise LogWriteError(self.path, err.errno, err.strerror or str(err)) from None


def _other_episode(path: Path, identity: tuple[str | None, str | None]) -> str | None:
    """"the log of another episode (seed N)" when ``path`` is a readable log whose recorded config or seed differs
    from ``identity`` (config YAML, seed); None when nothing is there, it is this episode's (a re-run), or it is
    unreadable (a corrupt or partial file is no result to protect)."""
    if not path.is_file():
        return None
    # imported here: the MCAP reader (~8 ms to import) is needed only where a log is already there
    from mcap.reader import make_reader

    try:
        with open(path, "rb") as f:
            for record in make_reader(f).iter_metadata():
                if record.name == RUN_METADATA:
                    meta = dict(record.metadata)
                    config, seed = meta.get("config"), meta.get("seed")
                    same_config = config == identity[0] or (
                        isinstance(config, str) and isinstance(identity[0], str)
                        and same_episode_config(config, identity[0]))  # (resume, episodes: the same episode)
                    if not same_config or seed != identity[1]:
                        same_seed = seed == identity[1]
                        return (f"the log of another episode ({'another config' if same_seed else 'seed '}"
                                f"{'' if same_seed else meta.get('seed')})")
                    return None
    except Exception:  # any reader failure: the file is not a finished log
        return None
    return None


def _write_errno(path: Path) -> int | None:
    """The operating system's error for writing one block more to ``path`` (a file being abandoned), if any."""
    try:
        with open(path, "ab") as f:
            f.write(b"\0" * 4096)
            f.flush()
            os.fsync(f.fileno())
    except OSError as err:
        return err.errno
    return None


def _errno_of(text: str) -> int | None:
    """The operating system error code in one of the SDK's error texts (``... Os { code: 28, ...``)."""
    match = _OS_CODE.search(text)
    return int(match.group(1)) if match else None


def _policy_fields(fields: Mapping[str, Any]) -> dict[str, Any]:
    """A policy's own values of one step for the log, in key order: numbers as floats (like every logged number),
    booleans and strings as they are (the planning layer has checked them:
    ``fuzzynav.planning.layer.checked_action``)."""
    return {key: value if isinstance(value, str) else bool(value) if isinstance(value, bool | np.bool_)
            else _r(float(value)) for key, value in sorted(fields.items())}


def run_metadata(config_yaml: str, seed: int, scenario: str, extra: Mapping[str, Any] | None = None) -> dict[str, str]:
    """The ``fuzzynav.run`` metadata record: config, seed, scenario, versions, git commit, which forms of the
    kernels ran (``kernels``: :func:`fuzzynav.numerics.compiled.in_use`; all strings)."""
    from fuzzynav.numerics import compiled
    from runners.logs.provenance import provenance

    meta = {"config": config_yaml, "seed": str(seed), "scenario": scenario, **provenance(),
            "kernels": compiled.in_use()}
    for key, value in (extra or {}).items():
        meta[key] = str(value)
    return meta
