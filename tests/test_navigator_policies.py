"""The navigator group chooses the policy: every option composes to its policy and planner, a planner on the
command line wins, a bad navigator section is one line naming the field, a policy that returns a command the
robot cannot execute stops the episode with an error, and every policy runs, logs, replays and is reported
side by side (end to end, through the real commands)."""

from __future__ import annotations

import enum
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzynav.config import episode_config_from_dict
from fuzzynav.episode import Episode, EpisodeConfig
from fuzzynav.params.names import DEFAULT_POLICY
from fuzzynav.planning.planner import PlannerConfig, find_new_path
from fuzzynav.planning.tpt import build_tpt
from fuzzynav.policies.base import Action, Observation, registered_policies
from fuzzynav.sensing.tracking import Track
from tests.conftest import CONF, ROOT, load_controller, load_scenario, one_error_line

OPTIONS = {"fuzzy_tpt": ("fuzzy", "auto"), "default": ("fuzzy", "auto"), "paper_literal": ("fuzzy", "auto"),
           "fuzzy": ("fuzzy", "none"), "dwa": ("dwa", "none"), "apf": ("apf", "none"), "vfh": ("vfh", "none"),
           "orca": ("orca", "none"), "direct": ("direct", "none")}


def _compose(*overrides: str) -> dict:
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from runners.configuration import schema

    schema.register()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        return OmegaConf.to_container(compose("config", overrides=list(overrides)), resolve=True)


def test_every_navigator_option_has_a_test():
    assert {p.stem for p in (CONF / "navigator").glob("*.yaml")} == set(OPTIONS) | {"custom"}


@pytest.mark.parametrize("option", sorted(OPTIONS))
def test_each_navigator_option_names_its_policy_and_its_planner(option):
    cfg = _compose(f"navigator={option}")
    ep = episode_config_from_dict({k: cfg[k] for k in ("navigator", "planner", "robot", "dt")})
    assert (ep.policy, ep.planner.strategy) == OPTIONS[option]


@pytest.mark.parametrize(("overrides", "expected"), [
    (["navigator=dwa", "planner=auto"], ("dwa", "auto")), (["planner=auto", "navigator=dwa"], ("dwa", "auto")),
    (["navigator=fuzzy", "planner=wait"], ("fuzzy", "wait")), (["navigator=orca", "planner=auto_h4"], ("orca", "auto")),
])
def test_a_planner_on_the_command_line_wins_over_the_options_default(overrides, expected):
    cfg = _compose(*overrides)
    assert (cfg["navigator"].get("policy"), cfg["planner"]["strategy"]) == expected


def test_the_default_is_the_papers_method_with_the_defaults_of_the_library():
    cfg = _compose()
    ep = episode_config_from_dict({k: cfg[k] for k in ("navigator", "planner")})
    assert ep.policy == "fuzzy" and ep.navigator == EpisodeConfig().navigator and ep.planner == PlannerConfig()


@pytest.mark.parametrize(("navigator", "message"), [
    ({"policy": "nope"}, "navigator.policy: unknown policy 'nope' (known: apf, direct, dwa, fuzzy, orca, vfh;"),
    ({"policy": "dwa", "alpha": 1}, "navigator.alpha: unknown key"),
    ({"policy": "dwa", "alpha_heading": -1}, "navigator.alpha_heading: must be in [0, 1,000,000], got -1"),
    ({"policy": "dwa", "turn_samples": 10**9}, "navigator.turn_samples: must be in [3, 721]"),
    ({"policy": "dwa", "turn_samples": 4}, "navigator.turn_samples: must be an odd number >= 3"),
    ({"policy": "vfh", "smoothing_l": 100}, "navigator.smoothing_l: must be in [1, 36]"),
    ({"_target_": "a." + "b" * 300}, "navigator._target_: expected an import path"),
    ({"policy": "dwa", "alpha_heading": "high"}, "navigator.alpha_heading: expected a number"),
    ({"policy": "apf", "influence_cm": math.nan}, "navigator.influence_cm:"),
    ({"policy": "fuzzy", "static_near_cm": 1e300}, "navigator.static_near_cm:"),
    ({"policy": "dwa", "_target_": "a.B"}, "navigator._target_: give either navigator.policy"),
    ({"_target_": "no_such_module_xyz.Policy"}, "navigator._target_: cannot import 'no_such_module_xyz'"),
    ({"_target_": "fuzzynav.policies.base.NoSuchFactory"},
     "navigator._target_: 'fuzzynav.policies.base' has no callable"),
    ({"_target_": "../etc/passwd"}, "navigator._target_: expected an import path"),
    ({"_target_": "???"}, "navigator._target_: not given (navigator=custom needs navigator._target_=package.module."
                          "Factory; a sweep over every navigator leaves the template out with "
                          "navigator='glob(*,exclude=custom)')"),
    ({"policy": 3}, "navigator.policy: expected a policy name"),
    ({"policy": None}, "navigator.policy: null (give a policy name)"),
    ({"_target_": None}, "navigator._target_: null (give an import path)"),
    ({"policy": "DWA"}, "navigator.policy: expected a policy name"),
    ({"policy": "dwa", 3: 1}, "navigator"),
])
def test_a_bad_navigator_section_is_one_line_naming_the_field(navigator, message):
    with pytest.raises(ValueError) as err:
        episode_config_from_dict({"navigator": navigator})
    assert str(err.value).startswith(message), str(err.value)
    assert "\n" not in str(err.value)


