"""Plug-ins that misbehave (hostile tester, round 2): a pedestrian model writing into what it is given, a policy
tampering with the shared fuzzy controller or its observation, and models and generators whose code raises
anything (SystemExit included). Each must end in one line naming the plug-in and what failed, never a traceback,
an exit status 0 or a silently wrong result."""

from __future__ import annotations

import pickle
import re
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode import Episode, EpisodeConfig
from fuzzynav.kinematics import RobotLimits, RobotState
from fuzzynav.pedestrians.base import MODELS, ObstacleModelError, register_obstacle_model
from fuzzynav.pedestrians.crowd import Crowd
from fuzzynav.policies.base import POLICIES, Action, Observation, PolicyContext, make_policy, register_policy
from fuzzynav.scenarios.generator import GENERATORS, generate, register_generator
from fuzzynav.scenarios.scenario import ScenarioError, scenario_from_dict
from fuzzynav.scenarios.world import World
from tests.conftest import ROOT, load_controller, load_scenario, one_error_line

FAR_ROBOT = RobotState(-1e6, -1e6, 0.0, 0.0)


@dataclass(frozen=True)
class _NoConfig:
    pass


def _scene(model: str) -> object:
    return scenario_from_dict({"name": "t", "bounds": [0, 0, 1200, 800],
                               "robot": {"start": [100, 400], "heading": 0, "goal": [1100, 400], "radius": 20},
                               "dynamic_obstacles": [
                                   {"id": "a", "radius": 20, "start": [600, 600], "velocity": [10, 0], "model": model},
                                   {"id": "b", "radius": 20, "start": [600, 200], "velocity": [-10, 0]}],
                               "max_steps": 50})


def _registered_for_a_test(register_as, registry: dict, prefix: str):
    """A fixture's body: ``register(plugin) -> name`` registers under a fresh name, removed after the test."""
    names: list[str] = []

    def register(plugin) -> str:
        name = f"{prefix}_{len(names)}"
        register_as(name)(plugin)
        names.append(name)
        return name

    yield register
    for name in names:
        registry.pop(name, None)


@pytest.fixture
def model_of():
    """Register a model class under a fresh name for one test: ``model_of(cls) -> name``."""
    def register_as(name: str):
        def register(cls: type) -> type:
            cls.config_class = _NoConfig
            return register_obstacle_model(name)(cls)
        return register

    yield from _registered_for_a_test(register_as, MODELS, "test_misbehaving_model")


class _Walker:
    """Walks its obstacles straight at their scenario velocity; ``misbehave(view)`` is called in every step."""

    def __init__(self, obstacles, config):
        self.x = np.array([o.start for o in obstacles], float)
        self.v = np.array([o.velocity for o in obstacles], float)

    def reset(self, rng):
        return self.x.copy(), self.v.copy()

    def misbehave(self, view):
        pass

    def step(self, view, indices, dt):
        self.misbehave(view)
        self.x = self.x + self.v * dt
        return self.x.copy(), self.v.copy()


# -- 1. a model cannot change the world it is given ------------------------------------------------------------


@pytest.mark.parametrize("write", [
    lambda view: view.velocities.__setitem__(slice(None), 0.0),  # logged a walker at vx=0 while it moved
    lambda view: view.positions.__setitem__(slice(None), view.positions + 5000.0),
    lambda view: view.radii.__setitem__(slice(None), 0.001),
    lambda view: np.add(view.positions, 1.0, out=view.positions),
])
def test_a_model_that_writes_into_its_view_fails_naming_it(model_of, write):
    class Writes(_Walker):
        def misbehave(self, view):
            write(view)

    name = model_of(Writes)
    s = _scene(name)
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds, s.static_obstacles), s.robot.radius)
    crowd.reset(0)
    before = (crowd.positions.copy(), crowd.velocities.copy(), crowd.radii.copy())
    with pytest.raises(ObstacleModelError, match=rf"^pedestrian model {name!r}: step\(\) failed: ValueError: "
                                                 ".*read-only"):
        crowd.step(FAR_ROBOT, 1.0)
    assert all((a == b).all() for a, b in zip(before, (crowd.positions, crowd.velocities, crowd.radii), strict=True))


