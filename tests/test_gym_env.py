"""The Gymnasium environment (runners.gym_env) and its logging wrapper (runners.gym_log).

The central check: an episode driven through the environment by the configured policy and logged by
``RecordMcap`` has the same message content (``runners.dataset.content_digests``) and the same run metadata as
the log ``python -m runners.run`` writes for the same configuration and seed.
"""

from __future__ import annotations

import math
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from fuzzynav.planning.layer import PLAN_MODES  # noqa: E402
from fuzzynav.policies.base import Action, make_policy  # noqa: E402
from runners.dataset import content_digests  # noqa: E402
from runners.gym_env import ENV_ID, NavigationEnv  # noqa: E402  (importing it registers fuzzynav/Navigation-v0)
from runners.gym_log import RecordMcap  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
USER_POLICY_DIR = Path(__file__).resolve().parent / "user_policy"


@pytest.fixture(scope="module")
def env() -> NavigationEnv:
    """One environment for the tests that only reset and step it (composing the config costs ~0.5 s); made
    through gymnasium.make for its spec (the checker re-makes it to try the render modes), unwrapped."""
    return gymnasium.make(ENV_ID, scenario="crossing_right").unwrapped


def _drive_with_policy(env, policy, seed: int) -> list[str]:
    """Run one episode with a fuzzynav policy through ``step_policy_action``; the executed modes."""
    env.reset(seed=seed)
    policy.reset(seed)
    modes = []
    while True:
        action = policy.act(env.unwrapped.observation)
        _, _, terminated, truncated, info = env.step_policy_action(action, policy.name)
        modes.append(info["mode"])
        if terminated or truncated:
            return modes


def _metadata(path: Path) -> dict[str, str]:
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        return next(dict(r.metadata) for r in make_reader(f).iter_metadata() if r.name == "fuzzynav.run")


# -- Gymnasium's own checks ---------------------------------------------------------------------------------------
def _strict_warnings() -> None:
    """The checker reports most problems as warnings: make them errors, except its advice to normalise a Box
    action space to [-1, 1] (the environment's actions are physical: degrees and cm/s, by design)."""
    warnings.simplefilter("error")
    warnings.filterwarnings("ignore", message=".*recommend using a symmetric and normalized space")


def test_check_env_passes(env: NavigationEnv) -> None:
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        _strict_warnings()
        check_env(env, skip_render_check=False)


def test_check_env_through_make_and_module_prefix() -> None:
    from gymnasium.utils.env_checker import check_env

    made = gymnasium.make(ENV_ID, scenario="head_on", render_mode="ansi")
    assert isinstance(made.unwrapped, NavigationEnv)
    with warnings.catch_warnings():
        _strict_warnings()
        check_env(made.unwrapped)
        obs, _ = made.reset(seed=0)  # through make's wrappers (order enforcing)
        assert made.observation_space.contains(obs)
        obs, reward, _, _, info = made.step(made.action_space.sample())
        assert made.observation_space.contains(obs) and math.isfinite(reward) and info["step"] == 1
        assert made.render().startswith("step 1:")
    # gymnasium's "module:" prefix imports runners.gym_env itself (already imported here: the id resolves)
    prefixed = gymnasium.make("runners.gym_env:fuzzynav/Navigation-v0", scenario="head_on")
    assert isinstance(prefixed.unwrapped, NavigationEnv)


def test_a_refused_first_reset_leaves_the_made_environment_usable() -> None:
    made = gymnasium.make(ENV_ID, scenario="head_on")
    with pytest.raises(ValueError, match="seed"):
        made.reset(seed=-1)
    obs, _ = made.reset(seed=0)
    obs, reward, _, _, info = made.step(made.action_space.sample())
    assert made.observation_space.contains(obs) and math.isfinite(reward) and info["step"] == 1


