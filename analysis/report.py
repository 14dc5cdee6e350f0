"""Reports from logs: ``python -m analysis.report <sweep dir or .mcap files...> [--out DIR]``.

Writes ``report.md`` and ``report.html`` with PNG plots beside them. The report shows before it lists: first the
overview figure (``overview.png``: success rate with its Wilson interval, time-to-goal and path length with
bootstrap intervals, per group and scenario), what the data says, the effect of h_wait, every seed's trajectory
per scenario and group, a gallery of the failed episodes, the paired differences whose interval excludes zero;
then the tables. Long tables stay in files: ``episodes.csv`` (one row per episode, every metric, its group's
labels), ``groups.csv`` (mean and 95 % interval of every metric per group), ``paired.csv`` (every paired difference
between variants on the same scenario and seed), these three also as Parquet with units (:mod:`analysis.tables`),
``failures.csv`` (every failed episode) and ``left_out.csv``. A group is every combination of the run parameters
whose values differ among the logs (:mod:`analysis.run_parameters`): two settings of any parameter are never
pooled. Logs that are not used (a copy of another log of the same episode, not a regular file, damaged, failing a
check, truncated, outcome ``error``/``interrupted``) are listed with their kind and reason and left out of the
statistics. Everything is computed from the logs.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import html
import itertools
import math
import os
import shutil
import sys
import tempfile
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis import gallery, plots
from analysis.cli_args import OneLineParser, jobs, number_in, path_problem, unwritable_dir
from analysis.deferred import deferred
from analysis.density import density_figure, density_table
from analysis.drawing import Figure, FigureError, Figures
from analysis.file_names import printable
from analysis.metrics import STANDARD_METRICS, Analysis, MetricOptions, analyse_logs, left_out_counts
from analysis.overview import overview
from analysis.recorded_people import horizon_figure, horizon_table, shown_table
from analysis.run_parameters import SHOWN, Grouping, format_value, provenance_warning
from analysis.stats import bootstrap_mean, excludes_zero, wilson
from analysis.tables import with_relative_logs, write_tables
from analysis.tpt_errors import models_of_columns
from analysis.trace import Trace, load_traces

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

METRICS = ["time_to_goal_s", "path_length_cm", "path_efficiency", "turn_count", "heading_change_deg_total",
           "collisions_static", "collisions_dynamic", "min_clearance_static_cm", "min_clearance_dynamic_cm",
           "wait_steps", "detour_count", "detour_extra_length_cm", "tpt_collisions_predicted", "tpt_ade_cm",
           "tpt_fde_cm", "compute_time_us_median", "compute_time_us_p99", "steps"]
MAIN_METRICS = ["time_to_goal_s", "path_length_cm", "turn_count", "min_clearance_dynamic_cm", "wait_steps"]
PAIRED_METRICS = ["success", "time_to_goal_s", "path_length_cm", "min_clearance_dynamic_cm", "turn_count"]
BOX_METRICS = ["time_to_goal_s", "path_length_cm", "min_clearance_dynamic_cm", "wait_steps"]
ROUNDING = 1e-9
"""Paired values whose difference is at most this share of the larger one are equal (floating-point rounding of
the same quantity computed along another path), so their difference counts as zero."""
PAIR_KEY = "seed"  # episodes of one scenario group with the same seed face the same world and obstacles


def _fmt(mean: float, lo: float, hi: float, digits: int = 1) -> str:
    if math.isnan(mean):
        return "–"
    if math.isnan(lo):
        return f"{mean:.{digits}f}"
    return f"{mean:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def _groups(df: pd.DataFrame):
    """(scenario label, variant) groups in the rows' order (the natural order :func:`analyse_logs` sorted)."""
    return df.groupby(["scenario_label", "variant"], sort=False)


