"""The study report, ``<study>/report/``: ``study.md`` (space, objectives, trials, best trial, held-out result with
intervals), ``heldout.csv``, ``trials.csv`` and the figures drawn by Optuna's matplotlib visualisation:
optimisation history (one per objective), parameter importances (fANOVA, Optuna's default evaluator) and, for
two objectives, the Pareto front.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only, no display (as the rest of the analysis)
import matplotlib.pyplot as plt
import optuna
import pandas as pd

from runners.tuning.heldout import Evaluated, interval_table
from runners.tuning.study import FAIL_REASON, INTERRUPTED, SURPLUS, counted
from runners.tuning.study_file import StudySpec

REPORT_DIR = "report"


def _save(axes: object, path: Path) -> Path:
    fig = getattr(axes, "figure", None) or plt.gcf()
    if isinstance(axes, list | tuple) or hasattr(axes, "flat"):
        fig = plt.gcf()
    fig.set_size_inches(7, 4.5)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close("all")
    return path


def figures(study: optuna.Study, spec: StudySpec, out: Path) -> dict[str, Path | str]:
    """The figures (path), or why one could not be drawn (text)."""
    from optuna.visualization import matplotlib as ovm

    drawn: dict[str, Path | str] = {}
    complete = study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.COMPLETE,))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Optuna marks its matplotlib plots experimental
        for i, o in enumerate(spec.objectives):
            target = None if len(spec.objectives) == 1 else (lambda t, i=i: t.values[i])
            drawn[f"history_{o.name}"] = _save(ovm.plot_optimization_history(study, target=target, target_name=o.name),
                                               out / f"history_{o.name}.png")
            key = f"importance_{o.name}"
            if len(complete) < 2:
                drawn[key] = "fewer than two completed trials"
                continue
            try:
                drawn[key] = _save(ovm.plot_param_importances(study, target=target, target_name=o.name),
                                   out / f"{key}.png")
            except (RuntimeError, ValueError) as err:  # e.g. every trial had the same values
                drawn[key] = f"not computable: {' '.join(str(err).split())[:120]}"
                plt.close("all")
        if len(spec.objectives) == 2:
            drawn["pareto_front"] = _save(ovm.plot_pareto_front(study, target_names=[o.name for o in spec.objectives]),
                                          out / "pareto_front.png")
    return drawn


def membership_figure(spec: StudySpec, evaluated: list[Evaluated], out: Path) -> Path | None:
    """The searched variables' membership functions: the base controller's (dashed) beside the best trial's."""
    import numpy as np

    from fuzzynav.controller.fuzzy_spec import Term, sample_membership
    from runners.tuning.episodes import hydra_conf, run_config

    tuned = next((ev for ev in evaluated if ev.trial is not None), None)
    if not spec.controller_space or tuned is None:
        return None
    with hydra_conf():
        before = run_config(evaluated[0].overrides, spec.scenarios[0], spec.heldout).controller
        after = run_config(tuned.overrides, spec.scenarios[0], spec.heldout).controller
    fig, axes = plt.subplots(len(spec.controller_space), 1, figsize=(7, 2.4 * len(spec.controller_space)),
                             squeeze=False)
    for ax, names in zip(axes[:, 0], spec.controller_space, strict=True):
        section = "inputs" if names[0] in before.inputs else "outputs"
        var_before, var_after = before[section][names[0]], after[section][names[0]]
        u0, u1 = float(var_before.universe[0]), float(var_before.universe[1])
        grid = np.linspace(u0, u1, 400)
        for k, name in enumerate(var_before.terms):
            colour = f"C{k}"
            for var, style, who in ((var_before, "--", before.name), (var_after, "-", after.name)):
                term = Term(name, var.terms[name].mf, tuple(float(p) for p in var.terms[name].params))
                ax.plot(grid, sample_membership(term, grid, u1), style, color=colour,
                        label=f"{name} ({who})" if style == "-" or k == 0 else None)
        ax.set_title(f"{', '.join(names)}: {before.name} (dashed) and {after.name}", fontsize=9)
        ax.set_ylim(-0.02, 1.05)
        ax.legend(fontsize=6, ncol=3)
    fig.tight_layout()
    path = out / "membership.png"
    fig.savefig(path, dpi=110)
    plt.close("all")
    return path


def trials_table(study: optuna.Study, spec: StudySpec) -> pd.DataFrame:
    rows = []
    for t in study.get_trials(deepcopy=False):
        if t.user_attrs.get(SURPLUS):  # asked for beyond the budget by a worker, never run
            continue
        row = {"number": t.number, "state": t.state.name, "counted": counted(t),
               "interrupted": bool(t.user_attrs.get(INTERRUPTED, False)), "default": bool(t.user_attrs.get("default"))}
        row.update({p.key: t.params.get(p.key) for p in spec.space})
        if spec.controller_space:
            row["controller_partition_coordinates"] = sum(k.startswith("controller~") for k in t.params)
        for i, o in enumerate(spec.objectives):
            row[o.name] = t.values[i] if t.values else math.nan
        row["seconds"] = (t.datetime_complete - t.datetime_start).total_seconds() \
            if t.datetime_complete and t.datetime_start else math.nan
        row["fail_reason"] = t.user_attrs.get(FAIL_REASON, "")
        rows.append(row)
    return pd.DataFrame(rows)


