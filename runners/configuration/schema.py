"""Hydra structured configs: mutable mirrors of fuzzynav's frozen config dataclasses.

The library's frozen dataclasses stay the single source of truth (fields, types, defaults); this module
derives OmegaConf-compatible copies from them (tuples become lists) and stores them in Hydra's
ConfigStore under the ``schema`` group, so a typo or a wrong type fails at composition with Hydra's own
error naming the key, and ``glob(*)`` sweeps over the real groups never pick them up.
"""

from __future__ import annotations

import dataclasses
import typing
from typing import Any

from hydra.core.config_store import ConfigStore

from fuzzynav.kinematics import RobotLimits
from fuzzynav.planning.planner import PlannerConfig
from fuzzynav.sensing.laser import LaserConfig
from fuzzynav.sensing.perception import PerceptionConfig
from fuzzynav.sensing.sonar import SonarConfig

_MIRRORS: dict[type, type] = {}


def mutable_mirror(cls: type) -> type:
    """A non-frozen dataclass with the same fields and defaults as ``cls`` (recursively)."""
    if cls in _MIRRORS:
        return _MIRRORS[cls]
    hints = typing.get_type_hints(cls)
    fields = []
    for f in dataclasses.fields(cls):
        hint = hints[f.name]
        default: Any = f.default
        if dataclasses.is_dataclass(hint):
            mirror = mutable_mirror(hint)
            fields.append((f.name, mirror, dataclasses.field(default_factory=mirror)))
            continue
        if typing.get_origin(hint) is tuple:
            args = [a for a in typing.get_args(hint) if a is not Ellipsis]
            item = args[0] if args else Any
            value = list(default)
            fields.append((f.name, list[item], dataclasses.field(default_factory=lambda v=value: list(v))))
            continue
        # OmegaConf turns any integer into a boolean for a bool field (``swept_tpt=3`` became true): such
        # fields stay untyped here and fuzzynav's own parser (fuzzynav.config) accepts only true or false
        fields.append((f.name, Any if hint is bool else hint, dataclasses.field(default=default)))
    # a class of this module, found by its name (as pickle finds a class): the configs a sweep sends to its workers
    # and copies for each job refer to it instead of carrying its definition (in module ``types``, made by
    # make_dataclass, cloudpickle wrote the class into every pickle and read it back each time: ~8 ms a config)
    name = f"{cls.__name__}Schema"
    mirror = dataclasses.make_dataclass(name, fields, namespace={"__module__": __name__})
    if globals().setdefault(name, mirror) is not mirror:
        raise RuntimeError(f"two schemas named {name}")
    _MIRRORS[cls] = mirror
    return mirror


RobotLimitsSchema = mutable_mirror(RobotLimits)
SonarSchema = mutable_mirror(SonarConfig)
LaserSchema = mutable_mirror(LaserConfig)
PlannerSchema = mutable_mirror(PlannerConfig)
PerceptionSchema = mutable_mirror(PerceptionConfig)


@dataclasses.dataclass
class SensorsSchema:
    """The ``sensors`` group: sonar and laser."""

    sonar: SonarSchema = dataclasses.field(default_factory=SonarSchema)  # type: ignore[valid-type]
    laser: LaserSchema = dataclasses.field(default_factory=LaserSchema)  # type: ignore[valid-type]


@dataclasses.dataclass
class RunSchema:
    """The whole run configuration (``conf/config.yaml``). Scenario, controller and navigator (whose keys
    depend on the policy) are validated by fuzzynav's own parsers (which name the field), so they are
    free-form here."""

    scenario: Any = None
    controller: Any = None
    robot: RobotLimitsSchema = dataclasses.field(default_factory=RobotLimitsSchema)  # type: ignore[valid-type]
    sensors: SensorsSchema = dataclasses.field(default_factory=SensorsSchema)
    planner: PlannerSchema = dataclasses.field(default_factory=PlannerSchema)  # type: ignore[valid-type]
    perception: PerceptionSchema = dataclasses.field(default_factory=PerceptionSchema)  # type: ignore[valid-type]
    navigator: Any = None  # the policy and its parameters: checked by the policy's own config (fuzzynav.policies.base)
    seed: int = 0
    episodes: int = 1
    dt: float = 1.0
    terminate_on_collision: Any = True  # checked as a boolean by fuzzynav.config (see mutable_mirror)
    resume: Any = False


def register() -> None:
    """Store the schemas (idempotent: once stored, not built again; building the structured config takes ~8 ms,
    and a run's start registers them from more than one place)."""
    cs = ConfigStore.instance()
    try:
        if "run.yaml" in cs.list("schema"):
            return
    except OSError:  # no schema group yet
        pass
    cs.store(group="schema", name="run", node=RunSchema)