def group_table(df: pd.DataFrame, grouping: Grouping) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(main table for the report, long table of every metric per group with interval bounds). A group is one
    scenario label and one variant: every run parameter that differs among the logs is in one or the other."""
    constant = [*SHOWN, *(k for k in grouping.dimensions if k not in SHOWN), "scenario_label", "variant"]
    metrics = [*METRICS, *STANDARD_METRICS]  # groups.csv: every metric
    values = {m: np.asarray(df[m], dtype=float) for m in metrics}  # once, not a Series per group and metric
    main_rows, long_rows = [], []
    for (scenario, variant), g in _groups(df.assign(_row=np.arange(len(df)))):
        at = g["_row"].to_numpy()
        n = len(g)
        row = {"scenario": scenario, "variant": variant, "episodes": n}
        keys = {c: g[c].iloc[0] for c in constant}
        outcomes = g["outcome"].to_numpy()
        # the collision rate counts every episode with a contact: with terminate_on_collision=false one that reached
        # the goal through an obstacle ended as "goal", and the rate read 0 beside a success rate of 0
        ended = {"collision_rate": int(((outcomes == "collision") | touched(g)).sum()),
                 "timeout_rate": int((outcomes == "timeout").sum())}
        for metric, k in (("success", int(g["success"].sum())), *ended.items()):
            p, lo, hi = wilson(k, n)
            row[f"{metric.replace('_', ' ')}{'' if metric.endswith('rate') else ' rate'} [95% Wilson]"] = \
                f"{p:.2f} [{lo:.2f}, {hi:.2f}]"
            long_rows.append({**keys, "metric": metric, "n": n, "mean": p, "ci_low": lo, "ci_high": hi,
                              "interval": "wilson"})
        for metric in metrics:
            x = values[metric][at]
            mean, mlo, mhi = bootstrap_mean(x)
            long_rows.append({**keys, "metric": metric, "n": int((~np.isnan(x)).sum()), "mean": mean,
                              "ci_low": mlo, "ci_high": mhi, "interval": "bootstrap"})
            if metric in MAIN_METRICS:
                row[metric] = _fmt(mean, mlo, mhi)
        main_rows.append(row)
    return pd.DataFrame(main_rows), pd.DataFrame(long_rows)


def _factors(df: pd.DataFrame, grouping: Grouping) -> dict[str, tuple]:
    """Per variant: its strategy (with h_wait where the label shows it) and each other differing parameter."""
    return {row["variant"]: ((row["strategy"], format_value(row["h_wait"]) if row["strategy"] in
                              grouping.h_wait_shown else ""), *(format_value(row[k]) for k in grouping.variant_keys))
            for _, row in df.drop_duplicates("variant").iterrows()}


def paired_table(df: pd.DataFrame, grouping: Grouping) -> pd.DataFrame:
    """Mean paired difference (A − B) with a 95 % bootstrap interval between variants that differ in one
    factor only — the strategy (wait vs detour, each of them vs every auto(h)), h_wait between neighbouring
    settings of auto (h=1 vs h=2, h=2 vs h=3, ...: the effect of one more step of tolerated waiting; every
    setting is in the plots against h_wait) or one other differing parameter — run on the same scenario group
    and seed. Strategy ``none`` (the ablation) is not compared. Episodes repeated on a seed within a group are
    averaged."""
    factors = _factors(df, grouping)
    rows = []
    for scenario, sub in df[df["strategy"] != "none"].groupby("scenario_label", sort=False):
        per_seed = {v: _per_seed(g) for v, g in sub.groupby("variant", sort=False)}
        h_values = sorted({float(factors[v][0][1]) for v in per_seed
                           if factors[v][0][0] == "auto" and factors[v][0][1]})
        for a, b in itertools.combinations(per_seed, 2):
            changed = [i for i, (x, y) in enumerate(zip(factors[a], factors[b], strict=True)) if x != y]
            both_auto = factors[a][0][0] == factors[b][0][0] == "auto"
            if len(changed) != 1 or (changed == [0] and both_auto
                                     and not _neighbours(factors[a][0][1], factors[b][0][1], h_values)):
                continue
            (seeds_a, left), (seeds_b, right) = per_seed[a], per_seed[b]
            common, at_a, at_b = np.intersect1d(seeds_a, seeds_b, assume_unique=True, return_indices=True)
            if len(common) == 0:
                continue
            a_values, b_values = left[at_a], right[at_b]  # a row per common seed, ascending
            diffs = a_values - b_values
            # equal up to rounding (a straight path of 999.9999999999989 cm against 1000 cm) is no difference: such
            # a pair of a few ulps on one side of zero made an interval [-4, -7e-13] "exclude zero"
            with np.errstate(invalid="ignore"):
                diffs[np.abs(diffs) <= ROUNDING * np.maximum(np.abs(a_values), np.abs(b_values))] = 0.0
            for j, metric in enumerate(PAIRED_METRICS):
                diff = diffs[:, j]
                mean, lo, hi = bootstrap_mean(diff)
                pairs = int((~np.isnan(diff)).sum())
                rows.append({"scenario": scenario, "A": a, "B": b, "metric": metric, "pairs": pairs,
                             "mean_a_minus_b": mean, "ci_low": lo, "ci_high": hi,
                             "excludes_zero": excludes_zero(lo, hi)})
    return pd.DataFrame(rows, columns=["scenario", "A", "B", "metric", "pairs", "mean_a_minus_b", "ci_low", "ci_high",
                                       "excludes_zero"])


def _per_seed(g: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """(the seeds of a group's episodes, ascending; their :data:`PAIRED_METRICS` as floats, a row per seed): each
    seed's episode, or where a seed was run more than once the mean of its episodes (pandas' group mean; plain
    arrays otherwise: grouping every group of every scenario was most of the table's time)."""
    seeds = g[PAIR_KEY].to_numpy()
    if len(np.unique(seeds)) < len(seeds):
        means = g.groupby(PAIR_KEY)[PAIRED_METRICS].mean()
        return means.index.to_numpy(), means.to_numpy(dtype=float, na_value=np.nan)
    order = np.argsort(seeds, kind="stable")
    return seeds[order], g[PAIRED_METRICS].to_numpy(dtype=float, na_value=np.nan)[order]


def _neighbours(h_a: str, h_b: str, h_values: list[float]) -> bool:
    """Whether two shown h_wait values are next to each other among the settings of this scenario group."""
    if not h_a or not h_b:
        return False
    i, j = h_values.index(float(h_a)), h_values.index(float(h_b))
    return abs(i - j) == 1


def parameter_table(df: pd.DataFrame, grouping: Grouping, runs: list[dict] | None = None) -> pd.DataFrame:
    """Each shown run parameter and each group dimension: its label name and its values with episode counts (as the
    labels show them, from ``runs``, the episodes' parameters in ``df``'s order, where given: a table keeps no
    difference between null and a missing key)."""
    rows = []
    for key in [*SHOWN, *(k for k in grouping.dimensions if k not in SHOWN)]:
        if runs is not None and len(runs) == len(df):
            counts = Counter(grouping.value_label(run, key) for run in runs)
        else:
            counts = Counter(df[key].map(format_value))
        if len(counts) == 1:
            role = "same in every episode"
        elif key == "scenario" or key in grouping.scenario_keys:
            role = "scenario"
        else:
            role = "variant"
        rows.append({"parameter": key, "label": grouping.short.get(key, key), "groups by": role,
                     "values (episodes)": ", ".join(f"{v} ({n})" for v, n in counts.items())})
    return pd.DataFrame(rows)


def warnings(df: pd.DataFrame, analysis: Analysis) -> list[str]:
    """Things that can make pooled numbers wrong: logs from different code, an episode counted twice."""
    out = []
    warning = provenance_warning(analysis.grouping, analysis.runs)
    if warning:
        out.append(warning)
    repeats = df.duplicated(["scenario_label", "variant", "seed"]).sum()
    if repeats:
        out.append(f"warning: {repeats} episode(s) repeat a seed already in their group (the same logs given twice, "
                   "or two runs of one configuration); each is counted in the group statistics.")
    return out


def touched(g: pd.DataFrame) -> np.ndarray:
    """Per episode, whether the robot touched anything (the contacts recomputed from the logged geometry, as
    ``success`` counts them)."""
    return (np.asarray(g["collisions_static"], dtype=float) + np.asarray(g["collisions_dynamic"], dtype=float)) > 0


def who_reaches_the_goal(scenario: str, sub: pd.DataFrame) -> str:
    """One plain sentence for a scenario: how often each group reached the goal (groups with the same count
    together, best first), how the others ended, and whether the best and the worst group are told apart by
    their 95 % Wilson intervals."""
    counts = []
    for variant, g in sub.groupby("variant", sort=False):
        outcomes = g["outcome"].to_numpy()
        counts.append((variant, int(g["success"].sum()), len(g), int((outcomes == "collision").sum()),
                       int((outcomes == "timeout").sum()), int(((outcomes == "goal") & touched(g)).sum())))
    by_count: dict[tuple[int, int], list[str]] = {}
    for variant, k, n, *_ in sorted(counts, key=lambda c: -c[1] / c[2]):
        by_count.setdefault((k, n), []).append(variant)
    parts = [f"{k}/{n} by {', '.join(vs[:-1]) + ' and ' + vs[-1] if len(vs) > 1 else vs[0]}"
             for (k, n), vs in by_count.items()]
    collisions, timeouts, touched_goals = (sum(c[i] for c in counts) for i in (3, 4, 5))
    ended = [f"{collisions} collision{'s' if collisions != 1 else ''}" if collisions else "",
             f"{touched_goals} goal{'s' if touched_goals != 1 else ''} after a contact" if touched_goals else "",
             f"{timeouts} timeout{'s' if timeouts != 1 else ''}" if timeouts else ""]
    ended_text = f" (failures: {', '.join(e for e in ended if e)})" if any(ended) else ""
    # "without a contact" only where some goal came after one (terminate_on_collision=false): else it is the same
    text = f"{scenario}: goal reached{' without a contact' if touched_goals else ''} {'; '.join(parts)}{ended_text}."
    if len(by_count) < 2:
        return text + (" No group differs from another." if len(counts) > 1 else "")
    (best_k, best_n), (worst_k, worst_n) = next(iter(by_count)), list(by_count)[-1]
    _, best_lo, _ = wilson(best_k, best_n)
    _, _, worst_hi = wilson(worst_k, worst_n)
    episodes = min(c[2] for c in counts)
    if best_lo > worst_hi:
        return text + " The best and the worst differ clearly (their 95 % intervals do not overlap)."
    return text + (f" The best and the worst are not separable with {episodes} episode{'s' if episodes != 1 else ''}"
                   " per group (their 95 % intervals overlap).")


SAME_EPISODE = ["outcome", "steps", "path_length_cm"]  # episodes equal in these ran the same way


def unchanged_by(df: pd.DataFrame, grouping: Grouping) -> list[str]:
    """One line per scenario and swept parameter that changed no episode: groups that differ only in that
    parameter (h_wait of ``auto``, or one other differing run parameter) whose episodes on every common seed have
    the same outcome, steps and path length. A sweep over h_wait where waiting never happens must say so rather
    than show four equal bars."""
    factors = _factors(df, grouping)
    names = ["h_wait", *(grouping.short.get(k, k) for k in grouping.variant_keys)]
    out = []
    for scenario, sub in df.groupby("scenario_label", sort=False):
        per_variant = {v: g.set_index(PAIR_KEY)[SAME_EPISODE] for v, g in sub.groupby("variant", sort=False)
                       if not g[PAIR_KEY].duplicated().any()}
        for position, name in enumerate(names):
            families: dict[tuple, list[str]] = {}
            for variant in per_variant:
                f = factors[variant]
                if position == 0:
                    if not f[0][1]:  # a strategy that does not read h_wait
                        continue
                    rest = (f[0][0], *f[1:])
                else:
                    rest = (f[0], *f[1:position], *f[position + 1:])
                families.setdefault(rest, []).append(variant)
            for members in families.values():
                if len(members) < 2:
                    continue
                tables = [per_variant[v] for v in members]
                seeds = tables[0].index
                for t in tables[1:]:
                    seeds = seeds.intersection(t.index)
                if len(seeds) == 0:
                    continue
                first = tables[0].loc[seeds]
                if all(t.loc[seeds].equals(first) for t in tables[1:]):
                    out.append(f"{scenario}: {name} changed no episode ({', '.join(members)}: the same outcome, "
                               f"steps and path on each of {len(seeds)} common seed{'s' if len(seeds) != 1 else ''}).")
    return out


def findings(df: pd.DataFrame, paired: pd.DataFrame) -> list[str]:
    """Statements computed from the numbers (no hand-written prose)."""
    out = []
    for scenario, sub in df.groupby("scenario_label", sort=False):
        rates = sub.groupby("variant", sort=False)["success"].mean()
        best_rate = rates.max()
        best = [v for v in rates.index if rates[v] == best_rate]
        out.append(who_reaches_the_goal(scenario, sub))
        ttg = sub[sub["variant"].isin(best)].groupby("variant", sort=False)["time_to_goal_s"].mean().dropna()
        if not ttg.empty and best_rate > 0:  # no group succeeded: none is "the best" (goals after a contact)
            fastest = ttg.idxmin()
            line = (f"{scenario}: among the best, the shortest mean time-to-goal is {ttg.min():.1f} s with {fastest}")
            others = paired[(paired["scenario"] == scenario) & (paired["metric"] == "time_to_goal_s")
                            & ((paired["A"] == fastest) | (paired["B"] == fastest))]
            significant = []
            for _, r in others.iterrows():
                other = r["B"] if r["A"] == fastest else r["A"]
                if other not in best:
                    continue
                sign = 1 if r["A"] == fastest else -1
                diff, lo, hi = sign * r["mean_a_minus_b"], sign * r["ci_low"], sign * r["ci_high"]
                lo, hi = min(lo, hi) + 0.0, max(lo, hi) + 0.0  # + 0.0: no "-0.0"
                verdict = "the interval excludes zero" if r["excludes_zero"] else "the interval includes zero"
                significant.append(f"vs {other}: {diff:+.1f} s [{lo:+.1f}, {hi:+.1f}], {verdict}")
            out.append(line + ("; paired on seeds " + "; ".join(significant) if significant else "") + ".")
    return out


INLINE_ROWS = 40
"""Rows of a long table shown in the report (paired differences, logs left out); the whole table is a CSV file."""


def _bounded(table: pd.DataFrame, csv_name: str, what: str, limit: int = INLINE_ROWS) -> tuple[pd.DataFrame, str]:
    """(the first ``limit`` rows, a sentence saying where the rest are, '' when all are shown): a report of
    thousands of episodes stays readable."""
    if len(table) <= limit:
        return table, ""
    return table.head(limit), f"The first {limit} of {len(table)} {what} are shown; all of them: {csv_name}."


def _markdown_table(table: pd.DataFrame) -> str:
    """``table`` as a Markdown table whose text cells cannot break it: ``|`` escaped, line breaks as spaces (a log
    named ``a|b.mcap`` split its row into two columns)."""
    def cell(value: object) -> object:
        return " ".join(value.replace("|", "\\|").splitlines()) if isinstance(value, str) else value

    text = table.copy()
    for column in text.columns:
        if text[column].dtype.kind not in "biufcmM":  # (text: object or pandas' string dtype)
            text[column] = text[column].map(cell)
    return text.to_markdown(index=False)


@dataclass
class Report:
    """The report's content as blocks, rendered to Markdown and HTML alike. Kinds: ``h2``, ``p``, ``list``,
    ``table`` (a DataFrame), ``img`` (a PNG's path, or a :class:`analysis.drawing.Figure` drawn before the report
    is rendered) and ``gallery`` (a list of :class:`analysis.gallery.Failure`: a table of the pictured failures,
    shown under their figure)."""

    title: str
    blocks: list[tuple[str, object]] = field(default_factory=list)

    def add(self, kind: str, value: object) -> None:
        self.blocks.append((kind, value))

    def markdown(self) -> str:
        lines = [f"# {self.title}", ""]
        for kind, value in self.blocks:
            if kind == "h2":
                lines += [f"## {value}", ""]
            elif kind == "p":
                lines += [str(value), ""]
            elif kind == "list":
                lines += [f"- {item}" for item in value] + [""]  # type: ignore[attr-defined]
            elif kind == "table":
                lines += [_markdown_table(value) if not value.empty else "_none_", ""]  # type: ignore[arg-type]
            elif kind == "img":
                lines += [f"![{_image(value).stem}]({_image(value).name})", ""]
            elif kind == "gallery":
                table = _gallery_table(value)  # type: ignore[arg-type]
                lines += [_markdown_table(table) if not table.empty else "_none_", ""]
        return "\n".join(lines)

    def html(self) -> str:
        body = [f"<h1>{html.escape(self.title)}</h1>"]
        for kind, value in self.blocks:
            if kind == "h2":
                body.append(f"<h2>{html.escape(str(value))}</h2>")
            elif kind == "p":
                body.append(f"<p>{html.escape(str(value))}</p>")
            elif kind == "list":
                body.append("<ul>" + "".join(f"<li>{html.escape(str(i))}</li>" for i in value) + "</ul>")  # type: ignore
            elif kind == "table":
                body.append(value.to_html(index=False, border=0, classes="t", na_rep="–")  # type: ignore
                            if not value.empty else "<p><em>none</em></p>")  # type: ignore[attr-defined]
            elif kind == "img":
                name = html.escape(_image(value).name)
                body.append(f'<p><img id="{html.escape(_image(value).stem)}" src="{name}" alt="{name}"></p>')
            elif kind == "gallery":
                table = _gallery_table(value)  # type: ignore[arg-type]
                body.append(table.to_html(index=False, border=0, classes="t", na_rep="–")
                            if not table.empty else "<p><em>none</em></p>")
        style = ("body{font-family:sans-serif;max-width:1400px;margin:0.5em auto;padding:0 1em}"
                 "h1{font-size:1.2em;margin:0.2em 0}h2{margin-top:1.4em}"
                 "table.t{border-collapse:collapse;font-size:13px}table.t td,table.t th{border:1px solid #ccc;"
                 "padding:3px 6px;text-align:right}img{max-width:100%}")
        check = ("<script>window.addEventListener('load',function(){var bad=[].slice.call("
                 "document.images).filter(function(i){return !(i.complete&&i.naturalWidth>0)});"
                 "document.title=bad.length?'report: '+bad.length+' broken image(s)':'report: ok';});</script>")
        return (f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(self.title)}</title>"
                f"<style>{style}</style>{check}</head><body>{''.join(body)}</body></html>")


