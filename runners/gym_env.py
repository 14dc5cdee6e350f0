"""A Gymnasium environment on fuzzynav's policy seam: ``gymnasium.make("fuzzynav/Navigation-v0", scenario=...)``.

Install the optional extra (``pip install -e '.[gym]'``) and import this module once, which registers the id::

    import gymnasium
    import runners.gym_env  # noqa: F401  (registers fuzzynav/Navigation-v0)

    env = gymnasium.make("fuzzynav/Navigation-v0", scenario="crossing_right")
    obs, info = env.reset(seed=3)
    obs, reward, terminated, truncated, info = env.step([0.0, 30.0])   # steer 0 deg, 30 cm/s

or, without the import, ``gymnasium.make("runners.gym_env:fuzzynav/Navigation-v0", ...)``.

The agent's action takes the place of the navigation policy (:mod:`fuzzynav.policies.base`): it is the command of a
small policy object (mode and name ``agent``) that the episode's navigator calls. The agent drives: the paper's
wait/detour layer, which replaces the command whenever the TPT predicts a collision, is off (``planner=none``)
unless the overrides choose a planner (``overrides=["planner=auto"]``); the decision actually executed is in
``info["mode"]``: ``agent`` or a plan's ``wait``/``detour``/``evade``/``stop``.
:meth:`NavigationEnv.step_policy_action` lets a fuzzynav policy drive instead, recorded exactly as under
``runners.run`` (same decision mode, name and fields), so that ``runners.gym_log.RecordMcap`` writes the same
log content as ``python -m runners.run``.

Configuration is composed from ``conf/`` with Hydra exactly as ``runners.run`` composes it, and checked by the
same code (:func:`runners.configuration.precheck.precheck`, :func:`runners.configuration.run_inputs.load_run`): a bad
argument is one
``ValueError`` naming the field. This module does no file I/O of its own (Hydra reads ``conf/``; a scenario
path is read by ``runners.configuration.data_files``).

Units: cm, s, degrees, cm/s (the reward is in metres).
"""

from __future__ import annotations

import contextlib
import copy
import re
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import gymnasium
import numpy as np
from gymnasium import spaces

from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode import Episode, EpisodeConfig, StepRecord
from fuzzynav.numerics import portable_math
from fuzzynav.params import limits
from fuzzynav.params.checks import check_number
from fuzzynav.params.names import AGENT, is_policy_id
from fuzzynav.planning.layer import checked_action
from fuzzynav.policies.base import Action, Observation, Policy, PolicyContext, make_policy
from fuzzynav.scenarios.scenario import Scenario, ScenarioError, scenario_from_dict
from fuzzynav.sensing.laser import LaserScan
from runners.configuration import plugins as config_plugins
from runners.logs import yaml_text

ENV_ID = "fuzzynav/Navigation-v0"


# reward terms (see NavigationEnv's docstring)
GOAL_REWARD = 10.0
COLLISION_PENALTY = -10.0
STEP_PENALTY = -0.01

_SCENARIO_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}")
_RUN_KEYS = ("seed", "episodes")  # run settings the environment chooses itself (reset's seed, one episode each)


class AgentPolicy:
    """The policy slot's occupant in the environment: it returns the command it was given for this step.

    ``name`` is ``agent`` for the agent's actions (:meth:`NavigationEnv.step`), or the name of the fuzzynav
    policy whose action it passes on (:meth:`NavigationEnv.step_policy_action`), so the decision record names
    the policy exactly as under ``runners.run``. The observation it is called with is the one the environment
    showed the agent: the episode senses once per step (:meth:`fuzzynav.episode.Episode.observe`)."""

    def __init__(self) -> None:
        self.name = AGENT
        self.pending: Action | None = None

    def reset(self, seed: int) -> None:
        """Nothing to forget: the command comes from outside each step."""
        self.pending = None

    def act(self, observation: Observation) -> Action:
        """The command set for this step (the planning layer calls this once per step)."""
        if self.pending is None:
            raise RuntimeError("AgentPolicy.act: no command was set for this step (drive the episode through "
                               "NavigationEnv.step or step_policy_action)")
        action, self.pending = self.pending, None
        return action


