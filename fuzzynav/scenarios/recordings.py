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

import math
from dataclasses import dataclass

import numpy as np

FORMATS = {"obsmat": 8, "xy": 4}
#: the largest recording read (bytes of text): ETH/UCY files are under 3 MB
MAX_TEXT_BYTES = 64 * 1024 * 1024
#: at most this many annotations per file (students03, the largest, has about 22,000)
MAX_ROWS = 1_000_000
ANNOTATION_HZ = 2.5


class RecordingError(ValueError):
    """A recording that cannot be read as its format says: the message names the file and line."""


@dataclass(frozen=True)
class PedestrianTrack:
    """One recorded pedestrian: annotation times ``t_s`` (K,) in s from the recording's first frame, strictly
    increasing, and positions ``xy_cm`` (K, 2) in cm."""

    id: str
    t_s: np.ndarray
    xy_cm: np.ndarray


@dataclass(frozen=True)
class Recording:
    """The pedestrians of one recording file (``source`` names it in errors), each with its track."""

    source: str
    tracks: tuple[PedestrianTrack, ...]
    annotation_dt_s: float

    @property
    def duration_s(self) -> float:
        """From the first to the last annotation of any pedestrian (s)."""
        if not self.tracks:
            return 0.0
        return max(float(t.t_s[-1]) for t in self.tracks) - min(float(t.t_s[0]) for t in self.tracks)


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


@dataclass(frozen=True)
class Resampled:
    """A recording at a run's steps: ``times_s`` (T,) from the window's start, positions ``xy_cm`` (N, T, 2) and
    ``present`` (N, T) per pedestrian ``ids`` (N,); absent positions are NaN."""

    ids: tuple[str, ...]
    times_s: np.ndarray
    xy_cm: np.ndarray
    present: np.ndarray


def resample(recording: Recording, dt_s: float, start_s: float = 0.0, duration_s: float | None = None,
             crop_cm: tuple[float, float, float, float] | None = None) -> Resampled:
    """Positions at ``start_s + k * dt_s`` for k = 0 .. (``duration_s`` / dt_s; default: to the recording's end)
    by linear interpolation within each pedestrian's track (module docstring). With ``crop_cm`` (x0, y0, x1, y1),
    a pedestrian is present only while inside the rectangle (boundary included). Pedestrians never present in
    the window are left out."""
    if not (math.isfinite(dt_s) and dt_s > 0):
        raise RecordingError(f"{recording.source}: dt must be a positive number of seconds, got {dt_s}")
    end = recording.duration_s if duration_s is None else start_s + duration_s
    if not (math.isfinite(start_s) and math.isfinite(end) and 0 <= start_s <= end):
        raise RecordingError(f"{recording.source}: time window [{start_s}, {end}] s is not a window of the "
                             "recording")
    count = math.floor((end - start_s) / dt_s + 1e-9) + 1
    if count > 1_000_000:
        raise RecordingError(f"{recording.source}: {count:,} steps in the window, more than 1,000,000")
    times = start_s + dt_s * np.arange(count)
    ids, positions, masks = [], [], []
    for track in recording.tracks:
        # a step on an annotation's time is inside whatever the last bit of k * dt says (0.4 * 3 > 1.2)
        inside = (times >= track.t_s[0] - 1e-9) & (times <= track.t_s[-1] + 1e-9)
        if len(track.t_s) == 1:
            xy = np.repeat(track.xy_cm[:1], count, axis=0)
        else:
            xy = np.stack([np.interp(times, track.t_s, track.xy_cm[:, 0]),
                           np.interp(times, track.t_s, track.xy_cm[:, 1])], axis=1)
        if crop_cm is not None:
            x0, y0, x1, y1 = crop_cm
            inside &= (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
        if not inside.any():
            continue
        xy[~inside] = np.nan
        ids.append(track.id)
        positions.append(xy)
        masks.append(inside)
    if not ids:
        return Resampled((), times - start_s, np.zeros((0, count, 2)), np.zeros((0, count), dtype=bool))
    return Resampled(tuple(ids), times - start_s, np.stack(positions), np.stack(masks))


#: the predictions compared by :func:`prediction_errors`
PREDICTORS = ("tpt", "cv", "standing")


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