def _gallery_table(failures: list[gallery.Failure]) -> pd.DataFrame:
    """The pictured failures in their panels' order (a row of panels per group, lowest seed first): the figure with
    the panel, scenario, group, seed, outcome, first contact step and log."""
    return pd.DataFrame([{"picture": f.picture, "scenario": f.row["scenario"], "group": f.row["variant"],
                          "seed": f.row["seed"], "outcome": f.row["outcome"],
                          "first contact step": _step(f.row["first_contact_step"]), "log": f.row["log"]}
                         for f in failures])


def _image(value: object) -> Path:
    """The file of an ``img`` block: a path, or a :class:`analysis.drawing.Figure` once drawn."""
    if isinstance(value, Figure):
        if value.path is None:
            raise ValueError("the report's figures are rendered before they are drawn")
        return value.path
    return Path(value)  # type: ignore[arg-type]


def _step(value: object) -> str:
    """A first contact step as text: ``–`` when no contact was flagged (a timeout without contact)."""
    return "–" if value is None or pd.isna(value) else str(int(value))  # type: ignore[arg-type]


def build_report(paths: Iterable[str | Path], out: Path, options: MetricOptions | None = None,
                 jobs: int = -1, analysis: Analysis | None = None, split_provenance: bool = False,
                 final_dir: Path | None = None) -> Report:
    """Compute everything and write the report files into ``out``; returns the report content. ``jobs``:
    worker processes reading the logs (-1: every core; see :func:`analysis.metrics.metrics_table`) and drawing
    the figures (:mod:`analysis.drawing`). ``analysis``: the logs
    already analysed (the sweep shares it with its summary); ``split_provenance``: logs from different code
    versions form separate groups instead of being pooled with a warning.

    The order is the reader's: the overview figure first (success rate, time-to-goal and path length per group
    and scenario with intervals), what the data says, the effect of h_wait, each scenario's trajectories, the
    failures, the paired differences whose interval excludes zero; then the tables behind them."""
    out.mkdir(parents=True, exist_ok=True)
    sources = [str(p) for p in paths]
    analysis = analysis or analyse_logs(sources, options, jobs=jobs, split_provenance=split_provenance, traces=True,
                                        meanwhile=plots.pyplot)  # matplotlib imported while workers read
    df, grouping = analysis.episodes, analysis.grouping
    excluded = analysis.excluded[["log", "kind", "outcome", "scenario_label", "variant", "reason"]].rename(
        columns={"scenario_label": "scenario"})
    tables_dir = final_dir or out  # where the files end up (built elsewhere to be written whole): logs from there
    with_relative_logs(excluded, tables_dir).to_csv(out / "left_out.csv", index=False)
    report = Report("fuzzynav report")
    kinds = left_out_counts(analysis.excluded)
    logs_line = (f"Logs: {', '.join(sources)} — {len(df)} episodes analysed, {len(excluded)} left out"
                 + (f" ({kinds})." if kinds else "."))
    opt = options or MetricOptions()
    logs_line += (f" Metric thresholds: a turn is a heading change above {opt.turn_threshold_deg:g}° per step, a "
                  f"near miss a clearance below {opt.near_miss_cm:g} cm, stalled slower than "
                  f"{opt.stall_speed_cm_s:g} cm/s, personal space {opt.personal_space_cm:g} cm beyond a moving "
                  "obstacle's surface (analysis.report --turn-threshold-deg, --near-miss-cm, --stall-speed-cm-s, "
                  "--personal-space-cm).")
    if df.empty:
        report.add("p", logs_line)
        _left_out(report, excluded)
        write_tables(out, df, pd.DataFrame(), pd.DataFrame(), logs_from=tables_dir)
        _write(report, out)
        return report
    main, long = group_table(df, grouping)
    # the figures first, drawn in worker processes while this one computes and writes the rest (analysis.drawing)
    figures = Figures()
    overview_figure = figures.add(overview, df, long, out, cost=6)
    h_wait_shown = bool((df.groupby("scenario_label")["variant"].nunique() >= 2).any())
    h_wait_figure = (figures.add(plots.h_wait_effect, df, plots.H_WAIT_METRICS, out,
                                 cost=len(plots.H_WAIT_METRICS) * df["scenario_label"].nunique())
                     if h_wait_shown else None)
    density = density_table(df)
    density_figure_ = None
    if not density.empty:
        density.to_csv(out / "density.csv", index=False)
        colours = {variant: style.color for variant, style in plots.palette(df).items()}
        density_figure_ = figures.add(density_figure, density, out, colours, cost=2)
    horizons = horizon_table(df)
    horizon_figure_ = None
    if not horizons.empty:
        horizons.to_csv(out / "recorded_horizons.csv", index=False)
        colours = {variant: style.color for variant, style in plots.palette(df).items()}
        dts = pd.unique(df["dt"]) if "dt" in df.columns else []
        horizon_figure_ = figures.add(horizon_figure, horizons, out, colours,
                                      float(dts[0]) if len(dts) == 1 else None,
                                      cost=horizons["scenario"].nunique())
    traces, contacts, unreadable = pictured_logs(analysis, jobs)
    groups = df.groupby("scenario_label", sort=False)["variant"].nunique()
    trajectory_figures = [figures.add(plots.trajectories, df, scenario, traces, out, cost=0.7 * groups[scenario])
                          for scenario in pd.unique(df["scenario_label"])]
    failures, counts, gallery_figures = gallery.gallery(df, traces, out, logs_from=tables_dir, contacts=contacts,
                                                        figures=figures)
    box_figure = figures.add(plots.box_by_variant, df, BOX_METRICS, out,
                             cost=1.3 * len(BOX_METRICS) * df["scenario_label"].nunique())
    paired = pd.DataFrame()

    def compose() -> None:
        """The report's text and tables, in the reader's order, with the figures where they show."""
        nonlocal paired
        paired = paired_table(df, grouping)
        report.add("img", overview_figure)
        report.add("p", logs_line + " Groups: every combination of the run parameters that differ among these "
                        "logs (see Run parameters); one colour per group in every figure.")
        report.add("h2", "What the data says")
        report.add("list", warnings(df, analysis) + findings(df, paired) + unchanged_by(df, grouping))

        report.add("h2", "Effect of h_wait")
        if h_wait_figure is not None:
            report.add("p", f"{', '.join(plots.H_WAIT_METRICS)}: the mean against h_wait for auto (a point per "
                            "group in its colour, joined by a grey line per setting of the other differing "
                            "parameters) with its 95 % bootstrap interval; groups that do not read h_wait as "
                            "horizontal lines with their interval as a band. Success rate, time-to-goal and path "
                            "length per group with their intervals: the overview figure (auto's h_wait settings next "
                            "to each other). Every metric per group: groups.csv.")
            report.add("img", h_wait_figure)
        else:
            report.add("p", "Not drawn: every scenario was run with a single strategy variant, so there is nothing "
                            "to compare (sweep e.g. `planner=auto_h1,auto_h2,auto_h3,auto_h4,wait,detour`).")

        _crowd_sections(report, df, density_figure_)
        _recorded_section(report, horizons, horizon_figure_)

        report.add("h2", "Trajectories")
        report.add("p", "Per scenario, a panel per group with the robot paths of its seeds (thin lines; up to "
                        f"{plots.MAX_SEEDS_PER_PANEL} per panel: the failed episodes first, then the lowest seeds), "
                        "contacts the simulator flagged as black x, moving obstacles' true paths dotted; axes fitted "
                        "to the walls.")
        for figure in trajectory_figures:
            report.add("img", figure)
        if unreadable:
            report.add("p", f"{len(unreadable)} log(s) could not be read again for the pictures (changed since the "
                            f"analysis?), e.g. {next(iter(unreadable.values()))[:300]}")

        report.add("h2", "Failures")
        n_failed = int(counts["failed"].sum()) if not counts.empty else 0
        read_all = n_failed <= gallery.READ_ALL_MAX
        report.add("p", f"{n_failed} of {len(df)} episodes failed (not a success: a collision, a timeout, or the "
                        f"goal reached after a contact); pictured: the first {gallery.MAX_PER_GROUP} of each group "
                        f"(lowest seeds), {len(failures)} in all: a row of panels per group in the figure(s) below, "
                        "listed in the same order under them. Every failure with its log: failures.csv, with the "
                        "first contact step (the first step the simulator flagged as in contact; empty with log_read "
                        "true: none flagged) "
                        + ("of each." if read_all else f"of those whose log the pictures read (more than "
                           f"{gallery.READ_ALL_MAX} failures: the others' logs are not read again; "
                           "`python -m runners.replay <log>` shows any episode's steps)."))
        if not counts.empty:
            report.add("table", counts)
        for figure in gallery_figures:
            report.add("img", figure)
        report.add("gallery", failures)

        report.add("h2", "Paired comparisons (same scenario and seed)")
        significant = paired[paired["excludes_zero"]]
        report.add("p", f"Differences A − B whose 95 % bootstrap interval excludes zero: {len(significant)} of "
                        f"{len(paired)} comparisons (variants differing in one factor, on the same scenario and "
                        "seed). Every comparison, with its interval: paired.csv (also paired.parquet, with units).")
        if not significant.empty:
            shown_rows = significant.copy()
            shown_rows["mean A−B [95% CI]"] = [_fmt(m, lo, hi, 2) for m, lo, hi in zip(
                shown_rows["mean_a_minus_b"], shown_rows["ci_low"], shown_rows["ci_high"], strict=True)]
            table, note = _bounded(shown_rows[["scenario", "A", "B", "metric", "pairs", "mean A−B [95% CI]"]],
                                   "paired.csv (excludes_zero true)", "differences")
            report.add("table", table)
            if note:
                report.add("p", note)

        report.add("h2", "Outcomes per scenario and variant")
        report.add("p", "Success = goal reached with no contact before the step limit; 95 % Wilson interval. Other "
                        "columns: mean [95 % percentile bootstrap interval]. Every metric: groups.csv.")
        report.add("table", main)
        report.add("h2", "Distributions per variant")
        report.add("img", box_figure)
        report.add("h2", "Run parameters")
        others = (f"here {', '.join(grouping.dimensions)}, named in labels by the end of the key"
                  if grouping.dimensions else "here none differs")
        report.add("p", "Episodes are grouped by scenario, strategy and h_wait, and by every other run parameter "
                        f"whose value differs among these logs ({others}); seeds are pooled.")
        report.add("table", parameter_table(df, grouping, analysis.runs))
        disagree = df[~df["collision_check_agrees"]]
        report.add("h2", "Collision cross-check")
        report.add("p", "Contacts recomputed from the logged geometry agree with the simulator's flags in "
                        f"{len(df) - len(disagree)} of {len(df)} episodes.")
        if not disagree.empty:
            columns = ["log", "scenario_label", "variant", "collisions_static", "collisions_logged_static",
                       "collisions_dynamic", "collisions_logged_dynamic"]
            table, note = _bounded(disagree[columns].rename(columns={"scenario_label": "scenario"}),
                                   "episodes.csv (collision_check_agrees false)", "disagreements")
            report.add("table", table)
            if note:
                report.add("p", note)
        _left_out(report, excluded)

    def compose_and_write() -> None:
        compose()
        write_tables(out, df, long, paired, logs_from=tables_dir)  # while the workers draw: they need no figure

    figures.draw(jobs, meanwhile=compose_and_write)
    _write(report, out)
    return report