class NavigationEnv(gymnasium.Env):
    """One fuzzynav episode per Gymnasium episode (see the module docstring).

    Constructor (keywords):

    - ``scenario``: a scenario name of ``conf/scenario/`` (``crossing_right``), a path to a scenario YAML file,
      or a :class:`fuzzynav.scenarios.scenario.Scenario`; default: the configuration's (``head_on``);
    - ``overrides``: Hydra override strings as on ``runners.run``'s command line (``["planner=auto",
      "sensors.laser.noise_std_cm=1"]``); ``seed`` and ``episodes`` are not accepted (``reset(seed=...)``
      chooses the seed, each reset is one episode); without a ``planner=...`` override the planner is ``none``
      (:func:`agent_drives`);
    - ``normalized``: False (default): the action is in the robot's units and observations float64; True:
      ``action_space = Box(-1, 1, (2,), float32)`` (``-1..1`` steering onto ``-max_turn_deg..max_turn_deg``,
      ``-1..1`` speed onto ``0..v_max``) and every observation part float32;
    - ``max_tracks``: rows of the obstacle part of the observation (default 8);
    - ``render_mode``: None or ``"ansi"`` (one line of text per step).

    Action space: ``Box(low=[-max_turn_deg, 0], high=[max_turn_deg, v_max], float64)`` (from ``robot``):
    ``action[0]`` the steering increment in degrees (positive = counter-clockwise = left), ``action[1]`` the speed
    in cm/s. The robot turns first, then moves ``v · dt`` (:func:`fuzzynav.kinematics.step_unicycle`); a speed of
    0 means stand still, and a speed in (0, v_min) is driven at ``v_min``: the robot moves at v_min..v_max or not
    at all. Values outside the box are clamped to it (``[0, -20]`` stands still); NaN/inf, text, booleans,
    complex numbers or a wrong shape are a ``ValueError``; ``reset`` takes no ``options``.

    Observation space (``Dict``, every part float64; positions and velocities bounded by ±1e9 cm, cm/s, fuzzynav's
    bound on every scenario number):

    - ``sonar`` (3,): left, front, right sonar readings, cm, in [0, ``sensors.sonar.range_cm``];
    - ``laser`` (N,): the laser's ranges, cm, beam k at ``k · 360 / N`` degrees counter-clockwise from the
      heading, in [0, ``sensors.laser.range_cm``] (``range_cm`` = no return);
    - ``robot`` (4,): x, y (cm), heading (degrees in [0, 360), counter-clockwise from +x), speed of the last
      step (cm/s);
    - ``goal`` (2,): x, y of the goal, cm;
    - ``tracks`` (max_tracks, 5): the perceived moving obstacles, nearest first: x, y (cm), vx, vy (cm/s),
      radius (cm); rows past the last obstacle are 0;
    - ``tracks_mask`` (max_tracks,): 1.0 for a row holding an obstacle, 0.0 for padding (obstacles beyond
      ``max_tracks`` are left out, the farthest first; ``info["tracks_dropped"]`` counts them).

    Perception is the configuration's (``perception=laser``: the laser tracker's estimates; ``ground_truth``:
    the true obstacles once in laser range), as every policy sees it.

    Reward per step: the progress towards the goal in metres (distance before minus after, /100), plus
    ``STEP_PENALTY`` (-0.01), plus ``GOAL_REWARD`` (+10) on reaching the goal, plus ``COLLISION_PENALTY`` (-10) on
    a step with a new contact. ``terminated`` on goal or collision, ``truncated`` on timeout (the scenario's
    ``max_steps``). ``info``: ``step``, ``outcome`` (None until the end), ``mode`` (the decision executed),
    ``distance_to_goal_cm``, ``contacts``, ``tracks_dropped``.

    ``env.unwrapped.observation`` is the step's :class:`fuzzynav.policies.base.Observation` (what a fuzzynav policy
    acts on), ``env.unwrapped.episode`` the :class:`fuzzynav.episode.Episode`, ``env.unwrapped.last_record``
    the last :class:`fuzzynav.episode.StepRecord`.
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["ansi"], "render_fps": 1}

    def __init__(self, scenario: str | Path | Scenario | None = None, overrides: Sequence[str] | None = None,
                 max_tracks: int = 8, render_mode: str | None = None, normalized: bool = False) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected None or one of {self.metadata['render_modes']}, got "
                             f"{str(render_mode)[:40]!r}")
        if isinstance(max_tracks, bool) or not isinstance(max_tracks, int | np.integer) or not 0 <= max_tracks <= 1000:
            raise ValueError(f"max_tracks: expected an integer in [0, 1000], got {str(max_tracks)[:40]!r}")
        if not isinstance(normalized, bool):
            raise ValueError(f"normalized: expected true or false, got {str(normalized)[:40]!r}")
        self.render_mode = render_mode
        self.max_tracks = int(max_tracks)
        self.normalized = normalized
        self.run = compose_run(scenario, overrides)
        cfg: EpisodeConfig = self.run.episode_config
        self.episode_config = cfg
        self.evaluator: FastEvaluator = self.run.evaluator
        lim = cfg.robot
        # normalised: what most learners expect (actions in [-1, 1], float32 observations)
        self._dtype = np.float32 if normalized else np.float64
        if normalized:
            self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        else:
            self.action_space = spaces.Box(low=np.array([-lim.max_turn_deg, 0.0]),
                                           high=np.array([lim.max_turn_deg, lim.v_max]), dtype=np.float64)
        # positions and velocities: fuzzynav's bound on every scenario number (|x| <= 1e9 cm, cm/s), not infinity
        # (Gymnasium's checker and many learners want finite bounds); _obs clips to them
        big, dt = limits.MAX_COORD_CM, self._dtype
        self.observation_space = spaces.Dict({
            "sonar": spaces.Box(0.0, cfg.sonar.range_cm, (3,), dt),
            "laser": spaces.Box(0.0, cfg.laser.range_cm, (cfg.laser.beams,), dt),
            "robot": spaces.Box(np.array([-big, -big, 0.0, 0.0], dtype=dt),
                                np.array([big, big, 360.0, lim.v_max], dtype=dt), dtype=dt),
            "goal": spaces.Box(-big, big, (2,), dt),
            "tracks": spaces.Box(-big, big, (self.max_tracks, 5), dt),
            "tracks_mask": spaces.Box(0.0, 1.0, (self.max_tracks,), dt),
        })
        self._agent = AgentPolicy()
        self.episode: Episode | None = None
        self.observation: Observation | None = None
        self.last_record: StepRecord | None = None
        self._scan: LaserScan | None = None
        self._dropped = 0

    # -- what a fuzzynav policy needs to drive this environment ---------------------------------------------
    @property
    def scenario(self) -> Scenario:
        """The scenario of the current episode (a generated scenario depends on the seed), else of seed 0."""
        return self.episode.scenario if self.episode is not None else self.run.scenario_for(0)

    @property
    def policy_context(self) -> PolicyContext:
        """The :class:`fuzzynav.policies.base.PolicyContext` a policy is built with under ``runners.run``."""
        cfg = self.episode_config
        return PolicyContext(cfg.robot, self.scenario.robot.radius, cfg.dt, cfg.sonar.front, self.evaluator)

    def configured_policy(self) -> Policy:
        """The policy the configuration names (``navigator`` group), built as ``runners.run`` builds it; drive with
        it through :meth:`step_policy_action` (call its ``reset(seed)`` after each :meth:`reset`)."""
        cfg = self.episode_config
        return make_policy(cfg.policy, cfg.navigator, self.policy_context)

    # -- Gymnasium API ---------------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        """A new episode with ``seed`` (an integer in [0, 2^53 - 1]; None: drawn from ``self.np_random``)."""
        if seed is not None:  # checked first: Gymnasium's own reset and checker keep a refused seed otherwise
            if isinstance(seed, np.integer):  # a seed drawn with numpy (Gymnasium's own reset takes Python ints)
                seed = int(seed)
            seed = int(check_number(seed, "seed", limits.FIELD_RANGES["seed"]))
        if options is not None and not (isinstance(options, Mapping) and len(options) == 0):
            what = f"unknown key(s) {sorted(map(str, options))[:5]}" if isinstance(options, Mapping) else \
                f"expected a dict, got {type(options).__name__}"
            raise ValueError(f"options: {what}; reset takes no options (choose the scenario and overrides when "
                             "making the environment)")
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31))
        self.episode = Episode(self.run.scenario_for(seed), self.evaluator, self.episode_config, seed=seed,
                               policy=self._agent)
        self.last_record = None
        self._sense()
        return self._obs(), self._info(None)

    def step(self, action: Any) -> tuple[dict, float, bool, bool, dict]:
        """One time step with the agent's command ``[dtheta_deg, v_cm_s]`` (normalised: ``[-1..1, -1..1]``), see
        the class docstring."""
        dtheta, v = self.command(action)
        return self._advance(Action(AGENT, dtheta, v, {}), AGENT)

    def command(self, action: Any) -> tuple[float, float]:
        """The command ``(dtheta_deg, v_cm_s)`` an action stands for: two real numbers (not text, booleans or
        complex numbers), finite, clamped to the action space and, when normalised, scaled from [-1, 1]."""
        if isinstance(action, str | bytes) or (isinstance(action, list | tuple) and any(
                isinstance(x, bool | np.bool_) for x in action)):  # numpy reads [True, 20] as the numbers [1, 20]
            arr = None
        else:
            try:
                arr = np.asarray(action)
            except (TypeError, ValueError):  # ragged input: numpy's own message does not say which argument
                arr = None
        if arr is None or arr.shape != (2,) or arr.dtype.kind not in "iuf":
            raise ValueError(f"action: expected 2 real numbers [dtheta_deg, v_cm_s], got {str(action)[:60]!r}")
        arr = arr.astype(np.float64)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"action: must be finite numbers, got [{arr[0]!r}, {arr[1]!r}]")
        low, high = self.action_space.low.astype(np.float64), self.action_space.high.astype(np.float64)
        arr = np.minimum(np.maximum(arr, low), high)
        if self.normalized:  # [-1, 1] onto [-max_turn, max_turn] and [0, v_max]
            lim = self.episode_config.robot
            return float(arr[0]) * lim.max_turn_deg, (float(arr[1]) + 1.0) / 2.0 * lim.v_max
        return float(arr[0]), float(arr[1])

    def step_policy_action(self, action: Action, policy_name: str) -> tuple[dict, float, bool, bool, dict]:
        """One time step with a fuzzynav policy's :class:`~fuzzynav.policies.base.Action` (its ``act`` on
        :attr:`observation`), its mode, fields and ``policy_name`` recorded as ``runners.run`` records them."""
        if not isinstance(policy_name, str) or not is_policy_id(policy_name):
            raise ValueError(f"policy_name: expected the policy's name, got {str(policy_name)[:40]!r}")
        # before the step (a bad action leaves the episode and its log as they are); the values checked are the
        # ones the robot executes
        return self._advance(checked_action(action, policy_name), policy_name)

    def render(self) -> str | None:
        """``ansi``: one line: step, pose (cm, degrees), speed (cm/s), distance to the goal (cm), last mode."""
        if self.render_mode != "ansi" or self.episode is None:
            return None
        s, rec = self.episode.state, self.last_record
        dist = portable_math.dist((s.x, s.y), self.episode.scenario.robot.goal)
        mode = rec.decision.mode if rec is not None else "-"
        return (f"step {self.episode.step_index}: x={s.x:.1f} y={s.y:.1f} heading={s.heading:.1f} v={s.v:.1f} "
                f"goal {dist:.1f} cm, mode {mode}, outcome {self.episode.outcome or '-'}")

    # -- internals -------------------------------------------------------------------------------------------
    def _advance(self, action: Action, name: str) -> tuple[dict, float, bool, bool, dict]:
        ep = self.episode
        if ep is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        if ep.done:
            raise gymnasium.error.ResetNeeded(f"the episode is over ({ep.outcome}): call reset()")
        before = portable_math.dist((ep.state.x, ep.state.y), ep.scenario.robot.goal)
        self._agent.name, self._agent.pending = name, action
        try:
            record = ep.step()
        finally:
            self._agent.pending = None
        self.last_record = record
        reward = (before - record.distance_to_goal) / 100.0 + STEP_PENALTY
        if record.new_contacts:
            reward += COLLISION_PENALTY
        if record.outcome == "goal":
            reward += GOAL_REWARD
        if not ep.done:
            self._sense()
        terminated = record.outcome in ("goal", "collision")
        truncated = record.outcome == "timeout"
        return self._obs(), float(reward), terminated, truncated, self._info(record)

    def _sense(self) -> None:
        """The coming step's sensing (:meth:`Episode.observe`: the episode then acts on exactly this)."""
        self.observation, self._scan = self.episode.observe()

    def _obs(self) -> dict[str, np.ndarray]:
        obs, scan = self.observation, self._scan
        s = obs.state
        tracks = sorted(obs.tracks, key=lambda t: portable_math.dist((t.x, t.y), (s.x, s.y)))  # stable: ties keep order
        self._dropped = max(0, len(tracks) - self.max_tracks)
        rows = np.zeros((self.max_tracks, 5))
        mask = np.zeros(self.max_tracks)
        for k, t in enumerate(tracks[:self.max_tracks]):
            rows[k] = (t.x, t.y, t.vx, t.vy, t.radius)
            mask[k] = 1.0
        big = limits.MAX_COORD_CM  # the spaces' bounds: a wild tracker estimate must not leave the space
        parts = {"sonar": np.array(obs.sonar, dtype=np.float64),
                 "laser": np.array(scan.ranges, dtype=np.float64),
                 "robot": np.array([min(max(s.x, -big), big), min(max(s.y, -big), big), s.heading, s.v]),
                 "goal": np.array(obs.goal, dtype=np.float64),
                 "tracks": np.clip(rows, -big, big), "tracks_mask": mask}
        if self._dtype is np.float64:
            return parts
        # float32 rounds a heading of 359.99999999 up to 360.0, outside [0, 360): kept inside each part's box
        out = {}
        for name, value in parts.items():
            box = self.observation_space[name]
            out[name] = np.minimum(np.maximum(value.astype(np.float32), box.low), box.high)
        return out

    def _info(self, record: StepRecord | None) -> dict[str, Any]:
        ep = self.episode
        return {"step": ep.step_index, "outcome": ep.outcome, "mode": record.decision.mode if record else None,
                "distance_to_goal_cm": portable_math.dist((ep.state.x, ep.state.y), ep.scenario.robot.goal),
                "contacts": ep.contacts, "tracks_dropped": self._dropped, "seed": ep.seed}


