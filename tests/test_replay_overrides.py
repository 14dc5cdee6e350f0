"""``runners.replay`` refuses what it cannot honour (issue 14, hostile inputs): ``--verify`` with a changed
config, the same override key twice, and overrides of keys the replayed navigator is not built from (an
open-loop replay feeds the recorded inputs, so the scenario, the seed, perception and the other sensors
cannot change a decision). Each refusal is one ``error:`` line, exit 2, before anything is replayed."""

from __future__ import annotations

import copy
import inspect
import os
from pathlib import Path
from typing import Any

import pytest

from analysis.episode_log import load_episode
from fuzzynav.planning.layer import build_planning_layer
from runners import replay
from tests.conftest import one_error_line
from tests.valid_logs import recorded_logs  # noqa: F401 - the session fixture

VERIFY_REFUSAL = ("error: --verify: re-decides with the recorded config; it cannot be combined with "
                  "--controller/overrides")


@pytest.fixture
def good(recorded_logs) -> Path:  # noqa: F811 - the fixture imported above
    """A complete paper_fig5 log whose plans a changed planner decides differently."""
    return recorded_logs[0]


def run_replay(capsys, tmp_path: Path, log: Path, *args: str) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of ``runners.replay LOG --quiet ARGS``, with ``--out TMP/x`` for a replay that
    draws its picture (not --verify, --controller or overrides)."""
    draws = not any(a in ("--verify", "--controller") or "=" in a for a in args)
    try:
        code = replay.main([str(log), "--quiet", *(["--out", str(tmp_path / "x")] if draws else []), *args])
    except SystemExit as stop:
        code = int(stop.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("args", [
    ["--controller", "listing", "--verify"],
    ["--verify", "planner.strategy=none"],
    ["--verify", "planner.h_wait=4", "--controller", "listing"],
])
def test_verify_with_a_changed_config_is_refused(args, capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, *args)
    assert code == 2 and out == ""
    assert one_error_line(err).startswith(VERIFY_REFUSAL)
    assert not list(tmp_path.iterdir())


def test_the_same_change_without_verify_lists_the_differences(capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, "planner.strategy=none")
    assert code == 0 and err == ""
    assert "decisions differ" in out and "0 decisions differ" not in out


@pytest.mark.parametrize("args, expect", [
    (["planner.h_wait=1", "planner.h_wait=3"], "override planner.h_wait: given twice (one value per key)"),
    (["planner={h_wait: 1}", "planner.h_wait=3"], "override planner.h_wait: overlaps override planner"),
    (["planner.h_wait=3", "planner={h_wait: 1}"], "override planner: overlaps override planner.h_wait"),
    (["controller.fallback.v=5", "controller.fallback.v=6"], "override controller.fallback.v: given twice"),
])
def test_a_key_given_twice_is_refused_naming_it(args, expect, capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, *args)
    assert code == 2 and out == ""
    assert one_error_line(err).startswith(f"error: {expect}")


def test_a_second_controller_is_refused(capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, "--controller", "listing", "--controller", "table1")
    assert code == 2 and out == ""
    assert one_error_line(err) == "error: --controller: given 2 times (one controller per replay)"


@pytest.mark.parametrize("override", ["scenario=u_trap", "seed=5", "scenario.max_steps=3", "sensors.laser.beams=90",
                                      "sensors.sonar.range_cm=100", "sensors={}", "perception.mode=ground_truth",
                                      "terminate_on_collision=false", "episodes=3"])
def test_an_override_the_navigator_does_not_read_is_refused(override, capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, override)
    key = override.partition("=")[0]
    assert code == 2 and out == ""
    line = one_error_line(err)
    assert line == (f"error: override {key}: has no effect on an open-loop replay (the recorded inputs are "
                    "replayed; only controller, planner, navigator, robot, dt can change a decision); run the episode "
                    "again with runners.run"), line


@pytest.mark.parametrize("override", ["sensors.sonar.front=[-20, 20]", "sensors.sonar.front=[-30, 30]"])
def test_the_front_sonar_sector_of_the_recorded_readings_cannot_change(override, capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, override)
    assert code == 2 and out == ""
    assert one_error_line(err) == ("error: override sensors.sonar.front: the sonar sector the recorded front readings "
                                   "were taken over: it cannot change in an open-loop replay; run the episode again "
                                   "with runners.run")


@pytest.mark.parametrize("overrides", [["planner.h_wait=4"], ["navigator.static_near_cm=80"], ["dt=0.5"],
                                       ["robot.max_turn_deg=90"], ["controller.fallback.v=12"],
                                       ["planner.h_wait=4", "dt=0.5"]])
def test_an_override_the_navigator_reads_is_replayed(overrides, capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, *overrides)
    assert code == 0 and err == "", err
    assert out.startswith("counterfactual replay of 14 recorded steps: ")


def test_the_navigator_sources_name_every_argument_of_the_navigator():
    params = set(inspect.signature(build_planning_layer).parameters)
    assert set(replay.NAVIGATOR_SOURCES) | {"robot_radius"} == params


def _arguments(monkeypatch, config: dict[str, Any]) -> dict[str, Any]:
    """The keyword arguments :func:`replay.navigator_for` gives the navigator for ``config`` (the evaluator as its
    controller spec, which compares by value)."""
    seen: dict[str, Any] = {}

    def capture(**kwargs: Any) -> None:
        seen.update(kwargs, controller=kwargs["controller"].spec)

    monkeypatch.setattr(replay, "build_planning_layer", capture)
    replay.navigator_for(config, 20.0)
    return seen


def _set(config: dict[str, Any], dotted: str, value: Any) -> dict[str, Any]:
    changed = copy.deepcopy(config)
    *parents, last = dotted.split(".")
    node = changed
    for key in parents:
        node = node[key]
    node[last] = value
    return changed


def test_each_source_reaches_its_argument_and_nothing_else_does(monkeypatch, good):
    config = load_episode(good, ("/scene",)).config
    recorded = _arguments(monkeypatch, config)
    sectors = {"left": [20.0, 60.0], "front": [-20.0, 20.0], "right": [-60.0, -20.0]}  # equally wide, adjacent
    changes = {"controller": ("controller.fallback.v", 12.0), "planner": ("planner.h_wait", 4),
               "params": ("navigator.static_near_cm", 80.0), "limits": ("robot.max_turn_deg", 90.0),
               "dt": ("dt", 0.5), "front_sector_deg": ("sensors.sonar", {**config["sensors"]["sonar"], **sectors}),
               "policy": ("navigator", {"policy": "direct"})}
    assert set(changes) == set(replay.NAVIGATOR_SOURCES)
    for argument, (key, value) in changes.items():
        source = replay.NAVIGATOR_SOURCES[argument]
        assert key.startswith(source) or source.startswith(key)  # inside the source, or holding it
        now = _arguments(monkeypatch, _set(config, key, value))
        changed = [name for name in recorded if now[name] != recorded[name]]
        # another policy has other parameters: the two arguments from the navigator section change together
        assert changed == (["policy", "params"] if argument == "policy" else [argument]), key
    # the keys a replay refuses leave every argument as it was
    for key, value in (("seed", 5), ("scenario.max_steps", 3), ("sensors.laser.beams", 90),
                       ("sensors.sonar.range_cm", 100.0), ("perception.mode", "ground_truth"),
                       ("terminate_on_collision", False)):
        assert _arguments(monkeypatch, _set(config, key, value)) == recorded, key


def test_a_bad_controller_file_is_named_not_the_log(capsys, tmp_path, good):
    """A rule on an unknown term in ``--controller c.yaml`` was reported against the log it was replayed on."""
    text = (Path(replay.CONF) / "controller" / "table1.yaml").read_text()
    bad = tmp_path / "c.yaml"
    bad.write_text(text.replace("-> dtheta=NB, v=slow\"   # Table 1 row 1", "-> dtheta=HUGE, v=slow\"", 1))
    assert bad.read_text() != text
    code, out, err = run_replay(capsys, tmp_path, good, "--controller", str(bad))
    assert code == 2 and out == ""
    line = one_error_line(err)
    assert line.startswith(f"error: {bad}: rules[0]: ") and "HUGE" in line and str(good) not in line


@pytest.mark.parametrize("kind", ["dir", "devnull", "fifo", "no_parent", "parent_is_file"])
def test_an_out_stem_that_cannot_be_a_file_stem_is_refused(kind, capsys, tmp_path, good):
    """``--out DIR`` wrote ``DIR.png`` beside the directory and ``--out /dev/null`` wrote ``/dev/null.png``."""
    work = tmp_path / "work"
    work.mkdir()
    stem = {"dir": work, "devnull": Path("/dev/null"), "fifo": work / "f", "no_parent": work / "no" / "x",
            "parent_is_file": work / "file" / "x"}[kind]
    if kind == "fifo":
        os.mkfifo(stem)
    if kind == "parent_is_file":
        (work / "file").write_text("")
    before = sorted(p.name for p in work.iterdir())
    code = replay.main([str(good), "--quiet", "--out", str(stem)])
    out = capsys.readouterr()
    assert code == 2 and out.out == ""
    assert one_error_line(out.err).startswith(f"error: --out: {stem}: ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["work"]
    assert sorted(p.name for p in work.iterdir()) == before


def test_an_out_stem_naming_a_folder_is_refused(capsys, tmp_path, good):
    """``--out outdir/`` (a folder that does not exist yet) wrote ``outdir.png`` beside it."""
    code = replay.main([str(good), "--quiet", "--out", f"{tmp_path / 'outdir'}/"])
    out = capsys.readouterr()
    assert code == 2 and one_error_line(out.err).startswith(f"error: --out: {tmp_path / 'outdir'}/: names a folder")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("args", [["--verify"], ["planner.h_wait=3"]])
def test_out_with_a_replay_that_draws_nothing_is_refused(args, capsys, tmp_path, good):
    """``--out`` was ignored without a word by ``--verify`` and by counterfactual replays, which draw no picture."""
    code = replay.main([str(good), "--quiet", "--out", str(tmp_path / "x"), *args])
    out = capsys.readouterr()
    assert code == 2 and one_error_line(out.err).startswith("error: --out: --verify, --controller and overrides")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("override, expect", [
    ("planner=", "override planner: a section of the recorded config; give its keys one by one"),
    ("planner={}", "override planner: a section of the recorded config"),
    ("navigator={}", "override navigator: a section of the recorded config"),
    ("planner.h_wait=1,3", "override planner.h_wait: one value per key"),
    ("+planner.h_wait=3", "override +planner.h_wait: a replay changes recorded values only"),
    ("~planner.h_wait=3", "a replay changes recorded values only"),
    ("planner.h_wait=010", "planner.h_wait: expected an integer, got '010'"),  # not YAML 1.1's octal 8
    ("planner.h_wait=1:0", "planner.h_wait: expected an integer, got '1:0'"),  # not YAML 1.1's base 60
])
def test_an_override_is_read_as_runners_run_reads_it_or_refused(override, expect, capsys, tmp_path, good):
    """``planner=`` replaced the recorded planner by the defaults and compared with a strategy nobody asked for;
    values were read by YAML 1.1 (``010`` was 8, ``1:0`` was 60, ``1e-3`` text), not by Hydra's grammar."""
    code, out, err = run_replay(capsys, tmp_path, good, override)
    assert code == 2 and out == "", (out, err)
    line = one_error_line(err)
    assert line.startswith("error: ") and expect in line, line