def pictured_logs(analysis: Analysis, jobs: int = -1
                  ) -> tuple[dict[str, Trace], dict[str, int | None], dict[str, str]]:
    """What the pictures and ``failures.csv`` need of the logs: (log -> :class:`analysis.trace.Trace` of each
    episode a trajectory panel or the failures gallery draws, log -> first contact step of each failure whose log
    the gallery reads (:func:`analysis.gallery.logs_to_read`, and the failures a panel draws), log -> why it could
    not be read). Taken from the analysis where its reading of the logs kept them (``analyse_logs(...,
    traces=True)``); the other logs are read again (in ``jobs`` worker processes: :func:`analysis.logs.read_logs`)."""
    df = analysis.episodes
    drawn = list(plots.panel_episodes(df)["log"])
    to_draw = list(dict.fromkeys([*drawn, *gallery.shown(df)["log"]]))
    read_for = {*drawn, *gallery.logs_to_read(df)}
    to_date = [log for log in gallery.failed(df)["log"] if log in read_for]  # first contact steps
    have, known = analysis.traces, analysis.first_contacts
    missing = [log for log in to_draw if log not in have]
    missing += [log for log in to_date if log not in have and log not in known and log not in missing]
    read, unreadable = load_traces(missing, jobs) if missing else ({}, {})
    traces = {log: have[log] if log in have else read[log] for log in to_draw if log in have or log in read}
    contacts: dict[str, int | None] = {}
    for log in to_date:
        if log in have or log in read:
            contacts[log] = (have[log] if log in have else read[log]).first_contact_step
        elif log in known and log not in to_draw:
            contacts[log] = known[log]
    return traces, contacts, unreadable


