"""Run episodes of one configuration, write one MCAP log per episode, print one line per episode.

    python -m runners.run                                       # head_on, Table 1, strategy auto
    python -m runners.run scenario=crossing_right planner=none episodes=3
    python -m runners.run controller=listing perception=ground_truth planner.h_wait=4

Configuration is composed by Hydra from ``conf/`` (see ``conf/config.yaml``). Logs go to Hydra's output
directory (``outputs/<date>/<time>/`` for a run, one numbered job directory per sweep job).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import logging
import os
import signal
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf, open_dict

from analysis import interrupts

# the exception of a stop request (a signal, a sweep's stop file: runners.sweeping.stop), re-exported from here
from analysis.interrupts import Interrupted
from fuzzynav import episode_identity
from fuzzynav.conf import CONF_DIR
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode import Episode, EpisodeConfig
from fuzzynav.params.names import DEFAULT_POLICY, reads_h_wait
from fuzzynav.pedestrians.base import MODEL_NOTE, model_source_digest
from fuzzynav.planning.layer import POLICY_NOTE, PolicyError
from fuzzynav.policies.base import policy_source_digest, split_navigator_section
from fuzzynav.scenarios.generator import generator_source_digest
from fuzzynav.scenarios.generators.recorded import recording_digest
from fuzzynav.scenarios.scenario import Scenario
from runners.configuration import plugins as config_plugins
from runners.configuration import schema

# input loading and validation live in runners.configuration.run_inputs; these names are imported from here by the
# dataset, bench and replay runners and the tests
from runners.configuration.run_inputs import ConfigFileError, episode_config, load_evaluator, load_run, load_scenario
from runners.logs import yaml_text
from runners.logs.mcap_log import EpisodeLogWriter, LogWriteError, run_metadata
from runners.logs.provenance import prefetch as prefetch_provenance
from runners.logs.provenance import provenance
from runners.sweeping import process_tree, stop
from runners.sweeping import resume as sweep_resume

__all__ = ["ConfigFileError", "Interrupted", "episode_config", "episode_metadata", "load_evaluator", "load_scenario",
           "log_name", "outcome_reason", "run_episode", "run_job"]

schema.register()


def log_name(scenario: str, cfg: dict[str, Any], seed: int) -> str:
    """``<scenario>__<strategy>__h<h_wait>__<controller>__<perception>__s<seed>.mcap`` for the paper's ``fuzzy``
    policy (the names logs had before policies could be chosen), ``<scenario>__<policy>__<strategy>__…`` for
    any other (``head_on__dwa__none__table1__laser__s0.mcap``). ``h<h_wait>`` only where the strategy reads it
    (:func:`fuzzynav.params.names.reads_h_wait`: auto), so that episodes that do not depend on it have one name."""
    planner = cfg.get("planner") or {}
    strategy = planner.get("strategy", "auto")
    controller = (cfg.get("controller") or {}).get("name", "controller")
    perception = (cfg.get("perception") or {}).get("mode", "laser")
    policy, _ = split_navigator_section(cfg.get("navigator"))
    policy_part = "" if policy == DEFAULT_POLICY else f"{policy}__"
    h_part = f"h{planner.get('h_wait', 2)}__" if reads_h_wait(strategy) else ""
    return f"{scenario}__{policy_part}{strategy}__{h_part}{controller}__{perception}__s{seed}.mcap"


def log_path(out_dir: Path, scenario: str, cfg: dict[str, Any], seed: int) -> Path:
    """The log file of an episode, always directly inside ``out_dir``. The names it is made of are validated
    where they are parsed (safe file-name parts); this is the last guard against a name that escapes."""
    path = out_dir / log_name(scenario, cfg, seed)
    if path.parent != out_dir or path.name.startswith(".") or len(path.name.encode()) > 255:
        raise ConfigFileError(f"log file name {path.name[:80]!r}: not a plain file name inside {out_dir}")
    return path


def scenario_data(value: Any) -> Any:
    """A scenario (or any part of it) as plain data for YAML: dataclasses as mappings without their None fields,
    tuples as lists."""
    import dataclasses

    if dataclasses.is_dataclass(value):
        return {k: scenario_data(v) for k, v in dataclasses.asdict(value).items() if v is not None}
    if isinstance(value, dict):
        return {k: scenario_data(v) for k, v in value.items() if v is not None}
    if isinstance(value, list | tuple):
        return [scenario_data(v) for v in value]
    return value


@functools.lru_cache(maxsize=64)
def scenario_yaml(scenario: Scenario) -> str:
    """The scenario as YAML (the exact world of the episode, generated ones included); cached, as every
    episode of a job logs the same scenario."""
    return yaml_text.dump(scenario_data(scenario))


def code_source(policy: str, scenario: Scenario, generator: Any = None) -> str:
    """The digest of the code outside fuzzynav that an episode runs (part of its identity, recorded as
    ``policy_source_sha256``): the policy's source (:func:`fuzzynav.policies.base.policy_source_digest`), combined
    with the sources of the other packages' pedestrian models its scenario uses and of the generator that made the
    scenario (``generator``: its name, None for a scenario file); '' when it runs fuzzynav's code only. A resumed
    sweep thus re-runs the episodes whose plug-ins changed instead of keeping their old logs."""
    policy_digest = policy_source_digest(policy)
    models = sorted({d.model for d in scenario.dynamic_obstacles if d.model})
    parts = [f"{name}={digest}" for name in models if (digest := model_source_digest(name))]
    if generator_digest := generator_source_digest(generator):
        parts.append(f"generator={generator_digest}")
    if not parts:
        return policy_digest
    return hashlib.sha256(";".join([f"policy={policy_digest}", *parts]).encode()).hexdigest()


def scenario_generator(plain: Any) -> Any:
    """The generator name of a run config's scenario section (None for a scenario file)."""
    section = plain.get("scenario") if isinstance(plain, dict) else None
    return section.get("generator") if isinstance(section, dict) else None


