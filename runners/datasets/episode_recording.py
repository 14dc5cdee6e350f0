"""One episode of a dataset, recorded in a worker process: its run config, its log and the log's content digests.

Here, not in :mod:`runners.dataset`, so that a worker finds these functions by name (``python -m runners.dataset``
runs that module as ``__main__``, whose functions joblib sends by value, each task with a new copy of their globals:
the assembled configs of :func:`run_config` were then lost after every episode).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

from analysis.logs import iter_messages
from fuzzynav.conf import CONF_DIR as CONF
from runners.configuration import plugins as config_plugins
from runners.logs import yaml_text
from runners.logs.fields import TIMING_FIELDS, BehaviourRecord


def _canonical(message: dict[str, Any]) -> bytes:
    clean = {k: v for k, v in message.items() if k not in TIMING_FIELDS}
    return json.dumps(clean, sort_keys=True, separators=(",", ":")).encode()


def content_digests(path: Path) -> dict[str, Any]:
    """SHA-256 of the message content, 8-hex digests per topic and per log time (step), and the behaviour
    record (:class:`runners.logs.fields.BehaviourRecord`)."""
    whole = hashlib.sha256()
    topics: dict[str, Any] = {}
    steps: dict[int, Any] = {}
    behaviour = BehaviourRecord()
    for topic, t, msg in iter_messages(path):
        data = _canonical(msg)
        line = topic.encode() + b"|" + str(t).encode() + b"|" + data + b"\n"
        whole.update(line)
        topics.setdefault(topic, hashlib.sha256()).update(line)
        steps.setdefault(t, hashlib.sha256()).update(line)
        behaviour.add(topic, t, msg)
    return {"sha256": whole.hexdigest(), "topics": {k: v.hexdigest()[:8] for k, v in sorted(topics.items())},
            "step_digests": [steps[t].hexdigest()[:8] for t in sorted(steps)], **behaviour.result()}


#: this worker process's episode configs of the current recording (its token; runners.dataset.record_all), assembled
#: from the configs Hydra composed once per scenario and variant (runners.configuration.job_configs.JobConfigs)
_ASSEMBLED: dict[str, Any] = {}


def _compose(overrides: list[str], with_hydra: bool = False) -> Any:
    """Hydra's run config for ``overrides`` (``with_hydra``: with Hydra's node, whose choices the assembly reads)."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from runners.configuration import schema

    schema.register()
    if GlobalHydra.instance().is_initialized():
        return compose("config", overrides=overrides, return_hydra_config=with_hydra)
    # a context: with one worker this runs in the caller's process, whose later prechecks initialise Hydra
    config_plugins.register()  # other packages' config folders (entry points)
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return compose("config", overrides=overrides, return_hydra_config=with_hydra)


def resolved_config_json(overrides: list[str]) -> str:
    """The run config Hydra composes for ``overrides``, resolved, as JSON with sorted keys (to compare two)."""
    from omegaconf import OmegaConf

    return json.dumps(OmegaConf.to_container(_compose(overrides), resolve=True), sort_keys=True, default=str)


def prepare_assembly(jobs: list[dict[str, Any]], workers: int, state: Path) -> str | None:
    """Ready the assembly of ``jobs``' configs (:func:`run_config`): the configs it needs, composed by Hydra once
    each, in parallel on ``workers`` processes, written with the rest of what the workers share to the file
    ``state``. Returns the recording's token, or None where that did not work out (a config that does not compose):
    every episode is then composed where it runs, and Hydra says what is wrong in its own words."""
    import functools
    import secrets

    import cloudpickle
    from joblib import Parallel, delayed
    from omegaconf import OmegaConf

    from runners.configuration.job_configs import JobConfigs

    try:
        configs = JobConfigs(OmegaConf.create(), functools.partial(_compose, with_hydra=True))
        needed = configs.to_compose([j["overrides"] for j in jobs])  # (the reference is composed here)
        composed = Parallel(n_jobs=workers)(delayed(_composed_bytes)(list(k)) for k in needed) if needed else []
        for key, data in zip(needed, composed, strict=True):
            if data is not None:
                configs.add_composed(key, data)
        state.write_bytes(cloudpickle.dumps(configs))
    except Exception:
        return None
    return secrets.token_hex(8)


def _composed_bytes(overrides: list[str]) -> bytes | None:
    """Hydra's config (with its node) of ``overrides``, pickled (in a worker); None where Hydra refuses it."""
    import pickle

    import cloudpickle

    try:
        return cloudpickle.dumps(_compose(overrides, with_hydra=True), protocol=pickle.HIGHEST_PROTOCOL)
    except Exception:
        return None


def run_config(job: dict[str, Any], token: str | None, state: str | None = None) -> Any:
    """The episode's run config: Hydra's composition of the job's overrides.

    With a ``token`` (:func:`prepare_assembly`: one per recording) it is assembled where that gives the same config,
    as a sweep's launcher does, from the recording's first episode and that episode with one scenario or variant
    changed (composed once each, in ``state``); the seed is a plain value. Composing was most of a verification's
    time (~0.3 s an episode, whose simulation takes 0.1-0.3 s). Without a token every episode is composed: a build,
    the reference that each verification's assembled configs are held against (through the logs' digests)."""
    import pickle

    from omegaconf import open_dict

    if token is None or state is None:
        return _compose(job["overrides"])
    configs = _ASSEMBLED.get(token)
    if configs is None:  # a new recording: the previous one's configs may come from files changed since
        _ASSEMBLED.clear()
        configs = _ASSEMBLED[token] = pickle.loads(Path(state).read_bytes())  # our own file (prepare_assembly)
    cfg = configs.config(job["overrides"])  # a new object, Hydra's node included
    with open_dict(cfg):  # as Hydra's compose() leaves it out
        del cfg["hydra"]
    return cfg


def record_episode(job: dict[str, Any], out_dir: str, token: str | None = None, state: str | None = None
                   ) -> dict[str, Any]:
    """Run one episode (in a worker) and return its digests (``token``, ``state``: :func:`run_config`)."""
    from omegaconf import OmegaConf

    from runners.run import episode_config, load_evaluator, load_scenario, run_episode, scenario_generator

    cfg = run_config(job, token, state)
    plain = OmegaConf.to_container(cfg, resolve=True)
    path = Path(out_dir) / job["file"]
    text = yaml_text.config_text(cfg, resolve=True)
    summary = run_episode(load_scenario(plain, job["seed"]), load_evaluator(plain), episode_config(plain),
                          job["seed"], path, text, generator=scenario_generator(plain))
    return {"file": job["file"], "outcome": summary["outcome"], "steps": summary["steps"], **content_digests(path)}


def forget_assembled() -> None:
    """Drop this process's assembled configs (the end of a recording that ran in it)."""
    _ASSEMBLED.clear()
