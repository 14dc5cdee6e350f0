"""Hydra runs and sweeps: config groups, user scenarios via hydra.searchpath, errors, the sweep command."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pandas as pd
import yaml

from analysis.log_inputs import find_logs
from analysis.logs import episode_summary
from runners.sweeping.size import count_episodes
from tests.conftest import CONF, ROOT


def cli(*args, timeout=600, env=None):
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout, env=None if env is None else {**os.environ, **env})


def test_user_scenario_through_searchpath(tmp_path):
    user = tmp_path / "my_conf"
    (user / "scenario").mkdir(parents=True)
    data = yaml.safe_load((CONF / "scenario" / "head_on.yaml").read_text())
    data.update(name="my_corridor", max_steps=50)
    (user / "scenario" / "my_corridor.yaml").write_text(yaml.safe_dump(data))
    out = cli("runners.run", f"hydra.searchpath=[file://{user}]", "scenario=my_corridor",
              f"hydra.run.dir={tmp_path / 'run'}")
    assert out.returncode == 0, out.stderr
    assert "my_corridor policy=fuzzy strategy=auto" in out.stdout
    assert episode_summary(find_logs([tmp_path / "run"])[0])["scenario"] == "my_corridor"


def test_bad_scenario_file_names_file_and_field(tmp_path):
    user = tmp_path / "my_conf"
    (user / "scenario").mkdir(parents=True)
    data = yaml.safe_load((CONF / "scenario" / "head_on.yaml").read_text())
    data["robot"]["start"] = [5000, 300]
    (user / "scenario" / "broken.yaml").write_text(yaml.safe_dump(data))
    out = cli("runners.run", f"hydra.searchpath=[file://{user}]", "scenario=broken", f"hydra.run.dir={tmp_path / 'r'}")
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "broken.yaml: robot.start: [5000.0, 300.0] is outside bounds" in lines[0]
    assert not list((tmp_path / "r").glob("*.mcap"))


def test_typo_and_wrong_type_fail_at_composition(tmp_path):
    out = cli("runners.run", "planner.h_wiat=3", f"hydra.run.dir={tmp_path}")
    assert out.returncode == 2 and out.stderr.strip() == (
        "error: config: planner.h_wiat: Key 'h_wiat' not in 'PlannerConfigSchema'")
    out = cli("runners.run", "planner.h_wait=two", f"hydra.run.dir={tmp_path}")
    assert out.returncode == 2 and "planner.h_wait" in out.stderr and "Traceback" not in out.stderr
    out = cli("runners.run", "planner.h_wait=-1", f"hydra.run.dir={tmp_path}")
    assert out.returncode == 2 and out.stderr.strip() == ("error: config: planner.h_wait: must be in [0, 1,000] steps, "
                                                          "got -1")
    out = cli("runners.sweep", "sweep=quick", "planner=auto,nope", f"hydra.sweep.dir={tmp_path / 's'}")
    assert out.returncode == 2 and "no config 'planner/nope'" in out.stderr and not (tmp_path / "s").exists()


def test_quick_sweep_end_to_end(tmp_path):
    # stderr is a pipe here, as under `| tee`, nohup or Slurm: plain progress lines instead of a bar
    out = cli("runners.sweep", "sweep=quick", f"hydra.sweep.dir={tmp_path}", "hydra.launcher.n_jobs=2",
              env={"FUZZYNAV_PROGRESS_EVERY_S": "0.05"})
    assert out.returncode == 0, out.stderr[-2000:]
    progress = [line for line in out.stderr.splitlines() if line.startswith("sweep: ")]
    assert progress and all(re.fullmatch(r"sweep: \d+/12 episodes \(\d+%\), ([\d.]+ episodes/s, "
                                         r"(about .+ left|done in .+)|started .+ ago)", line)
                            for line in progress), progress
    assert progress[-1].startswith("sweep: 12/12 episodes (100%)") and "\r" not in out.stderr
    logs = find_logs([tmp_path])
    assert len(logs) == 12
    assert all((log.parent / ".hydra" / "config.yaml").exists() for log in logs)
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert len(summary) == 12 and set(summary["strategy"]) == {"auto", "wait", "none"}
    assert (summary.loc[summary.strategy == "none", "outcome"] == "collision").all()
    assert (summary.loc[summary.strategy == "auto", "outcome"] == "goal").all()
    assert "success_rate" in out.stdout and "12 episode logs" in out.stdout


def test_count_episodes_of_the_default_sweep():
    from hydra import compose, initialize_config_dir

    from runners.configuration import schema

    schema.register()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("config", overrides=["sweep=default"], return_hydra_config=True)
        assert count_episodes(cfg) == 3 * 7 * 5


def test_sweeper_composes_every_swept_value_once():
    from hydra_plugins.fuzzynav_sweeper import representative_jobs

    grid = [[f"scenario={s}", f"planner=auto_h{p}", "episodes=5"] for s in ("a", "b", "c") for p in range(7)]
    picked = representative_jobs(grid)
    assert len(picked) == 9  # 7 planners with the first scenario, then the 2 other scenarios
    assert {j[0] for j in picked} == {"scenario=a", "scenario=b", "scenario=c"}
    assert {j[1] for j in picked} == {f"planner=auto_h{k}" for k in range(7)}
    seeds = [[f"seed={s}", "episodes=50"] for s in range(0, 1000, 50)]
    assert representative_jobs(seeds) == seeds[:1]  # numbers of one type compose alike
    mixed = [["x=1"], ["x=2"], ["x=1.5"], ["x=true"], ["x=null"], ["x=abc"], ["x=abd"], ["x=${seed}"]]
    assert representative_jobs(mixed) == [["x=1"], ["x=1.5"], ["x=true"], ["x=null"], ["x=abc"], ["x=abd"],
                                          ["x=${seed}"]]


def test_sweeper_reports_a_bad_preset_value_before_any_job(tmp_path):
    presets = tmp_path / "conf" / "sweep"
    presets.mkdir(parents=True)
    (presets / "bad_value.yaml").write_text(
        "# @package _global_\nepisodes: 1\nhydra:\n  sweeper:\n    params:\n"
        "      scenario: head_on,no_such_scenario\n      seed: range(0,6)\n")
    out = cli("runners.sweep", f"hydra.searchpath=[file://{tmp_path / 'conf'}]", "sweep=bad_value",
              f"hydra.sweep.dir={tmp_path / 's'}")
    lines = [ln for ln in out.stderr.splitlines() if ln.strip()]
    assert out.returncode == 2 and len(lines) == 1, out.stderr[-2000:]  # one line (Hydra's error was a dozen)
    assert lines[0].startswith("error: config: no config 'scenario/no_such_scenario' (available: corridor, ")
    assert lines[0].endswith("(the sweep's job scenario=no_such_scenario seed=0 sweep=bad_value)")
    assert not find_logs([tmp_path / "s"])  # validated before launching: nothing ran


def test_hydra_basic_sweeper_still_selectable(tmp_path):
    out = cli("runners.sweep", "sweep=quick", "scenario=head_on", "planner=auto,none", "hydra/sweeper=basic",
              f"hydra.sweep.dir={tmp_path}")
    assert out.returncode == 0, out.stderr[-2000:]
    assert len(find_logs([tmp_path])) == 4
    # Hydra's sweeper with fuzzynav's fault handling (runners.sweep.fault_tolerant_sweeper)
    assert "hydra_plugins.fuzzynav_sweeper.FaultTolerantSweeper" in (tmp_path / "multirun.yaml").read_text()


def test_parallel_summary_equals_the_serial_one(tmp_path, monkeypatch):
    import analysis.logs
    from runners.sweeping.summary import summarise
    from tests.handmade import write_log

    poses = [(100.0 * k, 0.0, 0.0) for k in range(8)]
    for k in range(5):
        write_log(tmp_path / f"good{k}.mcap", poses[: 3 + k], outcome="goal" if k % 2 else "timeout")
    write_log(tmp_path / "cut.mcap", poses, truncate=True)
    (tmp_path / "junk.mcap").write_bytes(b"\x00not an mcap" * 10)
    serial_episodes, serial_table = summarise(tmp_path)
    monkeypatch.setattr(analysis.logs, "PARALLEL_MIN_LOGS", 1)  # 7 logs in 4 chunks over 2 workers
    episodes, table = summarise(tmp_path, jobs=2)
    assert len(episodes) == 7 and (episodes["outcome"] == "unreadable").sum() == 1
    assert episodes.equals(serial_episodes) and table.equals(serial_table)


def test_many_one_episode_jobs_get_a_batching_tip():
    from runners.sweep import short_jobs_tip

    assert short_jobs_tip(105, 5) is None  # the default sweep: 21 jobs of 5 episodes
    assert short_jobs_tip(20, 1) is None and short_jobs_tip(None, 1) is None
    assert short_jobs_tip(1000, 250) is None and short_jobs_tip(5000, 10) is None
    tip = short_jobs_tip(1000, 1)
    assert tip is not None and "1000 jobs of 1 episode(s)" in tip and "episodes=" in tip
    assert "60 jobs of 2 episode(s)" in (short_jobs_tip(120, 2) or "")
