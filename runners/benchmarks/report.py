"""How long the analysis report takes, measured on real logs and on a 10,000-episode table built from them.

``python -m runners.benchmarks.report [--episodes 10000] [--seeds 10]`` (also called by :mod:`runners.bench`);
``python -m runners.benchmarks.report --logs DIR``: the whole report of existing logs, measured (e.g. of a sweep of
10,000 episodes: ``python -m runners.sweep episodes=477 hydra.sweep.dir=DIR`` makes 10,017).

1. **Real episodes**: the default sweep (3 scenarios x 7 strategy settings, ``--seeds`` seeds each: 210 episodes
   with 10) is run with ``runners.sweep``; then, timed separately, the *read stage* (:func:`analysis.metrics.
   analyse_logs`: every log verified, checked and turned into metrics, on every core) and the *report stage*
   (:func:`analysis.report.build_report` given that analysis: tables, intervals, figures, pictures of
   trajectories and failures, files).
2. **10,000 episodes, report stage**: generating 10,000 real logs would take longer than the rest of the
   benchmark, so the real episode table is repeated with new seed numbers (each copy keeps its group, its metrics
   and its real log) until it has ``--episodes`` rows, and the report stage is timed on it. Every per-episode
   cost of the report is paid for real: intervals over 10,000 rows, paired differences over the seeds, every
   failed episode's log read again for its first contact step, the capped trajectory panels and failure pictures
   read and drawn from real logs (an upper bound: the table carries no traces, so the report reads those logs
   again, where ``python -m analysis.report`` takes them from its one reading of the logs).
3. **10,000 episodes, read stage**: estimated from the real episodes: their read time per log in one process,
   shared out over every core, plus what the worker pool cost on them beyond that — the read stage costs the same
   per log whatever the number of logs (each is read on its own).
4. **The whole report of 10,000 episodes**: the estimated read stage plus the measured report stage, against the
   budget of :data:`BUDGET_S` seconds (#18 item 5); the report stage's own share of it is :data:`REPORT_BUDGET_S`.

The large table's report stage is timed first, in a process that has not drawn a figure yet (as
``python -m analysis.report`` would); the real episodes' report after it. The result says which number is measured
and which is estimated.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from runners.benchmarks.results_file import out_problem, write_results

ROOT = Path(__file__).resolve().parents[2]
BUDGET_S = 60.0
"""The whole report (read and report stages) of 10,000 episodes on a 2-core machine (#18 item 5)."""
REPORT_BUDGET_S = 15.0
"""The report stage's share of :data:`BUDGET_S` (the read stage needs about 30 s of it)."""


def _real_sweep(sweep_dir: Path, seeds: int) -> float:
    """Run the default sweep with ``seeds`` seeds per configuration into ``sweep_dir``; its wall time (s)."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "runners.sweep", f"episodes={seeds}", f"hydra.sweep.dir={sweep_dir}"],
                          cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"the benchmark's sweep failed: {done.stderr.strip().splitlines()[-1:]}")
    return time.perf_counter() - start


def repeated(analysis, episodes: int, link_dir: Path | None = None):
    """An :class:`analysis.metrics.Analysis` of ``episodes`` rows: the real episodes repeated, copy ``c`` of seed
    ``s`` numbered ``s + c * (largest seed + 1)`` (so that copies stay paired across groups on the same seed),
    in the groups' natural order then by seed, as :func:`analysis.metrics.analyse_logs` orders them. With
    ``link_dir``, each copy's log is a hard link of the real log under ``link_dir/<copy>/`` (a path of its own,
    so that the report reads it as often as it would read 10,000 distinct logs: it reads each path once)."""
    from analysis.metrics import Analysis

    real = analysis.episodes.assign(_run=range(len(analysis.episodes)))
    stride = int(real["seed"].max()) + 1
    copies = math.ceil(episodes / len(real))
    table = pd.concat([real.assign(seed=real["seed"] + c * stride) for c in range(copies)], ignore_index=True)
    table = table.head(episodes)
    if link_dir is not None:
        links = []
        for log, seed in zip(table["log"], table["seed"], strict=True):
            copy = int(seed) // stride
            if copy == 0:
                links.append(log)
                continue
            link = link_dir / str(copy) / Path(log).relative_to(Path(log).anchor)
            link.parent.mkdir(parents=True, exist_ok=True)
            if not link.exists():
                os.link(log, link)
            links.append(str(link))
        table["log"] = links
    group_rank = {key: rank for rank, key in enumerate(dict.fromkeys(zip(real["scenario_label"], real["variant"],
                                                                         strict=True)))}
    table["_rank"] = [group_rank[k] for k in zip(table["scenario_label"], table["variant"], strict=True)]
    table = table.sort_values(["_rank", "seed"], kind="stable").reset_index(drop=True)
    runs = [analysis.runs[i] for i in table["_run"]]
    return Analysis(table.drop(columns=["_run", "_rank"]), analysis.excluded, analysis.grouping, runs)


MAX_EPISODES = 1_000_000  # rows of the large table: its report stage holds them in memory
MAX_SEEDS = 10_000  # the sweep's own limit of episodes per job


def bench_report(episodes: int = 10_000, seeds: int = 10) -> dict:
    """Time the report (see the module docstring): the real default sweep with ``seeds`` seeds per configuration,
    read and report stages; the report stage on ``episodes`` rows built from it; the read stage for ``episodes``
    estimated from the real rate. Times in seconds, on this machine's cores (``cores``)."""
    from analysis.metrics import analyse_logs
    from analysis.report import build_report

    with tempfile.TemporaryDirectory(prefix="bench_report-") as tmp:
        sweep_dir = Path(tmp) / "sweep"
        sweep_s = _real_sweep(sweep_dir, seeds)
        start = time.perf_counter()
        analysis = analyse_logs([sweep_dir], jobs=-1, traces=True)  # as the report reads them
        read_s = time.perf_counter() - start
        start = time.perf_counter()
        analyse_logs([sweep_dir], jobs=1)  # the cost per log, without the worker pool
        read_one_s = time.perf_counter() - start
        big = repeated(analysis, episodes, Path(tmp) / "links")
        out = Path(tmp) / "big"
        start = time.perf_counter()  # first: nothing drawn or imported for the figures yet, as in a report's run
        build_report([sweep_dir], out, analysis=big)
        big_report_s = time.perf_counter() - start
        start = time.perf_counter()
        build_report([sweep_dir], Path(tmp) / "real", analysis=analysis)
        real_report_s = time.perf_counter() - start
        html = (out / "report.html").read_text()
        pngs = list(out.glob("*.png"))
        real_n, cores = len(analysis.episodes), os.cpu_count() or 1
        # every core reads its share of the logs at the one-process rate, plus what the pool costs beyond that on
        # the real logs (starting the workers, sending the rows back)
        pool_s = max(read_s - read_one_s / min(cores, real_n), 0.0)
        read_estimate_s = read_one_s / real_n * episodes / cores + pool_s
        return {
            "cores": os.cpu_count(),
            "real": {"episodes": real_n, "seeds_per_configuration": seeds, "sweep_s": sweep_s,
                     "read_stage_s": read_s, "read_stage_one_process_s": read_one_s, "pool_s": pool_s,
                     "report_stage_s": real_report_s, "measured": True},
            "synthetic": {"episodes": len(big.episodes), "failed": int((~big.episodes["success"]).sum()),
                          "report_stage_s": big_report_s, "measured": True,
                          "read_stage_s_estimate": read_estimate_s,
                          "total_s_estimate": read_estimate_s + big_report_s,
                          "budget_s": BUDGET_S, "report_stage_budget_s": REPORT_BUDGET_S,
                          "html_kb": len(html.encode()) / 1000, "html_table_rows": html.count("<tr>"),
                          "images": len(pngs), "images_kb": sum(p.stat().st_size for p in pngs) / 1000},
        }


