"""Draw an episode from its log: robot trail, obstacles, sonar sectors and TPT predicted paths (PNG, GIF)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.animation import FuncAnimation, PillowWriter
from matplotlib.patches import Circle, Wedge
from matplotlib.patches import Polygon as PolygonPatch

from analysis.episode_log import EpisodeLog

SONAR_SECTORS = {"left": (30.0, 90.0), "front": (-30.0, 30.0), "right": (-90.0, -30.0)}


def _sectors(log: EpisodeLog) -> dict[str, tuple[float, float]]:
    sonar = ((log.config.get("sensors") or {}).get("sonar") or {})
    return {k: tuple(sonar.get(k, v)) for k, v in SONAR_SECTORS.items()}


def _world(ax, log: EpisodeLog) -> None:
    for poly in log.static_polygons:
        ax.add_patch(PolygonPatch(np.array(poly.exterior.coords), closed=True, color="0.6"))
    if log.bounds:
        xmin, ymin, xmax, ymax = log.bounds
        ax.plot([xmin, xmax, xmax, xmin, xmin], [ymin, ymin, ymax, ymax, ymin], color="0.3", lw=1)
        ax.set_xlim(xmin - 20, xmax + 20)
        ax.set_ylim(ymin - 20, ymax + 20)
    if log.goal:
        ax.add_patch(Circle(log.goal, log.goal_tolerance or 20, color="tab:green", alpha=0.3))
    ax.set_aspect("equal")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")


def _snapshot(ax, log: EpisodeLog, k: int, alpha: float = 1.0) -> None:
    """The robot, its sonar sectors, the moving obstacles and the TPT at step k."""
    s = log.states[k]
    r = log.robot_radius
    ax.add_patch(Circle((s["x_cm"], s["y_cm"]), r, fill=False, color="tab:blue", alpha=alpha, lw=1.5))
    h = s["heading_deg"]
    ax.plot([s["x_cm"], s["x_cm"] + 1.6 * r * math.cos(math.radians(h))],
            [s["y_cm"], s["y_cm"] + 1.6 * r * math.sin(math.radians(h))], color="tab:blue", alpha=alpha)
    if k < len(log.sonar):
        son = log.sonar[k]
        for name, (lo, hi) in _sectors(log).items():
            reach = r + son[f"{name}_cm"]
            ax.add_patch(Wedge((s["x_cm"], s["y_cm"]), reach, h + lo, h + hi, width=reach - r,
                               color={"left": "tab:purple", "front": "tab:olive", "right": "tab:cyan"}[name],
                               alpha=0.15 * alpha))
    if k < len(log.truth):
        for o in log.truth[k]["obstacles"]:
            if not o.get("present", True):
                continue  # not in the world at this step (a recorded person before it appears or after it leaves)
            ax.add_patch(Circle((o["x_cm"], o["y_cm"]), o["radius_cm"], color="tab:red", alpha=0.5 * alpha))
    t = log.tpts.get(k)
    if t:
        robot = np.array(t["robot_cm"])
        ax.plot(robot[:, 0], robot[:, 1], ".-", color="tab:cyan", alpha=alpha, lw=1, ms=3)
        for j in range(len(t["obstacle_ids"])):
            pred = np.array([row[j] for row in t["obstacles_cm"]])
            ax.plot(pred[:, 0], pred[:, 1], ".-", color="tab:orange", alpha=alpha, lw=1, ms=3)
        for i, row in enumerate(t["collide"]):
            if any(row):
                ax.add_patch(Circle(robot[i], t["robot_radius_cm"], color="red", alpha=0.2 * alpha))


def default_steps(log: EpisodeLog, count: int = 4) -> list[int]:
    """Steps worth drawing: where plans were made (first ones), else evenly spread, plus the last step."""
    planned = [d["step"] for d in log.decisions if d.get("planning")]
    steps = planned[: count - 1] if planned else list(np.linspace(0, max(log.steps - 1, 0), count - 1, dtype=int))
    steps.append(max(log.steps - 1, 0))
    return sorted(set(int(s) for s in steps if 0 <= s < log.steps))


def render_png(log: EpisodeLog, out: Path, steps: Sequence[int] | None = None) -> Path:
    """The whole trail with snapshots (robot, sonar sectors, obstacles, TPT) at ``steps``."""
    fig, ax = plt.subplots(figsize=(9, 6))
    _world(ax, log)
    pos = log.positions
    if len(pos):
        ax.plot(pos[:, 0], pos[:, 1], "-", color="tab:blue", lw=1.5, label="robot trail")
        hits = [k + 1 for k, s in enumerate(log.states) if s["contact_static"] or s["contact_dynamic"]]
        if hits:
            ax.plot(pos[hits, 0], pos[hits, 1], "x", color="red", ms=10, mew=2, label="contact")
    paths: dict[str, list] = {}
    for m in log.truth:
        for o in m["obstacles"]:
            if o.get("present", True):
                paths.setdefault(o["id"], []).append((o["x_cm"], o["y_cm"]))
    for pts in paths.values():
        p = np.array(pts)
        ax.plot(p[:, 0], p[:, 1], ":", color="tab:red", alpha=0.7)
    chosen = list(steps) if steps is not None else default_steps(log)
    for k in chosen:
        if 0 <= k < log.steps:
            _snapshot(ax, log, k)
            s = log.states[k]
            ax.annotate(str(k), (s["x_cm"], s["y_cm"]), fontsize=8, color="tab:blue",
                        xytext=(4, 4), textcoords="offset points")
    ax.set_title(f"{log.meta.get('scenario')} — {log.meta.get('strategy')} h_wait={log.meta.get('h_wait')} "
                 f"seed={log.meta.get('seed')} — {log.outcome} after {log.steps} steps; snapshots at {chosen}")
    ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)
    return out


def render_gif(log: EpisodeLog, out: Path, fps: int = 4) -> Path:
    """One frame per step."""
    fig, ax = plt.subplots(figsize=(8, 5.5))
    pos = log.positions

    def frame(k: int):
        ax.clear()
        _world(ax, log)
        ax.plot(pos[: k + 1, 0], pos[: k + 1, 1], "-", color="tab:blue", lw=1.5)
        _snapshot(ax, log, k)
        mode = log.decisions[k]["mode"] if k < len(log.decisions) else ""
        ax.set_title(f"step {k}  t = {k * log.dt:.0f} s  mode {mode}")
        return []

    anim = FuncAnimation(fig, frame, frames=max(log.steps, 1), blit=False)
    anim.save(out, writer=PillowWriter(fps=fps))
    plt.close(fig)
    return out
