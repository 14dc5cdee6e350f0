"""Recorded pedestrian trajectories (the ETH/BIWI and UCY recordings and the benchmarks built on them), parsed
from their text formats and resampled to a run's time step. Pure functions over text and arrays: reading the
files is the caller's (``runners``).

Formats (whitespace-separated numbers, one annotation per line, positions in metres):

- ``obsmat``: ETH/BIWI's ``obsmat.txt`` (also UCY's converted ones): ``frame id x z y vx vz vy`` — 8 columns,
  the ground plane is x, y (z and vz are 0); the velocities are not used (they are the annotators' estimate;
  ours come from the positions, as the TPT's do).
- ``xy``: the 4-column ``frame id x y`` files of the trajectory-prediction benchmarks (Social-GAN, TrajNet),
  tab or space separated, sorted by frame or by pedestrian.

Time: the annotations are ``annotation_hz`` (2.5 Hz in both datasets: every 10th frame of a 25 fps video, every
6th of 15 fps) apart; the frame step is the smallest difference between the distinct frame numbers of the file,
and a frame's time is ``(frame - first frame) / frame step / annotation_hz`` seconds. A pedestrian's
annotations must be consecutive (frame numbers one step apart, in the file's order): a duplicate, a frame
going back, or a reappearance after a gap is an error naming the file and line, never mended silently (``max_gap``
allows that many missing annotations, interpolated; UCY's ``students03`` needs 1).

Resampling (:func:`resample`): a pedestrian's position at a run's step is the linear interpolation between
its two annotations around that time; before its first and after its last annotation it is absent (no
extrapolation). Units: cm and s from here on.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fuzzynav.pedestrians.recording import (  # the data and their resampling live with the model that replays them
    PedestrianTrack,
    Recording,
    RecordingError,
    Resampled,
    resample,
)

__all__ = ["ANNOTATION_HZ", "FORMATS", "PREDICTORS", "PedestrianTrack", "PredictionErrors", "Recording",
           "RecordingError", "Resampled", "parse", "prediction_errors", "read_recording", "resample"]

FORMATS = {"obsmat": 8, "xy": 4}
#: the largest recording read (bytes of text): ETH/UCY files are under 3 MB
MAX_TEXT_BYTES = 64 * 1024 * 1024
#: at most this many annotations per file (students03, the largest, has about 22,000)
MAX_ROWS = 1_000_000
ANNOTATION_HZ = 2.5


def parse(text: str, fmt: str, source: str, annotation_hz: float = ANNOTATION_HZ, max_gap: int = 0) -> Recording:
    """The recording in ``text`` (format ``fmt``: obsmat | xy); ``source`` is the file's name for messages.
    ``max_gap``: how many missing annotations a pedestrian's track may have between two of its annotations (they
    are then interpolated like any other time between annotations); more is an error. 0 (default): none."""
    if not (isinstance(max_gap, int) and 0 <= max_gap <= 1000):
        raise RecordingError(f"{source}: max_gap must be a whole number in [0, 1000], got {max_gap!r}")
    if fmt not in FORMATS:
        raise RecordingError(f"{source}: unknown format {fmt!r} (known: {', '.join(FORMATS)})")
    if not (math.isfinite(annotation_hz) and 0 < annotation_hz <= 1000):
        raise RecordingError(f"{source}: annotation_hz must be in (0, 1000], got {annotation_hz}")
    if len(text) > MAX_TEXT_BYTES:
        raise RecordingError(f"{source}: {len(text):,} characters, more than the limit of {MAX_TEXT_BYTES:,}")
    columns = FORMATS[fmt]
    frames: list[int] = []
    ids: list[str] = []
    xs: list[float] = []
    ys: list[float] = []
    lines: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        fields = line.split()
        if not fields or line.lstrip().startswith("#"):
            continue
        if len(fields) != columns:
            raise RecordingError(f"{source}: line {number}: {len(fields)} columns, the {fmt} format has {columns}")
        values = []
        for k, field in enumerate(fields):
            try:
                value = float(field)
            except ValueError:
                raise RecordingError(f"{source}: line {number}, column {k + 1}: {field[:20]!r} is not a number") \
                    from None
            if not math.isfinite(value) or abs(value) > 1e7:
                raise RecordingError(f"{source}: line {number}, column {k + 1}: {field[:20]} is not a finite "
                                     "number within ±1e7")
            values.append(value)
        frame = values[0]
        if frame != int(frame) or frame < 0:
            raise RecordingError(f"{source}: line {number}: frame {fields[0][:20]} is not a whole number >= 0")
        if values[1] != int(values[1]):
            raise RecordingError(f"{source}: line {number}: pedestrian id {fields[1][:20]} is not a whole number")
        frames.append(int(frame))
        ids.append(str(int(values[1])))
        xs.append(values[2])
        ys.append(values[4] if fmt == "obsmat" else values[3])
        lines.append(number)
        if len(frames) > MAX_ROWS:
            raise RecordingError(f"{source}: more than {MAX_ROWS:,} annotations")
    if not frames:
        raise RecordingError(f"{source}: no annotation (an empty file, or only comments)")
    distinct = np.unique(np.array(frames, dtype=np.int64))
    step = int(np.min(np.diff(distinct))) if len(distinct) > 1 else 1
    first = int(distinct[0])
    rows: dict[str, list[int]] = {}
    for k, pid in enumerate(ids):
        rows.setdefault(pid, []).append(k)
    tracks = []
    for pid, index in rows.items():
        previous = None
        for k in index:
            if previous is not None:
                gap = frames[k] - frames[previous]
                if gap == 0:
                    raise RecordingError(f"{source}: line {lines[k]}: pedestrian {pid} at frame {frames[k]} again "
                                         f"(first at line {lines[previous]})")
                if gap < 0:
                    raise RecordingError(f"{source}: line {lines[k]}: pedestrian {pid}'s frame {frames[k]} comes "
                                         f"after its frame {frames[previous]} (line {lines[previous]}): frames must "
                                         "increase")
                if gap % step or gap // step - 1 > max_gap:
                    missing = gap / step - 1
                    raise RecordingError(f"{source}: line {lines[k]}: pedestrian {pid} reappears at frame "
                                         f"{frames[k]} after frame {frames[previous]} (line {lines[previous]}): "
                                         f"{missing:g} annotation(s) missing (the frame step is {step}); max_gap "
                                         f"is {max_gap}")
            previous = k
        t = np.array([(frames[k] - first) / step / annotation_hz for k in index])
        xy = np.array([[xs[k] * 100.0, ys[k] * 100.0] for k in index])
        tracks.append(PedestrianTrack(pid, t, xy))
    return Recording(source, tuple(tracks), 1.0 / annotation_hz)


#: the predictions compared by :func:`prediction_errors`
PREDICTORS = ("tpt", "cv", "standing")


def read_recording(path: Path, fmt: str | None = None, annotation_hz: float = ANNOTATION_HZ,
                   max_gap: int = 0) -> tuple[Recording, str]:
    """The recording in the file at ``path`` and the file's SHA-256; :class:`RecordingError` (one line naming the
    file) when it cannot be read. The one place a recording file is read (the ``recorded`` scenario generator and
    the commands of :mod:`runners.recordings` and :mod:`runners.dataset`)."""
    fmt = fmt or ("obsmat" if path.name.lower().startswith("obsmat") else "xy")
    try:
        if not path.is_file():
            raise RecordingError(f"{path}: not a file" if path.exists() else f"{path}: no such file")
        size = path.stat().st_size
        if size > MAX_TEXT_BYTES:
            raise RecordingError(f"{path}: {size:,} bytes, more than the limit of {MAX_TEXT_BYTES:,} (ETH/UCY "
                                 "files are under 3 MB)")
        data = path.read_bytes()
    except RecordingError:
        raise
    except OSError as err:
        raise RecordingError(f"{path}: cannot be read ({err.strerror or err})") from None
    except ValueError as err:  # a NUL byte in the name
        raise RecordingError(f"{str(path)[:80]!r}: not a file name ({err})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise RecordingError(f"{path}: not a text file (byte {err.start} is not UTF-8)") from None
    return parse(text, fmt, str(path), annotation_hz, max_gap), hashlib.sha256(data).hexdigest()


@dataclass(frozen=True)
class PredictionErrors:
    """Average and final displacement errors (cm) of each predictor in :data:`PREDICTORS` for horizons k = 1 ..
    n_traj steps of ``dt_s``: ``ade_cm[name][k - 1]`` is the mean over samples of the mean distance over steps 1..k,
    ``fde_cm[name][k - 1]`` the mean distance at step k; ``samples`` (pedestrian, time) pairs from ``pedestrians``."""

    dt_s: float
    n_traj: int
    samples: int
    pedestrians: int
    ade_cm: dict[str, np.ndarray]
    fde_cm: dict[str, np.ndarray]


def prediction_errors(recording: Recording, dt_s: float, n_traj: int) -> PredictionErrors:
    """How well the TPT's constant-velocity prediction fits the recorded people, against the recorded truth.

    At every time t on the grid of ``dt_s`` steps (from the recording's first annotation) where a pedestrian's
    track covers t - dt_s to t + n_traj * dt_s, three predictions of its positions at t + k * dt_s: ``tpt`` — the
    table's rule, the last position plus k * dt_s times the velocity from the positions dt_s apart (what the
    tracker's finite difference gives, here without sensor noise); ``cv`` — the trajectory-prediction benchmarks'
    constant-velocity baseline, the velocity from the last two annotations (``annotation_dt_s`` apart); and
    ``standing`` — no motion. Positions between annotations are interpolated linearly (module docstring)."""
    if not (math.isfinite(dt_s) and 0 < dt_s <= 60):
        raise RecordingError(f"{recording.source}: dt must be in (0, 60] s, got {dt_s}")
    if not (isinstance(n_traj, int) and 1 <= n_traj <= 100):
        raise RecordingError(f"{recording.source}: n_traj must be a whole number in [1, 100], got {n_traj!r}")
    horizon = np.arange(1, n_traj + 1) * dt_s
    back = max(dt_s, recording.annotation_dt_s)
    errors: dict[str, list[np.ndarray]] = {name: [] for name in PREDICTORS}
    used = 0
    first = min((float(t.t_s[0]) for t in recording.tracks), default=0.0)
    for track in recording.tracks:
        t0, t1 = float(track.t_s[0]), float(track.t_s[-1])
        lo = math.ceil((t0 + back - first) / dt_s - 1e-9)
        hi = math.floor((t1 - horizon[-1] - first) / dt_s + 1e-9)
        if hi < lo:
            continue
        used += 1
        now = first + dt_s * np.arange(lo, hi + 1)

        def at(times: np.ndarray, t=track) -> np.ndarray:
            return np.stack([np.interp(times, t.t_s, t.xy_cm[:, 0]), np.interp(times, t.t_s, t.xy_cm[:, 1])],
                            axis=-1)

        here = at(now)  # (S, 2)
        truth = at(now[:, None] + horizon[None, :])  # (S, K, 2)
        v_tpt = (here - at(now - dt_s)) / dt_s
        v_cv = (here - at(now - recording.annotation_dt_s)) / recording.annotation_dt_s
        for name, velocity in (("tpt", v_tpt), ("cv", v_cv), ("standing", np.zeros_like(here))):
            predicted = here[:, None, :] + velocity[:, None, :] * horizon[None, :, None]
            diff = predicted - truth
            errors[name].append(np.sqrt(diff[..., 0] * diff[..., 0] + diff[..., 1] * diff[..., 1]))
    samples = sum(len(e) for e in errors["tpt"])
    ade, fde = {}, {}
    for name in PREDICTORS:
        if samples == 0:
            ade[name] = fde[name] = np.full(n_traj, np.nan)
            continue
        dist = np.concatenate(errors[name])  # (S, K)
        fde[name] = dist.mean(axis=0)
        ade[name] = (np.cumsum(dist, axis=1) / np.arange(1, n_traj + 1)).mean(axis=0)
    return PredictionErrors(dt_s, n_traj, samples, used, ade, fde)
