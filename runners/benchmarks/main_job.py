"""The main job as a user runs it, measured side by side with what the machine could do (issue #36).

* **Sweep efficiency**: the default sweep (``python -m runners.sweep``, 105 episodes) as a whole command, against
  the same episodes in one plain process (configs composed once per group outside the timing, logs written):
  ``efficiency = sweep episodes/s / (cores x plain episodes/s)``. Reported for the whole command (start-up,
  Hydra, the jobs, the summary and the report) and for its episodes phase (the first log to the last).
* **Time to the first step** of ``python -m runners.run`` (one episode): from the process's start to its log
  file appearing (the log is opened just before the first step).
* **Report speed**: ``python -m analysis.report`` on the default sweep's logs, in episodes/s, against the metrics
  alone (:func:`analysis.metrics.analyse_logs` in one process) on the same logs. The report is a whole command
  (start-up, imports, figures) on every core: it reads the logs and draws its figures in forked workers. Beside it,
  the same report against the metrics as a cold command on every core (:func:`metrics_command_seconds`: start-up,
  imports and the forked readers, as the report has them), so that what the report adds (its tables and figures)
  shows apart from what any command pays.
* **Kernels end to end** (:func:`bench_kernels`): each compiled kernel left off in turn
  (``FUZZYNAV_KERNELS_OFF``) on the documented workloads, as ratios to all kernels on, alternated in each round.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from fuzzynav.numerics import compiled

DEFAULT_SCENARIOS = ("paper_fig5", "head_on", "cyclist_crossing")  # conf/sweep/default.yaml
DEFAULT_PLANNERS = ("auto_h1", "auto_h2", "auto_h3", "auto_h4", "wait", "detour", "none")
DEFAULT_EPISODES = 5


def plain_process_seconds(seeds: range = range(DEFAULT_EPISODES)) -> tuple[int, float]:
    """(episodes, seconds) of the default sweep's configurations with ``seeds``, run one after the other in this
    process, with their logs; each group's config is composed before its episodes (outside the timing: composing is
    the sweep's overhead)."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from fuzzynav.conf import CONF_DIR
    from runners.configuration import schema
    from runners.logs import yaml_text
    from runners.run import config_hash, episode_config, load_evaluator, load_scenario, log_path, run_episode

    schema.register()
    n, seconds = 0, 0.0
    with tempfile.TemporaryDirectory() as tmp, initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        for scenario in DEFAULT_SCENARIOS:
            for planner in DEFAULT_PLANNERS:
                cfg = compose("config", overrides=[f"scenario={scenario}", f"planner={planner}"])
                plain = OmegaConf.to_container(cfg, resolve=True)
                text = yaml_text.config_text(cfg, resolve=True)
                evaluator, ep_cfg = load_evaluator(plain), episode_config(plain)
                tic = time.perf_counter()
                for seed in seeds:
                    world = load_scenario(plain, seed)
                    run_episode(world, evaluator, ep_cfg, seed, log_path(Path(tmp), world.name, plain, seed), text,
                                config_hash(text, seed))
                    n += 1
                seconds += time.perf_counter() - tic
    return n, seconds


def sweep_command(out: Path, *overrides: str) -> dict[str, Any]:
    """The default sweep (with ``overrides``) into ``out``: its wall time, when its first and last logs were written
    (s from the start), and each job's span (:func:`job_spans`)."""
    start_wall = time.time()
    tic = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "runners.sweep", *overrides, f"hydra.sweep.dir={out}"],
                         capture_output=True, text=True, timeout=3600, stdin=subprocess.DEVNULL)
    wall = time.perf_counter() - tic
    if res.returncode != 0:
        raise RuntimeError(f"the default sweep failed: {res.stderr[-500:]}")
    times = sorted(p.stat().st_mtime for p in out.glob("*/*.mcap"))
    return {"wall_s": wall, "episodes": len(times), "first_log_s": times[0] - start_wall,
            "last_log_s": times[-1] - start_wall, **schedule(out, start_wall, wall)}