def summary_line(result: dict) -> str:
    """One line for :mod:`runners.bench`: what was measured and what was estimated."""
    real, big = result["real"], result["synthetic"]
    return (f"report: {real['episodes']} real episodes: read {real['read_stage_s']:.1f} s + report "
            f"{real['report_stage_s']:.1f} s (measured); {big['episodes']} episodes (the real ones repeated): report "
            f"stage {big['report_stage_s']:.1f} s (measured), read stage ~{big['read_stage_s_estimate']:.0f} s "
            f"(estimated from the real rate) on {result['cores']} cores; HTML {big['html_kb']:.0f} kB, "
            f"{big['html_table_rows']} table rows, {big['images']} images")


def budget_lines(result: dict) -> list[str]:
    """The report of ``episodes`` against the budget: the report stage (measured) against its share, the whole
    report (read stage estimated + report stage measured) against :data:`BUDGET_S`."""
    big = result["synthetic"]
    n, report_s, read_s = big["episodes"], big["report_stage_s"], big["read_stage_s_estimate"]
    total = read_s + report_s
    budget, share = big.get("budget_s", BUDGET_S), big.get("report_stage_budget_s", REPORT_BUDGET_S)
    return [f"report stage, {n} episodes: {report_s:.1f} s (measured) — "
            f"{'within' if report_s <= share else 'OVER'} its {share:.0f} s share",
            f"whole report, {n} episodes: ~{total:.0f} s = read stage ~{read_s:.0f} s (estimated: the "
            f"{result['real']['episodes']} real logs' one-process time per log, scaled to {n} on {result['cores']} "
            f"cores, plus the worker pool's cost on them) + report stage {report_s:.1f} s (measured) — "
            f"{'within' if total <= budget else 'OVER'} the {budget:.0f} s budget"]


