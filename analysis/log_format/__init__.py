"""The log format, defined once: each topic of an episode log and the JSON schema of its messages. The writer
(``runners.logs.mcap_log``) registers these schemas in every MCAP log and writes messages that follow them; the
analysis derives its checks of the messages it reads from them (:mod:`analysis.log_check`).

Pure data, importing nothing else of the project: :mod:`analysis.log_format.foxglove` (the Foxglove message types;
metres, radians, seconds) and :mod:`analysis.log_format.fuzzynav` (fuzzynav's own; units in the field names)."""

from __future__ import annotations

from analysis.log_format.foxglove import FOXGLOVE_SCHEMAS
from analysis.log_format.fuzzynav import FUZZYNAV_SCHEMAS

__all__ = ["FOXGLOVE_SCHEMAS", "FUZZYNAV_SCHEMAS", "SCHEMAS", "TOPICS"]

SCHEMAS = {**FOXGLOVE_SCHEMAS, **FUZZYNAV_SCHEMAS}
"""Schema name -> a function returning the JSON schema (a fresh dict: callers may change it)."""

TOPICS = {
    "/scene": "foxglove.SceneUpdate",
    "/robot/pose": "foxglove.PoseInFrame",
    "/laser": "foxglove.LaserScan",
    "/log": "foxglove.Log",
    "/sonar": "fuzzynav.Sonar",
    "/tracks": "fuzzynav.Tracks",
    "/obstacles/truth": "fuzzynav.ObstaclesTruth",
    "/robot/state": "fuzzynav.RobotState",
    "/tpt": "fuzzynav.TPT",
    "/planner/decision": "fuzzynav.Decision",
    "/episode": "fuzzynav.Episode",
}
"""Each topic of a log and the name of its messages' schema (a key of :data:`SCHEMAS`)."""