def test_module_prefix_registers_in_a_fresh_process() -> None:
    code = ("import gymnasium; e = gymnasium.make('runners.gym_env:fuzzynav/Navigation-v0', scenario='head_on'); "
            "o, _ = e.reset(seed=1); print(sorted(o))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "'laser'" in out.stdout and "'tracks_mask'" in out.stdout


def test_spaces_follow_the_config() -> None:
    env = NavigationEnv(scenario="head_on", overrides=["robot.v_max=50", "sensors.laser.beams=90"], max_tracks=3)
    assert env.action_space.low.tolist() == [-120.0, 0.0] and env.action_space.high.tolist() == [120.0, 50.0]
    assert env.observation_space["laser"].shape == (90,)
    assert env.observation_space["tracks"].shape == (3, 5) and env.observation_space["tracks_mask"].shape == (3,)
    assert all(space.dtype == np.float64 for space in env.observation_space.values())


# -- behaviour ----------------------------------------------------------------------------------------------------
def test_same_seed_and_actions_give_the_same_episode(env: NavigationEnv) -> None:
    actions = np.random.default_rng(0).uniform(env.action_space.low, env.action_space.high, (25, 2))

    def run():
        obs, _ = env.reset(seed=5)
        trace = [obs]
        for a in actions:
            obs, reward, terminated, truncated, _ = env.step(a)
            trace.append((obs, reward, terminated, truncated))
            if terminated or truncated:
                break
        return trace

    first, second = run(), run()
    assert len(first) == len(second)
    for a, b in zip(first, second, strict=True):
        a_obs, b_obs = (a, b) if isinstance(a, dict) else (a[0], b[0])
        assert all(np.array_equal(a_obs[k], b_obs[k]) for k in a_obs)
        if not isinstance(a, dict):
            assert a[1:] == b[1:]


def test_reward_and_termination(env: NavigationEnv) -> None:
    """Standing still costs the time penalty only; driving at the goal reaches it (+10, terminated)."""
    env.reset(seed=0)
    _, reward, terminated, truncated, info = env.step([0.0, 0.0])
    assert reward == pytest.approx(-0.01) and not terminated and not truncated and info["mode"] == "agent"
    total, k = 0.0, 0
    while True:
        s = env.observation.state
        goal = env.observation.goal
        turn = math.degrees(math.atan2(goal[1] - s.y, goal[0] - s.x)) - s.heading
        turn = (turn + 180.0) % 360.0 - 180.0
        _, reward, terminated, truncated, info = env.step([turn, 40.0])
        total, k = total + reward, k + 1
        if terminated or truncated:
            break
    assert info["outcome"] in ("goal", "collision")
    if info["outcome"] == "goal":
        assert terminated and reward > 9.0
    else:
        assert terminated and reward < -9.0
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.step([0.0, 10.0])


def test_timeout_is_truncation() -> None:
    env = NavigationEnv(scenario="head_on")
    env.reset(seed=0)
    steps = 0
    while True:
        _, _, terminated, truncated, info = env.step([0.0, 0.0])  # stand still until the step limit
        steps += 1
        if terminated or truncated:
            break
    assert info["outcome"] in ("timeout", "collision")
    if info["outcome"] == "timeout":
        assert truncated and not terminated and steps == env.scenario.max_steps


def test_wait_detour_layer_runs_on_top_of_the_agent() -> None:
    """With planner=auto the agent's command is overridden by a plan when the table predicts a collision."""
    env = NavigationEnv(scenario="head_on", overrides=["planner=auto"])
    env.reset(seed=0)
    modes = set()
    for _ in range(60):
        _, _, terminated, truncated, info = env.step([0.0, 30.0])  # straight at the oncoming walker
        modes.add(info["mode"])
        if terminated or truncated:
            break
    assert modes & set(PLAN_MODES), modes


def test_scenario_as_path_and_object_and_generated() -> None:
    from fuzzynav.scenarios.scenario import scenario_from_dict
    from tests.conftest import load_yaml

    path = ROOT / "conf" / "scenario" / "head_on.yaml"
    by_name, by_path = NavigationEnv(scenario="head_on"), NavigationEnv(scenario=str(path))
    by_object = NavigationEnv(scenario=scenario_from_dict(load_yaml(path)))
    observations = [e.reset(seed=2)[0] for e in (by_name, by_path, by_object)]
    for obs in observations[1:]:
        assert all(np.array_equal(obs[k], observations[0][k]) for k in obs)
    generated = NavigationEnv(scenario="random_mixed")
    generated.reset(seed=1)
    first = generated.scenario
    generated.reset(seed=2)
    assert generated.scenario != first  # a generated scenario is drawn from the episode's seed, as in runners.run


# -- the same log as runners.run ----------------------------------------------------------------------------------
@pytest.mark.parametrize("overrides", [["navigator=dwa"], ["planner=auto"]], ids=["dwa", "fuzzy_tpt"])
def test_same_log_content_as_runners_run(tmp_path: Path, overrides: list[str]) -> None:
    run_dir = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "runners.run", *overrides, "scenario=crossing_right", "seed=3",
                           f"hydra.run.dir={run_dir}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (run_log,) = run_dir.glob("*.mcap")

    made = gymnasium.make(ENV_ID, scenario="crossing_right", overrides=overrides)
    env = RecordMcap(made, tmp_path / "env", policy=made.unwrapped.episode_config.policy)
    policy = env.unwrapped.configured_policy()
    modes = _drive_with_policy(env, policy, seed=3)
    env.close()
    (env_log,) = env.paths
    assert env_log.name == run_log.name
    if "planner=auto" in overrides:
        assert set(modes) & set(PLAN_MODES), "the wait/detour layer must have intervened for this check to count"
    ran, drove = content_digests(run_log), content_digests(env_log)
    assert drove["topics"] == ran["topics"]
    assert drove["sha256"] == ran["sha256"]
    assert _metadata(env_log) == _metadata(run_log)


def test_record_mcap_finishes_an_unfinished_episode(tmp_path: Path) -> None:
    from analysis.logs import iter_messages

    env = RecordMcap(NavigationEnv(scenario="head_on"), tmp_path)
    env.reset(seed=0)
    for _ in range(3):
        env.step([0.0, 20.0])
    env.reset(seed=1)  # the first episode's log ends here, as interrupted
    env.step([0.0, 20.0])
    env.close()
    assert [p.name for p in env.paths] == [f"head_on__agent__none__table1__laser__s{s}.mcap" for s in (0, 1)]
    ends = [[m for topic, _, m in iter_messages(p) if topic == "/episode"] for p in env.paths]
    assert [(e[0]["outcome"], e[0]["steps"]) for e in ends] == [("interrupted", 3), ("interrupted", 1)]


# -- vector environments ------------------------------------------------------------------------------------------
def _make(scenario: str):
    # the "module:" prefix: an AsyncVectorEnv's worker process imports runners.gym_env itself
    return lambda: gymnasium.make(f"runners.gym_env:{ENV_ID}", scenario=scenario)


@pytest.mark.parametrize("vector", ["sync", "async"])
def test_vector_envs_run_20_steps(vector: str) -> None:
    fns = [_make(s) for s in ("head_on", "crossing_right", "overtaking")]
    started = time.perf_counter()
    venv = (gymnasium.vector.SyncVectorEnv(fns) if vector == "sync"
            else gymnasium.vector.AsyncVectorEnv(fns, context="spawn"))
    try:
        obs, _ = venv.reset(seed=[0, 1, 2])
        assert obs["laser"].shape == (3, 360) and obs["tracks"].shape == (3, 8, 5)
        for _ in range(20):  # a finished episode is reset by the vector env (autoreset)
            obs, rewards, _, _, _ = venv.step(np.tile([0.0, 25.0], (3, 1)))
            assert rewards.shape == (3,) and np.all(np.isfinite(rewards))
    finally:
        venv.close()
    assert time.perf_counter() - started < 120


# -- a policy defined outside the repository -------------------------------------------------------------------------
def test_user_policy_drives_the_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(USER_POLICY_DIR))
    env = NavigationEnv(scenario="head_on", overrides=["navigator=custom", "navigator._target_=my_policies.Straight"])
    policy = env.configured_policy()
    assert type(policy).__name__ == "Straight" and policy.name == "straight"
    modes = _drive_with_policy(env, policy, seed=0)
    assert set(modes) == {"straight"} and env.last_record.decision.policy == "straight"
    assert env.episode.outcome in ("goal", "collision")
    # the same module through make_policy on an environment configured for another policy
    other = NavigationEnv(scenario="head_on")
    straight = make_policy("my_policies.Straight", {"speed_cm_s": 20.0}, other.policy_context)
    other.reset(seed=0)
    _, _, _, _, info = other.step_policy_action(straight.act(other.observation), straight.name)
    assert info["mode"] in ("straight", *PLAN_MODES) and other.last_record.decision.v_cm_s in (0.0, 20.0)