def episode_metadata(scenario: Scenario, evaluator: FastEvaluator, ep_cfg: EpisodeConfig, seed: int,
                     config_yaml: str, digest: str = "", generator: Any = None) -> dict[str, str]:
    """The ``fuzzynav.run`` metadata of an episode's log (also written by the Gymnasium environment's
    ``runners.gym_log.RecordMcap``, so that both logs are the same); ``generator``: the name of the generator that
    made ``scenario`` (:func:`scenario_generator`), None for a scenario file."""
    source = code_source(ep_cfg.policy, scenario, generator)
    recording = scenario_recording(scenario, generator)
    return run_metadata(config_yaml, seed, scenario.name, {
        "policy": ep_cfg.policy, "strategy": ep_cfg.planner.strategy, "h_wait": ep_cfg.planner.h_wait,
        "controller": evaluator.spec.name, "perception": ep_cfg.perception.mode,
        "scenario_yaml": scenario_yaml(scenario), "config_hash": digest or config_hash(config_yaml, seed),
        **({episode_identity.POLICY_SOURCE: source} if source else {}),
        **({episode_identity.RECORDING: recording} if recording else {})})


def scenario_recording(scenario: Scenario, generator: Any) -> str:
    """The SHA-256 of the recording a scenario of the ``recorded`` generator was read from (part of its episodes'
    identity, recorded as ``recording_sha256``: the config names the recording by its path only); '' for others."""
    return recording_digest(scenario.description) if generator == "recorded" else ""


def outcome_reason(outcome: str, max_steps: int) -> str:
    """The reason logged with a finished episode's outcome (``/episode``, ``/log``); '' for other outcomes."""
    return {"goal": "within goal tolerance", "collision": "contact with an obstacle",
            "timeout": f"max_steps {max_steps} reached"}.get(outcome, "")


