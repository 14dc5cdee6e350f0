"""The comparison report, ``<out>/report/``: ``comparison.md``, ``comparison.csv``, ``comparison_overall.csv`` and
``comparison.png``.

Per scenario (never pooled: scenarios differ), per method (study) and configuration (``published``: the study's
default, the method as its paper gives it; ``tuned``: its best trial, or each evaluated Pareto trial), on the
held-out seeds that every study shares: each objective and each of its metrics with its 95 % interval (Wilson for
success, percentile bootstrap otherwise: :func:`runners.tuning.heldout.metric_interval`), and the difference from
the common reference (the reference study's published configuration: Table 1 as published), paired by scenario and
seed (the same world) with its bootstrap interval.

An objective's interval is that of the mean of each episode's objective (:func:`analysis.objectives.episode_values`),
which is the scenario's objective when every term is defined for every episode (a ``fill`` value makes it so); a
scenario where a term is undefined for some episode gets its objective without an interval, and says why.

The all-scenario score (``comparison_overall.csv``, the methods table) is the study's own objective: the mean over
scenarios of each scenario's mean. Its 95 % interval is a percentile bootstrap stratified by scenario (the held-out
seeds resampled within each scenario: :func:`analysis.stats.stratified_bootstrap_mean`, seeded), and so is that of
its difference from the common reference, paired by scenario and seed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pandas as pd

from analysis.objectives import episode_values, objective_value
from analysis.stats import bootstrap_mean, stratified_bootstrap_mean
from runners.tuning.comparison_file import Comparison
from runners.tuning.heldout import Evaluated, metric_interval
from runners.tuning.report import REPORT_DIR
from runners.tuning.study import counted
from runners.tuning.study_file import StudySpec

PUBLISHED = "published"


def configuration_name(ev: Evaluated) -> str:
    """``published`` for a study's default, else the held-out label (``tuned``, ``trial_<n>``)."""
    return PUBLISHED if ev.trial is None else ev.label


def _per_seed(episodes: pd.DataFrame, scenario: str, column: str, objective: Any = None) -> pd.Series:
    """One scenario's values by seed: a metric's, or (``objective``) each episode's objective."""
    if episodes.empty or "scenario" not in episodes:
        return pd.Series(dtype=float)
    sub = episodes[episodes["scenario"] == scenario]
    values = episode_values(sub, objective) if objective is not None else sub[column].astype(float)
    return pd.Series(values.to_numpy(dtype=float), index=sub["seed"].to_numpy())


def _paired(values: pd.Series, reference: pd.Series) -> tuple[float, float, float, int]:
    common = values.index.intersection(reference.index)
    diffs = [d for d in (values[common] - reference[common]).tolist() if not math.isnan(d)]
    return (*bootstrap_mean(diffs), len(diffs)) if diffs else (math.nan, math.nan, math.nan, 0)


def comparison_table(comparison: Comparison, results: list[tuple[StudySpec, Any, list[Evaluated]]]
                     ) -> pd.DataFrame:
    """One row per scenario, quantity (each objective, then each of their metrics), study and configuration."""
    ref_spec = comparison.reference
    ref = next(evaluated[0] for spec, _, evaluated in results if spec is ref_spec)
    objectives = ref_spec.objectives
    metrics = list(dict.fromkeys(m for o in objectives for m in o.metrics))
    quantities = [(o.name, "objective", o) for o in objectives] + [(m, "metric", None) for m in metrics]
    rows = []
    for scenario in ref_spec.scenarios:
        for name, kind, objective in quantities:
            reference = _per_seed(ref.results.episodes, scenario, name, objective)
            for spec, _, evaluated in results:
                for ev in evaluated:
                    values = _per_seed(ev.results.episodes, scenario, name, objective)
                    note = ""
                    if objective is None:
                        mean, lo, hi, n = metric_interval(name, values.tolist())
                    else:
                        sub = ev.results.episodes
                        sub = sub[sub["scenario"] == scenario] if not sub.empty else sub
                        mean, n = objective_value(sub, objective), len(values)
                        lo, hi = (bootstrap_mean(values.tolist())[1:] if n and not values.isna().any()
                                  else (math.nan, math.nan))
                        if values.isna().any():
                            note = "a term is undefined for some episodes (no fill): no interval"
                    d_mean, d_lo, d_hi, pairs = _paired(values, reference)
                    rows.append({"scenario": scenario, "quantity": name, "kind": kind, "study": spec.name,
                                 "configuration": configuration_name(ev), "trial": ev.trial,
                                 "same_as_published": ev.same_as_default, "n": n, "mean": mean, "ci_low": lo,
                                 "ci_high": hi, "vs_reference": d_mean, "vs_reference_ci_low": d_lo,
                                 "vs_reference_ci_high": d_hi, "pairs": pairs, "note": note})
    return pd.DataFrame(rows)


