"""Report figures (matplotlib, PNG): metric vs h_wait, box plots per strategy, trajectories per scenario."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.patches import Circle
from matplotlib.patches import Polygon as PolygonPatch

from analysis.episode_log import load_episode

STRATEGY_COLORS = {"auto": "tab:blue", "wait": "tab:orange", "detour": "tab:green", "none": "tab:red"}


def _color(variant: str):
    """Strategy colours; auto(h=k) in darker blues as k grows."""
    if variant.startswith("auto(h="):
        k = int(variant[len("auto(h="):-1])
        return plt.cm.Blues(min(0.35 + 0.15 * k, 1.0))
    return STRATEGY_COLORS.get(variant.split("(")[0], "tab:gray")


def _per_scenario(df: pd.DataFrame, out: Path, filename: str, draw) -> Path:
    """One panel per scenario, ``draw(ax, rows_of_that_scenario)``, saved as ``out/filename``."""
    scenarios = sorted(df["scenario"].unique())
    fig, axes = plt.subplots(1, len(scenarios), figsize=(4.2 * len(scenarios), 3.4), squeeze=False)
    for ax, scenario in zip(axes[0], scenarios, strict=True):
        draw(ax, df[df["scenario"] == scenario])
        ax.set_title(scenario)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path = out / filename
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def metric_vs_h_wait(df: pd.DataFrame, metric: str, out: Path) -> Path:
    """One panel per scenario: the metric's mean (±95 % bootstrap interval) against h_wait for ``auto``, and
    the strategies that ignore h_wait as horizontal bands."""
    from analysis.stats import bootstrap_mean

    def draw(ax, sub: pd.DataFrame) -> None:
        auto = sub[sub["strategy"] == "auto"]
        if not auto.empty:
            hs = sorted(auto["h_wait"].dropna().unique())
            stats = [bootstrap_mean(auto.loc[auto["h_wait"] == h, metric]) for h in hs]
            means = [s[0] for s in stats]
            lo = [s[0] - s[1] if not math.isnan(s[1]) else 0 for s in stats]
            hi = [s[2] - s[0] if not math.isnan(s[2]) else 0 for s in stats]
            ax.errorbar(hs, means, yerr=[lo, hi], marker="o", capsize=3, color=_color("auto"), label="auto")
        for strategy in ("wait", "detour", "none"):
            rows = sub[sub["strategy"] == strategy]
            if rows.empty:
                continue
            mean, low, high = bootstrap_mean(rows[metric])
            if math.isnan(mean):
                continue
            ax.axhline(mean, color=_color(strategy), linestyle="--", label=strategy)
            if not math.isnan(low):
                ax.axhspan(low, high, color=_color(strategy), alpha=0.12)
        ax.set_xlabel("h_wait (steps)")
        ax.set_ylabel(metric)
        ax.legend(fontsize=7)

    return _per_scenario(df, out, f"h_wait_{metric}.png", draw)


def box_by_strategy(df: pd.DataFrame, metric: str, out: Path) -> Path:
    """Box plot of a metric per strategy variant, one panel per scenario."""
    variants = sorted(df["variant"].unique())

    def draw(ax, sub: pd.DataFrame) -> None:
        data = [sub.loc[sub["variant"] == v, metric].dropna().to_numpy() for v in variants]
        box = ax.boxplot(data, tick_labels=variants, patch_artist=True)
        for patch, v in zip(box["boxes"], variants, strict=True):
            patch.set_facecolor(_color(v))
            patch.set_alpha(0.5)
        ax.set_ylabel(metric)
        ax.tick_params(axis="x", rotation=45, labelsize=7)

    return _per_scenario(df, out, f"box_{metric}.png", draw)


def trajectories(df: pd.DataFrame, scenario: str, out: Path) -> Path:
    """Robot paths of each strategy variant (lowest seed) over the static world and the moving obstacles'
    true paths; contacts are marked with a red x."""
    sub = df[df["scenario"] == scenario].sort_values("seed")
    first = sub.groupby("variant").head(1)
    fig, ax = plt.subplots(figsize=(7, 5))
    drawn_world = False
    for _, row in first.iterrows():
        log = load_episode(row["log"], ["/scene", "/robot/state", "/obstacles/truth"])
        if not drawn_world:
            for poly in log.static_polygons:
                ax.add_patch(PolygonPatch(np.array(poly.exterior.coords), closed=True, color="0.6"))
            if log.bounds:
                xmin, ymin, xmax, ymax = log.bounds
                ax.plot([xmin, xmax, xmax, xmin, xmin], [ymin, ymin, ymax, ymax, ymin], color="0.3")
            if log.goal:
                ax.add_patch(Circle(log.goal, log.goal_tolerance or 20, color="tab:green", alpha=0.3))
            tracks: dict[str, list] = {}
            for m in log.truth:
                for o in m["obstacles"]:
                    tracks.setdefault(o["id"], []).append((o["x_cm"], o["y_cm"]))
            for oid, pts in tracks.items():
                p = np.array(pts)
                ax.plot(p[:, 0], p[:, 1], ":", color="tab:red", alpha=0.6)
                ax.annotate(oid, p[0], fontsize=7, color="tab:red")
            drawn_world = True
        pos = log.positions
        ax.plot(pos[:, 0], pos[:, 1], "-", color=_color(row["variant"]), alpha=0.8, label=row["variant"])
        hits = [k + 1 for k, s in enumerate(log.states) if s["contact_static"] or s["contact_dynamic"]]
        if hits:
            ax.plot(pos[hits, 0], pos[hits, 1], "x", color="red", markersize=9, mew=2)
    ax.set_aspect("equal")
    ax.set_title(f"{scenario}: robot paths (seed {int(first['seed'].min()) if len(first) else '-'})")
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    path = out / f"trajectories_{scenario}.png"
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path