# -- bad arguments: one ValueError (or Gymnasium error) naming the field, never a hang ------------------------------
@pytest.mark.parametrize(("kwargs", "field"), [
    ({"scenario": "no_such_world"}, "scenario/no_such_world"),
    ({"scenario": "../etc/passwd"}, "scenario:"),
    ({"scenario": "/nonexistent/world.yaml"}, "scenario:"),
    ({"scenario": 42}, "scenario:"),
    ({"overrides": ["planner.h_wiat=3"]}, "planner.h_wiat"),
    ({"overrides": ["sensors.laser.noise_std_cm=-1"]}, "sensors.laser.noise_std_cm"),
    ({"overrides": ["planner=auto,wait"]}, "planner"),
    ({"overrides": ["seed=4"]}, "seed"),
    ({"overrides": "planner=auto"}, "overrides"),
    ({"overrides": ["--cfg"]}, "overrides"),
    ({"overrides": ["navigator=custom"]}, "navigator._target_"),
    ({"max_tracks": -1}, "max_tracks"),
    ({"render_mode": "human"}, "render_mode"),
])
@pytest.mark.filterwarnings("ignore:.*render_mode")  # gymnasium.make warns first about render_mode='human'
def test_bad_kwargs_are_one_line_value_errors(kwargs: dict, field: str) -> None:
    started = time.perf_counter()
    with pytest.raises(ValueError) as info:
        gymnasium.make(ENV_ID, **{"scenario": "head_on", **kwargs})
    message = str(info.value)
    assert "\n" not in message and field in message, message
    assert time.perf_counter() - started < 30