def schedule(sweep_dir: Path, start_wall: float, wall: float) -> dict[str, Any]:
    """The sweep's jobs as the simulation (:func:`simulated_wall_s`) takes them: each job's span in job order, from
    its ``.hydra/`` snapshot (written as the job starts) to its last log, plus an equal share of the time the workers
    spent between jobs (making the next config, the hand-off, waiting: cores x the jobs' phase - the spans' sum);
    the time before the first job starts and after the last log."""
    starts, ends = [], []
    for job in sorted((p.parent.parent for p in sweep_dir.glob("*/.hydra/config.yaml")), key=lambda p: int(p.name)):
        logs = [p.stat().st_mtime for p in job.glob("*.mcap")]
        if logs:
            starts.append((job / ".hydra" / "config.yaml").stat().st_mtime)
            ends.append(max(logs))
    if not starts:
        return {"job_spans_s": [], "before_jobs_s": wall, "after_jobs_s": 0.0}
    spans = [e - b for b, e in zip(starts, ends, strict=True)]
    phase = max(ends) - min(starts)
    gap = max(0.0, ((os.cpu_count() or 1) * phase - sum(spans)) / len(spans))
    return {"job_spans_s": [span + gap for span in spans], "before_jobs_s": min(starts) - start_wall,
            "after_jobs_s": start_wall + wall - max(ends)}


def simulated_wall_s(spans: list[float], workers: int, before_s: float, after_s: float) -> tuple[float, float]:
    """(whole command, episodes phase) on ``workers`` cores, by simulation of the launcher's schedule: each job,
    in order, goes to the first worker free (as joblib hands them out), taking its measured span; the time before the
    first job and after the last log are the measured ones (both run in the launching process and do not shrink with
    more cores). Assumes a core of that machine as fast as this one's, and the same per-job cost; the launching
    process's share of a job (~0.1 ms: its overrides pickled) is not a bottleneck at that count."""
    import heapq

    free = [0.0] * workers
    end = 0.0
    for span in spans:
        start = heapq.heappop(free)
        heapq.heappush(free, start + span)
        end = max(end, start + span)
    return before_s + end + after_s, end


def first_step_seconds(out: Path) -> float:
    """Seconds from starting ``python -m runners.run episodes=1`` to its log file appearing."""
    tic = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "runners.run", f"hydra.run.dir={out}"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL)
    seen = None
    while proc.poll() is None and seen is None:
        if out.is_dir() and any(".mcap" in p.name for p in out.iterdir()):  # the partial log, then the log
            seen = time.perf_counter() - tic
        time.sleep(0.002)
    proc.wait(timeout=300)
    if seen is None:  # ended before a poll saw it: the whole run is an upper bound
        seen = time.perf_counter() - tic
    return seen


def report_seconds(logs: Path, out: Path) -> float:
    tic = time.perf_counter()
    res = subprocess.run([sys.executable, "-m", "analysis.report", str(logs), "--out", str(out)], capture_output=True,
                         text=True, timeout=1800, stdin=subprocess.DEVNULL)
    if res.returncode != 0:
        raise RuntimeError(f"analysis.report failed: {res.stderr[-500:]}")
    return time.perf_counter() - tic


def metrics_seconds(logs: Path) -> float:
    """Seconds of :func:`analysis.metrics.analyse_logs` on ``logs`` in this process, warm: its libraries loaded
    before the timing (pandas too, which the module defers: :mod:`analysis.deferred`)."""
    from analysis import metrics
    from analysis.deferred import load
    from analysis.metrics import analyse_logs

    load(metrics.pd)
    tic = time.perf_counter()
    analyse_logs([logs], jobs=1)
    return time.perf_counter() - tic


METRICS_COMMAND = "import sys; from analysis.metrics import analyse_logs; analyse_logs(sys.argv[1:], jobs=-1)"
"""The metrics alone as a command: a fresh interpreter, :func:`analysis.metrics.analyse_logs` on every core (its
readers forked, as the report's are)."""


def metrics_command_seconds(logs: Path) -> float:
    """Seconds of :data:`METRICS_COMMAND` on ``logs``, from its start to its exit."""
    tic = time.perf_counter()
    res = subprocess.run([sys.executable, "-c", METRICS_COMMAND, str(logs)], capture_output=True, text=True,
                         timeout=1800, stdin=subprocess.DEVNULL)
    if res.returncode != 0:
        raise RuntimeError(f"the metrics command failed: {res.stderr[-500:]}")
    return time.perf_counter() - tic


