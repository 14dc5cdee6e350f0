"""Issue #19's and issue #36's targets, read off one run of ``python -m runners.bench`` (its ``bench.json``
results): for each, the measured value, the threshold, their ratio and whether it is met. Printed last by the
bench, so that one run says where every target stands.

A target whose measurement is missing (a peer engine not installed, the issue-time commit not in this checkout's
history, a section only the full run measures) is reported as not measured, never as met.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from runners.benchmarks.main_job import FULL_RUN_ONLY

CROWD_STEPS_PER_S = 500.0  # target 3: steps/s with 20 reactive pedestrians, per core
ANALYSIS_EPISODES_PER_S = 200.0  # target 4: 100-step episodes per second, one process
REPORT_SECONDS = 60.0  # target 4: the report of 10,000 episodes
RSS_GROWTH = 0.05  # target 4: "RSS flat" over a sweep: at most +5 % from 10 % of the episodes to the end
AGREEMENT_DEG = 1e-9  # target 2: ours vs scikit-fuzzy (Δθ degrees; v is held to the same number in cm/s)
STEP_RATIO = 2.0  # target 3: the logged step at least twice as fast as at the commit
SWEEP_EFFICIENCY = 0.8  # issue #36: the default sweep at >= 80 % of cores x one plain process's episodes/s
FIRST_STEP_S = 0.5  # issue #36: runners.run's first step under 0.5 s after its start (strictly)
REPORT_OVER_METRICS = 0.5  # issue #36: analysis.report at least half the metrics' episodes/s
KERNEL_GAIN = 1.3  # issue #36: a kernel stays where it gives >= 1.3 x on some documented workload end to end


@dataclass(frozen=True)
class Target:
    """One line of the summary: ``value`` against ``threshold`` (``higher`` is better, or lower; ``strict``: the
    threshold itself misses it; the line gives value / threshold, which meets the target at >= 1 or <= 1), ``None``
    when not measured (``note`` says why)."""

    name: str
    value: float | None
    threshold: float
    higher: bool
    unit: str
    note: str = ""
    strict: bool = False

    @property
    def met(self) -> bool | None:
        if self.value is None:
            return None
        if self.strict:
            return self.value > self.threshold if self.higher else self.value < self.threshold
        return self.value >= self.threshold if self.higher else self.value <= self.threshold

    @property
    def sign(self) -> str:
        """The comparison that meets the target: ``>=``, ``<=``, ``>`` or ``<``."""
        return (">" if self.higher else "<") + ("" if self.strict else "=")

    def as_dict(self) -> dict[str, Any]:
        """The target as ``bench.json`` holds it (what the performance page reads)."""
        return {"name": self.name, "value": self.value, "threshold": self.threshold, "higher_is_better": self.higher,
                "sign": self.sign, "unit": self.unit, "met": self.met, "note": self.note}

    def line(self) -> str:
        if self.value is None:
            return f"  {self.name}: not measured ({self.note})"
        sign = self.sign
        verdict = "met" if self.met else "NOT met"
        note = f"; {self.note}" if self.note else ""
        unit = f" {self.unit}" if self.unit else ""
        return (f"  {self.name}: {self.value:.3g}{unit} (target {sign} {self.threshold:g}: "
                f"{self.value / self.threshold:.3g} of it) — {verdict}{note}")


def targets(results: dict[str, Any]) -> list[Target]:
    """The targets of issue #19 from a bench run's ``results`` (the dict written to ``bench.json``)."""
    out = []
    for row in results.get("fuzzy", []):
        c = row["controller"]
        peers = {p["engine"]: p for p in row.get("peers", [])}
        missing = [name for name in ("ferrifuzz", "pyfuzzylite") if not peers.get(name, {}).get("installed")]
        out.append(Target(f"1 peers in the table ({c})", None if missing else 2.0, 2.0, True, "peer engines",
                          f"{', '.join(missing)} not installed: pip install -e '.[bench]'; pyfuzzylite --no-deps"
                          if missing else "ferrifuzz, pyfuzzylite"))
        ferri = "single_over_ferrifuzz" in row
        why = "ferrifuzz not installed"
        out.append(Target(f"2 single decision ours / ferrifuzz ({c})", row.get("single_over_ferrifuzz"), 1.0,
                          False, "", "" if ferri else why))
        out.append(Target(f"2 batch per core ours / ferrifuzz ({c})", row.get("batch_per_core_over_ferrifuzz"),
                          1.0, False, "", "" if ferri else why))
        out.append(Target(f"2 agreement with scikit-fuzzy ({c})",
                          max(row["max_disagreement_dtheta_deg"], row["max_disagreement_v_cm_s"]), AGREEMENT_DEG,
                          False, "deg / cm/s"))
    base = results.get("baseline")
    if base is not None:
        measured = base.get("measured")
        out.append(Target(f"3 logged step vs commit {base['commit'][:7]} (side by side)",
                          base["logged_ratio"] if measured else None, STEP_RATIO, True, "x",
                          f"without logging {base['plain_ratio']:.2f} x" if measured else base.get("why", "")))
    crowd = results.get("crowd")
    if crowd:
        slowest = min(crowd, key=lambda r: r["steps_per_s_with_logging"])
        out.append(Target("3 crowds, 20 pedestrians, slowest model", slowest["steps_per_s_with_logging"],
                          CROWD_STEPS_PER_S, True, "steps/s", slowest["model"]))
    if "analysis" in results:
        out.append(Target("4 analysis, one process", results["analysis"]["episodes_per_s"], ANALYSIS_EPISODES_PER_S,
                          True, "episodes/s"))
    report = results.get("report")
    if report:
        big = report["synthetic"]
        out.append(Target(f"4 report of {big['episodes']} episodes", big["total_s_estimate"], REPORT_SECONDS, False,
                          "s", "read stage estimated, report stage measured"))
    memory = results.get("memory")
    if memory:
        out.append(Target(f"4 RSS growth over {memory['episodes']} episodes", max(memory["growth"], 0.0) * 100,
                          RSS_GROWTH * 100, False, "%"))
    return out


