"""Benchmark of crowds (part of ``python -m runners.bench``): steps/s of ``crowd_crossing`` with 20 pedestrians
of each obstacle model, with laser perception and MCAP logging, the obstacle model's share of a step and the time
per step by stage.

The same seeds (so the same generated worlds) for every model; one process, one core.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

from fuzzynav.conf import CONF_DIR as CONF
from runners.benchmarks.stage_timers import stage_timers

MODELS = ("scripted", "social_force", "orca", "random_walk")


def _inputs(model: str, n: int) -> dict[str, Any]:
    scenario = yaml.safe_load((CONF / "scenario" / "crowd_crossing.yaml").read_text())
    scenario["params"].update(n=n, model=model)
    return {"sensors": yaml.safe_load((CONF / "sensors" / "default.yaml").read_text()),
            "navigator": yaml.safe_load((CONF / "navigator" / "fuzzy_tpt.yaml").read_text()),
            "planner": yaml.safe_load((CONF / "planner" / "auto.yaml").read_text()),
            "scenario": scenario,
            "controller": yaml.safe_load((CONF / "controller" / "table1.yaml").read_text())}


def bench_crowd(episodes: int, n: int = 20, max_steps: int = 60) -> list[dict[str, Any]]:
    """For each model: steps/s with logging over ``episodes`` episodes (seeds 0..episodes-1, at most ``max_steps``
    steps each, after a warm-up episode), then, in a second timed pass, the µs per step by stage
    (:func:`runners.benchmarks.stage_timers.stage_timers`; ``obstacles`` is the model's
    :meth:`fuzzynav.pedestrians.crowd.Crowd.step`)."""
    from runners.run import episode_config, load_evaluator, load_scenario, run_episode

    rows = []
    for model in MODELS:
        base = _inputs(model, n)
        base["scenario"]["params"]["max_steps"] = max_steps
        evaluator, cfg = load_evaluator(base), episode_config(base)
        scenarios = [load_scenario(base, seed) for seed in range(episodes)]

        def run(tmp: str, scenarios=scenarios, evaluator=evaluator, cfg=cfg) -> tuple[float, int]:
            t, steps = time.perf_counter(), 0
            for seed, scenario in enumerate(scenarios):
                steps += run_episode(scenario, evaluator, cfg, seed, Path(tmp) / f"{seed}.mcap", "")["steps"]
            return time.perf_counter() - t, steps

        with tempfile.TemporaryDirectory() as tmp:
            run_episode(scenarios[0], evaluator, cfg, 0, Path(tmp) / "warm.mcap", "")
            seconds, steps = run(tmp)  # no timers: their own cost stays out of steps/s
            timers = stage_timers(obstacles=True)
            try:
                t_prof, _ = run(tmp)
            finally:
                timers.restore()
        stages = timers.us_per_step(t_prof, steps)
        model_s = timers.total.get("obstacles", 0.0)
        rows.append({"model": model, "pedestrians": n, "episodes": episodes, "steps": steps,
                     "steps_per_s_with_logging": steps / seconds, "model_us_per_step": stages.get("obstacles", 0.0),
                     "model_share_of_step": model_s / t_prof, "us_per_step_by_stage": stages})
    return rows


def print_crowd(rows: list[dict[str, Any]]) -> None:
    print(f"crowds (crowd_crossing, {rows[0]['pedestrians']} pedestrians, laser perception, with logging; "
          "target >= 500 steps/s per core)")
    print(f"  {'model':<13} {'steps/s':>8} {'model µs/step':>14} {'model share':>12}")
    for r in rows:
        print(f"  {r['model']:<13} {r['steps_per_s_with_logging']:8.0f} {r['model_us_per_step']:14.0f} "
              f"{r['model_share_of_step']:12.0%}")
        print("    µs per step: " + ", ".join(f"{k} {v:.0f}" for k, v in r["us_per_step_by_stage"].items()))


if __name__ == "__main__":
    print_crowd(bench_crowd(5))