def overall_table(comparison: Comparison, results: list[tuple[StudySpec, Any, list[Evaluated]]]) -> pd.DataFrame:
    """One row per objective, study and configuration: the all-scenario held-out objective (the study's own
    number) with its scenario-stratified bootstrap interval, and its difference from the common reference paired by
    scenario and seed with its interval (stratified likewise). No interval (and a note) when some episode's
    objective is undefined (a term without fill): the all-scenario objective is then not a mean of episodes'."""
    ref_spec = comparison.reference
    ref = next(evaluated[0] for spec, _, evaluated in results if spec is ref_spec)
    scenarios = list(ref_spec.scenarios)
    rows = []
    for objective in ref_spec.objectives:
        reference = [_per_seed(ref.results.episodes, s, objective.name, objective) for s in scenarios]
        for spec, _, evaluated in results:
            for ev in evaluated:
                values = [_per_seed(ev.results.episodes, s, objective.name, objective) for s in scenarios]
                undefined = any(v.isna().any() for v in values)
                lo = hi = math.nan
                if not undefined:
                    lo, hi = stratified_bootstrap_mean([v.tolist() for v in values])[1:]
                diffs = []
                for v, r in zip(values, reference, strict=True):
                    common = v.index.intersection(r.index)
                    diffs.append([d for d in (v[common] - r[common]).tolist() if not math.isnan(d)])
                d_mean, d_lo, d_hi = stratified_bootstrap_mean(diffs)
                rows.append({"quantity": objective.name, "study": spec.name, "configuration": configuration_name(ev),
                             "trial": ev.trial, "same_as_published": ev.same_as_default, "scenarios": len(scenarios),
                             "n": sum(len(v) for v in values), "mean": ev.objectives.get(objective.name, math.nan),
                             "ci_low": lo, "ci_high": hi, "vs_reference": d_mean, "vs_reference_ci_low": d_lo,
                             "vs_reference_ci_high": d_hi, "pairs": sum(map(len, diffs)),
                             "note": "a term is undefined for some episodes (no fill): no interval" if undefined
                             else ""})
    return pd.DataFrame(rows)


def _f(v: Any) -> str:
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.4g}"


def _ci(mean: float, lo: float, hi: float) -> str:
    return f"{_f(mean)} [{_f(lo)}, {_f(hi)}]"


def comparison_figure(comparison: Comparison, table: pd.DataFrame, path: Path) -> Path:
    """Each objective (rows) in each scenario (columns): every method's published (open) and tuned (filled)
    held-out mean with its 95 % interval; the reference's published mean and interval as a dashed line and band."""
    from analysis import plots

    plt = plots.pyplot()
    objectives = [o.name for o in comparison.reference.objectives]
    scenarios = list(comparison.reference.scenarios)
    studies = [s.name for s in comparison.studies]
    fig, axes = plt.subplots(len(objectives), len(scenarios), squeeze=False,
                             figsize=(max(4.0, 3.2 * len(scenarios)), 3.4 * len(objectives)), sharey="row")
    for r, objective in enumerate(objectives):
        for c, scenario in enumerate(scenarios):
            ax = axes[r][c]
            rows = table[(table["quantity"] == objective) & (table["kind"] == "objective")
                         & (table["scenario"] == scenario)]
            ref = rows[(rows["study"] == comparison.reference.name) & (rows["configuration"] == PUBLISHED)].iloc[0]
            ax.axhline(ref["mean"], color="0.2", linestyle="--", linewidth=1)
            if not math.isnan(ref["ci_low"]):
                ax.axhspan(ref["ci_low"], ref["ci_high"], color="0.3", alpha=0.15, linewidth=0, zorder=0)
            for x, study in enumerate(studies):
                configurations = rows[rows["study"] == study]
                width = 0.5 / max(1, len(configurations))
                for k, (_, row) in enumerate(configurations.iterrows()):
                    published = row["configuration"] == PUBLISHED
                    pos = x - 0.25 + width * (k + 0.5)
                    low = row["mean"] - row["ci_low"] if not math.isnan(row["ci_low"]) else 0.0
                    high = row["ci_high"] - row["mean"] if not math.isnan(row["ci_high"]) else 0.0
                    ax.errorbar([pos], [row["mean"]], yerr=[[max(low, 0.0)], [max(high, 0.0)]], fmt="o",
                                color=f"C{x}", mfc="white" if published else f"C{x}", capsize=3,
                                label=("published" if published else "tuned") if x == 0 and k < 2 else None)
            ax.set_xticks(range(len(studies)))
            ax.set_xticklabels(studies, rotation=30, ha="right", fontsize=7)
            ax.set_title(scenario, fontsize=9)
            if c == 0:
                ax.set_ylabel(f"{objective} (held-out)")
                if r == 0:
                    ax.legend(fontsize=7)
    fig.suptitle(f"comparison {comparison.name} on held-out seeds {comparison.reference.heldout.text()}\n"
                 f"open: published, filled: tuned; dashed: {comparison.reference.name} published", fontsize=8)
    fig.tight_layout()
    return plots._save(fig, path)