def _left_out(report: Report, excluded: pd.DataFrame) -> None:
    """The *Logs left out* section: the first rows inline, all of them in left_out.csv."""
    report.add("h2", "Logs left out")
    table, note = _bounded(excluded, "left_out.csv", "logs left out")
    report.add("table", table)
    if note:
        report.add("p", note)


def _crowd_sections(report: Report, df: pd.DataFrame, density: Figure | None) -> None:
    """Crowds: success and clearance against the pedestrian count where a sweep varied it (``density``: its figure,
    planned with density.csv written), and the TPT's prediction error per obstacle model where logs have reactive
    pedestrians (each group's mean, never pooled)."""
    if density is not None:
        report.add("h2", "Crowd density")
        report.add("p", "Success rate (Wilson 95 % interval) and minimum clearance to moving obstacles (bootstrap "
                        "95 % interval, cm) against the number of pedestrians: one point per group, every count "
                        "its own group (density.csv).")
        report.add("img", density)
    by_model = tpt_error_table(df)
    if not by_model.empty:
        report.add("h2", "TPT prediction error by obstacle model")
        report.add("p", "Average and final displacement error (cm) of the Trajectory Prediction Table's obstacle "
                        "rows against the logged truth, per group and obstacle model (mean over the episodes that "
                        "predicted that model's obstacles, 95 % bootstrap interval). The TPT assumes constant "
                        "velocity: scripted obstacles fit it, reactive pedestrians do not.")
        report.add("table", by_model)