def test_the_built_in_models_step_on_a_read_only_view():
    """scripted, social_force, orca, random_walk side by side: their crowd's state (what they read) is read-only,
    and they still move."""
    s = scenario_from_dict({"name": "t", "bounds": [0, 0, 1200, 800],
                            "robot": {"start": [100, 400], "heading": 0, "goal": [1100, 400], "radius": 20},
                            "dynamic_obstacles": [
                                {"id": m, "radius": 20, "start": [300 + 150 * i, 200 + 100 * i], "velocity": [20, 0],
                                 "model": m}
                                for i, m in enumerate(("scripted", "social_force", "orca", "random_walk"))],
                            "max_steps": 50})
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds, s.static_obstacles), s.robot.radius)
    start, _ = crowd.reset(0)
    for _ in range(5):
        crowd.step(RobotState(100, 400, 0.0, 10.0), 1.0)
        assert not (crowd.positions.flags.writeable or crowd.velocities.flags.writeable
                    or crowd.radii.flags.writeable or crowd.present.flags.writeable)
    assert (np.abs(crowd.positions - start).sum(axis=1) > 0).all()


# -- 3. a model's code that raises: one error naming the model and the call ----------------------------------


@pytest.mark.parametrize("where, what", [("init", "factory(obstacles, config)"), ("reset", "reset(rng)"),
                                         ("step", "step()"), ("presence", "presence(step)")])
@pytest.mark.parametrize("error, shown", [(RuntimeError("model boom"), "RuntimeError: model boom"),
                                          (KeyError("boom"), "KeyError: 'boom'"),
                                          (ValueError("n: bad"), "ValueError: n: bad"),
                                          (SystemExit(0), "SystemExit: 0")])
def test_a_model_whose_code_raises_fails_naming_the_model_and_the_call(model_of, where, what, error, shown):
    class Raises(_Walker):
        def __init__(self, obstacles, config):
            super().__init__(obstacles, config)
            if where == "init":
                raise error

        def reset(self, rng):
            if where == "reset":
                raise error
            return super().reset(rng)

        def misbehave(self, view):
            if where == "step":
                raise error

        def presence(self, step):
            if where == "presence" and step > 0:
                raise error
            return np.ones(len(self.x), dtype=bool)

    name = model_of(Raises)
    message = "^" + re.escape(f"pedestrian model {name!r}: {what} failed: {shown}") + "$"
    if where in ("init", "reset"):  # before the episode's first step: the run's one-line config error
        with pytest.raises(ObstacleModelError, match=message):
            Episode(_scene(name), load_controller("table1"), EpisodeConfig(), seed=0)
        return
    episode = Episode(_scene(name), load_controller("table1"), EpisodeConfig(), seed=0)
    with pytest.raises(ObstacleModelError, match=message):
        episode.step()


def test_a_models_own_keyboard_interrupt_goes_on_with_a_note_naming_it(model_of):
    class Interrupts(_Walker):
        def misbehave(self, view):
            raise KeyboardInterrupt

    name = model_of(Interrupts)
    episode = Episode(_scene(name), load_controller("table1"), EpisodeConfig(), seed=0)
    with pytest.raises(KeyboardInterrupt) as info:
        episode.step()
    assert info.value.__notes__ == [f"pedestrian model {name!r}: step()"]


def test_a_failing_model_is_an_episode_error_naming_it(model_of):
    from runners.run import run_episode

    class Exits(_Walker):
        def misbehave(self, view):
            raise SystemExit(0)  # ended the run with exit status 0 and no output

    name = model_of(Exits)
    row = run_episode(_scene(name), FastEvaluator(load_controller("table1")), EpisodeConfig(), 0, None, "")
    assert row["outcome"] == "error"
    assert row["reason"] == f"ObstacleModelError: pedestrian model {name!r}: step() failed: SystemExit: 0"


# -- 2. a policy cannot change the shared controller or what the planner reads -------------------------------


