"""fuzzynav: fuzzy-logic robot navigation among static and moving obstacles (a Mamdani controller, the Trajectory
Prediction Table, wait/detour planning) and the baselines it is compared with.

The public API, importable from here (each name is loaded on first use, so ``import fuzzynav`` stays light)::

    import fuzzynav
    episode = fuzzynav.Episode(scenario, controller, fuzzynav.EpisodeConfig(), seed=0)

Subpackages, bottom to top: ``numerics`` (portable math, geometry, compiled kernels), ``params`` (limits,
checks, parsing), ``controller`` (the fuzzy controller), ``sensing``, ``pedestrians`` (obstacle models),
``policies``, ``scenarios``, ``planning`` (TPT, wait/detour); ``episode`` runs one episode. Units: cm, s,
degrees, cm/s.
"""

from __future__ import annotations

import importlib
from typing import Any

_API = {
    "Episode": "fuzzynav.episode",
    "EpisodeConfig": "fuzzynav.episode",
    "StepRecord": "fuzzynav.episode",
    "episode_config_from_dict": "fuzzynav.config",
    "Scenario": "fuzzynav.scenarios.scenario",
    "ScenarioError": "fuzzynav.scenarios.scenario",
    "scenario_from_dict": "fuzzynav.scenarios.scenario",
    "ControllerSpec": "fuzzynav.controller.fuzzy_spec",
    "PlannerConfig": "fuzzynav.planning.planner",
    "Policy": "fuzzynav.policies.base",
    "Observation": "fuzzynav.policies.base",
    "Action": "fuzzynav.policies.base",
    "PolicyContext": "fuzzynav.policies.base",
    "register_policy": "fuzzynav.policies.base",
    "make_policy": "fuzzynav.policies.base",
    "registered_policies": "fuzzynav.policies.base",
    "register_obstacle_model": "fuzzynav.pedestrians.base",
    "registered_models": "fuzzynav.pedestrians.base",
    "register_generator": "fuzzynav.scenarios.generator",
    "registered_generators": "fuzzynav.scenarios.generator",
}

__all__ = sorted(_API)


def __getattr__(name: str) -> Any:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'fuzzynav' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_API})
