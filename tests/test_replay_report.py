"""Replay (timeline, PNG/GIF, --verify, counterfactual) and the report built from a real small sweep."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pandas as pd
import pytest

from analysis.report import build_report
from fuzzynav.fuzzy_fast import FastEvaluator
from runners import replay
from runners.run import run_episode
from tests.conftest import ROOT, load_controller, load_scenario
from tests.handmade import rewrite_log


@pytest.fixture(scope="module")
def fresh_log(tmp_path_factory):
    """A real log with a recorded config (as runners.run writes it), from a Hydra composition."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from runners import schema
    from tests.conftest import CONF

    schema.register()
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("config", overrides=["scenario=head_on", "seed=2"])
    plain = OmegaConf.to_container(cfg, resolve=True)
    from runners.run import episode_config

    path = tmp_path_factory.mktemp("replay") / "head_on.mcap"
    run_episode(load_scenario("head_on"), FastEvaluator(load_controller("table1")), episode_config(plain), 2, path,
                OmegaConf.to_yaml(cfg, resolve=True))
    return path


def test_verify_passes_on_a_fresh_log(fresh_log, capsys):
    assert replay.main([str(fresh_log), "--verify"]) == 0
    assert "decisions reproduced" in capsys.readouterr().out


def _alter(src, dst, step: int):
    """Copy a log, changing the recorded mode of one decision."""

    def change(topic, msg):
        if topic == "/planner/decision" and msg["step"] == step:
            msg["mode"] = "fuzzy" if msg["mode"] != "fuzzy" else "direct"

    rewrite_log(src, dst, change)


def test_verify_fails_on_an_altered_decision(fresh_log, tmp_path, capsys):
    altered = tmp_path / "altered.mcap"
    _alter(fresh_log, altered, step=7)
    assert replay.main([str(altered), "--verify"]) == 1
    assert "differs at step 7: mode" in capsys.readouterr().out


def test_timeline_png_and_gif(fresh_log, tmp_path, capsys):
    stem = tmp_path / "ep"
    assert replay.main([str(fresh_log), "--animate", "--out", str(stem), "--steps", "3,10"]) == 0
    out = capsys.readouterr().out
    assert "plan detour" in out or "plan wait" in out or "plan evade" in out
    assert "outcome: goal" in out
    assert stem.with_suffix(".png").stat().st_size > 10_000
    assert stem.with_suffix(".gif").read_bytes()[:6] in (b"GIF89a", b"GIF87a")


def test_counterfactual_replay_lists_divergences(fresh_log, capsys):
    assert replay.main([str(fresh_log), "--controller", "listing", "planner.strategy=none"]) == 0
    out = capsys.readouterr().out
    assert "counterfactual replay" in out and "decisions differ" in out and "step" in out
    assert replay.main([str(fresh_log), "planner.h_wiat=3"]) == 2


def test_replay_rejects_non_logs(tmp_path, capsys):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"garbage")
    assert replay.main([str(junk)]) == 2
    assert "junk.mcap: not an MCAP file" in capsys.readouterr().err


@pytest.fixture(scope="module")
def small_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep")
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "sweep=quick", f"hydra.sweep.dir={out}",
                          "hydra.launcher.n_jobs=2"], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    return out, res.stdout


def test_sweep_writes_the_report(small_sweep):
    out, stdout = small_sweep
    rep = out / "report"
    md = (rep / "report.md").read_text()
    for section in ("What the data says", "Outcomes per scenario", "Paired comparisons", "Collision cross-check",
                    "Metrics against h_wait", "Trajectories", "Logs left out"):
        assert f"## {section}" in md, section
    assert "success rate [95% Wilson]" in md and "auto(h=2)" in md
    assert (rep / "trajectories_head_on.png").exists() and (rep / "h_wait_time_to_goal_s.png").exists()
    assert "report:" in stdout


def test_report_lists_bad_logs_and_still_renders(small_sweep, tmp_path):
    out, _ = small_sweep
    logs = sorted(out.rglob("*.mcap"))
    (tmp_path / "broken.mcap").write_bytes(b"\x89MCAP0\r\nnonsense")
    shutil.copy(logs[0], tmp_path / "good.mcap")
    data = logs[1].read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    report = build_report([tmp_path], tmp_path / "rep")
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "broken.mcap" in md and "cut.mcap" in md and "1 episodes analysed, 2 left out" in md
    assert report.blocks


def test_report_skips_h_wait_figures_without_variants(fresh_log, tmp_path):
    """One strategy variant per scenario: nothing to compare against h_wait, so no such figures."""
    shutil.copy(fresh_log, tmp_path / "only.mcap")
    build_report([tmp_path / "only.mcap"], tmp_path / "rep")
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "## Metrics against h_wait" in md and "Not drawn: every scenario was run with a single" in md
    assert not list((tmp_path / "rep").glob("h_wait_*.png"))
    assert (tmp_path / "rep" / "trajectories_head_on.png").exists()