def test_the_fuzzy_controller_cannot_be_changed_once_built():
    evaluator = FastEvaluator(load_controller("table1"))
    inputs = {v.name: 100.0 for v in evaluator.spec.inputs}
    before = evaluator.evaluate(inputs)
    with pytest.raises(AttributeError, match="read-only"):
        evaluator.evaluate = lambda inputs: (0.0, 0.0)
    with pytest.raises(AttributeError, match="read-only"):
        evaluator._tampered = True
    with pytest.raises(AttributeError, match="read-only"):
        del evaluator.spec
    for array in (evaluator._antecedents, evaluator._stacked_mfs, evaluator._stacked_weights,
                  evaluator._outputs["v"].mfs, evaluator._outputs["v"].grid, evaluator._inputs[0][1]):
        with pytest.raises(ValueError, match="read-only"):
            array[...] = 0.0
    with pytest.raises(TypeError):
        evaluator._outputs["v"] = None
    assert evaluator.evaluate(inputs) == before
    assert pickle.loads(pickle.dumps(evaluator)).evaluate(inputs) == before


def test_a_policy_that_replaces_the_controllers_evaluate_is_refused_naming_it():
    @register_policy("test_tamper_controller")
    class Tamper:
        name = "test_tamper_controller"

        def __init__(self, params, context):
            context.controller.evaluate = lambda inputs: (0.0, 0.0)  # /tmp/h2/bad/evil.py: half speed for all

        def reset(self, seed):
            pass

        def act(self, observation):
            return Action("go", 0.0, 0.0)

    try:
        evaluator = FastEvaluator(load_controller("table1"))
        context = PolicyContext(RobotLimits(), 20.0, controller=evaluator)
        with pytest.raises(ValueError, match=r"^navigator: building policy 'test_tamper_controller' failed: "
                                             r"AttributeError: .*cannot set 'evaluate'"):
            make_policy("test_tamper_controller", {}, context)
        assert "evaluate" not in vars(evaluator)
    finally:
        POLICIES.pop("test_tamper_controller", None)


class _ZeroesStaticPoints:
    name = "zeroes"

    def reset(self, seed):
        pass

    def act(self, observation):
        observation.static_points[:] = 0.0  # changed what the wait/detour planner did after it
        return Action("go", 0.0, 10.0)


def test_a_policy_that_writes_into_its_observation_fails_naming_it():
    episode = Episode(load_scenario("static_clutter"), load_controller("table1"), EpisodeConfig(), seed=0,
                      policy=_ZeroesStaticPoints())
    obs, _ = episode.observe()
    assert len(obs.static_points) and not obs.static_points.flags.writeable
    with pytest.raises(ValueError, match=r"^policy zeroes: act\(\) failed: ValueError: .*read-only"):
        episode.step()


def test_an_observation_does_not_change_its_callers_array():
    points = np.zeros((3, 2))
    obs = Observation(RobotState(0, 0, 0, 0), (1.0, 1.0), (1.0, 1.0, 1.0), (), points)
    assert points.flags.writeable and not obs.static_points.flags.writeable
    assert np.shares_memory(points, obs.static_points)


# -- 3. a generator's code that raises -----------------------------------------------------------------------


@pytest.fixture
def generator_of():
    yield from _registered_for_a_test(register_generator, GENERATORS, "test_misbehaving_gen")


@pytest.mark.parametrize("error, shown", [(KeyError("gen boom"), "KeyError: 'gen boom'"),
                                          (ValueError("n: bad on purpose"), "ValueError: n: bad on purpose"),
                                          (SystemExit(0), "SystemExit: 0"), (RuntimeError(), "RuntimeError")])
def test_a_generator_that_raises_fails_naming_it(generator_of, error, shown):
    def gen(params, seed, name):
        raise error

    name = generator_of(gen)
    with pytest.raises(ScenarioError, match=rf"^generator {name!r}: failed: {shown}$"):
        generate({"generator": name, "params": {}}, 0)


def test_a_generator_that_returns_no_mapping_is_named(generator_of):
    name = generator_of(lambda params, seed, name: None)
    with pytest.raises(ScenarioError, match=rf"^generator {name!r}: returned NoneType"):
        generate({"generator": name, "params": {}}, 0)