def run_episode(scenario: Scenario, evaluator: FastEvaluator, ep_cfg: EpisodeConfig, seed: int,
                log_path: Path | None, config_yaml: str, digest: str = "", generator: Any = None) -> dict[str, Any]:
    """Run one episode, writing its log; an exception inside the episode gives outcome ``error`` (logged
    with its traceback) instead of propagating. A stop request (:mod:`runners.sweeping.stop`: Ctrl-C, SIGTERM, a sweep's
    stop file) finishes the log as ``interrupted`` and re-raises; a log that cannot be written raises
    :class:`runners.logs.mcap_log.LogWriteError` (not an episode outcome: nothing is left at ``log_path``)."""
    try:
        episode = Episode(scenario, evaluator, ep_cfg, seed=seed)
    except KeyboardInterrupt as err:  # a policy's reset(seed) raising it, as any other failure of its reset
        if stop.from_signal(err):
            raise
        raise PolicyError(raised_by_code(err)) from None
    summary = {"scenario": scenario.name, "policy": ep_cfg.policy, "strategy": ep_cfg.planner.strategy,
               "h_wait": ep_cfg.planner.h_wait, "controller": evaluator.spec.name,
               "perception": ep_cfg.perception.mode, "seed": seed, "log": str(log_path) if log_path else ""}
    log = None  # created before the episode: a log that cannot be written is an error, not an episode outcome
    if log_path is not None:
        meta = episode_metadata(scenario, evaluator, ep_cfg, seed, config_yaml, digest, generator)
        log = EpisodeLogWriter(log_path, episode, meta, ep_cfg.planner.strategy, ep_cfg.perception.mode)
    outcome, reason = "error", ""
    try:
        for record in episode.run():
            if log is not None:
                log.step(record)
            stop.check()
        outcome = episode.outcome or "error"
        reason = outcome_reason(outcome, scenario.max_steps)
    except KeyboardInterrupt as err:
        if stop.from_signal(err):
            outcome, reason = "interrupted", interrupts.reason_of(err)
            raise
        # no signal behind it (a signal arrives as Interrupted here): code raised it, e.g. a policy's act()
        outcome, reason = "error", raised_by_code(err)
        if log is not None:
            log.log(log._last_time, 4, traceback.format_exc())
    except LogWriteError:
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
    """The ``config_hash`` a log records (:func:`fuzzynav.episode_identity.config_hash`: resolved config minus
    ``resume``, seed, this fuzzynav version); an integrity check of the metadata, not the episode's identity."""
    from runners.logs.provenance import provenance

    return episode_identity.config_hash(config_yaml, seed, provenance()["fuzzynav_version"])


