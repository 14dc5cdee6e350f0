"""A normal install runs everything: the wheel built from this tree, installed (not editable) in a fresh virtual
environment and run from a folder outside the checkout, sweeps, reports and makes the Gymnasium environment.

The fresh environment takes the project's dependencies from this test's environment (a ``.pth`` line naming its
site-packages, which adds the folder only: that environment's editable install of fuzzynav stays inactive), so the
test needs no download; what it installs is this tree's wheel alone.
"""

from __future__ import annotations

import os
import shutil
import site
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# what the wheel is built from (copied: building writes build/ and *.egg-info beside the sources)
SOURCES = ("pyproject.toml", "README.md", "build_backend", "conf", "fuzzynav", "runners", "analysis")


def _package_folders() -> set[str]:
    found = set()
    for top in ("fuzzynav", "runners", "analysis"):
        for init in (ROOT / top).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT)
            if rel.parts[:2] != ("runners", "hydra_sweeper"):
                found.add(".".join(rel.parts))
    return found


def test_every_package_folder_is_packaged():
    """A folder with an ``__init__.py`` that ``pyproject.toml`` does not list would be missing from the wheel
    (the editable install of a checkout would still find it, so only an install from the wheel would fail)."""
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    assert _package_folders() - listed == set()
    assert {"fuzzynav.conf", "hydra_plugins.fuzzynav_sweeper"} <= listed


def _run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 600) -> subprocess.CompletedProcess:
    res = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
                         stdin=subprocess.DEVNULL)
    assert res.returncode == 0, (f"{' '.join(cmd[:4])}... exit {res.returncode}\n{res.stdout[-2000:]}\n"
                                 f"{res.stderr[-3000:]}")
    return res


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> tuple[Path, Path, dict[str, str]]:
    """(python of a fresh venv with this tree's wheel installed, a working folder outside the checkout, env)."""
    tmp = tmp_path_factory.mktemp("wheel")
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        path = ROOT / name
        if path.is_dir():
            shutil.copytree(path, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.so", "*.egg-info"))
        else:
            shutil.copy2(path, src / name)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    env["PYTHONNOUSERSITE"] = "1"
    wheels = tmp / "wheels"
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheels), str(src)], tmp, env)
    (wheel,) = wheels.glob("fuzzynav-*.whl")
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", str(venv)], tmp, env)
    python = venv / "bin" / "python"
    purelib = _run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], tmp,
                   env).stdout.strip()
    deps = [p for p in site.getsitepackages() if Path(p).is_dir()]
    Path(purelib, "_test_dependencies.pth").write_text("".join(f"{p}\n" for p in deps))
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q", "--no-deps", "--no-index",
          str(wheel)], tmp, env)
    work = tmp / "work"
    work.mkdir()
    return python, work, env


def test_installed_package_is_not_the_checkout(installed):
    python, work, env = installed
    res = _run([str(python), "-c", "import fuzzynav, runners, analysis, fuzzynav.conf, hydra_plugins.fuzzynav_sweeper"
                " as s; print('\\n'.join(m.__file__ for m in (fuzzynav, runners, analysis, fuzzynav.conf, s)))"],
               work, env)
    venv = python.parents[1]
    for line in res.stdout.split():
        assert Path(line).resolve().is_relative_to(venv.resolve()), line
    assert (Path(res.stdout.split()[3]).parent / "config.yaml").is_file()


def test_installed_sweep_and_report_run_outside_the_checkout(installed):
    python, work, env = installed
    out = work / "sweep"
    res = _run([str(python), "-m", "runners.sweep", "sweep=quick", "scenario=head_on", "planner=auto,none",
                f"hydra.sweep.dir={out}"], work, env)
    assert "error" not in res.stderr.lower(), res.stderr[-2000:]
    logs = sorted(out.rglob("*.mcap"))
    assert len(logs) == 4, logs  # 2 planners x 2 episodes
    report = work / "report"
    _run([str(python), "-m", "analysis.report", str(out), "--out", str(report)], work, env)
    assert (report / "report.html").is_file() and (report / "episodes.csv").is_file()
    assert not (ROOT / "multirun").exists() or not any((ROOT / "multirun").rglob(out.name))


def test_installed_gymnasium_environment_steps(installed):
    pytest.importorskip("gymnasium")
    python, work, env = installed
    code = ("import gymnasium\n"
            "env = gymnasium.make('runners.gym_env:fuzzynav/Navigation-v0', scenario='head_on')\n"
            "obs, info = env.reset(seed=0)\n"
            "obs, reward, terminated, truncated, info = env.step(env.action_space.sample())\n"
            "print('stepped', type(obs).__name__)\n")
    assert "stepped" in _run([str(python), "-c", code], work, env).stdout