def test_a_number_hydra_reads_is_a_number_in_a_replay(capsys, tmp_path, good):
    code, out, err = run_replay(capsys, tmp_path, good, "navigator.static_near_cm=8e1")
    assert code == 0 and err == "" and "decisions differ" in out
    assert replay.parse_override("dt=1e-3") == ("dt", 0.001)


def test_a_difference_is_printed_as_a_plain_number():
    """A replayed value from numpy printed as ``now np.float64(-19.7065)``."""
    from types import SimpleNamespace

    import numpy as np

    recorded = {"mode": "direct", "dtheta_deg": 0.0, "v_cm_s": 40.0, "new_plan": False, "policy_fields": {"g": 1.0}}
    d = SimpleNamespace(mode="direct", dtheta_deg=np.float64(-19.70651), v_cm_s=np.float64(40.0), new_plan=False,
                        fields={"g": 1.0}, plan=None)
    found = replay._compare(3, recorded, d)
    assert found is not None and repr(found.replayed) == "-19.7065"
    d = SimpleNamespace(mode="direct", dtheta_deg=0.0, v_cm_s=40.0, new_plan=False, fields={"g": np.float64(2.5)},
                        plan=None)
    found = replay._compare(3, recorded, d)
    assert found is not None and repr(found.replayed) == "2.5"


def test_a_log_whose_name_starts_with_a_dash_is_read_after_double_dash(capsys, tmp_path, good, monkeypatch):
    """``runners.replay -- -x.mcap``: argparse's intermixed parsing dropped ``--`` and said the log was missing."""
    (tmp_path / "-x.mcap").write_bytes(good.read_bytes())
    monkeypatch.chdir(tmp_path)
    assert replay.main(["--quiet", "--out", str(tmp_path / "x"), "--", "-x.mcap"]) == 0
    assert (tmp_path / "x.png").is_file()
    assert replay.main(["--verify", "--", "-x.mcap"]) == 0
    assert "all" in capsys.readouterr().out
    assert replay.main(["--", "-missing.mcap"]) == 2
    assert capsys.readouterr().err.strip() == "error: -missing.mcap: no such file"