def run_job(cfg: DictConfig) -> list[dict[str, Any]]:
    """Run ``cfg.episodes`` episodes with consecutive seeds into Hydra's output directory. With ``resume=true`` an
    episode (:func:`fuzzynav.episode_identity.episode_key`: config, seed, fuzzynav version) whose log passes a full
    verification and ended goal/collision/timeout is kept (:func:`runners.sweeping.resume.keep`); the others run
    again.

    A stop request ends the episode in flight as ``interrupted``: in a single run the stop is raised (the process
    exits 130/143); in a sweep's job the results so far are returned, so that the launcher gets every finished
    job's results and writes the summary. A log that cannot be written asks the whole sweep to stop, then
    raises."""
    hydra_cfg = HydraConfig.get()
    runtime = hydra_cfg.runtime
    sweep_dir = Path(hydra_cfg.sweep.dir).absolute() if hydra_cfg.mode == RunMode.MULTIRUN else None
    # a worker between two jobs ignores SIGINT/SIGTERM: a terminal's Ctrl-C reaches every process of the sweep,
    # and a loky worker killed by it while idle would break the pool (and kill the others' episodes mid-log)
    in_worker = sweep_dir is not None and not stop.is_launcher()
    idle = signal.SIG_IGN if in_worker else None
    if in_worker:  # a worker whose launcher was killed (SIGKILL: it could not stop them) ends too
        process_tree.exit_with_parent()
    restore = stop.install(sweep_dir, idle)
    results: list[dict[str, Any]] = []
    try:
        stop.check()  # a job that starts after the sweep was asked to stop does nothing
        inputs = load_run(cfg, runtime)  # everything validated (every seed's scenario) before any log is written
        plain, evaluator, ep_cfg, seeds = inputs.plain, inputs.evaluator, inputs.episode_config, inputs.seeds
        out_dir = Path(runtime.output_dir)
        config_yaml = yaml_text.config_text(cfg, resolve=True)
        version = provenance()["fuzzynav_version"]
        generator = scenario_generator(plain)
        for seed in seeds:
            stop.check_between_episodes()
            scenario = inputs.scenarios[seed]
            # plug-ins' code is part of their episodes' identity
            source = code_source(ep_cfg.policy, scenario, generator)
            path = log_path(out_dir, scenario.name, plain, seed)
            digest = config_hash(config_yaml, seed)
            key = episode_identity.episode_key(config_yaml, seed, version, source,  # whatever the seed batching
                                               scenario_recording(scenario, generator))
            kept = sweep_resume.keep(path, key, sweep_dir) if plain.get("resume") else None
            if kept is not None:
                kept.update(kept=True, reason="resumed: complete log kept")
                results.append(kept)
                continue
            results.append(run_episode(scenario, evaluator, ep_cfg, seed, path, config_yaml, digest, generator))
            sweep_resume.supersede(sweep_dir, key)
    except KeyboardInterrupt:
        if sweep_dir is None:
            raise
    except OSError as err:
        if sweep_dir is not None:  # the other jobs would write into the same full or read-only file system
            stop.request_sweep_stop(sweep_dir, 0, f"sweep stopped: {err}")
        raise
    finally:
        restore()
    return results


def task(cfg: DictConfig) -> list[dict[str, Any]]:
    """The task function of a run (and of each sweep job): run the job, print each episode's line (a run) or
    one line for a problem, exit non-zero on a failure."""
    logging.raiseExceptions = False  # a job's log file on a full disk must not print a traceback per record
    interrupts.resume()  # a signal during Hydra's start, raised now that Hydra has handed over: one line, 128 + sig
    try:
        results = run_job(cfg)
    except KeyboardInterrupt as err:
        print(f"interrupted: the episode in flight was logged with outcome 'interrupted' ({interrupts.reason_of(err)})",
              file=sys.stderr)
        sys.exit(interrupts.exit_code(err))
    except OSError as err:  # a log that cannot be written (disk full, read-only): one line naming it
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            raise  # the sweep's launcher reports it (hydra_plugins.fuzzynav_sweeper)
        print(f"error: {err if isinstance(err, LogWriteError) else f'{err.filename}: {err.strerror or err}'}",
              file=sys.stderr)
        sys.exit(1)
    except (ConfigFileError, ValueError) as err:
        if HydraConfig.get().mode == RunMode.MULTIRUN:
            # a sweep's job whose combination of values is invalid (each value alone passed the check): the job
            # fails and the sweep goes on, then says which job and how to resume; SystemExit ended the whole sweep
            # at once, with no summary
            raise
        print(f"error: {err}" if isinstance(err, ConfigFileError) else f"error: config: {err}", file=sys.stderr)
        sys.exit(2)
    if HydraConfig.get().mode != RunMode.MULTIRUN:
        for r in results:
            h_wait = f" h_wait={r['h_wait']}" if reads_h_wait(r["strategy"]) else ""
            print(f"{r['scenario']} policy={r['policy']} strategy={r['strategy']}{h_wait} "
                  f"seed={r['seed']}: {r['outcome']} after {r['steps']} steps ({r['time_s']:.6g} s), "
                  f"contacts={r['contacts']}  log: {r['log']}" + (" (complete: kept)" if r.get("kept") else ""))
        failed = [r for r in results if r["outcome"] == "error"]
        if failed:  # an episode that raised (a policy's code, a bug) is no result: say why, exit non-zero
            r = failed[0]
            more = f" ({len(failed)} of {len(results)} episodes)" if len(results) > 1 else ""
            print(f"error: seed {r['seed']}: {' '.join(str(r['reason']).split())[:300]}{more}; traceback in "
                  f"{r['log'] or 'the log'} (/log)", file=sys.stderr)
            sys.exit(1)
    return results