def rule_table(study: optuna.Study, spec: StudySpec, evaluated: list[Evaluated]) -> list[str]:
    """For a study of rule outputs: each rule whose outputs an evaluated trial changed, beside the base
    controller's (Table 1's) outputs."""
    from runners.tuning import rule_space
    from runners.tuning.study import rule_outputs

    space = rule_outputs(spec)
    tuned = [ev for ev in evaluated if ev.trial is not None and not ev.same_as_default]
    if space is None or not tuned:
        return []
    base = rule_space.rules(space, rule_space.start_values(space))
    columns = [(ev.label, rule_space.rules(space, study.trials[ev.trial].params)) for ev in tuned]
    changed = [i for i in range(len(base)) if any(r[i] != base[i] for _, r in columns)]
    lines = ["", f"## Rule outputs beside the base controller's ({len(changed)} of {len(base)} rules changed)", "",
             "| rule | antecedent | base | " + " | ".join(label for label, _ in columns) + " |",
             "|---|---|---|" + "---|" * len(columns)]
    for i in changed:
        ante, _, out = base[i].partition(" -> ")
        lines.append(f"| {i} | {ante} | {out} | " + " | ".join(r[i].partition(" -> ")[2] for _, r in columns) + " |")
    return lines


def _f(v: float) -> str:
    return "—" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{v:.4g}"


def write_report(study: optuna.Study, spec: StudySpec, study_dir: Path, evaluated: list[Evaluated]) -> Path:
    """Write the report; returns ``study.md``."""
    out = study_dir / REPORT_DIR
    out.mkdir(parents=True, exist_ok=True)
    trials = trials_table(study, spec)
    trials.to_csv(out / "trials.csv", index=False)
    drawn = figures(study, spec, out)
    membership = membership_figure(spec, evaluated, out)
    if membership is not None:
        drawn["membership"] = membership
    held = interval_table(evaluated, spec)
    held.to_csv(out / "heldout.csv", index=False)
    lines = [f"# Study {spec.name}", "", spec.description, "",
             f"Study file `{spec.path}`; storage in `{study_dir}`; sampler {spec.sampler} (seed {spec.sampler_seed}).",
             f"Scenarios: {', '.join(spec.scenarios)}. Training seeds {spec.train.text()}; held-out seeds "
             f"{spec.heldout.text()} (disjoint).", "", "## Search space", "",
             *[f"- `{p.text}`" for p in spec.space], "", f"Base overrides: `{' '.join(spec.base) or '(none)'}`", "",
             "## Objectives", ""]
    for o in spec.objectives:
        terms = " + ".join(f"{w:g} × mean {m}" for m, w in o.terms)
        fill = f" (undefined values filled: {', '.join(f'{m}={v:g}' for m, v in o.fill)})" if o.fill else ""
        lines.append(f"- **{o.name}** ({o.direction}): {terms}, per scenario then averaged over scenarios{fill}")
    states = trials["state"].value_counts().to_dict()
    lines += ["", "## Trials", "", f"{len(trials)} trials: " + ", ".join(f"{n} {s.lower()}" for s, n in states.items())
              + f"; {int(trials['interrupted'].sum())} interrupted (not counted). All in `report/trials.csv`; each "
              "trial's logs in `trials/<number>/`.", ""]
    failed = trials[(trials["state"] == "FAIL") & trials["counted"]]
    for _, row in failed.head(5).iterrows():
        lines.append(f"- trial {row['number']} failed: {row['fail_reason']}")
    lines += ["", "## Figures", ""]
    for name, value in drawn.items():
        lines.append(f"![{name}]({value.name})" if isinstance(value, Path) else f"- {name}: {value}")
        lines.append("")
    lines += ["## Held-out result", "",
              "Mean and 95 % interval on the held-out seeds (Wilson for success, percentile bootstrap otherwise); "
              "the difference from the default is paired by seed (the same world), with its bootstrap interval. "
              "Logs in `heldout/<configuration>/`: `python -m analysis.report heldout` reports them in full.", ""]
    for ev in evaluated:
        values = ", ".join(f"{k}={_f(v)}" for k, v in ev.objectives.items())
        where = f"trial {ev.trial}, `{ev.label}.yaml`" if ev.trial is not None else "untuned"
        if ev.same_as_default:
            where += "; the default configuration itself: no tuned value beat it on the training seeds"
        shown = [o for o in ev.overrides[len(spec.base):] if (".terms." not in o or not spec.controller_space)
                 and not o.startswith("controller.rules=") and not o.startswith("controller.name=")]
        terms = sum(".terms." in o for o in ev.overrides[len(spec.base):]) if spec.controller_space else 0
        params = f"`{' '.join(shown)}`" if shown else "(defaults)"
        if terms:  # the searched membership functions: in the controller file and the membership figure
            params += f" and {terms} term overrides (see `controller/` and `membership.png`)"
        if spec.controller_rules and ev.trial is not None:
            params += " and its rules (see the rule table below and `controller/`)"
        lines.append(f"- **{ev.label}** ({where}): held-out objectives {values}; {params}")
    lines += ["", "| scenario | metric | configuration | n | mean [95 % CI] | vs default [95 % CI] |",
              "|---|---|---|---|---|---|"]
    for _, r in held.iterrows():
        diff = f"{_f(r.get('diff_vs_default'))} [{_f(r.get('diff_ci_low'))}, {_f(r.get('diff_ci_high'))}]" \
            if r["configuration"] != "default" else ""
        lines.append(f"| {r['scenario']} | {r['metric']} | {r['configuration']} | {r['n']} | {_f(r['mean'])} "
                     f"[{_f(r['ci_low'])}, {_f(r['ci_high'])}] | {diff} |")
    lines += rule_table(study, spec, evaluated)
    if len(evaluated) > 1:
        best = evaluated[1]
        lines += ["", f"Run the tuned configuration: `python -m runners.run --config-dir {study_dir.absolute()} "
                  f"--config-name {best.label} scenario={spec.scenarios[0]}`"]
    lines.append("")
    path = out / "study.md"
    path.write_text("\n".join(lines))
    return path
