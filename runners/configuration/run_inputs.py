"""The inputs of a run, loaded and validated in one place: the composed config's run settings (seed,
episodes), the episode configuration, the controller and the scenario(s).

Used by ``runners.run`` (in each job) and by the command-line check (:mod:`runners.configuration.precheck`, before
anything
runs), and by the dataset and bench runners through ``runners.run``. Every problem is one exception whose
message is one line naming the file (or the config key) and the field:

- :class:`ConfigFileError` for the scenario and controller files: ``…/my_world.yaml: robot.start: …``;
- ``ValueError`` for the run configuration: ``planner.safety_margin_cm: must be finite, got nan``.

Ranges and size limits come from :mod:`fuzzynav.params.limits`.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from omegaconf import DictConfig, ListConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.controller.fuzzy_spec import ControllerSpec, ControllerSpecError, check_fits_robot
from fuzzynav.episode import EpisodeConfig
from fuzzynav.params import limits
from fuzzynav.params.checks import check_number, kind_of, show
from fuzzynav.params.limits import Range
from fuzzynav.pedestrians.crowd import check_crowd_work
from fuzzynav.scenarios.generator import generate
from fuzzynav.scenarios.scenario import Scenario, ScenarioError, scenario_from_dict

DATA_GROUPS = ("scenario", "controller")  # config groups whose options are data files of fuzzynav's own parsers

_ANNOUNCE_SCENARIOS = 1_000  # a run generating this many scenarios up front says so
_EVALUATORS: dict[ControllerSpec, FastEvaluator] = {}  # one evaluator per controller and worker process


class ConfigFileError(Exception):
    """A scenario or controller file is invalid; the message names the file and the field."""


def source_of(group: str, runtime: Any = None) -> str:
    """Best description of the file a config group option came from: its path when Hydra's runtime (choices
    and config sources) is known — ``runtime`` or the running job's — else ``group=choice`` or ``group``."""
    if runtime is None:
        from hydra.core.hydra_config import HydraConfig

        try:
            runtime = HydraConfig.get().runtime
        except ValueError:
            return group
    choice = runtime.choices.get(group)
    if choice is None:
        return group
    for src in runtime.config_sources:
        if src.provider == "schema" or not src.path or src.schema not in (None, "file"):
            continue
        candidate = Path(src.path.replace("file://", "")) / group / f"{choice}.yaml"
        if candidate.exists():
            return str(candidate)
    return f"{group}={choice}"


def check_data_nodes(cfg: DictConfig, runtime: Any = None) -> None:
    """Scenario and controller are data: no ``${...}`` interpolation anywhere in them (checked before the
    config is resolved, so that ``${oc.env:...}`` is never evaluated)."""
    for group in DATA_GROUPS:
        node = cfg.get(group)
        if isinstance(node, DictConfig | ListConfig):
            field = _interpolation(OmegaConf.to_container(node, resolve=False), "")
            if field is not None:
                raise ConfigFileError(f"{source_of(group, runtime)}: {field[0] or 'top level'}: interpolation "
                                      f"{field[1]} is not allowed: scenario and controller files are data")


def _interpolation(value: Any, field: str) -> tuple[str, str] | None:
    """(field, text) of the first string holding ``${``, or None."""
    if isinstance(value, str):
        return (field, repr(value[:60])) if "${" in value else None
    if isinstance(value, Mapping):
        for key, item in value.items():
            found = _interpolation(key, field) or _interpolation(item, f"{field}.{key}" if field else str(key))
            if found:
                return found
    if isinstance(value, list):
        for i, item in enumerate(value):
            found = _interpolation(item, f"{field}[{i}]")
            if found:
                return found
    return None


def plain_config(cfg: DictConfig) -> dict[str, Any]:
    """The composed config as plain data, resolved, without Hydra's own node."""
    try:
        return {key: OmegaConf.to_container(cfg[key], resolve=True) if OmegaConf.is_config(cfg[key]) else cfg[key]
                for key in cfg if key != "hydra"}
    except OmegaConfBaseException as err:
        key = getattr(err, "full_key", None)  # ``planner.h_wait=${planner.h_wait}``: say which key
        where = f"{key}: " if key else ""
        raise ValueError(f"{where}cannot resolve the config: {str(err).splitlines()[0]}") from None


def run_seeds(cfg: Mapping[str, Any]) -> list[int]:
    """Seeds of the run's episodes: ``seed`` … ``seed + episodes - 1`` (both checked against their ranges)."""
    seed = int(check_number(cfg.get("seed", 0), "seed", limits.FIELD_RANGES["seed"]))
    episodes = int(check_number(cfg.get("episodes", 1), "episodes", limits.FIELD_RANGES["episodes"]))
    if seed + episodes - 1 > limits.MAX_SEED:
        raise ValueError(f"seed: seed + episodes - 1 = {seed + episodes - 1} is above the limit {limits.MAX_SEED} "
                         "(2^53 - 1)")
    return [seed + k for k in range(episodes)]


