"""Report figures (matplotlib, PNG): metric vs h_wait, box plots per variant, trajectories per scenario group.

Every figure draws one series per group (variant label from :mod:`analysis.run_parameters`), so each value of
a differing run parameter is its own line, box or path."""

from __future__ import annotations

import math
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.patches import Circle
from matplotlib.patches import Polygon as PolygonPatch

from analysis.episode_log import load_episode
from analysis.run_parameters import SEP

STRATEGY_COLORS = {"auto": "tab:blue", "wait": "tab:orange", "detour": "tab:green", "none": "tab:red"}
STRATEGY_LINES = {"auto": "-", "wait": "--", "detour": "-.", "none": ":"}


def _strategy_color(strategy: str, h_wait) -> tuple:
    """Strategy colours; auto in darker blues as h_wait grows."""
    if strategy == "auto" and h_wait is not None and not pd.isna(h_wait):
        return plt.cm.Blues(min(0.35 + 0.15 * float(h_wait), 1.0))
    return matplotlib.colors.to_rgba(STRATEGY_COLORS.get(strategy, "tab:gray"))


def styles(df: pd.DataFrame) -> dict[str, dict]:
    """Colour and line style of every variant, the same in every figure. Without other differing parameters
    the colour is the strategy's (auto: blues by h_wait); with them, the colour is the setting's (one colour
    per ``setting``, lighter for smaller h_wait) and the line style the strategy's, so that each value of a
    parameter is its own series."""
    settings = list(pd.unique(df["setting"]))
    cmap = plt.get_cmap("tab10")
    h_values = sorted(df["h_wait"].dropna().unique())
    out = {}
    for _, row in df.drop_duplicates("variant").iterrows():
        strategy, h_wait = str(row["strategy"]), row["h_wait"]
        if len(settings) <= 1:
            color = _strategy_color(strategy, h_wait)
        else:
            color = matplotlib.colors.to_rgba(cmap(settings.index(row["setting"]) % cmap.N))
            if strategy == "auto" and len(h_values) > 1 and not pd.isna(h_wait):
                light = 0.5 * (1 - h_values.index(h_wait) / (len(h_values) - 1))  # the largest h: full colour
                color = (*(c + (1 - c) * light for c in color[:3]), 1.0)
        out[row["variant"]] = {"color": color, "linestyle": STRATEGY_LINES.get(strategy, "-")}
    return out


def _file_part(label: str) -> str:
    """A scenario label as part of a file name (``random_mixed · n_dynamic=5`` -> ``random_mixed__n_dynamic=5``)."""
    return re.sub(r"[^A-Za-z0-9_.=-]+", "_", label.replace(SEP, "__"))


def _save(fig, path: Path) -> Path:
    """Write a figure and free it (one place, so that tests can look at every figure before it is saved)."""
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _legend_outside(fig) -> None:
    """One legend for the whole figure, right of the panels (inside, a dozen series would hide the data)."""
    entries: dict[str, object] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            entries.setdefault(label, handle)
    if entries:
        fig.legend(list(entries.values()), list(entries), loc="outside right upper", fontsize=6)


def _per_scenario(df: pd.DataFrame, out: Path, filename: str, draw, panel_width: float = 4.2,
                  legend: bool = False) -> Path:
    """One panel per scenario group, ``draw(ax, rows_of_that_scenario)``, saved as ``out/filename``; with
    ``legend``, the series of every panel in one legend on the right."""
    scenarios = list(pd.unique(df["scenario_label"]))
    width = panel_width * len(scenarios) + (2.0 if legend else 0.0)
    fig, axes = plt.subplots(1, len(scenarios), figsize=(width, 3.6), squeeze=False, layout="constrained")
    for ax, scenario in zip(axes[0], scenarios, strict=True):
        draw(ax, df[df["scenario_label"] == scenario])
        ax.set_title(scenario, fontsize=9)
        ax.grid(alpha=0.3)
    if legend:
        _legend_outside(fig)
    return _save(fig, out / filename)