def test_report_html_renders_in_headless_chromium(small_sweep):
    browser = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if browser is None:
        pytest.skip("no Chromium on this machine (.ci/run installs Debian's chromium)")
    page = small_sweep[0] / "report" / "report.html"
    res = subprocess.run([browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                          "--disable-component-update", "--disable-sync", "--no-first-run",
                          "--allow-file-access-from-files", "--virtual-time-budget=5000", "--dump-dom",
                          page.as_uri()], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "<title>report: ok</title>" in res.stdout, res.stdout[:500]


def test_the_same_episodes_batched_differently_in_two_sweeps_are_counted_once(tmp_path):
    """Sweep A runs seeds 0-1 in one job (``seed=0 episodes=2``), sweep B the same two episodes in two jobs
    (``seed=0,1 episodes=1``): their logs' config and ``config_hash`` differ (the batching is in the config), the
    episodes do not. ``analysis.report A B`` counts two episodes, lists B's two logs as duplicates and says so."""
    common = ["-m", "runners.sweep", "sweep=quick", "scenario=head_on", "planner=auto", "hydra.launcher.n_jobs=2"]
    dirs = {"a": (tmp_path / "a", ["seed=0", "episodes=2"]), "b": (tmp_path / "b", ["seed=0,1", "episodes=1"])}
    for sweep_dir, batching in dirs.values():
        done = subprocess.run([sys.executable, *common, *batching, f"hydra.sweep.dir={sweep_dir}"], cwd=ROOT,
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr[-2000:]
    out = tmp_path / "report"
    done = subprocess.run([sys.executable, "-m", "analysis.report", str(dirs["a"][0]), str(dirs["b"][0]), "--out",
                           str(out)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert "2 log(s) left out (2 duplicate)" in done.stdout, done.stdout
    episodes = pd.read_csv(out / "episodes.csv")
    assert sorted(episodes["seed"]) == [0, 1] and all(str(dirs["a"][0]) in log for log in episodes["log"])
    assert "2 episodes analysed, 2 left out (2 duplicate)" in (out / "report.md").read_text()


# -- issue 14 ----------------------------------------------------------------------------------------------------
def report_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "analysis.report", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)


def test_a_report_on_no_logs_is_an_error(tmp_path):
    """An empty directory gave an empty report, exit 0."""
    (tmp_path / "empty").mkdir()
    res = report_cli(str(tmp_path / "empty"), "--out", str(tmp_path / "out"))
    assert res.returncode == 2 and res.stderr == f"error: no logs found in {tmp_path / 'empty'}\n", res.stderr
    assert not (tmp_path / "out").exists()
    res = report_cli(str(tmp_path / "empty"))  # the default --out (empty/report) is not left behind either
    assert res.returncode == 2 and list((tmp_path / "empty").iterdir()) == []


def test_a_symlink_loop_is_named_as_such(tmp_path):
    (tmp_path / "x.mcap").symlink_to(tmp_path / "x.mcap")
    (tmp_path / "d.mcap").symlink_to(tmp_path / "nowhere.mcap")
    for name, problem in (("x.mcap", "symlink loop"), ("d.mcap", "dangling symlink"),
                          ("n.mcap", "no such file or directory")):
        res = report_cli(str(tmp_path / name), "--out", str(tmp_path / "out"))
        assert res.returncode == 2 and res.stderr.startswith(f"error: {tmp_path / name}: {problem}"), res.stderr
        assert len(res.stderr.splitlines()) == 1


def test_a_failed_report_leaves_nothing_behind(fresh_log, tmp_path, monkeypatch, capsys):
    """A report that fails (a full disk) after its plots were drawn left the PNGs in --out."""
    import errno

    from analysis import report

    def disk_full(rep, out, *args):
        raise OSError(errno.ENOSPC, "No space left on device", str(out / "report.md"))

    out = tmp_path / "rep"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    monkeypatch.setattr(report, "_write", disk_full)
    assert report.main([str(fresh_log), "--out", str(out), "--jobs", "1"]) == 1
    assert f"error: {out / 'report.md'}: cannot write the report: No space left on device (nothing written)" in \
        capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    monkeypatch.undo()
    assert report.main([str(fresh_log), "--out", str(out), "--jobs", "1"]) == 0
    assert {"notes.txt", "report.md", "report.html", "episodes.csv"} <= {p.name for p in out.iterdir()}
    assert list(out.glob("*.png")) and not list(out.glob(".report.partial*"))
