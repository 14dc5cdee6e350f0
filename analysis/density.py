"""Crowd density in the report: success and clearance against the number of pedestrians.

A crowd scenario swept over its pedestrian count (``scenario.params.n=5,10,20``) gives one scenario group per
count (``crowd_crossing · n=20``: different worlds, never pooled). This module lines those groups up along the
count: one point per group and variant, success rate with its Wilson interval and the mean minimum clearance to
moving obstacles with its bootstrap interval (cm). Nothing is pooled across counts or variants.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

from analysis.deferred import deferred
from analysis.stats import bootstrap_mean, wilson

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

#: the scenario parameters that count pedestrians (``groups``: the number of groups of ``group_size``)
COUNT_KEYS = ("scenario.params.n", "scenario.params.n_groups")


def count_key(df: pd.DataFrame) -> str | None:
    """The pedestrian-count column that differs among the episodes (a dimension of the report), or None."""
    for key in COUNT_KEYS:
        if key in df.columns and df[key].nunique(dropna=True) > 1:
            return key
    return None


def density_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per scenario (with its other differing ``scenario.*`` parameters), count and variant: episodes,
    success rate [Wilson 95 %], mean minimum clearance to moving obstacles [bootstrap 95 %] (cm). Empty when no
    count differs."""
    key = count_key(df)
    if key is None:
        return pd.DataFrame()
    rows = []
    sub = df[pd.to_numeric(df[key], errors="coerce").notna()]
    # a scenario's other differing parameters (its model, its speeds...) split its lines: never pooled
    others = [c for c in df.columns if c.startswith("scenario.") and c != key]
    line = sub["scenario"].astype(str)
    for c in others:
        line = line + f" · {c.rpartition('.')[2]}=" + sub[c].astype(str)
    sub = sub.assign(_line=line)
    for (scenario, count, variant), g in sub.groupby(["_line", key, "variant"], sort=False):
        rate, lo, hi = wilson(int(g["success"].sum()), len(g))
        clear, c_lo, c_hi = bootstrap_mean(g["min_clearance_dynamic_cm"])
        rows.append({"scenario": scenario, "pedestrians": int(float(count)), "variant": variant, "episodes": len(g),
                     "success": rate, "success_lo": lo, "success_hi": hi, "min_clearance_dynamic_cm": clear,
                     "clearance_lo": c_lo, "clearance_hi": c_hi})
    # the variants keep the report's natural order (first appearance); counts ascend
    return pd.DataFrame(rows).sort_values(["scenario", "pedestrians"], kind="stable").reset_index(drop=True)


def density_figure(table: pd.DataFrame, out: Path, colors: Mapping[str, object] | None = None) -> Path | None:
    """``out/density.png``: per scenario, success and clearance against the pedestrian count, one line per
    variant (``colors``: variant -> matplotlib colour, the report's palette). None for an empty table."""
    if table.empty:
        return None
    from analysis.plots import pyplot

    plt = pyplot()
    scenarios = list(pd.unique(table["scenario"]))
    fig, axes = plt.subplots(len(scenarios), 2, figsize=(9.0, 3.0 * len(scenarios)), squeeze=False,
                             layout="constrained")
    for (ax_s, ax_c), scenario in zip(axes, scenarios, strict=True):
        rows = table[table["scenario"] == scenario]
        variants = list(pd.unique(rows["variant"]))
        span = max(float(rows["pedestrians"].max() - rows["pedestrians"].min()), 1.0)
        for k, (variant, g) in enumerate(rows.groupby("variant", sort=False)):
            color = (colors or {}).get(variant)
            # variants side by side at each count, so that equal values (all 1.0) do not hide each other
            x = g["pedestrians"].to_numpy() + 0.012 * span * (k - (len(variants) - 1) / 2)
            ax_s.errorbar(x, g["success"], yerr=[g["success"] - g["success_lo"], g["success_hi"] - g["success"]],
                          marker="o", capsize=3, label=variant, color=color)
            lo = [0.0 if math.isnan(a) else m - a for m, a in zip(g["min_clearance_dynamic_cm"], g["clearance_lo"],
                                                                    strict=True)]
            hi = [0.0 if math.isnan(b) else b - m for m, b in zip(g["min_clearance_dynamic_cm"], g["clearance_hi"],
                                                                    strict=True)]
            ax_c.errorbar(x, g["min_clearance_dynamic_cm"], yerr=[lo, hi], marker="o", capsize=3, label=variant,
                          color=color)
        ax_s.set_ylim(-0.05, 1.05)
        ax_s.set_ylabel("success rate")
        ax_c.set_ylabel("min clearance to moving (cm)")
        for ax in (ax_s, ax_c):
            ax.set_xlabel("pedestrians")
            ax.set_title(scenario, fontsize=9)
            ax.grid(alpha=0.3)
        ax_c.legend(fontsize=6, loc="best")
    path = out / "density.png"
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path
