"""Where Hydra's settings make a run or a sweep write, checked on each composed config before anything runs.

A run writes into ``hydra.run.dir``, a sweep's jobs into ``hydra.sweep.dir``/``hydra.sweep.subdir``; Hydra's
``.hydra/`` snapshot goes into ``hydra.output_subdir`` of that folder and the job's log file is named after
``hydra.job.name``. Each of them can be set, or resolved from another setting, to a path outside the folder
(``hydra.sweep.subdir=${hydra.job.override_dirname}`` with a value holding ``../``, ``hydra.output_subdir=../x``,
``hydra.job.name=../x``), and ``hydra.sweep.dir`` to a folder that depends on the job
(``hydra.sweep.dir=out_${planner.strategy}``): the jobs then wrote into several sweeps, and the summary covered
one. Each is one line here, and the command stops before any folder is made.
"""

from __future__ import annotations

import logging
import re
from pathlib import PurePath

from omegaconf import DictConfig, OmegaConf, open_dict, read_write

#: Hydra's file handler's file name (conf/config.yaml keeps Hydra's): the job's folder and name
LOG_FILE = "${hydra.runtime.output_dir}/${hydra.job.name}.log"
_PLAIN_NAME = re.compile(r"[^/\\\0]+")


def _inside(text: str) -> bool:
    """Whether ``text`` is a relative path that stays inside the folder it is relative to."""
    path = PurePath(text)
    return bool(text) and not path.is_absolute() and ".." not in path.parts and not text.startswith("~")


def _resolved(cfg: DictConfig, key: str) -> tuple[object, str | None]:
    """(the value of ``key``, None), or (None, one line on why it does not resolve)."""
    try:
        return OmegaConf.select(cfg, key, throw_on_resolution_failure=True), None
    except Exception as err:
        detail = " ".join(str(err).split("\n")[0].split())[:160]
        return None, f"config: {key}: cannot be resolved before the jobs run ({detail})"


def _folder_problem(cfg: DictConfig, key: str, outside: str) -> tuple[object, str | None]:
    """(the value of ``key``, a folder relative to the run's or job's folder, None), or (None, one line: it does
    not resolve, or it resolves outside; ``outside`` says why that matters and how to write it)."""
    value, problem = _resolved(cfg, key)
    if problem is None and value is not None and not _inside(str(value)):
        problem = f"config: {key}: resolves to {str(value)[:80]!r}, outside {outside}"
    return value, problem


def run_paths_problem(cfg: DictConfig) -> str | None:
    """The first setting of ``cfg`` (composed with Hydra's node) that would write outside the run's or a job's
    folder, or None: ``hydra.output_subdir``, ``hydra.job.name``, the file handler's ``filename``; and a logging
    level that is none (Hydra's logging set-up raised it as two tracebacks)."""
    if "hydra" not in cfg:
        return None
    _, problem = _folder_problem(cfg, "hydra.output_subdir", "the job's folder (Hydra's .hydra/ snapshot goes "
                                 "there): give a relative folder such as .hydra, or null for none")
    if problem:
        return problem
    name, problem = _resolved(cfg, "hydra.job.name")
    if problem:
        return problem
    if name is not None and (not _PLAIN_NAME.fullmatch(str(name)) or str(name) in (".", "..")):
        return (f"config: hydra.job.name: {str(name)[:80]!r} is not a plain name (it names the job's log file, "
                "<job folder>/<name>.log)")
    handlers = OmegaConf.select(cfg, "hydra.job_logging.handlers", default=None)
    if isinstance(handlers, DictConfig):
        for handler, spec in handlers.items():
            if not isinstance(spec, DictConfig) or "filename" not in spec:
                continue
            raw = OmegaConf.to_container(spec, resolve=False).get("filename")  # type: ignore[union-attr]
            text = str(raw)
            if text != LOG_FILE and not (text.startswith("${hydra.runtime.output_dir}/")
                                         and _inside(text.removeprefix("${hydra.runtime.output_dir}/"))):
                return (f"config: hydra.job_logging.handlers.{handler}.filename: {text[:80]!r} is outside the job's "
                        f"folder: give a name inside it, ${{hydra.runtime.output_dir}}/<name>.log")
    for key in ("hydra.job_logging.root.level", "hydra.hydra_logging.root.level"):
        level = OmegaConf.select(cfg, key, default=None, throw_on_resolution_failure=False)
        known = (isinstance(level, int) and not isinstance(level, bool)) or (
            isinstance(level, str) and isinstance(logging.getLevelName(level), int))
        if level is not None and not known:
            return (f"config: {key}: {str(level)[:40]!r} is not a logging level (DEBUG, INFO, WARNING, ERROR or "
                    "CRITICAL)")
    return None


