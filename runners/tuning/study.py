"""A study's trials: Optuna's ask-and-tell loop around :func:`runners.tuning.episodes.run_configuration`.

Each trial asks the sampler for a value of every parameter, runs the study's scenarios on its training seeds
with those values (logs in ``<study>/trials/<number>/``), computes the objectives from the logs
(:mod:`analysis.objectives`) and tells Optuna. A trial whose configuration does not validate, whose episodes
fail (outcome ``error``, a log left out) or whose objective is NaN is told FAIL with its one-line reason in the
trial's ``fail_reason`` attribute; the study goes on. A stopped trial (Ctrl-C, SIGTERM, a killed worker) is
FAIL with ``interrupted`` and is not counted: re-running the command runs it again.

The trial budget counts the trials that ended (completed or failed, not interrupted). Workers sharing one study
never exceed it: the storage numbers trials in the order they were created (one writer at a time), so after
``ask`` a worker counts the trials numbered before its own that use the budget or are running; if they already
fill it, its trial is surplus, told FAIL with the ``surplus`` attribute before any parameter is asked (not
counted, never run) and the worker stops. Optuna's ``MaxTrialsCallback`` is not enough: it stops a worker after
its trial, when the trials other workers already began overrun the budget.
"""

from __future__ import annotations

import functools
import math
import os
import socket
from collections.abc import Callable
from pathlib import Path
from typing import Any

import optuna
from optuna.trial import FrozenTrial, TrialState

from analysis.objectives import objective_value, undefined
from runners.tuning import controller_space, rule_space
from runners.tuning.episodes import ConfigurationError, hydra_conf, run_configuration
from runners.tuning.space import Parameter, overrides_of, suggest
from runners.tuning.storage import trial_dir
from runners.tuning.study_file import StudySpec
from runners.tuning.study_record import DEFINITION, StudyChangedError, check_resumed, definition

FAIL_REASON = "fail_reason"
INTERRUPTED = "interrupted"
SURPLUS = "surplus"
OVERRIDES = "overrides"
WORKER = "worker"
METRICS = "metrics"

optuna.logging.set_verbosity(optuna.logging.WARNING)  # the command prints one line per trial of its own


def make_sampler(spec: StudySpec, worker: int = 0, trials_before: int = 0) -> optuna.samplers.BaseSampler:
    """The study file's sampler, seeded from ``sampler_seed``, the worker's index and the number of trials the
    study had when this process opened it: workers must not propose the same points, nor a resumed command the
    points its first run already tried (a sampler restarts its random sequence from its seed). One worker run
    without interruption is reproducible."""
    seed = (spec.sampler_seed + 100_003 * worker + 1_009 * trials_before) % 2**32
    if spec.sampler == "tpe":
        return optuna.samplers.TPESampler(seed=seed, multivariate=True)
    if spec.sampler == "cmaes":
        return optuna.samplers.CmaEsSampler(seed=seed, warn_independent_sampling=False)
    if spec.sampler == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=seed)
    return optuna.samplers.RandomSampler(seed=seed)


def counted(trial: FrozenTrial) -> bool:
    """Whether a trial uses the budget: completed, or failed for a reason of its own (not interrupted)."""
    if trial.state == TrialState.COMPLETE:
        return True
    return trial.state == TrialState.FAIL and not trial.user_attrs.get(INTERRUPTED, False) \
        and FAIL_REASON in trial.user_attrs


@functools.lru_cache(maxsize=8)
def partition_groups(spec: StudySpec) -> tuple[controller_space.PartitionGroup, ...]:
    """The controller variables searched as partitions, from the base configuration's controller (composed)."""
    if not spec.controller_space:
        return ()
    from omegaconf import OmegaConf

    from runners.tuning.episodes import run_config

    with hydra_conf():
        cfg = run_config(spec.base, spec.scenarios[0], spec.train)
    return tuple(controller_space.resolve(spec.controller_space, OmegaConf.to_container(cfg.controller, resolve=True)))


@functools.lru_cache(maxsize=8)
def rule_outputs(spec: StudySpec) -> rule_space.RuleSpace | None:
    """The rule outputs searched (``controller_rules``), from the base configuration's controller (composed)."""
    if not spec.controller_rules:
        return None
    from omegaconf import OmegaConf

    from runners.tuning.episodes import run_config

    with hydra_conf():
        cfg = run_config(spec.base, spec.scenarios[0], spec.train)
    return rule_space.resolve(spec.controller_rules, OmegaConf.to_container(cfg.controller, resolve=True))


