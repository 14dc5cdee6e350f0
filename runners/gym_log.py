"""``RecordMcap``: a Gymnasium wrapper writing one MCAP log per episode of :mod:`runners.gym_env`.

    from runners.gym_log import RecordMcap
    env = RecordMcap(gymnasium.make("fuzzynav/Navigation-v0", scenario="crossing_right"), "logs/")

Each episode's log has the name, writer (:class:`runners.logs.mcap_log.EpisodeLogWriter`), metadata and ending
messages that ``python -m runners.run`` writes for the same configuration and seed; driven by the configured
policy through ``step_policy_action``, its message content is the same (``runners.dataset.content_digests``).
An episode left unfinished by ``reset`` or ``close`` is finished as ``interrupted``; an exception inside a step
finishes it as ``error`` (with the traceback in ``/log``) and propagates.

One log can be open at a time per process (the writer's rule): wrap one environment per process, e.g. in a
``gymnasium.vector.AsyncVectorEnv``, not several in a ``SyncVectorEnv``.
"""

from __future__ import annotations

import dataclasses
import traceback
from pathlib import Path
from types import MappingProxyType
from typing import Any

import gymnasium

from fuzzynav.policies.base import Action
from runners.gym_env import AGENT, NavigationEnv
from runners.logs.mcap_log import EpisodeLogWriter
from runners.run import episode_metadata, log_path, outcome_reason, scenario_generator


class RecordMcap(gymnasium.Wrapper):
    """Writes each episode of the wrapped :class:`runners.gym_env.NavigationEnv` to ``out_dir`` (created if
    needed) as ``runners.run`` names it (``<scenario>__…__s<seed>.mcap``); ``paths`` lists the logs written.

    A log names the policy that drove the episode, so that no analysis pools it with another policy's episodes:
    ``policy=None`` (default) records an agent's actions (:meth:`step`): the metadata, the logged config's
    ``navigator`` section and the file name say ``agent``. ``policy="dwa"`` (the configuration's own policy, the
    one :meth:`~runners.gym_env.NavigationEnv.configured_policy` builds) records that policy driving through
    :meth:`step_policy_action`, exactly as ``runners.run`` logs it. Mixing the two in one recorder is refused."""

    def __init__(self, env: gymnasium.Env, out_dir: str | Path, policy: str | None = None) -> None:
        super().__init__(env)
        if not isinstance(env.unwrapped, NavigationEnv):
            raise ValueError(f"env: RecordMcap records fuzzynav/Navigation-v0, got {type(env.unwrapped).__name__}")
        configured = env.unwrapped.episode_config.policy
        if policy is not None and policy != configured:
            raise ValueError(f"policy: {str(policy)[:60]!r} is not the configured policy {configured!r} (the "
                             "navigator group); RecordMcap(policy=None) records an agent")
        if not isinstance(out_dir, str | Path) or not str(out_dir):
            raise ValueError(f"out_dir: expected a directory path, got {str(out_dir)[:60]!r}")
        self.out_dir = Path(out_dir).absolute()
        if self.out_dir.exists() and not self.out_dir.is_dir():
            raise ValueError(f"out_dir: {self.out_dir} exists and is not a directory")
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ValueError(f"out_dir: {self.out_dir}: {err.strerror or err}") from None
        self.policy = policy
        self.paths: list[Path] = []
        self._log: EpisodeLogWriter | None = None

    @property
    def nav(self) -> NavigationEnv:
        return self.env.unwrapped  # type: ignore[return-value]

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        self._finish("interrupted", "reset before the episode ended")
        obs, info = self.env.reset(seed=seed, options=options)
        nav = self.nav
        episode, cfg, run = nav.episode, nav.episode_config, nav.run
        seed_ = episode.seed
        scenario = episode.scenario
        plain = run.plain
        if self.policy is None:  # the agent drives: its logs say so (metadata, config, file name)
            cfg = dataclasses.replace(cfg, policy=AGENT, navigator=MappingProxyType({}))
            plain = {**plain, "navigator": {"policy": AGENT}}
        config_yaml = run.config_yaml(seed_) if self.policy else run.config_yaml(seed_, {"policy": AGENT})
        meta = episode_metadata(scenario, nav.evaluator, cfg, seed_, config_yaml, generator=scenario_generator(plain))
        path = log_path(self.out_dir, scenario.name, plain, seed_)
        self._log = EpisodeLogWriter(path, episode, meta, cfg.planner.strategy, cfg.perception.mode)
        self.paths.append(path)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict]:
        if self.policy is not None:
            raise ValueError(f"action: this recorder logs policy {self.policy!r} (step_policy_action); "
                             "RecordMcap(policy=None) records an agent's actions")
        return self._logged(lambda: self.env.step(action))

    def step_policy_action(self, action: Action, policy_name: str) -> tuple[Any, float, bool, bool, dict]:
        """:meth:`runners.gym_env.NavigationEnv.step_policy_action`, logged."""
        if self.policy is None or policy_name != self.policy:
            raise ValueError(f"policy_name: this recorder logs {self.policy or AGENT!r}, not "
                             f"{str(policy_name)[:60]!r} (RecordMcap(env, out_dir, policy=...))")
        inner = self.env.get_wrapper_attr("step_policy_action")
        return self._logged(lambda: inner(action, policy_name))

    def close(self) -> None:
        self._finish("interrupted", "environment closed before the episode ended")
        super().close()

    def _logged(self, step) -> tuple[Any, float, bool, bool, dict]:
        before = self.nav.last_record
        try:
            result = step()
        except ValueError:  # a bad action: nothing was stepped, the episode goes on
            raise
        except Exception as err:
            if self._log is not None and self.nav.last_record is before:
                self._log.log(self._log._last_time, 4, traceback.format_exc())
                self._finish("error", f"{type(err).__name__}: {err}")
            raise
        if self._log is not None:
            self._log.step(self.nav.last_record)
            episode = self.nav.episode
            if episode.done:
                self._finish(episode.outcome, outcome_reason(episode.outcome, episode.scenario.max_steps))
        return result

    def _finish(self, outcome: str, reason: str) -> None:
        log, self._log = self._log, None
        if log is not None:
            log.finish(outcome, reason)
