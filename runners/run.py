"""Run episodes of one configuration, write one MCAP log per episode, print one line per episode.

    python -m runners.run                                       # head_on, Table 1, strategy auto
    python -m runners.run scenario=crossing_right planner=none episodes=3
    python -m runners.run controller=listing perception=ground_truth planner.h_wait=4

Configuration is composed by Hydra from ``conf/`` (see ``conf/config.yaml``). Logs go to Hydra's output
directory (``outputs/<date>/<time>/`` for a run, one numbered job directory per sweep job).
"""

from __future__ import annotations

import functools
import hashlib
import os
import signal
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import hydra
import yaml
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from fuzzynav.episode import Episode, EpisodeConfig
from fuzzynav.fuzzy_fast import FastEvaluator
from fuzzynav.scenario import Scenario
from runners import schema
from runners.mcap_log import EpisodeLogWriter, run_metadata

# input loading and validation live in runners.run_inputs; these names are imported from here by the dataset,
# bench and replay runners and the tests
from runners.run_inputs import ConfigFileError, episode_config, load_evaluator, load_run, load_scenario

__all__ = ["ConfigFileError", "episode_config", "load_evaluator", "load_scenario", "log_name", "run_episode",
           "run_job"]

schema.register()
CONF_DIR = str(Path(__file__).resolve().parents[1] / "conf")  # absolute: works from any working directory


def log_name(scenario: str, cfg: dict[str, Any], seed: int) -> str:
    """``<scenario>__<strategy>__h<h_wait>__<controller>__<perception>__s<seed>.mcap``"""
    planner = cfg.get("planner") or {}
    controller = (cfg.get("controller") or {}).get("name", "controller")
    perception = (cfg.get("perception") or {}).get("mode", "laser")
    return (f"{scenario}__{planner.get('strategy', 'auto')}__h{planner.get('h_wait', 2)}__{controller}"
            f"__{perception}__s{seed}.mcap")


def log_path(out_dir: Path, scenario: str, cfg: dict[str, Any], seed: int) -> Path:
    """The log file of an episode, always directly inside ``out_dir``. The names it is made of are validated
    where they are parsed (safe file-name parts); this is the last guard against a name that escapes."""
    path = out_dir / log_name(scenario, cfg, seed)
    if path.parent != out_dir or path.name.startswith(".") or len(path.name.encode()) > 255:
        raise ConfigFileError(f"log file name {path.name[:80]!r}: not a plain file name inside {out_dir}")
    return path


@functools.lru_cache(maxsize=64)
def scenario_yaml(scenario: Scenario) -> str:
    """The scenario as YAML (the exact world of the episode, generated ones included); cached, as every
    episode of a job logs the same scenario."""
    import dataclasses

    def clean(value):
        if dataclasses.is_dataclass(value):
            return {k: clean(v) for k, v in dataclasses.asdict(value).items() if v is not None}
        if isinstance(value, dict):
            return {k: clean(v) for k, v in value.items() if v is not None}
        if isinstance(value, list | tuple):
            return [clean(v) for v in value]
        return value

    return yaml.safe_dump(clean(scenario), sort_keys=False)


