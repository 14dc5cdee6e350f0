"""Recorded people in the report: how well the TPT predicted them per horizon step, against constant velocity.

From the per-episode columns of :mod:`analysis.horizon_errors`: per scenario group (a recording's window: windows
and recordings are scenario parameters, never pooled), variant (policy, perception, ...: laser tracks and ground
truth are different groups), predictor (``tpt``, ``cv``) and horizon k, the mean over the episodes of their ADE_k and
FDE_k (cm) with a 95 % bootstrap interval over the episodes. Written as ``recorded_horizons.csv``, drawn as
``recorded_horizons.png``; absent (empty table) for logs without TPT predictions of recorded people.
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Mapping
from pathlib import Path

from analysis.deferred import deferred
from analysis.horizon_errors import PREDICTORS, column, count_column, horizons_of_columns
from analysis.stats import bootstrap_mean

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

COLUMNS = ["scenario", "variant", "predictor", "horizon", "episodes", "predictions", "ade_cm", "ade_lo", "ade_hi",
           "fde_cm", "fde_lo", "fde_hi"]
PANEL_COLUMNS = 4  # two scenario groups (ADE and FDE each) per row of the figure


def horizon_table(df: pd.DataFrame) -> pd.DataFrame:
    """One row per scenario group, variant, predictor and horizon k whose episodes scored predictions at k (module
    docstring); columns :data:`COLUMNS` (``horizon`` in steps, errors in cm). Empty when there are none."""
    horizons = horizons_of_columns(df.columns)
    if not horizons:
        return pd.DataFrame(columns=COLUMNS)
    rows = []
    for (scenario, variant), g in df.groupby(["scenario_label", "variant"], sort=False):
        for predictor in PREDICTORS:
            for k in horizons:
                scored = g[pd.to_numeric(g[count_column(k)], errors="coerce").fillna(0) > 0]
                if scored.empty:
                    continue
                ade = bootstrap_mean(scored[column(predictor, "ade", k)].to_numpy(dtype=float))
                fde = bootstrap_mean(scored[column(predictor, "fde", k)].to_numpy(dtype=float))
                rows.append({"scenario": scenario, "variant": variant, "predictor": predictor, "horizon": k,
                             "episodes": len(scored), "predictions": int(scored[count_column(k)].sum()),
                             "ade_cm": ade[0], "ade_lo": ade[1], "ade_hi": ade[2],
                             "fde_cm": fde[0], "fde_lo": fde[1], "fde_hi": fde[2]})
    return pd.DataFrame(rows, columns=COLUMNS)


def shown_table(table: pd.DataFrame, horizons: tuple[int, ...] = (1, 4, 9)) -> pd.DataFrame:
    """The report's inline table: per scenario group and variant, FDE of the TPT and of constant velocity
    [95 % bootstrap] at the ``horizons`` the table has (the first, the fourth and the ninth step: the paper's
    n_traj), with the number of predictions; every horizon and ADE: recorded_horizons.csv."""
    rows = []
    present = sorted(set(table["horizon"]))
    wanted = [k for k in horizons if k in present] or present[:1]
    for (scenario, variant), g in table.groupby(["scenario", "variant"], sort=False):
        row: dict[str, object] = {"scenario": scenario, "variant": variant}
        for k in wanted:
            at = g[g["horizon"] == k]
            for predictor in PREDICTORS:
                r = at[at["predictor"] == predictor]
                row[f"{predictor} FDE h{k} (cm)"] = "–" if r.empty else _interval(*r.iloc[0][["fde_cm", "fde_lo",
                                                                                               "fde_hi"]])
            row[f"predictions h{k}"] = int(at["predictions"].iloc[0]) if not at.empty else 0
        rows.append(row)
    return pd.DataFrame(rows)


def _interval(mean: float, lo: float, hi: float) -> str:
    if math.isnan(mean):
        return "–"
    return f"{mean:.0f}" if math.isnan(lo) else f"{mean:.0f} [{lo:.0f}, {hi:.0f}]"


def horizon_figure(table: pd.DataFrame, out: Path, colors: Mapping[str, object] | None = None,
                   dt_s: float | None = None) -> Path | None:
    """``out/recorded_horizons.png``: per scenario group, ADE and FDE against the horizon, one colour per variant,
    the TPT solid and constant velocity dashed, with 95 % bootstrap intervals; None for an empty table. ``dt_s``:
    the episodes' step (s) when it is one for all, to label the horizon in seconds."""
    if table.empty:
        return None
    from matplotlib.ticker import MaxNLocator

    from analysis import plots
    from analysis.plots import pyplot

    plt = pyplot()
    scenarios = list(pd.unique(table["scenario"]))
    per_row = PANEL_COLUMNS // 2
    n_rows = math.ceil(len(scenarios) / per_row)
    fig, axes = plt.subplots(n_rows, PANEL_COLUMNS, figsize=(3.2 * PANEL_COLUMNS, 2.6 * n_rows), squeeze=False,
                             layout="constrained")
    for ax in axes.flat[2 * len(scenarios):]:
        ax.set_visible(False)
    for i, scenario in enumerate(scenarios):
        ax_a, ax_f = axes.flat[2 * i], axes.flat[2 * i + 1]
        rows = table[table["scenario"] == scenario]
        for (variant, predictor), g in rows.groupby(["variant", "predictor"], sort=False):
            color = (colors or {}).get(variant)
            style = "-" if predictor == "tpt" else "--"
            for ax, error in ((ax_a, "ade"), (ax_f, "fde")):
                mean, lo, hi = g[f"{error}_cm"], g[f"{error}_lo"], g[f"{error}_hi"]
                ax.errorbar(g["horizon"], mean, yerr=[(mean - lo).fillna(0.0), (hi - mean).fillna(0.0)],
                            linestyle=style, marker="o" if predictor == "tpt" else "s", markersize=3, capsize=2,
                            color=color, label=f"{variant} · {predictor}")
        for ax, error in ((ax_a, "ADE"), (ax_f, "FDE")):
            ax.set_title(textwrap.fill(f"{scenario} · {error}", 48), fontsize=6)
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # horizons are whole steps
            ax.set_xlabel(f"horizon (steps{f' of {dt_s:g} s' if dt_s else ''})", fontsize=7)
            ax.set_ylabel(f"{error} (cm)", fontsize=7)
            ax.tick_params(labelsize=6)
            ax.grid(alpha=0.3)
        ax_f.legend(fontsize=5, loc="upper left")
    return plots._save(fig, out / "recorded_horizons.png")
