"""Benchmarks (speed is measured here, never asserted in unit tests).

    python -m runners.bench            # full run (about 12 minutes on 2 cores; the kernel's table about 3)
    python -m runners.bench --quick    # reduced sizes, without the 1,000-episode sweep and the kernels' table
                                       # (a few minutes; CI runs it, no thresholds)

1. Fuzzy decision: our evaluator, the peer engines ferrifuzz and pyfuzzylite (when installed:
   ``pip install -e '.[bench]'``; runners/benchmarks/peers.py builds them from the same definition) and
   scikit-fuzzy's ControlSystemSimulation.compute() on the same seeded inputs — time per single decision,
   batch time per decision, each one's largest disagreement with scikit-fuzzy, and issue #19's target 2
   (ours / ferrifuzz, single and batch per core).
2. Simulation on ``mixed`` with laser perception: steps/s without and with MCAP logging, and the time per
   step by stage (sensors, tracking, TPT, planner, controller, logging, rest).
3. Sweep overhead: real ``runners.sweep`` runs of short episodes on all cores (two jobs per core, and 20
   jobs), three rounds, vs the same episodes' own compute time divided by the cores, measured two ways: one
   after the other in this process (one core) before and after, and in each round split over one plain
   process per core started together (all cores busy, as in the sweep, but no launcher or Hydra); with the
   time of each phase.
4. Analysis: episodes/s and messages/s of the metrics table on logs of ~100-step episodes.
5. Memory: resident set size of one process running many episodes (with logs), early vs late.
6. Report: the time to write the report of 10,000 episodes (:mod:`runners.benchmarks.report`).
7. Crowds: ``crowd_crossing`` with 20 pedestrians of each obstacle model (scripted, social force, ORCA, random
   walk): steps/s with laser perception and logging, and the model's time per step (:mod:`runners.benchmarks.crowd`);
   and replaying a 300-person recording: the replay's and the sensing's µs per step against a ``mixed`` step
   (:mod:`runners.benchmarks.recorded`).
8. Side by side with the commit issue #19 was filed against: CPU time per step on ``mixed`` with and without
   logging, each tree in its own child process, alternated (:mod:`runners.benchmarks.baseline`).
9. The main job (:mod:`runners.benchmarks.main_job`): ``sweep efficiency`` (the default sweep's episodes/s as a
   whole command / (cores x the same episodes in one plain process)), the time to the first step of
   ``runners.run``, the report's episodes/s against the metrics alone (in one warm process, and as a cold command
   on every core); in the full run also each compiled kernel's end-to-end gain on the documented workloads (each
   kernel off in turn, ``FUZZYNAV_KERNELS_OFF``; the ORCA kernel's is the ORCA crowd sweep), and a 1,000-episode
   sweep's efficiency, on these cores and on 16 by simulation of the launcher's schedule from the measured jobs.
10. Tuning (:mod:`runners.benchmarks.tuning`, issue #39): trials per minute of ``runners.tune``'s trial loop and
    the study machinery's overhead over the same episodes run plainly.
11. Issue #19's and issue #36's targets, each with its value, threshold and verdict
    (:mod:`runners.benchmarks.targets`).

Times are medians of repetitions after a warm-up where it applies; ratios are from the same run.
Writes ``bench.json`` (path with ``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
import warnings
from pathlib import Path
from typing import Any

from runners.benchmarks.fuzzy import bench_fuzzy, print_fuzzy
from runners.benchmarks.results_file import out_problem, write_results
from runners.benchmarks.simulation import _scenario_and_config, bench_simulation


def _own_compute(episodes: int, first_seed: int = 0) -> float:
    """Seconds to run ``episodes`` logged ``head_on`` episodes (seeds from ``first_seed``) one after the other
    in this process."""
    import tempfile

    from runners.run import run_episode

    scenario, evaluator, cfg = _scenario_and_config("head_on")
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        for seed in range(first_seed, first_seed + episodes):
            run_episode(scenario, evaluator, cfg, seed, Path(tmp) / f"{seed}.mcap", "")
        return time.perf_counter() - t


def _share_after_barrier(args: tuple[int, int, Any]) -> float:
    """In a worker of :func:`_own_compute_all_cores`: warm up, wait for the others, run this share; seconds."""
    episodes, first_seed, barrier = args
    _own_compute(5, first_seed=10**6)  # imports and caches, outside the timing
    barrier.wait()
    return _own_compute(episodes, first_seed)


def _own_compute_all_cores(episodes: int, cores: int) -> float:
    """Wall seconds for the same ``episodes`` split over ``cores`` plain processes that start together: every
    core busy, as in a sweep, with no launcher or Hydra (cores share caches and memory bandwidth, so this is
    usually slower than one core's time divided by the cores)."""
    import multiprocessing

    shares = [episodes // cores + (i < episodes % cores) for i in range(cores)]
    firsts = [sum(shares[:i]) for i in range(cores)]
    context = multiprocessing.get_context("spawn")
    with context.Manager() as manager:
        barrier = manager.Barrier(cores + 1)
        with context.Pool(cores) as pool:
            done = pool.map_async(_share_after_barrier, [(n, f, barrier) for n, f in zip(shares, firsts, strict=True)])
            barrier.wait()
            t = time.perf_counter()
            done.get()
            return time.perf_counter() - t


def _sweep_once(episodes: int, per_job: int) -> dict:
    """Wall time and phases of one real ``runners.sweep`` of ``head_on`` episodes, ``per_job`` seeds a job.

    Phases come from the files the sweep writes: start-up (interpreter, imports, config checks) until Hydra
    writes ``multirun.yaml``; then job validation and worker start until the first job's ``.hydra/``
    snapshot; episodes until the last log; summary; report."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "s"
        t0 = time.time()
        res = subprocess.run([sys.executable, "-m", "runners.sweep", "sweep=quick", "scenario=head_on", "planner=auto",
                              f"seed=range(0,{episodes},{per_job})", f"episodes={per_job}", f"hydra.sweep.dir={out}"],
                             cwd=tmp, capture_output=True, text=True)
        wall = time.time() - t0
        if res.returncode != 0:
            raise RuntimeError(f"sweep failed: {res.stderr[-500:]}")
        first_job = min(p.stat().st_mtime for p in out.glob("*/.hydra/config.yaml"))
        last_log = max(p.stat().st_mtime for p in out.rglob("*.mcap"))
        marks = {"start-up": (out / "multirun.yaml").stat().st_mtime, "validation + workers": first_job,
                 "episodes": last_log, "summary": (out / "summary.csv").stat().st_mtime,
                 "report": (out / "report" / "report.html").stat().st_mtime}
    phases, previous = {}, t0
    for name, mark in marks.items():
        phases[name] = mark - previous
        previous = mark
    return {"jobs": episodes // per_job, "episodes_per_job": per_job, "wall_s_to_summary": marks["summary"] - t0,
            "wall_s_with_report": wall, "phases_s": phases}


def bench_sweep(episodes: int, rounds: int = 3) -> dict:
    """Real sweeps of ``episodes`` short episodes (``head_on``) on all cores, seeds batched into Hydra jobs as
    the presets do: as two jobs per core (the README's advice for a seed sweep) and as 20 shorter jobs (the
    per-job cost visible). Against the same episodes' own compute time, measured two ways: one after the other
    in this process before and after all rounds, divided by the cores (``ideal``); and split over one plain
    process per core (:func:`_own_compute_all_cores`), run right before the sweeps of each round, so that a
    slow spell of the machine hits a sweep and its reference alike. Each shape reports the round with the
    median ratio to its all-cores run."""
    cores = os.cpu_count() or 1
    before = _own_compute(episodes)
    per_round = []
    for _ in range(rounds):
        all_cores = _own_compute_all_cores(episodes, cores)
        shapes = [_sweep_once(episodes, episodes // jobs) for jobs in (2 * cores, 20)]
        for shape in shapes:
            shape.update(all_cores_s=all_cores, wall_over_all_cores=shape["wall_s_to_summary"] / all_cores)
        per_round.append(shapes)
    after = _own_compute(episodes)
    ideal = (before + after) / 2 / cores
    shapes = []
    for k in range(len(per_round[0])):
        runs = sorted((r[k] for r in per_round), key=lambda shape: shape["wall_over_all_cores"])
        shape = dict(runs[len(runs) // 2])
        shape.update(wall_over_ideal=shape["wall_s_to_summary"] / ideal,
                     wall_with_report_over_ideal=shape["wall_s_with_report"] / ideal,
                     rounds_over_all_cores=[r[k]["wall_over_all_cores"] for r in per_round],
                     rounds_over_ideal=[r[k]["wall_s_to_summary"] / ideal for r in per_round])
        shapes.append(shape)
    return {"episodes": episodes, "cores": cores, "rounds": rounds, "own_compute_s_before": before,
            "own_compute_s_after": after, "ideal_s": ideal, "shapes": shapes}


def bench_analysis(episodes: int, reps: int = 3) -> dict:
    """Metrics table throughput on logs of ~100-step episodes (``overtaking``), one core: the median of ``reps``
    timings of the whole table (this machine's speed drifts by up to a third between two such runs a second
    apart; the best of them is kept too)."""
    import tempfile

    from analysis.episode_log import METRIC_TOPICS
    from analysis.logs import iter_messages
    from analysis.metrics import metrics_table
    from runners.run import run_episode

    scenario, evaluator, cfg = _scenario_and_config("overtaking")
    with tempfile.TemporaryDirectory() as tmp:
        logs = [Path(tmp) / f"{seed}.mcap" for seed in range(episodes)]
        for seed, path in enumerate(logs):
            run_episode(scenario, evaluator, cfg, seed, path, "")
        metrics_table([str(p) for p in logs[:2]])  # warm-up (imports)
        times = []
        for _ in range(reps):
            t = time.perf_counter()
            df, _ = metrics_table([str(p) for p in logs])
            times.append(time.perf_counter() - t)
        seconds = statistics.median(times)
        messages = sum(1 for p in logs for _ in iter_messages(p, METRIC_TOPICS))
    return {"scenario": "overtaking", "episodes": len(df), "seconds": seconds, "episodes_per_s": len(df) / seconds,
            "episodes_per_s_best": len(df) / min(times), "repetitions": reps,
            "messages_per_s": messages / seconds, "mean_steps": float(df["steps"].mean())}


def bench_memory(episodes: int) -> dict:
    """RSS of this process while running ``episodes`` logged episodes: after 10 %, and at the end."""
    import tempfile

    from runners.run import run_episode

    def rss_mb() -> float:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * (os.sysconf("SC_PAGE_SIZE") / 1e6)

    scenario, evaluator, cfg = _scenario_and_config("head_on")
    early = None
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(episodes):
            path = Path(tmp) / "ep.mcap"
            path.unlink(missing_ok=True)  # one file reused (bounded disk use); a log never replaces another's
            run_episode(scenario, evaluator, cfg, k, path, "")
            if k + 1 == episodes // 10:
                early = rss_mb()
    late = rss_mb()
    return {"episodes": episodes, "rss_mb_at_10pct": early, "rss_mb_at_end": late,
            "growth": (late - early) / early if early else float("nan")}


def kernels_line(in_use: dict[str, bool], built: dict[str, bool], switched_off: bool) -> str:
    """The bench's first line: which compiled kernels (full module names in ``in_use``, short names in ``built``)
    are in use, and for the others why their Python/numpy form runs — not built at install (no C compiler),
    ``FUZZYNAV_KERNEL=python``, or named in ``FUZZYNAV_KERNELS_OFF``."""
    def why(name: str) -> str:
        return ("not built at install: no C compiler?" if not built.get(name.rpartition(".")[2], False) else
                "FUZZYNAV_KERNEL=python" if switched_off else "FUZZYNAV_KERNELS_OFF")

    head = "compiled kernels (fuzzynav/numerics/compiled.py): "
    off = [name for name, on in in_use.items() if not on]
    if not off:  # (one kernel: its name, not "all 1")
        return head + (f"all {len(in_use)} in use" if len(in_use) > 1 else
                       ", ".join(f"{name.rpartition('.')[2]} in use" for name in in_use))
    reasons = {why(name) for name in off}
    if len(off) == len(in_use) and len(reasons) == 1:
        return head + f"none in use, the Python/numpy forms run ({reasons.pop()})"
    return head + f"{len(in_use) - len(off)} of {len(in_use)} in use; " + ", ".join(
        f"{name.rpartition('.')[2]} Python/numpy form ({why(name)})" for name in off)


def bytecode_line() -> str:
    """Turn Python's bytecode cache on for the commands timed below (they inherit this environment), and say so.

    A user's Python writes ``__pycache__/`` on a module's first import and reads it from then on; with
    ``PYTHONDONTWRITEBYTECODE`` set (some containers and sandboxes set it) every command compiles fuzzynav's ~200
    modules again, which adds about 0.1 s to each process's start (a run's first step, each sweep worker, the report)
    and is not what a user's commands cost. Each figure's first round writes the cache."""
    was = os.environ.pop("PYTHONDONTWRITEBYTECODE", None)
    sys.dont_write_bytecode = False
    note = " (PYTHONDONTWRITEBYTECODE was set: unset for the commands timed, as a user's Python has it)" if was else ""
    return f"bytecode cache: on{note}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true",
                        help="reduced sizes, without the 1,000-episode sweep and the kernels' table (a few minutes)")
    parser.add_argument("--out", default="bench.json", help="where to write the results (JSON)")
    args = parser.parse_args(argv)
    problem = out_problem(Path(args.out))
    if problem:
        print(f"error: --out: {problem}", file=sys.stderr)
        return 2
    warnings.filterwarnings("ignore", category=DeprecationWarning)
    n_single, n_ref, reps = (200, 20, 3) if args.quick else (1000, 200, 7)
    from fuzzynav.numerics import compiled

    kernels = {name: compiled.load(name) is not None and not compiled.switched_off()
               for name in compiled.KERNELS}
    # first, before any timing: which forms the numbers below are of (an install without a C compiler builds no
    # kernel and says so nowhere else)
    print(kernels_line(kernels, compiled.built(), compiled.switched_off()), flush=True)
    bytecode = bytecode_line()
    print(bytecode, flush=True)
    results = {"machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine(),
                           "system": platform.platform(), "compiled_kernels": kernels,
                           "kernels_built": compiled.built(), "kernels": compiled.in_use(), "bytecode": bytecode},
               "quick": args.quick, "fuzzy": [bench_fuzzy(n, n_single, n_ref, 2_000 if args.quick else 10_000, reps)
                                              for n in ("table1", "listing")]}
    results["simulation"] = bench_simulation(3, 1) if args.quick else bench_simulation(20, 7)
    results["sweep"] = bench_sweep(100, rounds=1) if args.quick else bench_sweep(1000)
    results["analysis"] = bench_analysis(20 if args.quick else 200)
    results["memory"] = bench_memory(60 if args.quick else 1000)
    print_fuzzy(results["fuzzy"])
    sim = results["simulation"]
    print(f"\nsimulation ({sim['scenario']}, laser perception, {sim['steps']} steps, median of "
          f"{sim['repetitions']}): "
          f"{sim['steps_per_s_without_logging']:.0f} steps/s without logging, "
          f"{sim['steps_per_s_with_logging']:.0f} with; logging is {sim['logging_share_of_step']:.0%} of a step "
          f"(median of the pairs: {', '.join(f'{x:.0%}' for x in sim['logging_share_per_pair'])})")
    print("  µs per step: " + ", ".join(f"{k} {v:.0f}" for k, v in sim["us_per_step_by_stage"].items()))
    sw = results["sweep"]
    print(f"sweep: {sw['episodes']} episodes on {sw['cores']} cores, {sw['rounds']} round(s): own compute "
          f"{sw['own_compute_s_before']:.1f} s before and {sw['own_compute_s_after']:.1f} s after -> ideal "
          f"{sw['ideal_s']:.1f} s; each round also runs them on all cores without launcher or Hydra first")
    for shape in sw["shapes"]:
        rounds = ", ".join(f"{r:.2f}" for r in shape["rounds_over_all_cores"])
        print(f"  {shape['jobs']} jobs x {shape['episodes_per_job']}: {shape['wall_over_all_cores']:.2f} x the "
              f"all-cores run (rounds: {rounds}); that round: wall to summary {shape['wall_s_to_summary']:.1f} s "
              f"vs all-cores {shape['all_cores_s']:.1f} s, {shape['wall_over_ideal']:.2f} x ideal; with the report "
              f"{shape['wall_s_with_report']:.1f} s = {shape['wall_with_report_over_ideal']:.2f} x ideal")
        print("    phases (s): " + ", ".join(f"{k} {v:.1f}" for k, v in shape["phases_s"].items()))
    an = results["analysis"]
    print(f"analysis: {an['episodes_per_s']:.1f} episodes/s (median of {an['repetitions']}; best "
          f"{an['episodes_per_s_best']:.1f}), {an['messages_per_s']:.0f} messages/s ({an['episodes']} "
          f"{an['scenario']} episodes of {an['mean_steps']:.0f} steps); target 4 of issue #19 (>= 200 episodes/s): "
          f"{an['episodes_per_s'] / 200:.2f} of it")
    mem = results["memory"]
    print(f"memory: RSS {mem['rss_mb_at_10pct']:.1f} MB after {mem['episodes'] // 10} episodes, "
          f"{mem['rss_mb_at_end']:.1f} MB after {mem['episodes']} ({mem['growth']:+.1%})")
    from runners.benchmarks.report import bench_report, summary_line  # the report for 10,000 episodes (#18)

    results["report"] = bench_report(1000, 2) if args.quick else bench_report(10_000, 10)
    print(summary_line(results["report"]))
    from runners.benchmarks.crowd import bench_crowd, print_crowd  # 20 reactive pedestrians (#17)

    results["crowd"] = bench_crowd(2 if args.quick else 10)
    print_crowd(results["crowd"])
    from runners.benchmarks.recorded import bench_recorded, print_recorded  # 300 recorded people (#38)

    results["recorded"] = bench_recorded(1, 120) if args.quick else bench_recorded(3)
    print_recorded(results["recorded"])
    from runners.benchmarks.main_job import (
        bench_kernels,
        bench_large_sweep,
        bench_main_job,
        print_kernels,
        print_large_sweep,
        print_main_job,
    )

    results["main_job"] = bench_main_job(rounds=1 if args.quick else 3)  # issue #36: the job a user runs
    print_main_job(results["main_job"])
    if not args.quick:  # the 1,000-episode sweep and its plain twin: about 2 minutes (main_job.FULL_RUN_ONLY)
        results["large_sweep"] = bench_large_sweep()
        print_large_sweep(results["large_sweep"])
    if not args.quick:  # each kernel off in turn on every documented workload: several minutes
        results["kernels"] = bench_kernels(rounds=2)
        print_kernels(results["kernels"])
    from runners.benchmarks.tuning import bench_tuning, tuning_line  # issue #39: the study machinery's cost

    results["tuning"] = bench_tuning(5, 4) if args.quick else bench_tuning(20, 10)
    print(tuning_line(results["tuning"]))
    from runners.benchmarks.baseline import bench_baseline, print_baseline  # target 3, side by side
    from runners.benchmarks.targets import main_job_targets, print_targets, targets

    results["baseline"] = bench_baseline(rounds=1, episodes=3, passes=1) if args.quick else bench_baseline()
    print_baseline(results["baseline"])
    results["targets"] = [t.as_dict() for t in targets(results)]
    results["main_job_targets"] = [t.as_dict() for t in main_job_targets(results)]
    print()
    print_targets(results)
    written, problem = write_results(Path(args.out), json.dumps(results, indent=2))
    if problem:
        print(f"error: --out: {problem}", file=sys.stderr)
        return 1
    print(f"wrote {written}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