def _recorded_section(report: Report, horizons: pd.DataFrame, figure: Figure | None) -> None:
    """Recorded people (:mod:`analysis.recorded_people`): the TPT's error per horizon step against constant velocity,
    figure first; nothing for logs without TPT predictions of recorded people."""
    if horizons.empty or figure is None:
        return
    report.add("h2", "Recorded people: the TPT against constant velocity")
    report.add("img", figure)
    report.add("p", "Per scenario group (a recording's window) and variant: how far the Trajectory Prediction "
                    "Table's rows put the recorded people they predicted from where the recording has them k steps "
                    "later (FDE: at step k; ADE: the mean over steps 1 … k; cm), solid, and the trajectory-prediction "
                    "benchmarks' constant-velocity baseline (velocity over the last annotation interval) on the same "
                    "predictions of the same people, dashed; mean over the episodes with its 95 % bootstrap "
                    "interval. Laser tracks and ground truth (perception) are separate variants. A prediction counts "
                    "while the person is a replay (not reacting). Every horizon, ADE and FDE: recorded_horizons.csv; "
                    "every policy on each window: the overview figure and Outcomes per scenario and variant (windows "
                    "are scenario groups, never pooled).")
    table, note = _bounded(shown_table(horizons), "recorded_horizons.csv", "groups")
    report.add("table", table)
    if note:
        report.add("p", note)