def sweep_paths(cfg: DictConfig) -> tuple[str, str] | str:
    """(``hydra.sweep.dir``, ``hydra.sweep.subdir``) of a job's composed config, resolved as the job will (its
    number and id set to 0), or one line on why they would put the job outside its sweep's folder."""
    sweep_dir, problem = _resolved(cfg, "hydra.sweep.dir")  # made before any job has a number
    if problem:
        return f"{problem}: the folder of the whole sweep cannot depend on the job"
    job = cfg.hydra.job
    before = {key: OmegaConf.to_container(job, resolve=False).get(key) for key in ("num", "id")}
    with read_write(job), open_dict(job):  # (set for the check and put back: a copy of the config took ~10 ms)
        job.num, job.id = 0, "0"
        try:
            subdir, problem = _folder_problem(cfg, "hydra.sweep.subdir", _SWEEP_FOLDER)
            return problem or (str(sweep_dir), str(subdir))
        finally:
            for key, value in before.items():
                if value is None:
                    del job[key]
                else:
                    job[key] = value


def one_sweep_dir(dirs: dict[str, list[str]]) -> str | None:
    """One line when the jobs' ``hydra.sweep.dir`` (resolved, each with the overrides of a job that composes it)
    is more than one folder: the sweep's summary, report and resume cover one folder."""
    if len(dirs) <= 1:
        return None
    (first, a), (second, b) = list(dirs.items())[:2]
    differ = [o for o in b if o not in a][:2] or b[-1:]
    return (f"config: hydra.sweep.dir: resolves to another folder for each job ({first[:60]!r}, and "
            f"{second[:60]!r} with {' '.join(differ)[:80]}): it is the folder of the whole sweep; give one folder, "
            "and vary the jobs' folders with hydra.sweep.subdir")


def job_dir_problem(cfg: DictConfig, sweep_dir: str) -> str | None:
    """One line when a job's config (its number set) puts it outside ``sweep_dir``, the launching process's sweep
    folder: its ``hydra.sweep.dir`` resolves to another folder, or its subdir leaves the folder."""
    paths = sweep_paths_of_job(cfg)
    if isinstance(paths, str):
        return paths
    if paths[0] != sweep_dir:
        return (f"config: hydra.sweep.dir: resolves to {paths[0][:80]!r} for this job, not the sweep's folder "
                f"{sweep_dir[:80]!r}: it is the folder of the whole sweep; vary the jobs' folders with "
                "hydra.sweep.subdir")
    return None


def sweep_paths_of_job(cfg: DictConfig) -> tuple[str, str] | str:
    """:func:`sweep_paths` of a job's own config (its number and id set by the launcher)."""
    sweep_dir, problem = _resolved(cfg, "hydra.sweep.dir")
    if problem:
        return problem
    subdir, problem = _folder_problem(cfg, "hydra.sweep.subdir", _SWEEP_FOLDER)
    return problem or (str(sweep_dir), str(subdir))


_SWEEP_FOLDER = ("the sweep's folder; each job writes into a folder of the sweep's: include ${hydra.job.num}, and "
                 "no value that holds '..' or '/'")
