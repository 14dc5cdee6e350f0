"""The simulation's benchmark (``python -m runners.bench``): steps per second of the ``mixed`` scenario with and
without logging, and the wall time per step by stage. ``_scenario_and_config`` is also the side-by-side baseline's
way into a tree (:mod:`runners.benchmarks.baseline`)."""

from __future__ import annotations

import statistics
import time
from pathlib import Path

import yaml

from fuzzynav.conf import CONF_DIR as CONF
from runners.benchmarks.stage_timers import stage_timers


def _scenario_and_config(name: str):
    from runners.run import episode_config, load_evaluator, load_scenario

    base = {"sensors": yaml.safe_load((CONF / "sensors" / "default.yaml").read_text()),
            "navigator": yaml.safe_load((CONF / "navigator" / "fuzzy_tpt.yaml").read_text()),
            "planner": yaml.safe_load((CONF / "planner" / "auto.yaml").read_text()),
            "scenario": yaml.safe_load((CONF / "scenario" / f"{name}.yaml").read_text()),
            "controller": yaml.safe_load((CONF / "controller" / "table1.yaml").read_text())}
    return load_scenario(base), load_evaluator(base), episode_config(base)


def bench_simulation(episodes: int, reps: int) -> dict:
    """Steps/s on ``mixed`` (laser perception) with and without logging (medians of ``reps`` alternated
    runs of ``episodes`` episodes each), logging's share of a step (median over the alternated pairs), and
    the per-stage breakdown."""
    import tempfile

    from runners.run import run_episode

    scenario, evaluator, cfg = _scenario_and_config("mixed")

    def run(log: bool) -> tuple[float, int]:
        t, steps = time.perf_counter(), 0
        with tempfile.TemporaryDirectory() as tmp:
            for seed in range(episodes):
                path = Path(tmp) / f"{seed}.mcap" if log else None
                steps += run_episode(scenario, evaluator, cfg, seed, path, "")["steps"]
        return time.perf_counter() - t, steps

    run(False)  # warm-up
    run(True)
    plain, logged = [], []
    for _ in range(reps):  # alternated, so that a slow spell of the machine hits both alike
        t_plain, steps = run(False)
        plain.append(t_plain)
        logged.append(run(True)[0])
    t_plain, t_log = statistics.median(plain), statistics.median(logged)
    # the share from each alternated pair, then the median: a slow spell of the machine hits a pair alike
    shares = [(log_s - plain_s) / log_s for plain_s, log_s in zip(plain, logged, strict=True)]
    timers = stage_timers()
    try:
        t_prof, _ = run(True)
    finally:
        timers.restore()
    return {"scenario": "mixed", "episodes": episodes, "repetitions": reps, "steps": steps,
            "steps_per_s_without_logging": steps / t_plain, "steps_per_s_with_logging": steps / t_log,
            "logging_share_of_step": statistics.median(shares), "logging_share_per_pair": shares,
            "us_per_step_by_stage": timers.us_per_step(t_prof, steps)}