# -- configuration: composed and checked by runners' code, as runners.run does ------------------------------------
class ComposedRun:
    """The composed, checked configuration of the environment's runs: ``config`` (Hydra's task config, without
    its ``hydra`` node, as ``runners.run`` sees it), ``plain`` (resolved plain data), ``episode_config`` and
    ``evaluator``; :meth:`scenario_for` gives a seed's scenario (generated scenarios depend on the seed)."""

    def __init__(self, config: Any, plain: dict[str, Any], episode_config: EpisodeConfig,
                 evaluator: FastEvaluator, fixed: Scenario | None) -> None:
        self.config, self.plain, self.episode_config, self.evaluator = config, plain, episode_config, evaluator
        self._fixed = fixed
        self._generated: tuple[int, Scenario] | None = None

    def scenario_for(self, seed: int) -> Scenario:
        if self._fixed is not None:
            return self._fixed
        if self._generated is None or self._generated[0] != seed:
            from runners.configuration.run_inputs import load_scenario

            self._generated = (seed, load_scenario(self.plain, seed))
        return self._generated[1]

    def config_yaml(self, seed: int, navigator: Mapping[str, Any] | None = None) -> str:
        """The resolved config as ``runners.run`` logs it for an episode of ``seed`` (``seed: <seed>``);
        ``navigator``: another ``navigator`` section in its place (an agent's log names the agent)."""
        from omegaconf import open_dict

        cfg = copy.deepcopy(self.config)
        with open_dict(cfg):
            cfg.seed = seed
            if navigator is not None:
                cfg.navigator = dict(navigator)
        return yaml_text.config_text(cfg, resolve=True)