def _overall_cells(overall: pd.DataFrame, study: str, ev: Evaluated, objective: str, reference: str) -> str:
    """The methods table's two cells of one objective: the all-scenario mean [CI] and the difference from the
    reference [CI]."""
    row = overall[(overall["quantity"] == objective) & (overall["study"] == study)
                  & (overall["configuration"] == configuration_name(ev))].iloc[0]
    mean = _ci(row["mean"], row["ci_low"], row["ci_high"]) + (f" ({row['note']})" if row["note"] else "")
    is_ref = study == reference and row["configuration"] == PUBLISHED
    diff = "(reference)" if is_ref else _ci(row["vs_reference"], row["vs_reference_ci_low"],
                                            row["vs_reference_ci_high"])
    return f"{mean} | {diff}"


def write_comparison_report(comparison: Comparison, out: Path, results: list[tuple[StudySpec, Any, list[Evaluated]]]
                            ) -> Path:
    """Write ``<out>/report/comparison.{md,csv,png}``; returns the markdown file."""
    folder = out / REPORT_DIR
    folder.mkdir(parents=True, exist_ok=True)
    table = comparison_table(comparison, results)
    table.to_csv(folder / "comparison.csv", index=False)
    overall = overall_table(comparison, results)
    overall.to_csv(folder / "comparison_overall.csv", index=False)
    figure = comparison_figure(comparison, table, folder / "comparison.png")
    ref = comparison.reference
    lines = [f"# Comparison {comparison.name}", "", *([comparison.description, ""] if comparison.description else []),
             f"Comparison file `{comparison.path}`; studies in `{out}/<study>/`. Every method is tuned on the same "
             f"budget: {ref.trials} trials x {len(ref.scenarios)} scenarios x {ref.train.count} training seeds "
             f"({ref.train.text()}) = {comparison.budget} episodes, and evaluated on the same held-out seeds "
             f"({ref.heldout.text()}, never a training seed) of the scenarios {', '.join(ref.scenarios)}.", "",
             "Objectives: " + "; ".join(f"**{o.name}** ({o.direction}) = "
                                        + " + ".join(f"{w:g} x mean {m}" for m, w in o.terms)
                                        + (f", undefined values filled: {', '.join(f'{m}={v:g}' for m, v in o.fill)}"
                                           if o.fill else "") for o in ref.objectives), "",
             f"Common reference: **{ref.name} {PUBLISHED}** (the reference study's default configuration).", "",
             "## Methods", "",
             *[f"- **{spec.name}**: {spec.description or '(no description)'}" for spec in comparison.studies], "",
             "| study | base | sampler | trials completed / failed | configuration | trial | "
             + " | ".join(f"held-out {o.name} (all scenarios) [95 % CI] | vs {ref.name} {PUBLISHED} [95 % CI]"
                          for o in ref.objectives) + " |",
             "|---|---|---|---|---|---|" + "---|---|" * len(ref.objectives)]
    for spec, study, evaluated in results:
        trials = study.get_trials(deepcopy=False)
        done = sum(t.state.name == "COMPLETE" for t in trials)
        failed = sum(counted(t) and t.state.name == "FAIL" for t in trials)
        for ev in evaluated:
            trial = "—" if ev.trial is None else str(ev.trial) + (" (= published)" if ev.same_as_default else "")
            lines.append(f"| {spec.name} | `{' '.join(spec.base) or '(none)'}` | {spec.sampler} | {done} / "
                         f"{failed} | {configuration_name(ev)} | {trial} | "
                         + " | ".join(_overall_cells(overall, spec.name, ev, o.name, ref.name)
                                      for o in ref.objectives) + " |")
    lines += ["", "The all-scenario objective is the study's own (each scenario's mean, then their mean): the number "
              "the study optimised. Its 95 % interval, and that of its difference from "
              f"{ref.name} {PUBLISHED} (paired by scenario and seed), is a percentile bootstrap that resamples the "
              "held-out seeds within each scenario (seeded: the same report every time); all rows in "
              "`comparison_overall.csv`. The tables below keep the scenarios apart.", "",
              f"![comparison]({figure.name})", "",
              "## Held-out results per scenario", "",
              "Mean and 95 % interval on the held-out seeds (Wilson for success, percentile bootstrap otherwise); "
              f"the difference from {ref.name} {PUBLISHED} is paired by seed (the same world), with its bootstrap "
              "interval. All rows in `comparison.csv`; each study's own report in `<study>/report/study.md`.", ""]
    for scenario in ref.scenarios:
        lines += [f"### {scenario}", "", "| quantity | study | configuration | n | mean [95 % CI] | "
                  f"vs {ref.name} {PUBLISHED} [95 % CI] |", "|---|---|---|---|---|---|"]
        for _, r in table[table["scenario"] == scenario].iterrows():
            is_ref = r["study"] == ref.name and r["configuration"] == PUBLISHED
            diff = "(reference)" if is_ref else _ci(r["vs_reference"], r["vs_reference_ci_low"],
                                                    r["vs_reference_ci_high"])
            note = f" ({r['note']})" if r["note"] else ""
            lines.append(f"| {r['quantity']} | {r['study']} | {r['configuration']} | {r['n']} | "
                         f"{_ci(r['mean'], r['ci_low'], r['ci_high'])}{note} | {diff} |")
        lines.append("")
    path = folder / "comparison.md"
    path.write_text("\n".join(lines))
    return path