def test_a_generator_cannot_change_the_parameters_of_the_next_seed(generator_of):
    base = load_scenario("head_on")

    def gen(params, seed, name):
        assert "x" not in params
        params["x"] = 1
        params["nested"]["y"] = 2
        return {"name": name, "bounds": list(base.bounds), "max_steps": 10,
                "robot": {"start": list(base.robot.start), "heading": 0, "goal": list(base.robot.goal), "radius": 20}}

    name = generator_of(gen)
    data = {"generator": name, "params": {"nested": {}}}
    generate(data, 0)
    generate(data, 1)
    assert data["params"] == {"nested": {}}


# -- end to end: the plug-ins of an installed package (an entry point), as a user runs them ---------------------


def _package(tmp_path: Path) -> dict[str, str]:
    """A package with a pedestrian model and a generator (entry points), and its scenario files."""
    (tmp_path / "misbehaving_pkg.py").write_text(textwrap.dedent("""
        from dataclasses import dataclass
        import numpy as np

        @dataclass(frozen=True)
        class Config:
            mode: str = "ok"

        class Model:
            config_class = Config
            def __init__(self, obstacles, config):
                self.mode = config.mode
                self.x = np.array([o.start for o in obstacles], float)
                self.v = np.array([o.velocity for o in obstacles], float)
            def reset(self, rng):
                if self.mode == "reset_exit":
                    raise SystemExit(0)
                return self.x.copy(), self.v.copy()
            def step(self, view, indices, dt):
                if self.mode == "step_exit":
                    raise SystemExit(0)
                if self.mode == "mutate":
                    view.velocities[:] = 0.0
                self.x = self.x + self.v * dt
                return self.x.copy(), self.v.copy()

        def ring(params, seed, name):
            raise KeyError("gen boom")
    """))
    dist = tmp_path / "misbehaving_pkg-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: misbehaving_pkg\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[fuzzynav.pedestrians]\nmisbehaving = misbehaving_pkg:Model\n"
                                           "[fuzzynav.generators]\nmisbehaving_ring = misbehaving_pkg:ring\n")
    return {"PYTHONPATH": f"{tmp_path}:{ROOT}", "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}


def _run(tmp_path: Path, env: dict[str, str], *overrides: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "runners.run", *overrides, f"hydra.run.dir={tmp_path / 'out'}"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("mode, status, line", [
    ("step_exit", 1, "error: seed 0: ObstacleModelError: pedestrian model 'misbehaving': step() failed: "
                     "SystemExit: 0; traceback in "),
    ("mutate", 1, "error: seed 0: ObstacleModelError: pedestrian model 'misbehaving': step() failed: ValueError: "
                  "assignment destination is read-only; traceback in "),
    ("reset_exit", 2, "error: config: pedestrian model 'misbehaving': reset(rng) failed: SystemExit: 0"),
])
def test_a_run_with_a_failing_model_prints_one_line_and_exits_non_zero(tmp_path, mode, status, line):
    env = _package(tmp_path)
    proc = _run(tmp_path, env, "scenario=head_on", "planner=none", "+scenario.dynamic_obstacles.0.model=misbehaving",
                f"+scenario.dynamic_obstacles.0.model_params.mode={mode}")
    assert proc.returncode == status, proc.stderr
    assert one_error_line(proc.stderr).startswith(line)


def test_a_run_with_a_failing_generator_prints_one_line_and_exits_non_zero(tmp_path):
    env = _package(tmp_path)
    proc = _run(tmp_path, env, "scenario=corridor_flow", "scenario.generator=misbehaving_ring")
    assert proc.returncode == 2, proc.stderr
    assert one_error_line(proc.stderr).endswith("generator 'misbehaving_ring': failed: KeyError: 'gen boom'")


def test_a_models_own_keyboard_interrupt_is_named_by_the_model():
    from fuzzynav.pedestrians.base import call_model
    from runners.run import raised_by_code

    def step() -> None:
        raise KeyboardInterrupt

    try:
        call_model("mine", "step()", step)
    except KeyboardInterrupt as err:
        line = raised_by_code(err)
    assert line.startswith("pedestrian model 'mine': step() raised KeyboardInterrupt (no signal"), line