def test_a_numpy_integer_seed_is_the_same_seed(env: NavigationEnv) -> None:
    first, _ = env.reset(seed=np.int64(3))
    again, _ = env.reset(seed=3)
    assert all(np.array_equal(first[k], again[k]) for k in first)


@pytest.mark.parametrize(("action", "field"), [
    ([math.nan, 10.0], "finite"),
    ([0.0, math.inf], "finite"),
    ([0.0, 10.0, 1.0], "2 real numbers"),
    ([[0.0, 10.0]], "2 real numbers"),
    ("fast", "2 real numbers"),
    (["left", 10.0], "2 real numbers"),
    ({"v": 10.0}, "2 real numbers"),
    (["1", "20"], "2 real numbers"),  # numpy would read text as numbers
    ([1j, 20.0], "2 real numbers"),
    ([True, False], "2 real numbers"),
    ([True, 20.0], "2 real numbers"),  # numpy would read [1.0, 20.0]
    ((0.0, np.bool_(True)), "2 real numbers"),
])
def test_bad_actions_are_value_errors(env: NavigationEnv, action, field: str) -> None:
    env.reset(seed=0)
    with pytest.raises(ValueError, match=field):
        env.step(action)
    _, _, _, _, info = env.step([0.0, 10.0])  # the episode is untouched by the refused action
    assert info["step"] == 1
    with pytest.raises(ValueError, match="finite"):
        env.step_policy_action(Action("x", math.nan, 10.0), "x")
    with pytest.raises((ValueError, gymnasium.error.Error), match=r"[Ss]eed"):
        env.reset(seed=-1)


def test_step_before_reset_is_a_gymnasium_error() -> None:
    env = NavigationEnv(scenario="head_on")
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.step([0.0, 10.0])


def test_bad_scenario_file_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "my_world.yaml"
    bad.write_text((ROOT / "conf" / "scenario" / "head_on.yaml").read_text().replace("max_steps:", "max_stepz:"))
    with pytest.raises(ValueError, match=r"^scenario: .*my_world\.yaml: .*max_stepz"):
        NavigationEnv(scenario=bad)


def test_composes_inside_a_program_that_initialised_hydra() -> None:
    """A @hydra.main training script has Hydra initialised; the environment composes its own config all the same
    and leaves the program's Hydra as it was."""
    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    with initialize_config_dir(config_dir=str(ROOT / "conf"), version_base="1.3"):
        outer = GlobalHydra.instance()
        env = NavigationEnv(scenario="head_on", overrides=["planner=wait"])
        assert env.episode_config.planner.strategy == "wait"
        assert GlobalHydra.instance() is outer and outer.is_initialized()


