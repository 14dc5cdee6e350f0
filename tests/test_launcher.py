"""The launcher's job runner (runners.sweeping.job_run) against Hydra's own run_job, on the same
configs: the same .hydra/ snapshot, output directory, working directory, environment, callbacks and result."""

from __future__ import annotations

import copy
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import pytest
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from hydra.core.singleton import Singleton
from hydra.core.utils import JobRuntime, JobStatus, run_job
from hydra.types import HydraContext
from hydra_plugins.fuzzynav_sweeper import launch_state
from omegaconf import OmegaConf, open_dict

from fuzzynav.conf import CONF_DIR
from runners.configuration import schema
from runners.sweeping import job_run


class Recorder:
    """Callbacks that note what they were called with."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, Any]] = []

    def on_job_start(self, config: Any, task_function: Any) -> None:
        self.calls.append(("start", OmegaConf.to_container(config.hydra.overrides.task)))

    def on_job_end(self, config: Any, job_return: Any) -> None:
        self.calls.append(("end", job_return.status))


def sweep_config(sweep_dir: Path, overrides: list[str], *, chdir: bool, env: dict[str, str]) -> Any:
    schema.register()
    with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
        cfg = compose("config", overrides=overrides, return_hydra_config=True)
    with open_dict(cfg):
        cfg.hydra.sweep.dir = str(sweep_dir)
        cfg.hydra.job.num = 3
        cfg.hydra.job.id = "run_3"
        cfg.hydra.job.chdir = chdir
        cfg.hydra.job.env_set = env
        cfg.hydra.overrides.task = overrides
    return cfg


def task_noting(seen: dict[str, Any], fail: bool):
    def task(cfg: Any) -> Any:
        seen.update(cwd=os.getcwd(), env=os.environ.get("FUZZYNAV_TEST_ENV"), hydra_in_cfg="hydra" in cfg,
                    output_dir=HydraConfig.get().runtime.output_dir, seed=cfg.seed)
        if fail:
            raise RuntimeError("task failed")
        return {"seed": cfg.seed}
    return task


@pytest.mark.parametrize("chdir", [False, True])
@pytest.mark.parametrize("fail", [False, True])
@pytest.mark.parametrize("mode", ["sweep", "run"])
def test_job_run_matches_hydras_run_job(tmp_path: Path, chdir: bool, fail: bool, mode: str) -> None:
    """A sweep's job (``hydra.sweep.dir``/``hydra.sweep.subdir``) and ``runners.run``'s single run
    (``hydra.run.dir``)."""
    JobRuntime.instance().set("name", "run")
    overrides = ["scenario=head_on", "planner=wait", "seed=7"]
    keys = ("hydra.sweep.dir", "hydra.sweep.subdir") if mode == "sweep" else ("hydra.run.dir", None)
    outputs = {}
    for name, runner in (("hydra", "hydra"), ("ours", "ours")):
        sweep_dir = tmp_path / name
        cfg = sweep_config(sweep_dir, overrides, chdir=chdir, env={"FUZZYNAV_TEST_ENV": "set"})
        if mode == "run":
            with open_dict(cfg):
                cfg.hydra.run.dir = str(sweep_dir / "3")
        seen: dict[str, Any] = {}
        callbacks = Recorder()
        context = HydraContext(config_loader=None, callbacks=callbacks)  # type: ignore[arg-type]
        before_cwd, before_hydra = os.getcwd(), HydraConfig.instance().cfg
        if runner == "hydra":
            ret = run_job(task_function=task_noting(seen, fail), config=copy.deepcopy(cfg),
                          job_dir_key=keys[0], job_subdir_key=keys[1], hydra_context=context)
        else:
            ret = job_run.run_job(copy.deepcopy(cfg), context, task_noting(seen, fail), *keys)
        assert os.getcwd() == before_cwd and HydraConfig.instance().cfg is before_hydra
        assert "FUZZYNAV_TEST_ENV" not in os.environ
        job_dir = sweep_dir / "3"
        snapshot = {p.name: p.read_text().replace(str(sweep_dir), "<sweep>")
                    for p in sorted((job_dir / ".hydra").iterdir())}
        seen = {k: (v.replace(str(sweep_dir), "<sweep>") if isinstance(v, str) else v) for k, v in seen.items()}
        outputs[name] = dict(
            snapshot=snapshot, seen=seen, calls=callbacks.calls, status=ret.status, overrides=ret.overrides,
            task_name=ret.task_name, working_dir=str(ret.working_dir).replace(str(sweep_dir), "<sweep>"),
            value=repr(ret._return_value), cfg=OmegaConf.to_container(ret.cfg),
            hydra_cfg=OmegaConf.to_yaml(ret.hydra_cfg).replace(str(sweep_dir), "<sweep>"))
    assert outputs["ours"] == outputs["hydra"]
    assert outputs["ours"]["status"] == (JobStatus.FAILED if fail else JobStatus.COMPLETED)
    assert outputs["ours"]["seen"]["cwd"].endswith("/3") == chdir
    assert set(outputs["ours"]["snapshot"]) == {"config.yaml", "hydra.yaml", "overrides.yaml"}


def test_slim_result_keeps_what_the_sweepers_read(tmp_path: Path) -> None:
    JobRuntime.instance().set("name", "run")
    cfg = sweep_config(tmp_path, ["seed=2"], chdir=False, env={})
    context = HydraContext(config_loader=None, callbacks=Recorder())  # type: ignore[arg-type]
    ret = job_run.slim(job_run.run_job(cfg, context, task_noting({}, fail=True)))
    assert ret.status == JobStatus.FAILED and isinstance(ret._return_value, RuntimeError)
    assert ret.hydra_cfg.hydra.job.num == 3 and ret.cfg is None and ret.overrides == ["seed=2"]


def test_launch_state_is_read_once_per_worker_and_removed(tmp_path: Path) -> None:
    cfg = OmegaConf.create({"a": 1})
    state = launch_state.LaunchState(cfg, HydraContext(config_loader=None, callbacks=None),  # type: ignore[arg-type]
                                     len, Singleton.get_state(), None)
    ref = launch_state.write(state, tmp_path)
    first = launch_state.worker_state(ref)
    assert first.master == cfg and first.task_function is len
    Path(ref.path).unlink()  # a worker keeps the launch's state: later jobs do not read the file again
    assert launch_state.worker_state(ref) is first
    launch_state.remove(ref)  # already gone: no error
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    stale = tmp_path / f"{launch_state.PREFIX}{int(dead.stdout)}-0123-x.pkl"  # left by a killed launch
    stale.write_bytes(b"state")
    mine = tmp_path / f"{launch_state.PREFIX}{os.getpid()}-4567-y.pkl"  # this process's other launch, in progress
    mine.write_bytes(b"state")
    other = launch_state.write(state, tmp_path)
    assert launch_state.worker_state(other) is not first  # a new launch, a new state
    assert not stale.exists() and mine.exists()
    launch_state.remove(other)
    assert [p.name for p in tmp_path.iterdir()] == [mine.name]


def test_a_sweep_leaves_no_launch_file(tmp_path: Path) -> None:
    before = set(Path(tempfile.gettempdir()).glob(f"{launch_state.PREFIX}*"))
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "sweep=quick", "episodes=1", "hydra.launcher.n_jobs=2",
                          f"hydra.sweep.dir={tmp_path / 's'}"], capture_output=True, text=True, timeout=600,
                         cwd=Path(__file__).resolve().parents[1])
    assert res.returncode == 0, res.stderr[-2000:]
    assert set(Path(tempfile.gettempdir()).glob(f"{launch_state.PREFIX}*")) <= before
    assert sorted(p.name for p in (tmp_path / "s" / ".fuzzynav").iterdir()) == ["lock"]


def test_a_job_log_file_that_cannot_be_made_raises_the_file_systems_error(tmp_path: Path, monkeypatch) -> None:
    """A job folder the job may not write into (chattr +i): logging's "Unable to configure handler 'file'" ended
    the sweep as "a worker process was lost (ValueError ...)", naming no file; the OSError behind it names it."""
    JobRuntime.instance().set("name", "run")
    cfg = sweep_config(tmp_path, ["seed=2"], chdir=False, env={})
    context = HydraContext(config_loader=None, callbacks=Recorder())  # type: ignore[arg-type]

    def refused(*args, **kwargs):
        try:
            raise PermissionError(1, "Operation not permitted", str(tmp_path / "3" / "run.log"))
        except PermissionError as err:
            raise ValueError("Unable to configure handler 'file'") from err

    monkeypatch.setattr(job_run, "configure_log", refused)
    with pytest.raises(PermissionError) as err:
        job_run.run_job(cfg, context, task_noting({}, fail=False))
    assert err.value.filename == str(tmp_path / "3" / "run.log")