_VALUES = st.one_of(st.none(), st.booleans(), st.integers(-10**9, 10**9), st.floats(allow_nan=True),
                    st.text(max_size=12), st.lists(st.integers(), max_size=3))
_KEYS = st.one_of(st.sampled_from(["policy", "_target_", "alpha_heading", "speed_cm_s", "static_near_cm",
                                   "smoothing_l", "reciprocity", "turn_samples", "margin_cm"]), st.text(max_size=8))
_POLICIES = st.sampled_from(sorted(registered_policies()))  # every one found, plug-ins included


@settings(max_examples=300, deadline=None)
@given(policy=_POLICIES, extra=st.dictionaries(_KEYS, _VALUES, max_size=4))
def test_any_navigator_section_is_read_or_refused_in_one_line(policy, extra):
    section = {"policy": policy, **extra}
    try:
        ep = episode_config_from_dict({"navigator": section})
    except ValueError as err:
        text = str(err)
        assert "\n" not in text and text.startswith(("navigator", "controller")), text
        return
    assert ep.policy in registered_policies()


class _Returns:
    """A policy that returns a fixed (possibly broken) action."""

    name = "broken"

    def __init__(self, action: object) -> None:
        self.action = action

    def reset(self, seed: int) -> None:
        pass

    def act(self, observation: Observation) -> object:
        return self.action


@pytest.mark.parametrize(("action", "message"), [
    (Action("go", math.nan, 20.0), "policy broken: dtheta_deg = nan is not a finite number"),
    (Action("go", 0.0, math.inf), "policy broken: v_cm_s = inf is not a finite number"),
    (Action("go", 0.0, -5.0), "policy broken: v_cm_s = -5 is outside [0, 1000] (0 = stand still)"),
    (Action("go", 1e308, 20.0), "policy broken: dtheta_deg = 1e+308 is outside [-1e+06, 1e+06]"),
    (Action("go", 0.0, 1e308), "policy broken: v_cm_s = 1e+308 is outside [0, 1000]"),
    (Action("go", "0", 10.0), "policy broken: dtheta_deg = '0' is not a finite number"),
    (Action("go", 0.0, 10.0, {"x": 10**400}), "policy broken: field 'x' = 1000000000000000000000000000000000000"),
    (Action("go", 0.0, 10.0, {"x": "\ud800"}), "policy broken: field 'x' = "),
    (Action("go", 0.0, 10.0, {5: 1.0}), "policy broken: field name 5 is not a (UTF-8) string"),
    (Action("go", 0.0, 10.0, [1, 2]), "policy broken: fields is list, not a mapping"),
    (Action("wait", 0.0, 0.0), "policy broken: mode 'wait' is not a mode name"),
    (Action("Go Left", 0.0, 10.0), "policy broken: mode 'Go Left' is not a mode name"),
    (Action("go", 0.0, 10.0, {"x": math.nan}), "policy broken: field 'x' = nan is not a finite number"),
    (Action("go", 0.0, 10.0, {"x": [1, 2]}), "policy broken: field 'x' = [1, 2] is not a finite number"),
    ((0.0, 10.0), "policy broken: act() returned tuple, not a fuzzynav.policies.base.Action"),
    (Action("go", True, 10.0), "policy broken: dtheta_deg = True is not a finite number"),
    (Action("go", 0.0, 10.0, {f"f{k}": 1.0 for k in range(65)}), "policy broken: more than the limit of 64 fields"),
    (Action("go", 0.0, 10.0, {"x" * 257: 1.0}), "policy broken: field 'xxxx"),
    (Action("go", 0.0, 10.0, {"x": "y" * 10**6}), "policy broken: field 'x': value of 1,000,000 characters, more than"),
])
def test_a_command_the_robot_cannot_execute_stops_the_episode_naming_the_policy(action, message):
    episode = Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0,
                      policy=_Returns(action))
    with pytest.raises(ValueError) as err:
        episode.step()
    assert str(err.value).startswith(message), str(err.value)


