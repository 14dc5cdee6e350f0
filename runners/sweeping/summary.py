"""A sweep's summary: one row per episode log (``summary.csv``) and the outcomes per group (scenario label ×
variant), printed at the end of a sweep (:mod:`runners.sweeping.end`), from the analysis of its logs."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

from runners.sweeping.outputs import write_whole

if TYPE_CHECKING:  # pandas and the analysis are imported where the summary is written, not with this module
    import pandas as pd

    from analysis.metrics import Analysis

SUMMARY_COLUMNS = ["outcome", "success", "steps", "time_to_goal_s", "collisions_static", "collisions_dynamic"]


def summarise(sweep_dir: Path, jobs: int = 1, analysis: Analysis | None = None
              ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per-episode rows read back from the logs (in ``jobs`` processes when there are many; or from
    ``analysis``, the same logs already analysed) and outcomes per group (scenario label × variant).

    Success is the metrics' ``success`` column (:func:`analysis.run_parameters.is_success`): the summary and
    the report cannot disagree. Logs left out of the statistics (a copy, damaged, truncated, outcome ``error`` or
    ``interrupted``, ...) are rows with their outcome, kind and reason, and ``left_out`` in their group's row."""
    import pandas as pd

    from analysis.metrics import analyse_logs

    analysis = analysis or analyse_logs([sweep_dir], jobs=jobs)
    ok, bad = analysis.episodes, analysis.excluded
    dims = [k for k in analysis.grouping.dimensions if k not in ("controller", "perception")]
    columns = ["log", "scenario", "strategy", "h_wait", "controller", "perception", *dims, "scenario_label",
               "variant", "seed", *SUMMARY_COLUMNS, "kind", "reason"]
    parts = [frame.reindex(columns=columns) for frame in (ok, bad) if not frame.empty]
    if not parts:
        return pd.DataFrame(columns=columns), pd.DataFrame()
    episodes = pd.concat(parts, ignore_index=True)
    keys = ["scenario_label", "variant"]
    analysed = ok.reindex(columns=[*keys, "outcome", "steps"]).assign(
        success=ok["success"].astype(float) if "success" in ok else math.nan, left_out=0)
    left_out = bad.dropna(subset=["variant"]).reindex(columns=keys).assign(left_out=1)  # readable metadata
    frames = [frame for frame in (analysed, left_out) if not frame.empty]
    if not frames:  # every log left out, none with readable metadata (hostile14c swp_dt_0p7 crashed here)
        return episodes, pd.DataFrame(columns=["scenario", "variant", "episodes", "success_rate", "goal",
                                               "collision", "timeout", "left_out", "mean_steps"])
    rows = pd.concat(frames, ignore_index=True)
    rows = rows.reindex(columns=[*keys, "outcome", "steps", "success", "left_out"]).astype(
        {"steps": float, "success": float})  # numbers even when every log of a group was left out
    table = rows.groupby(keys, sort=False).agg(
        episodes=("outcome", "count"), success_rate=("success", "mean"),
        goal=("outcome", lambda s: int((s == "goal").sum())),
        collision=("outcome", lambda s: int((s == "collision").sum())),
        timeout=("outcome", lambda s: int((s == "timeout").sum())),
        left_out=("left_out", "sum"), mean_steps=("steps", "mean")).reset_index()
    return episodes, table.rename(columns={"scenario_label": "scenario"})


def write_summary(sweep_dir: Path, jobs: int = 1, analysis: Analysis | None = None) -> pd.DataFrame:
    """Write ``summary.csv`` (one row per episode log) and print the outcome table."""
    import pandas as pd

    from analysis.metrics import analyse_logs, left_out_counts
    from analysis.run_parameters import provenance_warning
    from analysis.tables import with_relative_logs

    analysis = analysis or analyse_logs([sweep_dir], jobs=jobs)
    episodes, table = summarise(sweep_dir, analysis=analysis)
    if episodes.empty:
        print(f"no logs found in {sweep_dir}")
        return table
    relative = with_relative_logs(episodes, sweep_dir)
    write_whole(sweep_dir / "summary.csv", lambda f: relative.to_csv(f, index=False))  # whole or absent
    with pd.option_context("display.width", 200, "display.max_rows", 500, "display.max_colwidth", 80):
        print(table.to_string(index=False, na_rep="-", float_format=lambda x: f"{x:.2f}" if not math.isnan(x) else "-"))
    kinds = left_out_counts(analysis.excluded)
    print(f"{len(episodes)} episode logs in {sweep_dir}" + (f" ({len(analysis.excluded)} left out: {kinds})" if kinds
                                                            else "") + f"; rows in {sweep_dir / 'summary.csv'}")
    warning = provenance_warning(analysis.grouping, analysis.runs)
    if warning:
        print(warning)
    return table