def episode_config(cfg: Mapping[str, Any]) -> EpisodeConfig:
    """The library's EpisodeConfig from the composed run config (plain data)."""
    sensors = cfg.get("sensors") or {}
    if not isinstance(sensors, Mapping):
        raise ValueError(f"sensors: expected a mapping, got {kind_of(sensors)}")
    return episode_config_from_dict({
        "dt": cfg.get("dt", 1.0), "robot": cfg.get("robot") or {}, "sonar": sensors.get("sonar") or {},
        "laser": sensors.get("laser") or {}, "perception": cfg.get("perception") or {},
        "planner": cfg.get("planner") or {}, "navigator": cfg.get("navigator") or {},
        "terminate_on_collision": cfg.get("terminate_on_collision", True)})


def load_scenario(cfg: Mapping[str, Any], seed: int = 0, runtime: Any = None) -> Scenario:
    """The scenario of the config; a generated one (``generator:`` key) is expanded with ``seed``."""
    data = cfg.get("scenario") or {}
    try:
        if isinstance(data, Mapping) and "generator" in data:
            return generate(data, seed)[0]
        return scenario_from_dict(data)
    except ScenarioError as err:
        raise ConfigFileError(f"{source_of('scenario', runtime)}: {err}") from None


def load_controller(cfg: Mapping[str, Any], runtime: Any = None) -> ControllerSpec:
    """The controller definition of the config, validated."""
    try:
        return ControllerSpec.from_dict(cfg.get("controller") or {})
    except ControllerSpecError as err:
        raise ConfigFileError(f"{source_of('controller', runtime)}: {err}") from None


def load_evaluator(cfg: Mapping[str, Any], runtime: Any = None) -> FastEvaluator:
    """One evaluator per controller definition and worker process (built once, reused by every episode)."""
    spec = load_controller(cfg, runtime)
    if spec not in _EVALUATORS:
        _EVALUATORS[spec] = FastEvaluator(spec)
    return _EVALUATORS[spec]


def check_controller_fits(spec: ControllerSpec, ep_cfg: EpisodeConfig, runtime: Any = None) -> None:
    """The controller's speed output must reach the robot's speed range (see :func:`check_fits_robot`)."""
    try:
        check_fits_robot(spec, ep_cfg.robot.v_min, ep_cfg.robot.v_max)
    except ControllerSpecError as err:
        raise ConfigFileError(f"{source_of('controller', runtime)}: {err}") from None


def check_launcher(hydra_node: Any) -> None:
    """``hydra.launcher.n_jobs`` of a local launcher (fuzzynav's or Hydra's joblib launcher): an integer, not 0,
    |n| <= the limit."""
    launcher = hydra_node.get("launcher") if hydra_node is not None else None
    target = str(launcher.get("_target_", "")) if launcher else ""
    if "FuzzynavLauncher" in target and not isinstance(launcher.get("assemble", True), bool):
        raise ValueError(f"hydra.launcher.assemble: must be true or false, not {launcher.get('assemble')!r:.60}")
    if "FuzzynavLauncher" in target and launcher.get("n_jobs", -1) is None:
        raise ValueError("hydra.launcher.n_jobs: must be an integer (a number of worker processes; -1 = all cores), "
                         "not null")
    if ("joblib" not in target and "FuzzynavLauncher" not in target) or launcher.get("n_jobs") is None:
        return
    n = launcher.get("n_jobs")
    rng = Range(-limits.MAX_LAUNCHER_JOBS, limits.MAX_LAUNCHER_JOBS, integer=True)
    check_number(n, "hydra.launcher.n_jobs", rng)
    if n == 0:
        raise ValueError("hydra.launcher.n_jobs: must not be 0 (a number of worker processes; -1 = all cores)")


def check_sweeper(hydra_node: Any) -> None:
    """``hydra.sweeper.max_batch_size`` (how many jobs the sweeper hands the launcher at once): null (all) or a
    positive integer; Hydra's sweeper asserted or raised a TypeError on 0, -1, 1e9 or text."""
    sweeper = hydra_node.get("sweeper") if hydra_node is not None else None
    size = sweeper.get("max_batch_size") if sweeper else None
    if size is None:
        return
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise ValueError(f"hydra.sweeper.max_batch_size: {size!r:.40} is not a number of jobs (a positive integer, "
                         "or null for all of them at once)")