def run_episode(scenario: Scenario, evaluator: FastEvaluator, ep_cfg: EpisodeConfig, seed: int,
                log_path: Path | None, config_yaml: str, digest: str = "") -> dict[str, Any]:
    """Run one episode, writing its log; an exception inside the episode gives outcome ``error`` (logged
    with its traceback) instead of propagating. Ctrl-C finishes the log as ``interrupted`` and re-raises."""
    episode = Episode(scenario, evaluator, ep_cfg, seed=seed)
    summary = {"scenario": scenario.name, "strategy": ep_cfg.planner.strategy, "h_wait": ep_cfg.planner.h_wait,
               "controller": evaluator.spec.name, "perception": ep_cfg.perception.mode, "seed": seed,
               "log": str(log_path) if log_path else ""}
    log = None  # created before the episode: a log that cannot be written is an error, not an episode outcome
    if log_path is not None:
        meta = run_metadata(config_yaml, seed, scenario.name, {
            "strategy": ep_cfg.planner.strategy, "h_wait": ep_cfg.planner.h_wait,
            "controller": evaluator.spec.name, "perception": ep_cfg.perception.mode,
            "scenario_yaml": scenario_yaml(scenario), "config_hash": digest or config_hash(config_yaml, seed)})
        log = EpisodeLogWriter(log_path, episode, meta, ep_cfg.planner.strategy, ep_cfg.perception.mode)
    outcome, reason = "error", ""
    try:
        for record in episode.run():
            if log is not None:
                log.step(record)
            _stop_if_requested()
        outcome = episode.outcome or "error"
        reason = {"goal": "within goal tolerance", "collision": "contact with an obstacle",
                  "timeout": f"max_steps {scenario.max_steps} reached"}.get(outcome, "")
    except KeyboardInterrupt as err:
        outcome = "interrupted"
        reason = "terminated (SIGTERM)" if isinstance(err, Interrupted) else "interrupted (Ctrl-C)"
        raise
    except Exception as err:  # an episode that raises must not stop the sweep
        outcome, reason = "error", f"{type(err).__name__}: {err}"
        if log is not None:
            log.log(log._last_time, 4, traceback.format_exc())
    finally:
        if log is not None:
            log.finish(outcome, reason)
    summary.update(outcome=outcome, steps=episode.step_index, time_s=episode.step_index * ep_cfg.dt,
                   contacts=episode.contacts, reason=reason)
    return summary


def config_hash(config_yaml: str, seed: int) -> str:
    """What makes an episode the same episode: resolved config (minus ``resume``), seed, fuzzynav version."""
    from runners.provenance import provenance

    body = "\n".join(line for line in config_yaml.splitlines() if not line.startswith("resume:"))
    text = f"{body}\nseed={seed}\nfuzzynav={provenance()['fuzzynav_version']}"
    return hashlib.sha256(text.encode()).hexdigest()


def completed_summary(path: Path, expected_hash: str) -> dict[str, Any] | None:
    """The summary of an existing complete log of the same episode (same config hash), else None."""
    from analysis.logs import LogError, episode_summary, is_complete, read_metadata

    if not path.exists() or not is_complete(path):
        return None
    try:
        if read_metadata(path).get("config_hash") != expected_hash:
            return None
        row = episode_summary(path)
    except LogError:
        return None
    return row if row["outcome"] not in ("incomplete", "interrupted") else None


class Interrupted(KeyboardInterrupt):
    """SIGTERM, turned into the same clean stop as Ctrl-C (the log in flight is finished as interrupted)."""


_STOP_REQUESTED: list[int] = []  # signals received while a job runs, acted on between two steps


def _stop(signum: int) -> KeyboardInterrupt:
    """The exception a stop signal raises: :class:`Interrupted` for SIGTERM, KeyboardInterrupt for SIGINT."""
    return Interrupted("terminated") if signum == signal.SIGTERM else KeyboardInterrupt()


def _on_stop_signal(signum, frame) -> None:
    """SIGINT/SIGTERM during a job: noted, and raised between two steps (see :func:`_stop_if_requested`), so
    that a log is never cut in the middle of a message. A second signal stops at once."""
    if _STOP_REQUESTED:
        raise _stop(signum)
    _STOP_REQUESTED.append(signum)


def _stop_if_requested() -> None:
    """Raise the pending stop, if any (see :func:`_stop`)."""
    if _STOP_REQUESTED:
        raise _stop(_STOP_REQUESTED[0])


