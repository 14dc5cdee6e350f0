"""Benchmark of a tuning study (part of ``python -m runners.bench``; issue #39): trials per minute of
``runners.tune``'s trial loop, and the overhead of the study machinery over the same episodes run plainly.

A TPE study of ``planner.h_wait`` and ``planner.safety_margin_cm`` on ``head_on`` runs ``trials`` trials of
``seeds`` episodes each, in this process with its SQLite storage in a temporary folder: Optuna's ask and tell,
composing and validating each trial's config, the episodes with their logs, the metrics read back from the logs
and the objective. Then each completed trial's episodes run again as plain episodes (config composed outside
the timing, as :func:`runners.benchmarks.main_job.plain_process_seconds` does). The overhead is
study seconds / plain seconds − 1, split into the part outside the episodes: sampler and storage, composition,
metrics from the logs. One process, one core.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

STUDY = {
    "name": "bench", "base": ["planner=auto"],
    "space": ["planner.h_wait=int(range(1,6))", "planner.safety_margin_cm=interval(0,30)"],
    "objectives": [{"name": "score", "direction": "maximize", "terms": {"success": 1.0, "time_to_goal_s": -0.005},
                    "fill": {"time_to_goal_s": 120}}],
    "scenarios": ["head_on"], "heldout_seeds": {"start": 10**6, "count": 1}, "sampler": "tpe",
}


def bench_tuning(trials: int = 20, seeds: int = 10) -> dict[str, Any]:
    """Trials per minute and the overhead of the study over plain episodes (see the module docstring)."""
    import runners.tuning.study as study_module
    from runners.configuration.run_inputs import load_run
    from runners.logs import yaml_text
    from runners.run import config_hash, log_path, run_episode
    from runners.tuning import episodes as trial_episodes
    from runners.tuning.storage import open_storage
    from runners.tuning.study import create_or_load, run_trials
    from runners.tuning.study_file import study_from_data

    spec = study_from_data({**STUDY, "train_seeds": {"start": 0, "count": seeds}, "trials": trials},
                           Path("runners/benchmarks/tuning.py"))
    spent = {"episodes": 0.0, "metrics": 0.0}
    real_run, real_metrics = run_episode, trial_episodes.metrics_table

    def timed_episode(*args: Any, **kwargs: Any) -> dict[str, Any]:
        tic = time.perf_counter()
        try:
            return real_run(*args, **kwargs)
        finally:
            spent["episodes"] += time.perf_counter() - tic

    def timed_metrics(*args: Any, **kwargs: Any) -> Any:
        tic = time.perf_counter()
        try:
            return real_metrics(*args, **kwargs)
        finally:
            spent["metrics"] += time.perf_counter() - tic

    with tempfile.TemporaryDirectory() as tmp, trial_episodes.hydra_conf():
        study_dir = Path(tmp) / "study"
        study_dir.mkdir()
        trial_episodes.run_episode, trial_episodes.metrics_table = timed_episode, timed_metrics
        try:
            tic = time.perf_counter()
            study = create_or_load(spec, open_storage(study_dir, "sqlite"))
            setup_s = time.perf_counter() - tic  # once per study: SQLite tables, the default's config
            spent["episodes"] = spent["metrics"] = 0.0
            tic = time.perf_counter()
            run_trials(study, spec, study_dir, trials)
            study_s = time.perf_counter() - tic
        finally:
            trial_episodes.run_episode, trial_episodes.metrics_table = real_run, real_metrics
        complete = [t for t in study.get_trials(deepcopy=False) if t.state.name == "COMPLETE"]
        plain_s, episodes = 0.0, 0
        for t in complete:  # the same episodes, plainly
            cfg = trial_episodes.run_config(t.user_attrs[study_module.OVERRIDES], spec.scenarios[0], spec.train)
            run = load_run(cfg)
            text = yaml_text.config_text(cfg, resolve=True)
            out = Path(tmp) / "plain" / str(t.number)
            out.mkdir(parents=True)
            tic = time.perf_counter()
            for seed in run.seeds:
                world = run.scenarios[seed]
                run_episode(world, run.evaluator, run.episode_config, seed, log_path(out, world.name, run.plain, seed),
                            text, config_hash(text, seed))
                episodes += 1
            plain_s += time.perf_counter() - tic
    outside = study_s - spent["episodes"]
    return {"trials": len(complete), "episodes_per_trial": seeds, "episodes": episodes, "scenario": spec.scenarios[0],
            "study_s": study_s, "plain_episodes_s": plain_s, "trials_per_minute": 60 * len(complete) / study_s,
            "overhead": study_s / plain_s - 1, "overhead_s_per_trial": (study_s - plain_s) / len(complete),
            "episodes_in_study_s": spent["episodes"], "metrics_s": spent["metrics"],
            "sampler_storage_compose_s": outside - spent["metrics"], "study_setup_s": setup_s}


def tuning_line(r: dict[str, Any]) -> str:
    return (f"tuning (runners.tune's trial loop, TPE + SQLite, {r['trials']} trials x {r['episodes_per_trial']} "
            f"{r['scenario']} episodes, one core): {r['trials_per_minute']:.1f} trials/min; study {r['study_s']:.1f} s "
            f"vs the same episodes plainly {r['plain_episodes_s']:.1f} s: overhead {r['overhead']:+.0%}, "
            f"{r['overhead_s_per_trial']:.2f} s per trial (outside the episodes: metrics from the logs "
            f"{r['metrics_s']:.1f} s, sampler, storage and composing {r['sampler_storage_compose_s']:.1f} s); creating "
            f"the study {r['study_setup_s']:.1f} s once")


if __name__ == "__main__":
    print(tuning_line(bench_tuning()))