#: Hydra's entry point: composes the config (twice: once to read ``hydra.mode``, once to run) and runs
#: :func:`task`; a plain single run goes through :func:`run_composed` instead, with the config already composed
main = hydra.main(version_base="1.3", config_path=str(CONF_DIR), config_name="config")(task)  # absolute: any cwd

#: ``hydra.job.name`` of a run and of each sweep job: Hydra names it after the task function's file (run.py)
JOB_NAME = Path(__file__).stem


def run_composed(cfg: DictConfig) -> None:
    """A single run from the config that the command-line check composed (with Hydra's node), as ``hydra.main``
    runs one: logging configured, the ``hydra.callbacks`` notified, the job run as Hydra's own
    :func:`hydra.core.utils.run_job` runs it (output directory, ``.hydra/`` snapshot, job logging, ``HydraConfig``) by
    :func:`runners.sweeping.job_run.run_job`, which spares Hydra's copies of the config (tests/test_launcher.py).
    ``hydra.main`` composed the same config twice more (~0.1 s each: once for ``hydra.mode``, once to run); the
    config Hydra would have composed is this one with ``hydra.mode=RUN`` added, as Hydra adds it."""
    from hydra import initialize_config_dir
    from hydra.core.utils import configure_log
    from hydra.types import HydraContext

    from runners.sweeping.job_run import run_job

    with open_dict(cfg.hydra):  # what Hydra does for a run whose config leaves hydra.mode unset
        cfg.hydra.mode = RunMode.RUN
        cfg.hydra.overrides.hydra.append("hydra.mode=RUN")
    # Hydra global state as during hydra.main's job (a job's code may compose a config of its own)
    with initialize_config_dir(config_dir=str(CONF_DIR), job_name=JOB_NAME, version_base="1.3"):
        configure_log(cfg.hydra.hydra_logging, cfg.hydra.verbose)
        callbacks = RunCallbacks(cfg)
        callbacks.on_run_start(config=cfg, config_name="config")
        ret = run_job(cfg, HydraContext(config_loader=None, callbacks=callbacks),  # type: ignore[arg-type]
                      task, job_dir_key="hydra.run.dir", job_subdir_key=None)
        callbacks.on_run_end(config=cfg, config_name="config", job_return=ret)
    try:
        ret.return_value  # noqa: B018 -- a job's exception: Hydra's line naming the overrides, then raised
    except Exception as err:  # as Hydra reports it: the traceback from the task function on, exit 1
        tb = err.__traceback__
        while tb is not None and tb.tb_frame.f_code is not task.__code__:
            tb = tb.tb_next
        traceback.print_exception(type(err), err, tb or err.__traceback__)
        print("\nSet the environment variable HYDRA_FULL_ERROR=1 for a complete stack trace.", file=sys.stderr)
        sys.exit(1)


class RunCallbacks:
    """The ``hydra.callbacks`` of a config, instantiated and notified as Hydra does (a callback that raises an
    ``Exception`` is a warning; ``on_*_end`` in reverse order)."""

    def __init__(self, cfg: DictConfig) -> None:
        from hydra.utils import instantiate

        self.callbacks = [instantiate(spec) for spec in (OmegaConf.select(cfg, "hydra.callbacks") or {}).values()]

    def _notify(self, name: str, reverse: bool = False, **kwargs: Any) -> None:
        import warnings

        for callback in reversed(self.callbacks) if reverse else self.callbacks:
            try:
                getattr(callback, name)(**kwargs)
            except Exception as err:
                warnings.warn(f"Callback {type(callback).__name__}.{name} raised {type(err).__name__}: {err}",
                              stacklevel=2)

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._notify("on_run_start", config=config, **kwargs)

    def on_run_end(self, config: DictConfig, **kwargs: Any) -> None:
        self._notify("on_run_end", reverse=True, config=config, **kwargs)

    def on_job_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._notify("on_job_start", config=config, **kwargs)

    def on_job_end(self, config: DictConfig, **kwargs: Any) -> None:
        self._notify("on_job_end", reverse=True, config=config, **kwargs)