def tpt_error_table(df: pd.DataFrame) -> pd.DataFrame:
    """Rows (scenario, group, obstacle model, episodes, ADE, FDE) for the groups whose logs have obstacles of a
    model other than ``scripted``; empty when every obstacle is scripted."""
    models = models_of_columns(df.columns)
    if not any(m != "scripted" and df[f"tpt_ade_cm_{m}"].notna().any() for m in models):
        return pd.DataFrame()
    rows = []
    for (scenario, variant), g in _groups(df):
        for m in models:
            ade = g[f"tpt_ade_cm_{m}"].dropna()
            if ade.empty:
                continue
            rows.append({"scenario": scenario, "variant": variant, "obstacle model": m, "episodes": len(ade),
                         "ADE (cm)": _fmt(*bootstrap_mean(ade)),
                         "FDE (cm)": _fmt(*bootstrap_mean(g[f"tpt_fde_cm_{m}"].dropna()))})
    return pd.DataFrame(rows)


def _write(report: Report, out: Path) -> None:
    """``report.md`` and ``report.html`` (after the figures they show are drawn; the tables are written by then).
    UTF-8, whatever the locale; a path given in bytes that are not UTF-8 is written with escapes."""
    (out / "report.md").write_text(printable(report.markdown()), encoding="utf-8")
    (out / "report.html").write_text(printable(report.html()), encoding="utf-8")


#: the names of the files the report last written into a folder wrote (hidden, in that folder): a later report
#: into the same folder removes those it does not write itself (``failures_2.png`` of a report with more groups,
#: ``trajectories_<scenario>.png`` of a scenario no longer in the logs), so that no figure of another report is
#: left beside this one's
WRITTEN_LIST = ".report-files"


def previous_report_files(out: Path) -> set[str]:
    """The plain file names :data:`WRITTEN_LIST` in ``out`` lists (none if it is missing or unreadable); a name
    with a directory part, a hidden name or ``report``'s own list is left out, so an edited list cannot reach
    outside ``out``."""
    try:
        lines = (out / WRITTEN_LIST).read_text(encoding="utf-8", errors="replace").splitlines()
    except (OSError, ValueError):
        return set()
    return {n for n in lines[:100_000] if n and n == Path(n).name and not n.startswith(".") and "\\" not in n
            and n.lower().endswith(REPORT_SUFFIXES)}


#: the kinds of file a report writes: the only files its list can make a later report remove (never a log, were
#: the list edited to name one and the report written into the logs' folder)
REPORT_SUFFIXES = (".png", ".csv", ".parquet", ".md", ".html")


