"""Motion of the scripted moving obstacles: position and velocity as pure functions of time.

Positions in cm, velocities in cm/s, time in s from the start of the episode.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from fuzzynav.numerics.portable_math import norm2

if TYPE_CHECKING:
    from fuzzynav.scenarios.scenario import DynamicObstacle


class ObstacleMotion:
    """Precomputed paths of a scenario's moving obstacles; :meth:`at` gives their state at time t."""

    def __init__(self, obstacles: Sequence[DynamicObstacle]) -> None:
        self.ids = tuple(o.id for o in obstacles)
        self.radii = np.array([o.radius for o in obstacles], dtype=float)
        self._paths = []
        for o in obstacles:
            if o.waypoints is None:
                self._paths.append(("cv", np.array(o.start, float), np.array(o.velocity, float)))
                continue
            pts = np.array(o.waypoints, dtype=float)
            if o.loop and len(pts) > 1:
                pts = np.vstack([pts, pts[:1]])
            seg = np.diff(pts, axis=0)
            lengths = norm2(seg) if len(pts) > 1 else np.zeros(0)
            cum = np.concatenate([[0.0], np.cumsum(lengths)])
            self._paths.append(("wp", pts, cum, float(o.speed), bool(o.loop)))

    def __len__(self) -> int:
        return len(self.ids)

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions (N, 2) in cm and velocities (N, 2) in cm/s at time ``t`` seconds."""
        n = len(self._paths)
        pos = np.zeros((n, 2))
        vel = np.zeros((n, 2))
        for i, path in enumerate(self._paths):
            if path[0] == "cv":
                _, start, v = path
                pos[i] = start + v * t
                vel[i] = v
                continue
            _, pts, cum, speed, loop = path
            total = cum[-1]
            if total == 0.0:
                pos[i] = pts[0]
                continue
            s = speed * t
            if loop:
                s = s % total
            elif s >= total:
                pos[i] = pts[-1]
                continue
            k = min(int(np.searchsorted(cum, s, side="right")) - 1, len(cum) - 2)
            seg_len = cum[k + 1] - cum[k]
            direction = (pts[k + 1] - pts[k]) / seg_len
            pos[i] = pts[k] + direction * (s - cum[k])
            vel[i] = direction * speed
        return pos, vel