def run_job(cfg: DictConfig) -> list[dict[str, Any]]:
    """Run ``cfg.episodes`` episodes with consecutive seeds into Hydra's output directory. With
    ``resume=true`` an episode whose complete log with the same config hash is already there is kept."""
    runtime = HydraConfig.get().runtime
    inputs = load_run(cfg, runtime)  # everything validated (every seed's scenario) before any log is written
    plain, evaluator, ep_cfg, seeds = inputs.plain, inputs.evaluator, inputs.episode_config, inputs.seeds
    out_dir = Path(runtime.output_dir)
    config_yaml = OmegaConf.to_yaml(cfg, resolve=True)
    results = []
    previous = _install_stop_handlers()
    try:
        for seed in seeds:
            _stop_if_requested()
            scenario = inputs.scenarios[seed]
            path = log_path(out_dir, scenario.name, plain, seed)
            digest = config_hash(config_yaml, seed)
            kept = completed_summary(path, digest) if plain.get("resume") else None
            if kept is not None:
                kept.update(kept=True, reason="resumed: complete log kept")
                results.append(kept)
                continue
            results.append(run_episode(scenario, evaluator, ep_cfg, seed, path, config_yaml, digest))
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
    return results


def _install_stop_handlers() -> dict[int, Any]:
    """Route SIGINT and SIGTERM to :func:`_on_stop_signal`; returns the previous handlers (none outside the
    main thread, where Python cannot install handlers: there the signals act as before)."""
    _STOP_REQUESTED.clear()
    previous = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        try:
            previous[signum] = signal.signal(signum, _on_stop_signal)
        except ValueError:  # not the main thread
            break
    return previous


@hydra.main(version_base="1.3", config_path=CONF_DIR, config_name="config")
def main(cfg: DictConfig) -> list[dict[str, Any]]:
    try:
        results = run_job(cfg)
    except KeyboardInterrupt as err:
        print(f"interrupted: the episode in flight was logged with outcome 'interrupted' ({err or 'Ctrl-C'})",
              file=sys.stderr)
        sys.exit(143 if isinstance(err, Interrupted) else 130)
    except ConfigFileError as err:
        print(f"error: {err}", file=sys.stderr)
        sys.exit(2)
    except ValueError as err:
        print(f"error: config: {err}", file=sys.stderr)
        sys.exit(2)
    if HydraConfig.get().mode != RunMode.MULTIRUN:
        for r in results:
            print(f"{r['scenario']} strategy={r['strategy']} h_wait={r['h_wait']} seed={r['seed']}: {r['outcome']} "
                  f"after {r['steps']} steps ({r['time_s']:.0f} s), contacts={r['contacts']}  log: {r['log']}")
    return results


def cli(on_config: Callable[[DictConfig], None] | None = None) -> None:
    """``python -m runners.run``: a one-line error for a bad override or config file, then Hydra.
    ``on_config`` gets the first config the check composes (see :func:`runners.precheck.precheck`)."""
    from runners.precheck import debug_requested, precheck

    args = sys.argv[1:]
    if "--debug" in args:
        args.remove("--debug")
        sys.argv = [sys.argv[0], *args]
        os.environ["HYDRA_FULL_ERROR"] = "1"
    if not debug_requested(args) and "--help" not in args and "-h" not in args:
        problem = precheck(args, on_config)
        if problem:
            print(f"error: {problem}", file=sys.stderr)
            sys.exit(2)
    register_sweeper()
    main()


def register_sweeper() -> None:
    """Register fuzzynav's sweeper (``conf/hydra/sweeper/fuzzynav.yaml``) with Hydra. Hydra finds plugins by
    scanning the ``hydra_plugins`` package, which misses packages installed in editable mode (``pip install
    -e``), so it is registered here by hand; without fuzzynav installed, multirun says how to install it."""
    from hydra.core.plugins import Plugins

    try:
        from hydra_plugins.fuzzynav_sweeper import FuzzynavSweeper
    except ImportError:
        multirun = "--multirun" in sys.argv or "-m" in sys.argv
        if multirun and not any(a.startswith("hydra/sweeper=") for a in sys.argv):
            print("error: the sweeper hydra_plugins.fuzzynav_sweeper is not installed: run `pip install -e .` in "
                  "the fuzzynav checkout (or choose Hydra's with hydra/sweeper=basic)", file=sys.stderr)
            sys.exit(2)
        return
    Plugins.instance().register(FuzzynavSweeper)


if __name__ == "__main__":
    cli()
