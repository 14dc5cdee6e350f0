"""The report's first figure: each group's success rate, time-to-goal and path length at a glance.

A dot plot with three panels side by side sharing one vertical axis: a band per scenario group, in it a row per
group (policy/strategy and every other differing run parameter, :mod:`analysis.run_parameters`), a dot for the
mean and a bar for its 95 % interval: Wilson for the success rate, percentile bootstrap for time-to-goal (over the
episodes that reached the goal) and path length (over every episode). The numbers are the report's group table
(``groups.csv``): the figure computes nothing of its own.
"""

from __future__ import annotations

import math
from pathlib import Path

from analysis import plots
from analysis.deferred import deferred

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

PANELS = (("success", "success rate", "(Wilson 95 %)"),
          ("time_to_goal_s", "time to goal (s)", "(episodes reaching the goal; bootstrap 95 %)"),
          ("path_length_cm", "path length (cm)", "(every episode; bootstrap 95 %)"))
"""(metric, axis label, what the interval is over) of each panel, left to right."""
FILENAME = "overview.png"
WIDTH_IN = 14.0
"""The figure's width (inches; 1260 px at 90 dpi): a 1280 px wide window shows it whole."""
MAX_HEIGHT_IN = 6.6
"""The figure's height bound (inches, 90 dpi: 594 px), so that it fits the first screen however many groups."""


def overview(df: pd.DataFrame, groups: pd.DataFrame, out: Path) -> Path:
    """``overview.png`` in ``out``. ``df``: the episodes (for the groups' order and colours); ``groups``: the long
    group table of :func:`analysis.report.group_table` (one row per scenario label, variant and metric with
    ``mean``, ``ci_low``, ``ci_high``)."""
    pal = plots.palette(df)
    stats = groups.set_index(["scenario_label", "variant", "metric"])[["mean", "ci_low", "ci_high", "n"]]
    scenarios = list(pd.unique(df["scenario_label"]))
    rows: list[tuple[float, str, str]] = []  # (y, scenario, variant), top to bottom
    centres, edges, y = [], [], 0.0
    for scenario in scenarios:
        present = set(df.loc[df["scenario_label"] == scenario, "variant"])
        variants = [v for v in pal if v in present]
        start = y
        for variant in variants:
            rows.append((y, scenario, variant))
            y += 1.0
        centres.append((start + y - 1) / 2)
        edges.append(y)  # the separator in the empty row between two scenario bands
        y += 1.0
    height = min(MAX_HEIGHT_IN, max(2.6, 1.3 + 0.16 * len(rows) + 0.16 * len(scenarios)))
    point = max(2.5, min(6.0, 70.0 / max(len(rows), 1)))  # marker size: smaller when rows are many
    left = 0.3 + max(len(s) for s in scenarios) * 0.6 * 8 / 72  # the scenario labels at 8 pt
    right = plots.legend_width_in(list(pal)) + 0.1
    panel_w = max(2.2, (WIDTH_IN - left - right - 0.3 * (len(PANELS) - 1)) / len(PANELS))
    fig, axes = plots.grid(1, len(PANELS), panel_w, height - 1.05, left=left, right=right, top=0.35, bottom=0.7,
                           wspace=0.3, sharey=True)
    axes = axes[0]
    for ax, (metric, label, over) in zip(axes, PANELS, strict=True):
        bars: list = []
        for yy, scenario, variant in rows:
            key = (scenario, variant, metric)
            if key not in stats.index:
                continue
            mean, lo, hi = (float(stats.at[key, c]) for c in ("mean", "ci_low", "ci_high"))
            if math.isnan(mean):
                continue
            plots.interval(ax, yy, mean, lo, hi, pal[variant], variant, horizontal=True, size=point, bars=bars)
        plots.draw_bars(ax, bars)
        for edge in edges[:-1]:
            ax.axhline(edge, color="0.8", lw=0.8)
        ax.set_xlabel(f"{label}\n{over}", fontsize=8)
        ax.grid(alpha=0.3, axis="x")
        ax.tick_params(labelsize=8)
        if metric == "success":
            ax.set_xlim(-0.03, 1.03)
    axes[0].set_yticks(centres, scenarios, fontsize=8)
    axes[0].set_ylim(y - 0.5, -1.0)  # the first scenario on top
    axes[0].tick_params(axis="y", length=0)
    n = len(df)
    fig.suptitle(f"Overview: {n} episodes in {len(rows)} groups — dot: mean, bar: 95 % interval", fontsize=10)
    plots._legend_outside(fig, fontsize=7)
    return plots._save(fig, out / FILENAME)