def _absent(results: dict[str, Any], key: str) -> str:
    """Why a section of the main job is not in ``results``: only the full run measures it, or this run lacks it."""
    if key in FULL_RUN_ONLY and results.get("quick"):
        return f"no {key} in a --quick run: the full run measures it"
    return f"no {key} in this run's results"


def main_job_targets(results: dict[str, Any]) -> list[Target]:
    """Issue #36's targets from the main job's figures (:mod:`runners.benchmarks.main_job`); each is a row whether or
    not its section was measured (a ``--quick`` run has no 1,000-episode sweep and no kernels' table)."""
    out = []
    job = results.get("main_job")
    if job:
        out.append(Target("sweep efficiency, the default sweep as a whole command", job["sweep_efficiency"],
                          SWEEP_EFFICIENCY, True, "", f"{job['cores']} cores"))
        out.append(Target("sweep efficiency, the default sweep's episodes phase", job["episodes_phase_efficiency"],
                          SWEEP_EFFICIENCY, True, "", f"{job['cores']} cores"))
        out.append(Target("sweep efficiency, the default sweep as a whole command", job["simulated_sweep_efficiency"],
                          SWEEP_EFFICIENCY, True, "", f"{job['simulated_cores']} cores, simulated schedule"))
        out.append(Target("time to the first step of runners.run", job["first_step_s"], FIRST_STEP_S, False, "s",
                          strict=True))
        out.append(Target("analysis.report / the metrics alone (episodes/s)", job["report_over_metrics"],
                          REPORT_OVER_METRICS, True, "", "the default sweep's logs"))
    else:
        why = _absent(results, "main_job")
        out += [Target("sweep efficiency, the default sweep as a whole command", None, SWEEP_EFFICIENCY, True, "", why),
                Target("time to the first step of runners.run", None, FIRST_STEP_S, False, "s", why, strict=True),
                Target("analysis.report / the metrics alone (episodes/s)", None, REPORT_OVER_METRICS, True, "", why)]
    large = results.get("large_sweep")
    if large:
        out.append(Target("sweep efficiency, a 1,000-episode sweep as a whole command", large["sweep_efficiency"],
                          SWEEP_EFFICIENCY, True, "", f"{large['cores']} cores"))
        out.append(Target("sweep efficiency, a 1,000-episode sweep as a whole command",
                          large["simulated_sweep_efficiency"], SWEEP_EFFICIENCY, True, "",
                          f"{large['simulated_cores']} cores, simulated schedule"))
        if "report_over_metrics" in large:
            out.append(Target("analysis.report / the metrics alone (episodes/s)", large["report_over_metrics"],
                              REPORT_OVER_METRICS, True, "", f"the {large['episodes']} episodes' logs"))
    else:
        out.append(Target("sweep efficiency, a 1,000-episode sweep as a whole command", None, SWEEP_EFFICIENCY, True,
                          "", _absent(results, "large_sweep")))
    out += _kernel_targets(results)
    return out


def _kernel_targets(results: dict[str, Any]) -> list[Target]:
    """A row per kernel the run's install has (``machine.kernels_built``) or its kernels' table measured: its best
    end-to-end gain over the documented workloads (time with it off / all on), against :data:`KERNEL_GAIN`."""
    built = (results.get("machine") or {}).get("kernels_built") or {}
    kernels = results.get("kernels")
    gain = kernels["gain"] if kernels else {}
    measured = [k for k in next(iter(gain.values()), {}) if not k.startswith("all ")]
    out = []
    for kernel in dict.fromkeys([*measured, *built]):
        name = f"kernel {kernel}, best end-to-end gain"
        if kernel in measured:
            best = max(gain, key=lambda w: gain[w][kernel])
            out.append(Target(name, gain[best][kernel], KERNEL_GAIN, True, "x", best))
        else:
            why = ("not built at install (no C compiler?)" if built.get(kernel) is False
                   else "not in this run's kernels' table" if kernels else _absent(results, "kernels"))
            out.append(Target(name, None, KERNEL_GAIN, True, "x", why))
    if not out:
        out.append(Target("each kernel's best end-to-end gain", None, KERNEL_GAIN, True, "x",
                          _absent(results, "kernels")))
    return out


def print_targets(results: dict[str, Any]) -> None:
    rows = targets(results)
    met = sum(1 for t in rows if t.met)
    print(f"issue #19 targets: {met} of {len(rows)} met in this run")
    for t in rows:
        print(t.line())
    rows = main_job_targets(results)
    if rows:
        met = sum(1 for t in rows if t.met)
        print(f"issue #36 targets (the main job): {met} of {len(rows)} met in this run")
        for t in rows:
            print(t.line())