def write_whole(paths: Iterable[str | Path], out: Path, options: MetricOptions, analysis: Analysis,
                jobs: int = -1) -> None:
    """Write the report into ``out`` whole or not at all: built in a temporary directory inside ``out``, then each
    file moved into place (a rename needs no space); on a failure (a full disk) the temporary directory is
    removed and ``out`` holds what it held before, not a few plots of a report that does not exist. Once this report
    is in place, the files an earlier report in ``out`` wrote and this one did not are removed
    (:data:`WRITTEN_LIST`). ``jobs``: worker processes reading logs again for the pictures (as ``--jobs``)."""
    tmp = Path(tempfile.mkdtemp(prefix=".report.partial-", dir=out))
    try:
        build_report(paths, tmp, options, jobs=jobs, analysis=analysis, final_dir=out)
        written = sorted(item.name for item in tmp.iterdir())
        (tmp / WRITTEN_LIST).write_text("".join(f"{name}\n" for name in written))
        before = previous_report_files(out)
        _move_in(tmp, sorted(item.name for item in tmp.iterdir()), out)
        for name in sorted(before - set(written)):  # an earlier report's figure this one does not have
            with contextlib.suppress(OSError):
                if (out / name).is_file() and not (out / name).is_symlink():
                    (out / name).unlink()
    except OSError as err:  # name the file as the user knows it, not inside the temporary directory
        name = err.filename
        if name is not None and Path(name).is_relative_to(tmp):
            name = str(out / Path(name).relative_to(tmp))
        raise OSError(err.errno, err.strerror or str(err), name) from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _move_in(tmp: Path, names: list[str], out: Path) -> None:
    """Move the files ``names`` from ``tmp`` into ``out``, all or none: a name ``out`` holds as a directory fails
    before any file moves; the files they replace are set aside in ``tmp`` and put back should a move fail, so
    that ``out`` never mixes two reports."""
    for name in names:
        if (out / name).is_dir() and not (out / name).is_symlink():
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(out / name))
    aside = tmp / ".replaced"
    aside.mkdir()
    moved: list[tuple[str, bool]] = []  # (name, whether it replaced a file)
    try:
        for name in names:
            had = os.path.lexists(out / name)
            if had:
                os.replace(out / name, aside / name)
            moved.append((name, had))
            os.replace(tmp / name, out / name)
    except OSError:
        for name, had in reversed(moved):
            with contextlib.suppress(OSError):
                if os.path.lexists(out / name) and not os.path.lexists(tmp / name):
                    os.replace(out / name, tmp / name)
                if had:
                    os.replace(aside / name, out / name)
        raise


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("paths", nargs="+", help="sweep directories and/or .mcap files")
    parser.add_argument("--out", help="output directory (default: <path>/report for one directory, such as a "
                                      "sweep's; else ./report, so that a report of several sweeps does not replace "
                                      "the first one's own)")
    parser.add_argument("--turn-threshold-deg", type=number_in(0.0, 180.0, "degrees", lo_open=True), default=5.0,
                        help="heading change counted as a turn (degrees per step, in (0, 180])")
    parser.add_argument("--near-miss-cm", type=number_in(0.0, 10_000.0, "cm", lo_open=True), default=20.0,
                        help="a step whose clearance to an obstacle is below this is a near miss (cm, default 20)")
    parser.add_argument("--stall-speed-cm-s", type=number_in(0.0, 1_000.0, "cm/s", lo_open=True), default=1.0,
                        help="a step slower than this away from the goal is stalled (cm/s, default 1)")
    parser.add_argument("--personal-space-cm", type=number_in(0.0, 10_000.0, "cm"), default=45.0,
                        help="personal-space radius beyond a moving obstacle's surface (cm, default 45)")
    parser.add_argument("--jobs", type=jobs, default=-1,
                        help="worker processes reading the logs and drawing the figures (default -1: every core; 1: "
                             "this process only)")
    parser.add_argument("--split-provenance", action="store_true",
                        help="logs written by different code (fuzzynav version, git commit, library versions) form "
                             "separate groups (default: pooled, with a warning)")
    args = parser.parse_args(argv)
    problem = next((line for line in map(path_problem, args.paths) if line), None)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    first = Path(args.paths[0])
    if args.out is not None and not args.out.strip():  # "" is no directory: it wrote ./report instead
        parser.error("--out: an empty path; give the report's directory")
    out = Path(args.out) if args.out else (first / "report" if first.is_dir() and len(args.paths) == 1
                                           else Path("report"))
    existed = out.exists()
    problem = unwritable_dir(out)  # before the analysis, not after it
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    options = MetricOptions(turn_threshold_deg=args.turn_threshold_deg, near_miss_cm=args.near_miss_cm,
                            stall_speed_cm_s=args.stall_speed_cm_s, personal_space_cm=args.personal_space_cm)
    analysis = analyse_logs(args.paths, options, jobs=args.jobs, split_provenance=args.split_provenance,
                            traces=True, meanwhile=plots.pyplot)  # matplotlib imported while workers read
    if analysis.episodes.empty and analysis.excluded.empty:  # an empty report with exit 0 looked like a result
        if not existed:
            with contextlib.suppress(OSError):
                out.rmdir()
        print(f"error: no logs found in {', '.join(args.paths)}", file=sys.stderr)
        return 2
    try:
        write_whole(args.paths, out, options, analysis, args.jobs)
    except OSError as err:  # disk full, or the directory changed under us: nothing of the report was written
        print(f"error: {err.filename or out}: cannot write the report: {err.strerror or err} (nothing written)",
              file=sys.stderr)
        return 1
    except FigureError as err:  # a bug of ours or of matplotlib on these data: one line, HYDRA_FULL_ERROR=1 the rest
        if os.environ.get("HYDRA_FULL_ERROR") == "1":
            raise
        print(f"error: {out}: cannot write the report: {err} (nothing written; HYDRA_FULL_ERROR=1 shows where)",
              file=sys.stderr)
        return 1
    print(f"wrote {out / 'report.md'} and {out / 'report.html'}")
    if analysis.episodes.empty:  # a report of no episode is no result: it only lists why each log was left out
        n = len(analysis.excluded)
        first = str(analysis.excluded["reason"].iloc[0]) if n else ""  # the problem, with the file it is in
        log = str(analysis.excluded["log"].iloc[0]) if n else ""
        if log and log not in first:  # (an episode's own error, "episode raised: ...", does not name its log)
            first = f"{log}: {first}"
        more = f"; and {n - 1} more" if n > 1 else ""
        print(f"error: none of the {n} log(s) could be analysed ({left_out_counts(analysis.excluded)}): "
              f"{first[:300]}{more} (all in 'Logs left out' of {out / 'report.md'})", file=sys.stderr)
        return 1
    if len(analysis.excluded):
        print(f"{len(analysis.excluded)} log(s) left out ({left_out_counts(analysis.excluded)}), each with its "
              "reason: see 'Logs left out' in the report")
    return 0


def _exit_now(code: int) -> None:
    """End the command once everything is written and closed, without the interpreter's teardown (freeing every
    object one by one: 0.13-0.19 s, a tenth of the default sweep's report); where the output cannot be flushed,
    the ordinary exit reports it."""
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        raise SystemExit(code) from None
    os._exit(code)


if __name__ == "__main__":
    _exit_now(main())