def cli(on_config: Callable[[DictConfig], None] | None = None, sweep: bool = False) -> None:
    """``python -m runners.run``: a one-line error for a bad override or config file, then Hydra. A plain run (config
    overrides only) is composed once, by the check, and run from that config (:func:`run_composed`); Hydra's
    options (``--cfg``, ``--info``, ``--help`` ...), ``--debug`` and a sweep go through ``hydra.main``.
    ``on_config`` gets the first config the check composes (see :func:`runners.configuration.precheck.precheck`).
    ``sweep``: called by ``runners.sweep``, which adds ``--multirun``; a user's own ``-m`` is refused in one line
    naming the ``runners.sweep`` command (Hydra's multirun of ``runners.run`` wrote logs but printed no outcome,
    summary or report)."""
    from runners.configuration.command_line import canonical_arguments
    from runners.configuration.precheck import debug_requested, precheck

    args, problem = canonical_arguments(sys.argv[1:])
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)
    sys.argv = [sys.argv[0], *args]
    problem = argument_problem(args, sweep)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        sys.exit(2)
    if "--debug" in args:
        args.remove("--debug")
        sys.argv = [sys.argv[0], *args]
        os.environ["HYDRA_FULL_ERROR"] = "1"
    composed: list[DictConfig] = []  # a plain single run: the config the check composed, run as it is
    if not debug_requested(args) and "--help" not in args and "-h" not in args:
        overrides, problem, plain_run = hydra_overrides(args)
        problem = problem or primary_config_problem(args)
        if not problem and "--multirun" not in args and "-m" not in args:
            problem = single_run_sweep(overrides, shown=sweep)
        keep = composed.append if plain_run and not sweep and on_config is None else on_config
        primary = hydra_arguments(args)
        problem = problem or precheck(overrides, keep, multirun="--multirun" in args,
                                      config_dir=primary[0].config_dir if primary else None,
                                      config_name=primary[0].config_name if primary else None)
        if problem:
            print(f"error: {problem}", file=sys.stderr)
            sys.exit(2)
    # Hydra's way below for a config file that sets hydra.mode, and for hydra.verbose (Hydra's debug report)
    if composed and composed[0].hydra.mode is None and not composed[0].hydra.verbose:
        prefetch_provenance()  # the git commit the log records: looked up while the job starts
        interrupts.defer()  # until the task function: Hydra turns an interrupt inside OmegaConf into its own error
        run_composed(composed[0])
        return
    register_sweeper()
    interrupts.defer()
    main()


def raised_by_code(err: KeyboardInterrupt) -> str:
    """The reason an episode failed whose code raised ``KeyboardInterrupt`` itself (no signal): named by the
    policy or the pedestrian model it came from (the notes :mod:`fuzzynav.planning.layer` and
    :func:`fuzzynav.pedestrians.base.call_model` add), else by the innermost frame."""
    where = next((note for note in getattr(err, "__notes__", []) if note.startswith((POLICY_NOTE, MODEL_NOTE))),
                 None)
    if where is None:
        frames = traceback.extract_tb(err.__traceback__)
        where = f"{frames[-1].filename}:{frames[-1].lineno}" if frames else "the episode's code"
    return f"{where} raised KeyboardInterrupt (no signal was received: treated as the code's error)"