def bench_main_job(rounds: int = 3) -> dict[str, Any]:
    """Each figure's median over ``rounds``, the sweep and the plain process alternated."""
    cores = os.cpu_count() or 1
    rows: dict[str, list[float]] = {k: [] for k in ("sweep_wall_s", "sweep_first_log_s", "sweep_last_log_s",
                                                    "plain_s", "first_step_s", "report_s", "metrics_s",
                                                    "metrics_command_s", "sim_wall_s", "sim_phase_s")}
    episodes = 0
    for _ in range(rounds):
        with tempfile.TemporaryDirectory() as tmp:
            sweep = sweep_command(Path(tmp) / "sweep")
            episodes = int(sweep["episodes"])
            rows["sweep_wall_s"].append(sweep["wall_s"])
            rows["sweep_first_log_s"].append(sweep["first_log_s"])
            rows["sweep_last_log_s"].append(sweep["last_log_s"])
            sim = simulated_wall_s(sweep["job_spans_s"], SIMULATED_CORES, sweep["before_jobs_s"],
                                   sweep["after_jobs_s"])
            rows["sim_wall_s"].append(sim[0])
            rows["sim_phase_s"].append(sim[1])
            n, plain = plain_process_seconds()
            if n != episodes:
                raise RuntimeError(f"the plain process ran {n} episodes, the sweep {episodes}")
            rows["plain_s"].append(plain)
            rows["first_step_s"].append(first_step_seconds(Path(tmp) / "run"))
            rows["report_s"].append(report_seconds(Path(tmp) / "sweep", Path(tmp) / "report"))
            rows["metrics_s"].append(metrics_seconds(Path(tmp) / "sweep"))
            rows["metrics_command_s"].append(metrics_command_seconds(Path(tmp) / "sweep"))
    med = {k: statistics.median(v) for k, v in rows.items()}
    plain_rate = episodes / med["plain_s"]
    out = {"cores": cores, "episodes": episodes, "rounds": rounds, **med,
           "plain_episodes_per_s": plain_rate,
           "sweep_episodes_per_s": episodes / med["sweep_wall_s"],
           "sweep_efficiency": episodes / med["sweep_wall_s"] / (cores * plain_rate),
           "sweep_efficiency_to_last_log": episodes / med["sweep_last_log_s"] / (cores * plain_rate),
           "episodes_phase_efficiency": episodes / max(med["sweep_last_log_s"] - med["sweep_first_log_s"], 1e-9)
           / (cores * plain_rate),
           "simulated_cores": SIMULATED_CORES,
           "simulated_sweep_efficiency": episodes / med["sim_wall_s"] / (SIMULATED_CORES * plain_rate),
           "simulated_episodes_phase_efficiency": episodes / med["sim_phase_s"] / (SIMULATED_CORES * plain_rate),
           "report_episodes_per_s": episodes / med["report_s"],
           "metrics_episodes_per_s": episodes / med["metrics_s"],
           "metrics_command_episodes_per_s": episodes / med["metrics_command_s"]}
    out["report_over_metrics"] = out["report_episodes_per_s"] / out["metrics_episodes_per_s"]
    out["report_over_metrics_command"] = out["report_episodes_per_s"] / out["metrics_command_episodes_per_s"]
    return out


#: the 1,000-episode sweep: the default sweep's 21 configurations x 48 seeds, in jobs of 8 episodes (126 jobs; the
#: way docs/sweeps.md writes a long sweep: seed blocks)
LARGE_SWEEP = ("episodes=8", "seed=range(0,48,8)")
LARGE_SEEDS = range(48)
SIMULATED_CORES = 16
#: the sections of bench.json only the full run measures (``runners.bench --quick`` leaves them out: minutes each)
FULL_RUN_ONLY = ("large_sweep", "kernels")


