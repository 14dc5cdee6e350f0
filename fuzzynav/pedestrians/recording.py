"""A recording's pedestrians as data, and their positions at a run's steps: what the ``recorded`` obstacle model
replays (:mod:`fuzzynav.pedestrians.recorded`) and what the recording parsers make
(:mod:`fuzzynav.scenarios.recordings`, which says where the data come from).

Resampling (:func:`resample`): a pedestrian's position at a run's step is the linear interpolation between its two
annotations around that time; before its first and after its last annotation it is absent (no extrapolation).
Units: cm and s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


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