class _Exits(_Returns):
    """A policy whose code calls sys.exit (it ended a whole sweep with no message)."""

    def act(self, observation: Observation) -> object:
        raise SystemExit(3)


class _ResetFails(_Returns):
    def reset(self, seed: int) -> None:
        raise RuntimeError("no\nthanks")


def test_a_policy_that_exits_or_raises_fails_its_episode_not_the_process():
    episode = Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0,
                      policy=_Exits(None))
    with pytest.raises(ValueError, match=r"^policy broken: act\(\) failed: SystemExit: 3$"):
        episode.step()
    with pytest.raises(ValueError, match=r"^policy broken: reset\(seed\) failed: RuntimeError: no thanks$"):
        Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0,
                policy=_ResetFails(None))


def test_numpy_values_are_valid_fields():
    action = Action("go", np.float32(1.5), np.int64(10), {"ok": np.bool_(True), "n": np.int32(3)})
    episode = Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0,
                      policy=_Returns(action))
    assert episode.step().decision.fields["ok"]


@pytest.mark.parametrize("kind", [np.float16, np.float32, np.longdouble, np.int8, int])
def test_a_command_of_any_numeric_type_moves_the_robot_as_the_same_float64_command(kind):
    """The robot executes, and the log holds, the checked value as a Python float: a float16 command once carried
    float16 into the robot's position (overflowing in 60 steps), a longdouble one stopped the episode in shapely."""

    def run(dtheta, v, value) -> list:
        policy = _Returns(Action("go", dtheta, v, {"x": value}))
        episode = Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0, policy=policy)
        return [(r.next_state.x, r.next_state.y, r.next_state.heading, r.decision.v_cm_s, r.decision.fields["x"])
                for r in episode.run()]

    got = run(kind(3), kind(10), kind(2))
    assert got == run(3.0, 10.0, float(kind(2))) and len(got) > 30
    assert all(type(value) is float for row in got for value in row[:4])
    assert type(got[0][4]) is (int if issubclass(kind, int | np.integer) else float)


class _Flips(Action):
    """An Action whose speed answers 20 at the check's read and 1e9 at the next (it drove at 1e9 cm/s, logged as
    such, and the report counted a success)."""

    reads = 0

    @property  # type: ignore[override]
    def v_cm_s(self) -> float:
        type(self).reads += 1
        return 20.0 if type(self).reads % 2 else 1e9

    @v_cm_s.setter
    def v_cm_s(self, value: float) -> None:
        pass


class _Mode(str, enum.Enum):  # noqa: UP042 -- not StrEnum: its str() is "_Mode.GO", not the value
    GO = "go"


class _Lies(dict):
    """A mapping that says it is small."""

    def __len__(self) -> int:
        return 1


def test_the_robot_executes_the_values_checked_whatever_the_action_answers_later():
    _Flips.reads = 0
    record = Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0,
                     policy=_Returns(_Flips("go", 0.0, 20.0))).step()
    assert (record.decision.v_cm_s, record.next_state.v, _Flips.reads) == (20.0, 20.0, 1)


def test_a_str_enum_mode_is_its_value_and_a_mapping_cannot_hide_its_fields():
    record = Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0,
                     policy=_Returns(Action(_Mode.GO, 0.0, 10.0))).step()
    assert record.decision.mode == "go" and type(record.decision.mode) is str
    many = _Lies({f"f{k}": 1.0 for k in range(100)})
    with pytest.raises(ValueError, match=r"^policy broken: more than the limit of 64 fields"):
        Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=0,
                policy=_Returns(Action("go", 0.0, 10.0, many))).step()


