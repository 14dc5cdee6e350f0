"""Build the frozen config dataclasses from plain nested mappings (as composed by Hydra).

``episode_config_from_dict({"planner": {"strategy": "wait"}, "dt": 1.0})`` fills everything else with
defaults. An unknown key, a non-string key, a wrong type or a list of the wrong length raises ``ValueError``
naming the dotted field; the values are then checked by the dataclasses themselves, and every number of the
tree against its documented range (:func:`fuzzynav.params.checks.check_config_fields`, :mod:`fuzzynav.params.limits`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from fuzzynav.episode import EpisodeConfig
from fuzzynav.params.checks import check_key, kind_of
from fuzzynav.params.parsing import from_dict
from fuzzynav.policies.base import policy_params, split_navigator_section


def episode_config_from_dict(data: Mapping[str, Any] | None) -> EpisodeConfig:
    """An :class:`EpisodeConfig` from plain data (missing keys take their defaults). The ``navigator`` section
    names the policy (``policy``, or ``_target_`` for one defined outside fuzzynav; default ``fuzzy``) and holds
    its parameters, checked by the policy's ``config_class``."""
    data = {} if data is None else data
    if not isinstance(data, Mapping) or "navigator" not in data:
        return from_dict(EpisodeConfig, data)
    if "policy" in data:
        raise ValueError("policy: unknown key (the policy is chosen by navigator.policy)")
    section = data["navigator"]
    if section is not None and not isinstance(section, Mapping):
        raise ValueError(f"navigator: expected a mapping, got {kind_of(section)}")
    for key in section or {}:
        check_key(key, "navigator")
    name, params = split_navigator_section(section)
    rest = {k: v for k, v in data.items() if k != "navigator"}
    config = from_dict(EpisodeConfig, rest)
    return dataclasses.replace(config, navigator=policy_params(name, params), policy=name)
