"""What makes two logs the same episode: one definition for the sweep's resume and the analysis.

Pure functions over a log's ``fuzzynav.run`` metadata (or the values it is written from): the resolved config
as YAML text, the episode's seed and the fuzzynav version.

* :func:`episode_key` — the episode's identity: the config without the top-level keys that only say how seeds
  were batched into jobs (``seed``, a job's first seed, ``episodes``, and ``resume``), plus the episode's own seed
  and the fuzzynav version (and, for a scenario generated from a recording, the recording's SHA-256:
  :data:`RECORDING`). ``seed=0 episodes=4`` and ``seed=0,2 episodes=2`` run the same four episodes, so the
  resume keeps each once and the analysis counts each once, whatever the directories and batching.
* :func:`config_hash` — the ``config_hash`` written into every log (the config without ``resume`` only, so it
  still depends on the batching). It is kept as it is because the datasets' manifests hash the logs' content; it
  serves as the metadata's integrity check (:func:`analysis.log_check.check_metadata`), not as the identity.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any

from fuzzynav.params.names import PLANNER_OFF, reads_h_wait

BATCHING_KEYS = ("seed", "episodes", "resume")  # top-level config keys that do not change an episode
HASH_IGNORED_KEYS = ("resume",)  # what the logged config_hash leaves out (unchanged: logs must stay the same)
IDENTITY_FIELDS = ("config", "seed", "fuzzynav_version")  # the metadata fields the identity is computed from
POLICY_SOURCE = "policy_source_sha256"  # and this one where present: a _target_ policy's source digest
#: and this one where present: the SHA-256 of the recording a scenario's people were read from (the config names the
#: file by its path only: two recordings of one name are two worlds)
RECORDING = "recording_sha256"


def _digest(config_yaml: str, ignored: tuple[str, ...], seed: int | str, fuzzynav_version: str) -> str:
    """SHA-256 of the config's lines except the top-level ``<key>:`` lines of ``ignored`` (nested keys are
    indented, so a ``seed`` inside a section is kept), the seed and the version."""
    prefixes = tuple(f"{key}:" for key in ignored)
    body = "\n".join(line for line in config_yaml.splitlines() if not line.startswith(prefixes))
    return hashlib.sha256(f"{body}\nseed={seed}\nfuzzynav={fuzzynav_version}".encode()).hexdigest()


def episode_key(config_yaml: str, seed: int | str, fuzzynav_version: str, policy_source: str = "",
                recording: str = "") -> str:
    """The identity of the episode of ``seed`` run with the resolved config ``config_yaml`` by this fuzzynav
    version, whatever the seed batching (see the module docstring); ``policy_source``: the digest of a
    ``_target_`` policy's source (:func:`fuzzynav.policies.base.policy_source_digest`; '' for fuzzynav's own policies,
    which leaves the key as it was before policies could be chosen); ``recording``: the SHA-256 of the recording
    the scenario was generated from ('' for other scenarios, which leaves their key as it was)."""
    version = f"{fuzzynav_version}+policy:{policy_source}" if policy_source else fuzzynav_version
    if recording:
        version = f"{version}+recording:{recording}"
    return _digest(config_yaml, BATCHING_KEYS, seed, version)


def episode_key_of(meta: Mapping[str, Any] | None) -> str | None:
    """:func:`episode_key` of a ``fuzzynav.run`` metadata record, or None when it lacks the config, the seed or
    the fuzzynav version as text (a hand-written or damaged record: no identity, never merged with another)."""
    if not meta or not all(isinstance(meta.get(field), str) for field in IDENTITY_FIELDS):
        return None
    return episode_key(meta["config"], meta["seed"], meta["fuzzynav_version"], str(meta.get(POLICY_SOURCE, "")),
                       str(meta.get(RECORDING, "")))


def without_parts_off(config_yaml: str) -> str:
    """The resolved config (YAML text, as runners write it: a block per top-level key, indented by two spaces)
    without the settings of a planner part that is off: ``planner.h_wait`` where the strategy does not read it
    (:func:`fuzzynav.params.names.reads_h_wait`), and every planner setting but the strategy under strategy
    ``none``. Episodes that differ there only are the same bits (tests/test_parameters_off.py), and the analysis
    groups them without those settings (:mod:`analysis.run_parameters`), so it must count them once. The text is
    returned unchanged where it has no such planner block."""
    lines = config_yaml.splitlines()
    try:
        start = lines.index("planner:")
    except ValueError:
        return config_yaml
    end = next((i for i in range(start + 1, len(lines)) if lines[i] and not lines[i].startswith(" ")), len(lines))
    block = lines[start + 1:end]
    strategies = [line.removeprefix("  strategy: ") for line in block if line.startswith("  strategy: ")]
    if len(strategies) != 1:
        return config_yaml
    strategy = strategies[0].strip().strip("'\"")
    if strategy == PLANNER_OFF:
        kept = [f"  strategy: {strategies[0]}"]
    elif not reads_h_wait(strategy):
        kept = [line for line in block if not line.startswith("  h_wait:")]
    else:
        return config_yaml
    return "\n".join([*lines[:start + 1], *kept, *lines[end:]]) + ("\n" if config_yaml.endswith("\n") else "")


def counted_key_of(meta: Mapping[str, Any] | None) -> str | None:
    """:func:`episode_key_of` of the config :func:`without_parts_off`: the identity under which the analysis counts
    an episode once (``planner=wait planner.h_wait=1,2,3`` runs one episode per seed three times)."""
    if not meta or not isinstance(meta.get("config"), str):
        return episode_key_of(meta)
    return episode_key_of({**meta, "config": without_parts_off(meta["config"])})


def same_episode_config(config_a: str, config_b: str) -> bool:
    """Whether two resolved configs (YAML text) run the same episodes: equal but for :data:`BATCHING_KEYS` (a run
    with ``resume=true`` or another ``episodes`` re-runs the episode of the same seed, not another one)."""
    def body(config_yaml: str) -> list[str]:
        prefixes = tuple(f"{key}:" for key in BATCHING_KEYS)
        return [line for line in config_yaml.splitlines() if not line.startswith(prefixes)]

    return body(config_a) == body(config_b)


def config_hash(config_yaml: str, seed: int | str, fuzzynav_version: str) -> str:
    """The ``config_hash`` a log records: the config without ``resume``, the seed and the version."""
    return _digest(config_yaml, HASH_IGNORED_KEYS, seed, fuzzynav_version)