def all_parameters(spec: StudySpec) -> list[Parameter]:
    """The searched parameters: the space's, the controller partitions' coordinates, the rule outputs."""
    return [*spec.space, *controller_space.parameters(partition_groups(spec)),
            *rule_space.parameters(rule_outputs(spec))]


def trial_overrides(spec: StudySpec, values: dict[str, Any]) -> list[str]:
    """A trial's overrides: the base, the space's keys at their values, the partitions' terms, the rules."""
    return [*spec.base, *overrides_of(spec.space, values),
            *controller_space.overrides(partition_groups(spec), values),
            *rule_space.overrides(rule_outputs(spec), values)]


def default_values(spec: StudySpec) -> dict[str, Any] | None:
    """The values the base configuration gives the searched keys (the untuned method), if every one is a point of
    the space: enqueued as the study's first trial, so that the study starts from the default. None when a key
    is a config group (its option is not a value of the composed config) or a default lies outside the space."""
    from omegaconf import OmegaConf

    from runners.tuning.episodes import run_config

    with hydra_conf():
        cfg = run_config(spec.base, spec.scenarios[0], spec.train)
    values: dict[str, Any] = {}
    for p in spec.space:
        value = OmegaConf.select(cfg, p.key, default=None)
        if "." not in p.key or not p.contains(value):
            return None
        values[p.key] = value
    return {**values, **controller_space.start_values(partition_groups(spec)),
            **rule_space.start_values(rule_outputs(spec))}


def create_or_load(spec: StudySpec, storage: Any, worker: int = 0, study_dir: Path | None = None) -> optuna.Study:
    """The study named in the file, created with its directions and its record (the default enqueued), or loaded
    if the file still describes it (:mod:`runners.tuning.study_record`). Refused (:class:`StudyChangedError`,
    one line): a file whose scenarios, seeds, objectives, base or space differ from the stored study's, and a
    new name in a folder that holds another study, whose trial folders (``trials/00000`` …) the new study's
    trials would share. ``study_dir`` names the folder in the messages, and holds the logs that confirm a study
    stored before records existed."""
    where = str(study_dir) if study_dir is not None else "the study folder"
    try:
        study = optuna.load_study(study_name=spec.name, storage=storage)
    except KeyError:
        others = [s.study_name for s in storage.get_all_studies()]
        if others:
            raise StudyChangedError(
                f"{spec.path}: name: {others[0]!r} → {spec.name!r}: {where} holds the study {others[0]!r}, whose "
                "trial folders a new study would share: restore the file's name, or use another --out for the "
                "new study") from None
        study = optuna.create_study(study_name=spec.name, storage=storage, sampler=make_sampler(spec, worker),
                                    directions=spec.directions, load_if_exists=True)
        if not study.user_attrs:
            study.set_user_attr("space", [p.text for p in all_parameters(spec)])
            study.set_user_attr("objectives", [o.name for o in spec.objectives])
            study.set_user_attr("base", list(spec.base))
            study.set_user_attr(DEFINITION, definition(spec))
            defaults = default_values(spec)
            if defaults is not None:
                study.enqueue_trial(defaults, user_attrs={"default": True})
        return study
    study.sampler = make_sampler(spec, worker, len(study.get_trials(deepcopy=False)))
    record = check_resumed(spec, study, study_dir)  # first: it names every field of the file that changed
    directions = [d.name.lower() for d in study.directions]
    if directions != spec.directions:
        raise StudyChangedError(f"{spec.path}: objectives: the stored study {spec.name!r} in {where} has directions "
                                f"{directions}, the file {spec.directions}: restore the file, or use another --out")
    stored = study.user_attrs.get("space")
    if stored is not None and stored != [p.text for p in all_parameters(spec)]:
        # also what the file's controller_space/controller_rules resolve to in conf/'s base controller
        raise StudyChangedError(f"{spec.path}: space: differs from the stored study {spec.name!r} in {where} "
                                f"({'; '.join(stored)[:120]}): restore the file, or use another --out")
    if record:
        study.set_user_attr(DEFINITION, definition(spec))
    return study