def compose_run(scenario: str | Path | Scenario | None, overrides: Sequence[str] | None) -> ComposedRun:
    """Compose ``conf/`` with ``overrides`` (and ``scenario``) and check it exactly as ``python -m runners.run``
    does (:func:`runners.configuration.precheck.precheck`, :func:`runners.configuration.run_inputs.load_run`);
    ``ValueError`` with one line
    naming the field for any problem."""
    from omegaconf import DictConfig, OmegaConf, open_dict, read_write

    from runners.configuration.data_files import DataFileError, check_data_file
    from runners.configuration.precheck import precheck
    from runners.configuration.run_inputs import ConfigFileError, load_run
    from runners.run import scenario_yaml, single_run_sweep

    if overrides is None:
        overrides = []
    if isinstance(overrides, str) or not isinstance(overrides, Sequence):
        raise ValueError(f"overrides: expected a list of override strings such as ['planner=auto'], got "
                         f"{type(overrides).__name__}")
    overrides = list(overrides)
    for text in overrides:
        if not isinstance(text, str):
            raise ValueError(f"overrides: expected strings, got {type(text).__name__} {str(text)[:40]!r}")
        if text.startswith("-"):
            raise ValueError(f"overrides: {text[:60]!r} is an option, not a config override (key=value)")
        key = text.partition("=")[0].lstrip("+~")
        if key in _RUN_KEYS:
            raise ValueError(f"overrides: {key}: chosen by the environment (reset(seed=...); one episode per reset)")
        if key == "scenario" and scenario is not None:
            raise ValueError("overrides: scenario: given twice (the scenario argument and a scenario= override)")
    data: dict[str, Any] | None = None  # a scenario given as a file or an object, put into the config as data
    if isinstance(scenario, Scenario):
        import yaml

        data = yaml.safe_load(scenario_yaml(scenario))
    elif isinstance(scenario, Path) or (isinstance(scenario, str) and scenario.endswith((".yaml", ".yml"))):
        import yaml

        try:
            raw = check_data_file(Path(scenario))
        except DataFileError as err:
            raise ValueError(f"scenario: {err}") from None
        data = yaml.safe_load(raw)
        try:  # checked here so that the message names this file (load_run would name the composed option's)
            if not (isinstance(data, Mapping) and "generator" in data):  # a generator's are checked per seed
                scenario_from_dict(data)  # the data file check above made sure it is a mapping
        except ScenarioError as err:
            raise ValueError(f"scenario: {scenario}: {err}") from None
    elif isinstance(scenario, str):
        if not _SCENARIO_NAME.fullmatch(scenario):
            raise ValueError(f"scenario: expected a name of conf/scenario/, a .yaml path or a Scenario, got "
                             f"{scenario[:60]!r}")
        overrides = [f"scenario={scenario}", *overrides]
    elif scenario is not None:
        raise ValueError(f"scenario: expected a name of conf/scenario/, a .yaml path or a Scenario, got "
                         f"{type(scenario).__name__}")
    overrides = agent_drives(overrides)
    problem = single_run_sweep(overrides)
    composed: list[DictConfig] = []
    with _hydra_of_our_own():
        problem = problem or precheck(overrides, composed.append)
        if problem:
            raise ValueError(problem.removeprefix("error: "))
        # the precheck hands over the config it composed, except with no override at all (it then composes none)
        cfg = composed[0] if composed else _compose(overrides)
    runtime = cfg.hydra.runtime
    with read_write(cfg), open_dict(cfg):
        if data is not None:
            cfg.scenario = data
        task = copy.deepcopy(cfg)
        del task["hydra"]  # what runners.run's job sees (Hydra removes its node from the task config)
    try:
        inputs = load_run(cfg, runtime, all_seeds=False)
    except ConfigFileError as err:
        raise ValueError(f"scenario: {err}" if data is not None else str(err)) from None
    except ValueError as err:
        raise ValueError(str(err)) from None
    generated = isinstance(inputs.plain.get("scenario"), Mapping) and "generator" in inputs.plain["scenario"]
    fixed = None if generated else inputs.scenarios[inputs.seeds[0]]
    OmegaConf.set_readonly(task, False)
    return ComposedRun(task, inputs.plain, inputs.episode_config, inputs.evaluator, fixed)