def metric_vs_h_wait(df: pd.DataFrame, metric: str, out: Path) -> Path:
    """One panel per scenario group: the metric's mean (±95 % bootstrap interval) against h_wait for ``auto``,
    one line per setting of the other differing parameters (points of different settings are shifted a little
    sideways so that they do not hide each other), and the variants that ignore h_wait as horizontal lines
    with their interval as a band."""
    from analysis.stats import bootstrap_mean

    style = styles(df)
    settings = list(pd.unique(df["setting"]))
    dodge = 0.08 if len(settings) > 1 else 0.0

    def draw(ax, sub: pd.DataFrame) -> None:
        auto = sub[sub["strategy"] == "auto"]
        for i, setting in enumerate(settings):
            rows = auto[auto["setting"] == setting]
            if rows.empty:
                continue
            hs = sorted(rows["h_wait"].dropna().unique())
            stats = [bootstrap_mean(rows.loc[rows["h_wait"] == h, metric]) for h in hs]
            means = [s[0] for s in stats]
            lo = [s[0] - s[1] if not math.isnan(s[1]) else 0 for s in stats]
            hi = [s[2] - s[0] if not math.isnan(s[2]) else 0 for s in stats]
            xs = [h + dodge * (i - (len(settings) - 1) / 2) for h in hs]
            color = style[rows["variant"].iloc[-1]]["color"]  # the largest h_wait's: full colour
            ax.errorbar(xs, means, yerr=[lo, hi], marker="o", capsize=3, color=color,
                        label=SEP.join(["auto", setting]) if setting else "auto")
        for variant, rows in sub[sub["strategy"] != "auto"].groupby("variant", sort=False):
            mean, low, high = bootstrap_mean(rows[metric])
            if math.isnan(mean):
                continue
            ax.axhline(mean, label=variant, **style[variant])
            if not math.isnan(low):
                ax.axhspan(low, high, color=style[variant]["color"], alpha=0.12)
        hs = sorted(auto["h_wait"].dropna().unique())
        if hs:  # whole steps only, and room around a single h_wait
            ax.set_xticks(hs)
            ax.set_xlim(min(hs) - 0.5, max(hs) + 0.5)
        ax.set_xlabel("h_wait (steps)")
        ax.set_ylabel(metric)

    return _per_scenario(df, out, f"h_wait_{metric}.png", draw, legend=True)


def box_by_strategy(df: pd.DataFrame, metric: str, out: Path) -> Path:
    """Box plot of a metric per variant, one panel per scenario group."""
    style = styles(df)
    variants = list(pd.unique(df["variant"]))

    def draw(ax, sub: pd.DataFrame) -> None:
        data = [sub.loc[sub["variant"] == v, metric].dropna().to_numpy() for v in variants]
        box = ax.boxplot(data, tick_labels=variants, patch_artist=True)
        for patch, v in zip(box["boxes"], variants, strict=True):
            patch.set_facecolor(style[v]["color"])
            patch.set_linestyle(style[v]["linestyle"])
            patch.set_alpha(0.5)
        ax.set_ylabel(metric)
        ax.tick_params(axis="x", rotation=60, labelsize=6)
        for label in ax.get_xticklabels():
            label.set_horizontalalignment("right")
            label.set_rotation_mode("anchor")  # the label's end under its box

    return _per_scenario(df, out, f"box_{metric}.png", draw, panel_width=max(4.2, 1.5 + 0.45 * len(variants)))


def trajectories(df: pd.DataFrame, scenario: str, out: Path) -> Path:
    """Robot paths of each variant (lowest seed) in one scenario group over the static world and the moving
    obstacles' true paths; contacts are marked with a red x."""
    style = styles(df)
    sub = df[df["scenario_label"] == scenario].sort_values("seed", kind="stable")
    first = sub.groupby("variant", sort=False).head(1)
    first = first.set_index("variant").loc[list(pd.unique(sub["variant"]))].reset_index()  # the groups' order
    fig, ax = plt.subplots(figsize=(9, 5), layout="constrained")
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
        ax.plot(pos[:, 0], pos[:, 1], alpha=0.8, label=row["variant"], **style[row["variant"]])
        hits = [k + 1 for k, s in enumerate(log.states) if s["contact_static"] or s["contact_dynamic"]]
        if hits:
            ax.plot(pos[hits, 0], pos[hits, 1], "x", color="red", markersize=9, mew=2)
    ax.set_aspect("equal")
    ax.set_title(f"{scenario}: robot paths (seed {int(first['seed'].min()) if len(first) else '-'})", fontsize=9)
    ax.set_xlabel("x (cm)")
    ax.set_ylabel("y (cm)")
    _legend_outside(fig)
    return _save(fig, out / f"trajectories_{_file_part(scenario)}.png")