def argument_problem(args: list[str], sweep: bool) -> str | None:
    """One line about the first command-line argument a run (``sweep``: a sweep) cannot take, or None: text that
    is not UTF-8 (its logs could not be read back), ``-m`` or ``hydra.mode=MULTIRUN`` in a single run, the other's
    output folder (``hydra.run.dir`` in a sweep, ``hydra.sweep.dir`` in a run: Hydra ignores it, and the logs went to
    ./multirun/ or ./outputs/), and Hydra's options that fuzzynav does not support (``--experimental-rerun``
    unpickles the file it is given; ``--shell-completion``)."""
    from analysis.file_names import is_utf8, printable

    for i, arg in enumerate(args, start=1):
        if not is_utf8(arg):
            return (f"argument {i} ({printable(arg)[:60]}): not UTF-8 text (the run's config is logged as UTF-8 and "
                    "could not be read back)")
    if not sweep and ("--multirun" in args or "-m" in args):
        return multirun_problem(args)
    keys = [arg.lstrip("+~").partition("=")[0].strip() for arg in args]
    own, other = ("hydra.sweep.dir", "hydra.run.dir") if sweep else ("hydra.run.dir", "hydra.sweep.dir")
    for arg, key in zip(args, keys, strict=True):
        value = arg.partition("=")[2]
        if not sweep and key == "hydra.mode" and value.strip().upper() == "MULTIRUN":
            return multirun_problem([a for a in args if a != arg])
        if sweep and key == "hydra.mode" and value.strip().upper() == "RUN":
            return ("hydra.mode=RUN: runners.sweep runs a sweep; one configuration is python -m runners.run with the "
                    "same overrides")
        if key == other and own not in keys:  # (both given: the command's own is used, the other harmless)
            return (f"{other}: {'a single run' if sweep else 'a sweep'}'s folder; "
                    f"{'a sweep' if sweep else 'a single run'} writes into {own}={value[:80]}")
    for option in ("--experimental-rerun", "--shell-completion", "-sc"):
        if any(a == option or a.startswith(option + "=") for a in args):
            return f"{option}: Hydra's option is not supported by fuzzynav's commands (see --help)"
    if any(a == "--config-path" or a.startswith("--config-path=") for a in args):  # (written out in full before)
        return ("--config-path: the folder of an application's primary config, fixed for fuzzynav's commands; add a "
                "folder of configs with --config-dir DIR (and --config-name NAME for one of its files)")
    return None


def multirun_problem(args: list[str]) -> str:
    """One line for ``runners.run -m ...``: the same command line as a ``runners.sweep`` command."""
    import shlex

    # a sweep writes into hydra.sweep.dir: the single run's folder, said as the sweep's
    rest = [a.replace("hydra.run.dir=", "hydra.sweep.dir=", 1) if a.startswith("hydra.run.dir=") else a
            for a in args if a not in ("-m", "--multirun")]
    command = shlex.join(["python", "-m", "runners.sweep", *rest])
    return (f"-m/--multirun: runners.run runs one configuration; for a sweep (all cores, progress, a summary and the "
            f"report) use: {command[:300]}")