def agent_drives(overrides: list[str]) -> list[str]:
    """``overrides`` with ``planner=none`` first, unless they choose a planner (``planner=auto``,
    ``planner=wait``, ...): in the environment the agent drives, and the paper's wait/detour layer, which replaces
    the agent's command whenever the TPT predicts a collision, runs only when asked for. A ``planner.<key>`` override
    without a chosen planner would change nothing: ``ValueError`` saying to choose one."""
    chosen = False
    for text in overrides:
        key = text.partition("=")[0].lstrip("+~")
        if key in ("planner", "planner.strategy"):
            chosen = True
    if chosen:
        return overrides
    for text in overrides:
        key = text.partition("=")[0].lstrip("+~")
        if key.startswith("planner."):
            raise ValueError(f"overrides: {key[:60]}: the wait/detour layer is off in the environment (the agent "
                             "drives); choose it as well, e.g. overrides=['planner=auto', "
                             f"{text[:60]!r}]")
    return ["planner=none", *overrides]


@contextlib.contextmanager
def _hydra_of_our_own() -> Iterator[None]:
    """Compose ``conf/`` even inside a program that already initialised Hydra (a ``@hydra.main`` training script,
    a test): Hydra's ``initialize_config_dir`` refuses to run while its global instance is initialised, so that
    instance is set aside while the environment's config is composed, and put back afterwards."""
    from hydra.core.global_hydra import GlobalHydra
    from hydra.core.singleton import Singleton

    saved = Singleton._instances.get(GlobalHydra)
    if saved is not None:
        del Singleton._instances[GlobalHydra]
    try:
        yield
    finally:
        if saved is not None:
            Singleton._instances[GlobalHydra] = saved


def _compose(overrides: list[str]) -> Any:
    """The config composed from ``conf/`` as :func:`runners.configuration.precheck.precheck` composes it (Hydra's node
    included)."""
    from hydra import compose, initialize_config_dir

    from runners.configuration import schema
    from runners.configuration.precheck import CONF

    schema.register()
    config_plugins.register()  # other packages' config folders (entry points)
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return compose("config", overrides=overrides, return_hydra_config=True)


def register() -> None:
    """Register :data:`ENV_ID` with Gymnasium (once; importing this module does it)."""
    if ENV_ID not in gymnasium.registry:
        # Gymnasium's passive checker, which make() would add, breaks the environment for good when the first
        # reset is refused (a bad seed or option): its first step then fails inside the checker with a TypeError.
        # The environment passes the full checker instead (gymnasium.utils.env_checker.check_env, in the tests).
        gymnasium.register(id=ENV_ID, entry_point="runners.gym_env:NavigationEnv", disable_env_checker=True)


register()
