"""The names a configuration and a log use for a run's policy, its modes and its pedestrian models, and what a run
is when it names none: facts of the run parameters and of the log format, shared by the simulator (the policy
registry, :mod:`fuzzynav.policies.base`; the crowd, :mod:`fuzzynav.pedestrians`), the runners and the analysis
(which checks the logs against them and imports nothing of the simulator's parts)."""

from __future__ import annotations

import re
from typing import Any

#: the policy of a run when its ``navigator`` section names none: the paper's fuzzy controller
DEFAULT_POLICY = "fuzzy"
#: the policy name of episodes whose commands came from outside (a Gymnasium agent): reserved, never registered
AGENT = "agent"
NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")
"""A registered policy's or pedestrian model's name, and a mode name (:class:`fuzzynav.policies.base.Action`; the
log's ``/planner/decision.mode``)."""
IMPORT_PATH = re.compile(r"(?=.{3,200}$)[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)+")
"""The import path of a ``_target_`` policy factory: dotted identifiers, at most 200 characters."""

#: the model of an obstacle whose scenario entry names none: its scripted path (constant velocity or waypoints)
DEFAULT_MODEL = "scripted"

#: the wait/detour layer's strategies (``planner.strategy``)
STRATEGIES = ("auto", "wait", "detour", "none")
#: the strategies that read ``planner.h_wait`` (auto chooses between waiting and a detour by it; wait and detour do
#: what their names say whatever it is): elsewhere h_wait is in neither log file names nor report groups
READS_H_WAIT = ("auto",)
#: the strategy that leaves the policy alone: the layer reads no ``planner.*`` parameter at all
PLANNER_OFF = "none"


def reads_h_wait(strategy: object) -> bool:
    """Whether episodes of ``strategy`` depend on ``planner.h_wait`` (unknown strategies, as in a damaged log: yes)."""
    return strategy not in STRATEGIES or strategy in READS_H_WAIT


def is_policy_id(text: object) -> bool:
    """Whether ``text`` names a policy as a configuration and a log do: a registered name or an import path."""
    return isinstance(text, str) and bool(NAME.fullmatch(text) or IMPORT_PATH.fullmatch(text))


SCENARIO_DEFAULTS: dict[str, Any] = {"name": "unnamed", "description": "", "max_steps": 300, "goal_tolerance": None}
"""A scenario's values for the keys it leaves out (:func:`fuzzynav.scenarios.scenario.scenario_from_dict`; the
analysis compares a logged world with the config's scenario by them)."""
ROBOT_DEFAULTS: dict[str, Any] = {"heading": 0.0, "radius": 20.0}
"""The robot's heading (degrees) and radius (cm) where a scenario's ``robot`` leaves them out."""