def single_run_sweep(overrides: list[str], shown: bool = False) -> str | None:
    """One line about the first override that sweeps (``planner=auto,wait``, ``seed=range(3)``) in a single run:
    Hydra answered with five lines of options; ``runners.sweep`` is the command for it. ``shown``: the command is
    ``runners.sweep --cfg``/``--info``, which shows one configuration (Hydra's options do not sweep)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parser = OverridesParser.create()
    for text in overrides:
        try:
            (override,) = parser.parse_overrides([text])
        except Exception:  # an override that does not parse: the precheck reports it
            continue
        if override.is_sweep_override():
            key = override.get_key_element()
            if shown:
                return (f"config: {key[:80]}: {text.partition('=')[2][:80]!r} is a sweep; --cfg and --info show one "
                        "configuration of the sweep: give one value")
            return (f"config: {key[:80]}: {text.partition('=')[2][:80]!r} is a sweep and runners.run runs one "
                    f"configuration: use python -m runners.sweep (or quote the value for a string: "
                    f"{key[:80]}='...')")
    return None


def hydra_arguments(args: list[str]) -> tuple[Any, list[str]] | None:
    """The command-line arguments as Hydra's own parser reads them (its options, ``overrides``) and those it does
    not know; None for a malformed option of Hydra's (Hydra's own message follows when Hydra reads them)."""
    import io

    from hydra._internal.utils import get_args_parser

    try:
        with contextlib.redirect_stderr(io.StringIO()):
            return get_args_parser().parse_known_args(args)
    except SystemExit:
        return None


def hydra_overrides(args: list[str]) -> tuple[list[str], str | None, bool]:
    """The config overrides among the command-line arguments (as Hydra's own parser reads them: ``--cfg job`` is
    an option and its value), one line about the first argument that looks like an option but is none of
    Hydra's (Hydra printed its 8-line usage for ``--planner.h_wait=2``, a config override written with dashes),
    and whether the command is a plain run: overrides only (``--run`` at most: no ``--cfg``, ``--info``,
    ``--config-dir`` ...) and none of ``hydra.mode``."""
    parsed = hydra_arguments(args)
    if parsed is None:
        return [a for a in args if not a.startswith("-")], None, False
    known, unknown = parsed
    for arg in unknown:
        if arg.startswith("-"):
            bare = arg.lstrip("-")
            hint = f" (a config override has no dashes: {bare[:80]})" if "=" in bare and bare else ""
            return [], f"{arg[:80]}: unknown option{hint}; see --help", False
    overrides = list(known.overrides) + [a for a in unknown if not a.startswith("-")]
    options = not any(value for name, value in vars(known).items() if name not in ("overrides", "run"))
    mode = any(o.lstrip("+~").partition("=")[0].strip() == "hydra.mode" for o in overrides)
    return overrides, None, options and not mode


def primary_config_problem(args: list[str]) -> str | None:
    """One line when ``--config-dir`` is not a folder or ``--config-name`` names no YAML file in fuzzynav's
    ``conf/``, that folder or another package's config folder (Hydra answered with its search path, five lines),
    else None."""
    parsed = hydra_arguments(args)
    if parsed is None:
        return None
    known, _ = parsed
    try:
        folders = [CONF_DIR, *(folder for _, folder in config_plugins.plugin_config_dirs())]
    except config_plugins.PluginConfigError:  # the precheck reports a broken entry point
        return None
    if known.config_dir is not None:
        extra = Path(known.config_dir).expanduser()
        if not extra.is_dir():
            return f"--config-dir {str(known.config_dir)[:120]}: not a folder"
        folders.insert(0, extra)
    name = known.config_name
    if name is None or any((Path(folder) / f"{name.removesuffix('.yaml')}.yaml").is_file() for folder in folders):
        return None
    where = "conf/" + (f" or {str(known.config_dir)[:120]}" if known.config_dir is not None else "")
    return f"--config-name {str(name)[:80]}: no such config in {where} (fuzzynav's is config)"


def register_sweeper() -> None:
    """Register fuzzynav's sweeper (``conf/hydra/sweeper/fuzzynav.yaml``) and launcher (``all_cores``) with Hydra.
    Hydra finds plugins by scanning the ``hydra_plugins`` package, which misses packages installed in editable mode
    (``pip install -e``), so they are registered here by hand; without fuzzynav installed, multirun says how to
    install it."""
    from hydra.core.plugins import Plugins

    try:
        from hydra_plugins.fuzzynav_sweeper import FuzzynavSweeper
        from hydra_plugins.fuzzynav_sweeper.launcher import FuzzynavLauncher
    except ImportError:
        multirun = "--multirun" in sys.argv or "-m" in sys.argv
        if multirun and not any(a.startswith("hydra/sweeper=") for a in sys.argv):
            print("error: the sweeper hydra_plugins.fuzzynav_sweeper is not installed: run `pip install -e .` in "
                  "the fuzzynav checkout (or choose Hydra's with hydra/sweeper=basic)", file=sys.stderr)
            sys.exit(2)
        return
    Plugins.instance().register(FuzzynavSweeper)
    Plugins.instance().register(FuzzynavLauncher)
    config_plugins.register()


if __name__ == "__main__":
    cli()