def check_job_dir(hydra_node: Any) -> None:
    """``hydra.sweep.subdir``, a sweep job's directory inside ``hydra.sweep.dir``: a relative path without ``..``
    (as written, interpolations unresolved). ``../../x`` wrote the job's logs and snapshot outside the sweep
    directory, where neither the summary, the report nor a resume looks, and the sweep said it succeeded; an
    empty subdir put every job's files into the sweep directory itself."""
    sweep = hydra_node.get("sweep") if hydra_node is not None else None
    if sweep is None:
        return
    raw = (OmegaConf.to_container(sweep, resolve=False) if isinstance(sweep, DictConfig) else dict(sweep)).get("subdir")
    if raw is None:
        return
    text = str(raw)
    parts = PurePosixPath(text).parts
    if text.startswith(("/", "~")) or ".." in parts or not parts or "\\" in text:
        raise ValueError(f"hydra.sweep.subdir: {text[:60]!r} is not a directory inside the sweep directory (a "
                         "relative path, without '..')")


def check_output_dirs(hydra_node: Any) -> None:
    """``hydra.run.dir`` and ``hydra.sweep.dir``, the directories a run's or a sweep's files go to: not empty (as
    written, interpolations unresolved). An empty one is the current directory, which would receive the logs,
    ``run.log`` and ``.hydra/`` of the run beside whatever else is there."""
    if hydra_node is None:
        return
    for group in ("run", "sweep"):
        node = hydra_node.get(group)
        if node is None:
            continue
        raw = (OmegaConf.to_container(node, resolve=False) if isinstance(node, DictConfig) else dict(node)).get("dir")
        if raw is not None and not str(raw).strip():
            raise ValueError(f"hydra.{group}.dir: {str(raw)!r} is empty (it would be the current directory): name "
                             "the output directory")


@dataclass(frozen=True)
class RunInputs:
    """Everything a run needs, validated: seeds, episode config, evaluator, the scenario of each seed."""

    seeds: list[int]
    episode_config: EpisodeConfig
    evaluator: FastEvaluator
    scenarios: dict[int, Scenario]
    plain: dict[str, Any]


def load_run(cfg: DictConfig, runtime: Any = None, all_seeds: bool = True) -> RunInputs:
    """Validate and load a composed run config. ``all_seeds=False`` expands a generated scenario for the
    first seed only (the command-line check); a fixed scenario is parsed once for every seed."""
    check_data_nodes(cfg, runtime)
    if "hydra" in cfg:
        check_launcher(cfg.hydra)
        check_sweeper(cfg.hydra)
        check_job_dir(cfg.hydra)
        check_output_dirs(cfg.hydra)
    plain = plain_config(cfg)
    if not isinstance(plain.get("resume", False), bool):  # untyped in the schema (see runners.configuration.schema)
        raise ValueError(f"resume: expected true or false, got {show(plain.get('resume'))}")
    seeds = run_seeds(plain)
    ep_cfg = episode_config(plain)
    evaluator = load_evaluator(plain, runtime)
    check_controller_fits(evaluator.spec, ep_cfg, runtime)
    data = plain.get("scenario")
    if isinstance(data, Mapping) and "generator" in data:
        todo = seeds if all_seeds else seeds[:1]
        if len(todo) >= _ANNOUNCE_SCENARIOS:  # about 6 ms each: a long silent start otherwise
            print(f"generating and validating {len(todo):,} scenarios before the first episode (about "
                  f"{len(todo) * 0.006:.0f} s)", file=sys.stderr)
        scenarios = {seed: load_scenario(plain, seed, runtime) for seed in todo}
    else:
        scenario = load_scenario(plain, seeds[0], runtime)
        scenarios = dict.fromkeys(seeds, scenario)
    for scenario in {id(sc): sc for sc in scenarios.values()}.values():
        check_goal_tolerance(scenario, ep_cfg, runtime)
        try:
            check_crowd_work(scenario.dynamic_obstacles, ep_cfg.dt, scenario.max_steps)
        except ValueError as err:
            raise ConfigFileError(f"{source_of('scenario', runtime)}: {err}") from None
    return RunInputs(seeds, ep_cfg, evaluator, scenarios, plain)


def check_goal_tolerance(scenario: Scenario, ep_cfg: EpisodeConfig, runtime: Any = None) -> None:
    """The goal tolerance (cm) must be at least half the robot's shortest step (``robot.v_min`` × ``dt`` / 2):
    a robot that moves at least v_min·dt per step can always end a step that close to its goal, and with a
    smaller tolerance it may step over the goal from side to side until the episode times out."""
    shortest = ep_cfg.robot.v_min * ep_cfg.dt
    if scenario.tolerance < shortest / 2:
        raise ConfigFileError(f"{source_of('scenario', runtime)}: goal_tolerance: {scenario.tolerance:g} cm is "
                              f"below half the robot's shortest step ({shortest:g} cm: robot.v_min "
                              f"{ep_cfg.robot.v_min:g} cm/s x dt {ep_cfg.dt:g} s), so the goal may never be "
                              "reached")