def test_an_agents_log_names_the_agent_and_is_never_pooled_with_a_policy(tmp_path: Path) -> None:
    """An agent's episodes were logged with the configured policy's name (fuzzy) and the file name runners.run
    gives: a report pooled them with the fuzzy policy's episodes."""
    from analysis.episode_log import load_episode
    from analysis.metrics import analyse_logs

    env = RecordMcap(NavigationEnv(scenario="head_on"), tmp_path)
    env.reset(seed=0)
    for _ in range(3):
        env.step([0.0, 20.0])
    env.close()
    (path,) = env.paths
    log = load_episode(path)
    assert log.meta["policy"] == "agent" and log.config["navigator"] == {"policy": "agent"}
    assert {d["policy"] for d in log.decisions} == {"agent"}
    analysis = analyse_logs([tmp_path])
    assert set(analysis.excluded["policy"]) == {"agent"}  # interrupted, but labelled by what drove it
    with pytest.raises(ValueError, match=r"^action: this recorder logs policy 'fuzzy'"):
        RecordMcap(NavigationEnv(scenario="head_on"), tmp_path / "p", policy="fuzzy").step([0.0, 20.0])
    with pytest.raises(ValueError, match=r"^policy: 'dwa' is not the configured policy 'fuzzy'"):
        RecordMcap(NavigationEnv(scenario="head_on"), tmp_path / "q", policy="dwa")
    recorder = RecordMcap(NavigationEnv(scenario="head_on"), tmp_path / "r")
    recorder.reset(seed=0)
    try:
        with pytest.raises(ValueError, match=r"^policy_name: this recorder logs 'agent'"):
            recorder.step_policy_action(Action("fuzzy", 0.0, 20.0), "fuzzy")
    finally:
        recorder.close()  # one log may be open per process: the next test's would be refused
    for bad in ("", path):  # empty, or a file
        with pytest.raises(ValueError, match=r"^out_dir: "):
            RecordMcap(NavigationEnv(scenario="head_on"), bad)


# -- what an RL user expects (issue 37 item 7) --------------------------------------------------------------------
def test_the_agent_drives_by_default_and_the_layer_is_an_explicit_option() -> None:
    assert NavigationEnv(scenario="head_on").episode_config.planner.strategy == "none"
    assert NavigationEnv(scenario="head_on", overrides=["planner=auto"]).episode_config.planner.strategy == "auto"
    assert NavigationEnv(scenario="head_on", overrides=["planner.strategy=wait"]).episode_config.planner.strategy \
        == "wait"
    with pytest.raises(ValueError, match=r"^overrides: planner.h_wait: the wait/detour layer is off"):
        NavigationEnv(scenario="head_on", overrides=["planner.h_wait=3"])
    env = NavigationEnv(scenario="head_on")
    env.reset(seed=0)
    modes = set()
    done = False
    while not done:  # straight at the goal through a head-on obstacle: nothing takes the wheel
        goal_x = env.scenario.robot.goal[0]
        _, _, terminated, truncated, info = env.step([0.0, 30.0 if env.episode.state.x < goal_x else 0.0])
        modes.add(info["mode"])
        done = terminated or truncated
    assert modes == {"agent"}


@pytest.mark.parametrize(("action", "command"), [
    ([0.0, -20.0], (0.0, 0.0)),            # below the box: stand still
    ([1e7, 20.0], (120.0, 20.0)),          # a turn beyond the limit: the limit
    ([1e308, 1e308], (120.0, 40.0)),
    ([-1e308, 5.0], (-120.0, 5.0)),        # (0, v_min) is driven at v_min by the episode, as documented
    (np.array([3, 25], dtype=np.int64), (3.0, 25.0)),
])
def test_actions_outside_the_box_are_clamped(env: NavigationEnv, action, command) -> None:
    assert env.command(action) == command
    env.reset(seed=0)
    env.step(action)  # no PolicyError


def test_reset_takes_no_options(env: NavigationEnv) -> None:
    env.reset(seed=0, options={})
    with pytest.raises(ValueError, match=r"options: unknown key\(s\) \['goal'\]; reset takes no options"):
        env.reset(seed=0, options={"goal": [1, 2]})
    with pytest.raises(ValueError, match="options: expected a dict, got list"):
        env.reset(seed=0, options=[1])


def test_normalized_spaces_pass_gymnasiums_checker() -> None:
    from gymnasium.utils.env_checker import check_env

    env = NavigationEnv(scenario="crossing_right", normalized=True)
    assert env.action_space == gymnasium.spaces.Box(-1.0, 1.0, (2,), np.float32)
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert all(part.dtype == np.float32 and env.observation_space[name].contains(part) for name, part in obs.items())
    assert env.command([1.0, 1.0]) == (120.0, 40.0) and env.command([-1.0, -1.0]) == (-120.0, 0.0)
    assert env.command([0.0, 0.0]) == (0.0, 20.0) and env.command([5.0, -5.0]) == (120.0, 0.0)
    made = gymnasium.make(ENV_ID, scenario="head_on", normalized=True)
    made.reset(seed=1)
    obs, *_ = made.step(made.action_space.sample())
    assert made.observation_space.contains(obs)
    with pytest.raises(ValueError, match="normalized: expected true or false"):
        NavigationEnv(scenario="head_on", normalized="yes")