def test_an_injected_policy_is_reset_with_the_episodes_seed():
    seen = []

    class Remembers(_Returns):
        def reset(self, seed: int) -> None:
            seen.append(seed)

    Episode(load_scenario("head_on"), load_controller("table1"), EpisodeConfig(), seed=7,
            policy=Remembers(Action("go", 0.0, 10.0)))
    assert seen == [7]


@pytest.mark.parametrize("policy", sorted(set(registered_policies()) - {DEFAULT_POLICY}))
def test_each_baseline_is_deterministic_for_a_seed_in_a_whole_episode(policy):
    cfg = episode_config_from_dict({"navigator": {"policy": policy}, "planner": {"strategy": "none"}})

    def run() -> list[tuple]:
        episode = Episode(load_scenario("mixed"), load_controller("table1"), cfg, seed=3)
        return [(r.decision.mode, r.decision.dtheta_deg, r.decision.v_cm_s, tuple(sorted(r.decision.fields.items())))
                for r in episode.run()]

    first = run()
    assert first == run() and all(d[0] != "fuzzy" for d in first)


def test_the_tpt_layer_runs_on_top_of_a_baseline():
    """``navigator=dwa planner=auto``: when the table predicts a collision a plan overrides DWA."""
    cfg = episode_config_from_dict({"navigator": {"policy": "dwa"}, "planner": {"strategy": "auto"}})
    episode = Episode(load_scenario("head_on"), load_controller("table1"), cfg, seed=0)
    records = list(episode.run())
    modes = {r.decision.mode for r in records}
    assert "dwa" in modes and modes & {"wait", "detour"}, modes
    assert {r.decision.policy for r in records} == {"dwa"}


@pytest.mark.parametrize("strategy", ["auto", "wait", "detour"])
@pytest.mark.parametrize("offset", [0.0, 5.0, 30.0])
def test_a_robot_predicted_to_stand_still_gets_a_plan_with_a_step_or_none(strategy, offset):
    """A policy may command v = 0 (DWA with no admissible velocity): the table then predicts a standing robot,
    rG is where it stands, and the detour search returned an empty path that the navigator indexed (IndexError
    on head_on with navigator=dwa planner=auto)."""
    track = Track(1, 400.0, 300.0 + offset, -30.0, 0.0, 20.0)
    tpt = build_tpt((200.0, 300.0), (600.0, 300.0), 0.0, (track,), 20.0, 9, 1.0, 10.0, True)
    assert tpt.any_collision
    plan = find_new_path(tpt, PlannerConfig(strategy=strategy), 0.0, np.zeros((0, 2)), 20.0)
    assert plan is None or len(plan.path) > 0
    if strategy != "wait":
        assert plan is not None and plan.strategy in ("evade", "stop"), plan


@pytest.fixture(scope="module")
def policy_sweep(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("policies")
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "navigator=fuzzy_tpt,dwa,apf,vfh,orca,direct",
                          "scenario=crossing_right", "episodes=2", f"hydra.sweep.dir={out}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return out


def test_a_sweep_over_policies_logs_each_policy_and_reports_them_side_by_side(policy_sweep):
    logs = sorted(policy_sweep.rglob("*.mcap"))
    assert len(logs) == 12  # sweep=policies, not the default preset's planners: one planner per policy
    from analysis.episode_log import load_episode

    seen = set()
    for path in logs:
        log = load_episode(path)
        names = {d["policy"] for d in log.decisions}
        assert len(names) == 1 and log.meta["policy"] in names
        seen |= names
    assert seen == {"fuzzy", "dwa", "apf", "vfh", "orca", "direct"}
    report = next(policy_sweep.rglob("report.md")).read_text()
    for label in ("fuzzy · auto(h=2)", "dwa · none", "apf · none", "vfh · none", "orca · none", "direct · none"):
        assert label in report, label


def test_replay_verify_reproduces_every_policy(policy_sweep):
    for path in sorted(policy_sweep.rglob("*__s0.mcap")):
        res = subprocess.run([sys.executable, "-m", "runners.replay", str(path), "--verify"], cwd=ROOT,
                             capture_output=True, text=True, timeout=300)
        assert res.returncode == 0 and "decisions reproduced" in res.stdout, (path.name, res.stdout, res.stderr)


def test_a_bad_navigator_override_is_one_line_naming_the_field(tmp_path):
    res = subprocess.run([sys.executable, "-m", "runners.run", "navigator=dwa", "navigator.alpha_heading=-1",
                          f"hydra.run.dir={tmp_path}"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert res.returncode == 2
    assert one_error_line(res.stderr) == "error: config: navigator.alpha_heading: must be in [0, 1,000,000], got -1"


USER_POLICY = ROOT / "tests" / "user_policy"  # my_policies.Straight: a policy defined outside the package


def _with_user_policy() -> dict[str, str]:
    import os

    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(USER_POLICY), os.environ.get("PYTHONPATH", "")])}