def fail(study: optuna.Study, trial: optuna.Trial, reason: str) -> None:
    trial.set_user_attr(FAIL_REASON, " ".join(reason.split())[:500])
    study.tell(trial, state=TrialState.FAIL)


def within_budget(study: optuna.Study, number: int, budget: int) -> bool:
    """Whether trial ``number`` fits the budget: the trials numbered before it that are counted or running
    (:func:`counted`) leave room for it."""
    before = study.get_trials(deepcopy=False)[:number]
    return sum(counted(t) or t.state == TrialState.RUNNING for t in before) < budget


def run_trial(study: optuna.Study, spec: StudySpec, study_dir: Path, budget: int | None = None
              ) -> FrozenTrial | None:
    """Ask, run the trial's episodes, tell; returns the trial as stored, or None when the trial asked for was
    surplus (another worker's trials fill ``budget``)."""
    trial = study.ask()
    if budget is not None and not within_budget(study, trial.number, budget):
        trial.set_user_attr(SURPLUS, True)
        study.tell(trial, state=TrialState.FAIL)
        return None
    values = suggest(trial, all_parameters(spec))
    overrides = trial_overrides(spec, values)
    trial.set_user_attr(OVERRIDES, overrides)
    trial.set_user_attr(WORKER, worker_identity())
    try:
        result = run_configuration(overrides, spec.scenarios, spec.train, trial_dir(study_dir, trial.number))
    except KeyboardInterrupt:
        trial.set_user_attr(INTERRUPTED, True)
        study.tell(trial, state=TrialState.FAIL)
        raise
    except ConfigurationError as err:
        fail(study, trial, f"configuration: {err}")
        return study.trials[trial.number]
    except Exception as err:  # a crashed trial: the study goes on, the reason is kept
        fail(study, trial, f"crashed: {type(err).__name__}: {err}")
        return study.trials[trial.number]
    if not result.excluded.empty:
        first = result.excluded.iloc[0]
        fail(study, trial, f"{len(result.excluded)} of {len(result.logs)} episodes unusable; {first['log']}: "
                           f"{first['kind']}: {first['reason']}")
        return study.trials[trial.number]
    objective_values = [objective_value(result.episodes, o) for o in spec.objectives]
    trial.set_user_attr(METRICS, {o.name: v for o, v in zip(spec.objectives, objective_values, strict=True)})
    for o, v in zip(spec.objectives, objective_values, strict=True):
        if not math.isfinite(v):
            fail(study, trial, f"objective {o.name} is {v}: {undefined(result.episodes, o) or 'not finite'}")
            return study.trials[trial.number]
    study.tell(trial, objective_values)
    return study.trials[trial.number]


def worker_identity() -> dict[str, Any]:
    """Where a trial runs: host, process id and, in Slurm, the task: ``<array job>_<task>`` in a job array, the job
    id for a single job (Submitit submits one worker, ``--workers 1``, as a plain job, not an array of one)."""
    array, task = os.environ.get("SLURM_ARRAY_JOB_ID"), os.environ.get("SLURM_ARRAY_TASK_ID")
    return {"host": socket.gethostname(), "pid": os.getpid(),
            "slurm_task": f"{array}_{task}" if array and task else os.environ.get("SLURM_JOB_ID") or None}


def run_trials(study: optuna.Study, spec: StudySpec, study_dir: Path, budget: int,
               on_trial: Callable[[FrozenTrial], None] | None = None) -> None:
    """Run trials until ``budget`` trials of the study are counted (:func:`counted`), by anyone."""
    with hydra_conf():
        while sum(counted(t) for t in study.get_trials(deepcopy=False)) + running(study) < budget:
            frozen = run_trial(study, spec, study_dir, budget)
            if frozen is None:  # the other workers' trials fill the budget
                break
            if on_trial is not None:
                on_trial(frozen)


def running(study: optuna.Study) -> int:
    return len(study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)))


def fail_interrupted(study: optuna.Study) -> list[int]:
    """Mark the trials left RUNNING by a stopped command as interrupted (FAIL, not counted): called by the
    command that holds the study folder's lock, so no one else is running them. Returns their numbers."""
    numbers = []
    for t in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
        # Optuna's public API sets attributes only through the Trial of the process that asked for it
        study._storage.set_trial_user_attr(t._trial_id, INTERRUPTED, True)
        study.tell(t.number, state=TrialState.FAIL)
        numbers.append(t.number)
    return numbers