def bench_large_sweep(rounds: int = 2) -> dict[str, Any]:
    """The 1,000-episode sweep against the same episodes in one plain process (alternated, medians of ``rounds``), on
    this machine's cores and on :data:`SIMULATED_CORES` by :func:`simulated_wall_s` from this machine's job spans."""
    cores = os.cpu_count() or 1
    rows: dict[str, list[float]] = {k: [] for k in ("wall_s", "first_log_s", "last_log_s", "plain_s", "sim_wall_s",
                                                    "sim_phase_s", "report_s", "metrics_s")}
    episodes = 0
    for _ in range(rounds):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "sweep"
            sweep = sweep_command(out, *LARGE_SWEEP)
            episodes = int(sweep["episodes"])
            n, plain = plain_process_seconds(LARGE_SEEDS)
            if n != episodes:
                raise RuntimeError(f"the plain process ran {n} episodes, the sweep {episodes}")
            sim_wall, sim_phase = simulated_wall_s(sweep["job_spans_s"], SIMULATED_CORES, sweep["before_jobs_s"],
                                                   sweep["after_jobs_s"])
            # the report on these logs against the metrics alone, as for the default sweep: its fixed costs
            # (start-up, imports, a few figures) weigh less on 1,000 episodes than on 105
            report, metrics = report_seconds(out, Path(tmp) / "report"), metrics_seconds(out)
            for key, value in (("wall_s", sweep["wall_s"]), ("first_log_s", sweep["first_log_s"]),
                               ("last_log_s", sweep["last_log_s"]), ("plain_s", plain), ("sim_wall_s", sim_wall),
                               ("sim_phase_s", sim_phase), ("report_s", report), ("metrics_s", metrics)):
                rows[key].append(value)
    med = {k: statistics.median(v) for k, v in rows.items()}
    rate = episodes / med["plain_s"]
    return {"cores": cores, "episodes": episodes, "rounds": rounds, "overrides": list(LARGE_SWEEP), **med,
            "plain_episodes_per_s": rate,
            "sweep_efficiency": episodes / med["wall_s"] / (cores * rate),
            "episodes_phase_efficiency": episodes / max(med["last_log_s"] - med["first_log_s"], 1e-9) / (cores * rate),
            "simulated_cores": SIMULATED_CORES,
            "simulated_sweep_efficiency": episodes / med["sim_wall_s"] / (SIMULATED_CORES * rate),
            "simulated_episodes_phase_efficiency": episodes / med["sim_phase_s"] / (SIMULATED_CORES * rate),
            "report_episodes_per_s": episodes / med["report_s"], "metrics_episodes_per_s": episodes / med["metrics_s"],
            "report_over_metrics": med["metrics_s"] / med["report_s"]}


def print_large_sweep(r: dict[str, Any]) -> None:
    print(f"\n== A 1,000-episode sweep ({r['episodes']} episodes: the default sweep with {' '.join(r['overrides'])}), "
          f"medians of {r['rounds']} rounds ==")
    print(f"sweep efficiency (1,000 episodes): {r['sweep_efficiency']:.2f} on {r['cores']} cores (the whole command, "
          f"{r['wall_s']:.1f} s against {r['cores']} x {r['plain_episodes_per_s']:.1f} episodes/s in one plain "
          f"process); its episodes phase alone: {r['episodes_phase_efficiency']:.2f}")
    print(f"  on {r['simulated_cores']} cores, by simulation of the schedule from these job spans: "
          f"{r['simulated_sweep_efficiency']:.2f} (whole command, {r['sim_wall_s']:.1f} s), episodes phase "
          f"{r['simulated_episodes_phase_efficiency']:.2f}")
    if "report_s" in r:  # (a results file of an earlier bench has no report on these logs)
        print(f"report ({r['episodes']} episodes): {r['report_episodes_per_s']:.1f} episodes/s "
              f"({r['report_s']:.1f} s), the metrics alone {r['metrics_episodes_per_s']:.1f} episodes/s: "
              f"report / metrics = {r['report_over_metrics']:.2f}")


def print_main_job(r: dict[str, Any]) -> None:
    print(f"\n== The main job: the default sweep ({r['episodes']} episodes) on {r['cores']} cores, medians of "
          f"{r['rounds']} rounds ==")
    print(f"sweep efficiency: {r['sweep_efficiency']:.2f}  (the whole command, {r['sweep_wall_s']:.1f} s: "
          f"{r['sweep_episodes_per_s']:.1f} episodes/s against {r['cores']} x {r['plain_episodes_per_s']:.1f} "
          "in one plain process)")
    print(f"  to its last log: {r['sweep_efficiency_to_last_log']:.2f} (first log after {r['sweep_first_log_s']:.1f} s,"
          f" last after {r['sweep_last_log_s']:.1f} s); its episodes phase alone: "
          f"{r['episodes_phase_efficiency']:.2f}")
    print(f"  on {r['simulated_cores']} cores, by simulation of the schedule from these job spans: "
          f"{r['simulated_sweep_efficiency']:.2f} (whole command), episodes phase "
          f"{r['simulated_episodes_phase_efficiency']:.2f}")
    print(f"time to first step of runners.run: {r['first_step_s']:.2f} s")
    print(f"report: {r['report_episodes_per_s']:.1f} episodes/s ({r['report_s']:.1f} s), the metrics alone "
          f"{r['metrics_episodes_per_s']:.1f} episodes/s: report / metrics = {r['report_over_metrics']:.2f}")
    print(f"  against the metrics as a cold command on every core ({r['metrics_command_s']:.2f} s, "
          f"{r['metrics_command_episodes_per_s']:.1f} episodes/s): report / metrics command = "
          f"{r['report_over_metrics_command']:.2f}")