def bench_logs(paths: list[str]) -> dict:
    """The whole report of existing logs (a large sweep's directory), measured: read stage on every core and
    report stage, into a temporary directory. Seconds."""
    from analysis.metrics import analyse_logs
    from analysis.report import build_report

    with tempfile.TemporaryDirectory(prefix="bench_report-") as tmp:
        start = time.perf_counter()
        analysis = analyse_logs(paths, jobs=-1, traces=True)  # as the report reads them
        read_s = time.perf_counter() - start
        build_report(paths, Path(tmp) / "report", analysis=analysis)
        total_s = time.perf_counter() - start
    return {"cores": os.cpu_count(), "episodes": len(analysis.episodes), "left_out": len(analysis.excluded),
            "read_stage_s": read_s, "report_stage_s": total_s - read_s, "total_s": total_s, "budget_s": BUDGET_S,
            "measured": True}


def logs_line(result: dict) -> str:
    return (f"whole report of {result['episodes']} logged episodes ({result['left_out']} left out): "
            f"{result['total_s']:.1f} s (measured) = read stage {result['read_stage_s']:.1f} s + report stage "
            f"{result['report_stage_s']:.1f} s on {result['cores']} cores — "
            f"{'within' if result['total_s'] <= result['budget_s'] else 'OVER'} the {result['budget_s']:.0f} s budget")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=10_000, help="rows of the large table (default 10000)")
    parser.add_argument("--seeds", type=int, default=10, help="real seeds per configuration (default 10)")
    parser.add_argument("--logs", nargs="+", metavar="PATH",
                        help="instead: time the whole report of these logs (e.g. a 10,000-episode sweep's directory)")
    parser.add_argument("--out", help="also write the result here (JSON)")
    args = parser.parse_args(argv)
    problem = out_problem(Path(args.out)) if args.out else None
    if problem:
        parser.error(f"--out: {problem}")
    if not 1 <= args.episodes <= MAX_EPISODES:
        parser.error(f"--episodes: must be in [1, {MAX_EPISODES:,}], got {args.episodes}")
    if not 1 <= args.seeds <= MAX_SEEDS:
        parser.error(f"--seeds: must be in [1, {MAX_SEEDS:,}], got {args.seeds}")
    try:
        if args.logs:
            missing = [p for p in args.logs if not Path(p).exists()]
            if missing:
                parser.error(f"--logs: {missing[0]}: no such file or directory")
            result = bench_logs(args.logs)
            if result["episodes"] == 0:
                raise RuntimeError(f"--logs: no usable episode among them ({result['left_out']} left out)")
            print(logs_line(result))
        else:
            result = bench_report(args.episodes, args.seeds)
            print(summary_line(result))
            for line in budget_lines(result):
                print(line)
    except RuntimeError as err:
        print(f"bench_report: {err}", file=sys.stderr)
        return 1
    if args.out:
        _, problem = write_results(Path(args.out), json.dumps(result, indent=2))
        if problem:
            print(f"bench_report: --out: {problem}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