def test_a_policy_from_outside_the_repository_runs_logs_and_replays(tmp_path):
    res = subprocess.run([sys.executable, "-m", "runners.run", "navigator=custom",
                          "navigator._target_=my_policies.Straight", "+navigator.speed_cm_s=30",
                          "scenario=static_clutter", f"hydra.run.dir={tmp_path}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300, env=_with_user_policy())
    assert res.returncode == 0, res.stderr[-2000:]
    (path,) = tmp_path.glob("*.mcap")
    assert path.name.startswith("static_clutter__my_policies.Straight__none__")
    from analysis.episode_log import load_episode

    log = load_episode(path)
    assert log.meta["policy"] == "my_policies.Straight"
    assert {d["policy"] for d in log.decisions} == {"my_policies.Straight"}
    assert {round(d["v_cm_s"], 6) for d in log.decisions} == {30.0}
    res = subprocess.run([sys.executable, "-m", "runners.replay", str(path), "--verify"], cwd=ROOT,
                         capture_output=True, text=True, timeout=300, env=_with_user_policy())
    assert res.returncode == 0 and "decisions reproduced" in res.stdout, res.stdout + res.stderr


def test_a_policy_from_outside_the_repository_runs_in_a_sweep(tmp_path):
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "navigator=custom",
                          "navigator._target_=my_policies.Straight", "+navigator.speed_cm_s=20,30", "planner=none",
                          "scenario=head_on", "episodes=2", f"hydra.sweep.dir={tmp_path}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=600, env=_with_user_policy())
    assert res.returncode == 0, res.stderr[-2000:]
    assert len(list(tmp_path.rglob("*.mcap"))) == 4
    report = next(tmp_path.rglob("report.md")).read_text()
    assert "speed_cm_s=20" in report and "speed_cm_s=30" in report  # a user policy's parameter is a dimension


def test_a_policy_that_cannot_be_imported_is_one_line(tmp_path):
    res = subprocess.run([sys.executable, "-m", "runners.run", "navigator=custom",
                          "navigator._target_=my_policies.Straight", f"hydra.run.dir={tmp_path}"],
                         cwd=ROOT, capture_output=True, text=True, timeout=300)  # not on PYTHONPATH
    assert res.returncode == 2
    assert one_error_line(res.stderr).startswith("error: config: navigator._target_: cannot import 'my_policies'")


def test_a_user_policys_source_is_part_of_its_episodes_identity(tmp_path, monkeypatch):
    """A resumed sweep kept the logs of a user's policy whose code had changed (its result, not the new code's)."""
    from fuzzynav.episode_identity import episode_key, episode_key_of
    from fuzzynav.policies.base import policy_source_digest

    module = tmp_path / "changing_policy.py"
    module.write_text((USER_POLICY / "my_policies.py").read_text())
    monkeypatch.syspath_prepend(str(tmp_path))
    first = policy_source_digest("changing_policy.Straight")
    assert len(first) == 64 and policy_source_digest("dwa") == ""
    module.write_text(module.read_text() + "\n# changed\n")
    assert policy_source_digest("changing_policy.Straight") not in ("", first)
    assert episode_key("c", 1, "v") == episode_key("c", 1, "v", "")  # fuzzynav's own policies: keys as before
    assert episode_key("c", 1, "v", first) != episode_key("c", 1, "v")
    meta = {"config": "c", "seed": "1", "fuzzynav_version": "v", "policy_source_sha256": first}
    assert episode_key_of(meta) == episode_key("c", "1", "v", first)


def test_an_empty_report_directory_is_refused(tmp_path):
    """``--out ''`` wrote ./report in the current directory."""
    res = subprocess.run([sys.executable, "-m", "analysis.report", str(tmp_path), "--out", ""], cwd=ROOT,
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 2 and "--out: an empty path" in one_error_line(res.stderr)
    assert not (ROOT / "report").exists()