# A plug-in package of another author: a policy, a pedestrian model and their YAML, found through entry points only
PLUGIN_FILES = {
    "pyproject.toml": """\
[build-system]
requires = ["setuptools>=64"]
build-backend = "setuptools.build_meta"

[project]
name = "standing-plugin"
version = "0.1"

[project.entry-points."fuzzynav.policies"]
toward_goal = "standing_plugin.policy:TowardGoal"

[project.entry-points."fuzzynav.pedestrians"]
standing = "standing_plugin.model:Standing"

[project.entry-points."fuzzynav.conf"]
standing_plugin = "standing_plugin.conf"

[tool.setuptools]
packages = ["standing_plugin", "standing_plugin.conf"]

[tool.setuptools.package-data]
"standing_plugin.conf" = ["*/*.yaml"]
""",
    "standing_plugin/__init__.py": "",
    "standing_plugin/policy.py": """\
from dataclasses import dataclass

from fuzzynav.numerics.geometry import wrap_180
from fuzzynav.numerics.portable_math import bearing_deg
from fuzzynav.policies.base import Action


@dataclass(frozen=True)
class TowardGoalConfig:
    speed_cm_s: float = 20.0


class TowardGoal:
    name = "toward_goal"
    config_class = TowardGoalConfig

    def __init__(self, params, context):
        self.config, self.limits = params, context.limits

    def reset(self, seed):
        pass

    def act(self, observation):
        s = observation.state
        turn = wrap_180(bearing_deg(s.x, s.y, *observation.goal) - s.heading)
        turn = max(-self.limits.max_turn_deg, min(self.limits.max_turn_deg, turn))
        return Action("toward_goal", turn, self.config.speed_cm_s, {})
""",
    "standing_plugin/model.py": """\
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class StandingConfig:
    pass


class Standing:
    config_class = StandingConfig

    def __init__(self, obstacles, config):
        self.start = np.array([o.start if o.waypoints is None else o.waypoints[0] for o in obstacles], dtype=float)

    def reset(self, rng):
        return self.start.copy(), np.zeros_like(self.start)

    def step(self, view, indices, dt):
        return self.start.copy(), np.zeros_like(self.start)
""",
    "standing_plugin/conf/__init__.py": "",
    "standing_plugin/conf/navigator/toward_goal.yaml": """\
defaults:
  - override /planner@_global_.planner: none
  - _self_
policy: toward_goal
speed_cm_s: 25.0
""",
    "standing_plugin/conf/scenario/standing_people.yaml": """\
name: standing_people
bounds: [0, 0, 800, 400]
robot: {start: [50, 200], goal: [750, 200], heading: 0}
dynamic_obstacles:
  - {id: p1, radius: 20, start: [400, 300], velocity: [0, -10], model: standing}
max_steps: 80
""",
}


def test_plugin_package_joins_a_sweep_by_name(installed):
    """A policy, a pedestrian model and their YAML from another installed package: no file of fuzzynav names them,
    and ``navigator=toward_goal,dwa`` sweeps the plug-in beside a built-in on the plug-in's scenario."""
    python, work, env = installed
    src = work.parent / "plugin"
    for name, text in PLUGIN_FILES.items():
        (src / name).parent.mkdir(parents=True, exist_ok=True)
        (src / name).write_text(text)
    wheels = work.parent / "plugin_wheels"
    _run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(wheels), str(src)], work, env)
    (wheel,) = wheels.glob("standing_plugin-*.whl")
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "-q", "--no-deps", "--no-index",
          str(wheel)], work, env)
    out = work / "plugin_sweep"
    res = _run([str(python), "-m", "runners.sweep", "sweep=quick", "scenario=standing_people",
                "navigator=toward_goal,dwa", "planner=none", "episodes=1", f"hydra.sweep.dir={out}"], work, env)
    logs = sorted(p.name for p in out.rglob("*.mcap"))
    assert len(logs) == 2 and all(n.startswith("standing_people") for n in logs), (logs, res.stdout[-1500:])
    report = work / "plugin_report"
    _run([str(python), "-m", "analysis.report", str(out), "--out", str(report)], work, env)
    episodes = (report / "episodes.csv").read_text()
    assert "toward_goal" in episodes and "dwa" in episodes
    # an unknown name still says which ones are known, the plug-in's among them
    bad = subprocess.run([str(python), "-m", "runners.run", "scenario=standing_people", "navigator.policy=nope"],
                         cwd=work, env=env, capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL)
    assert bad.returncode != 0 and "toward_goal" in bad.stderr, bad.stderr[-1500:]