#: documented workloads (docs/quickstart, docs/crowds.md, docs/datasets.md): (name, python -m arguments; {t} is a
#: fresh temporary folder)
KERNEL_WORKLOADS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("default sweep", ("runners.sweep", "hydra.sweep.dir={t}/o")),
    ("crowd sweep (docs/crowds.md)", ("runners.sweep", "scenario=crowd_crossing", "scenario.params.n=5,10,20",
                                      "planner=auto,wait,detour,none", "hydra.sweep.dir={t}/o")),
    # the kept kernel's workload: a sweep of ORCA crowds (a single run of one is mostly start-up)
    ("orca crowd sweep (docs/crowds.md)", ("runners.sweep", "scenario=crowd_crossing", "scenario.params.model=orca",
                                           "scenario.params.n=20,40", "episodes=4", "hydra.sweep.dir={t}/o")),
    ("dataset verify paper_fig5", ("runners.dataset", "verify", "paper_fig5")),
)


def bench_kernels(rounds: int = 2, workloads: tuple[tuple[str, tuple[str, ...]], ...] = KERNEL_WORKLOADS
                  ) -> dict[str, Any]:
    """Each workload's wall time with every kernel on, with each kernel off in turn and, when more than one kernel
    is built, with all off; the order of the settings alternates between rounds. Returns the medians and the ratios
    off / on."""
    built = [k for k, ok in compiled.built().items() if ok]
    settings = [("all on", ""), *((k, k) for k in built)]
    if len(built) > 1:  # (with one kernel, all off is that kernel off: the same setting timed twice)
        settings.append(("all off", ",".join(built)))
    times: dict[str, dict[str, list[float]]] = {w: {s: [] for s, _ in settings} for w, _ in workloads}
    for rnd in range(rounds):
        for name, args in workloads:
            for label, off in settings if rnd % 2 == 0 else settings[::-1]:
                with tempfile.TemporaryDirectory() as tmp:
                    env = {**os.environ, compiled.KERNELS_OFF_ENV: off, compiled.KERNEL_ENV: ""}
                    tic = time.perf_counter()
                    res = subprocess.run([sys.executable, "-m", *(a.format(t=tmp) for a in args)], env=env,
                                         capture_output=True, text=True, timeout=3600, cwd=tmp,
                                         stdin=subprocess.DEVNULL)
                    times[name][label].append(time.perf_counter() - tic)
                    if res.returncode != 0:
                        raise RuntimeError(f"{name} with {label} off failed: {res.stderr[-500:]}")
    medians = {w: {s: statistics.median(v) for s, v in by.items()} for w, by in times.items()}
    gains = {w: {s: m[s] / m["all on"] for s in m if s != "all on"} for w, m in medians.items()}
    return {"rounds": rounds, "medians_s": medians, "gain": gains}


def print_kernels(r: dict[str, Any]) -> None:
    """A row per kernel: its end-to-end gain (time without it / with it) on each workload, and the best."""
    workloads = list(r["gain"])
    print(f"\n== Kernels end to end: time with the kernel off / all on, medians of {r['rounds']} rounds ==")
    print("kernel".ljust(20) + "".join(w[:24].rjust(26) for w in workloads) + "best".rjust(8))
    kernels = list(next(iter(r["gain"].values())))
    for k in kernels:
        gains = [r["gain"][w][k] for w in workloads]
        print(k.ljust(20) + "".join(f"{g:26.2f}" for g in gains) + f"{max(gains):8.2f}")
    print("workload, all on (s)".ljust(20) + "".join(f"{r['medians_s'][w]['all on']:26.1f}" for w in workloads))
