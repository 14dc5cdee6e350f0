"""Replay (timeline, PNG/GIF, --verify, counterfactual) and the report built from a real small sweep."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pandas as pd
import pytest

from analysis.report import build_report
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from runners import replay
from runners.run import run_episode
from tests.conftest import ROOT, load_controller, load_scenario
from tests.handmade import rewrite_log


@pytest.fixture(scope="module")
def fresh_log(tmp_path_factory):
    """A real log with a recorded config (as runners.run writes it), from a Hydra composition."""
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from runners.configuration import schema
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
    sections = ["What the data says", "Effect of h_wait", "Trajectories", "Failures", "Paired comparisons",
                "Outcomes per scenario", "Distributions per variant", "Run parameters", "Collision cross-check",
                "Logs left out"]
    at = [md.index(f"## {section}") for section in sections]
    assert at == sorted(at), "the report's sections are in the reader's order"
    assert md.index("![overview](overview.png)") < at[0], "the overview figure comes first"
    assert "success rate [95% Wilson]" in md and "auto(h=2)" in md
    for name in ("overview.png", "h_wait_effect.png", "trajectories_head_on.png", "trajectories_crossing_right.png",
                 "box_metrics.png", "failures.csv", "left_out.csv", "paired.csv"):
        assert (rep / name).exists(), name
    assert "report:" in stdout


def test_the_failures_gallery_pictures_every_failure_of_a_small_sweep(small_sweep):
    """Every failed episode of the quick sweep (8 episodes or fewer per group: all pictured) has its panel in the
    gallery's one figure, its log and its first contact step in the report and in failures.csv; a paired difference
    is shown only if its interval excludes zero."""
    out, _ = small_sweep
    rep = out / "report"
    episodes = pd.read_csv(rep / "episodes.csv")
    failures = pd.read_csv(rep / "failures.csv")
    assert sorted(failures["log"]) == sorted(episodes.loc[~episodes["success"], "log"])
    assert len(failures) > 0 and failures["log_read"].all()
    md = (rep / "report.md").read_text()
    assert set(failures["picture"]) == {"failures.png"} and "![failures](failures.png)" in md
    assert not list(rep.glob("failure_*.png"))  # one figure, not a file per failure
    for _, failure in failures.iterrows():
        assert (rep / failure["picture"]).exists()
        assert failure["log"] in md
        if failure["outcome"] == "collision":
            assert failure["first_contact_step"] >= 0
    paired = pd.read_csv(rep / "paired.csv")
    section = md[md.index("## Paired comparisons"):md.index("## Outcomes per scenario")]
    assert f"{int(paired['excludes_zero'].sum())} of {len(paired)} comparisons" in section
    shown = [line for line in section.splitlines() if line.startswith("| ") and "scenario" not in line]
    assert len(shown) == int(paired["excludes_zero"].sum())


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
    assert "## Effect of h_wait" in md and "Not drawn: every scenario was run with a single" in md
    assert not list((tmp_path / "rep").glob("h_wait_*.png"))
    assert (tmp_path / "rep" / "trajectories_head_on.png").exists()


def _chromium() -> str:
    browser = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    if browser is None:
        pytest.skip("no Chromium on this machine (.ci/run installs Debian's chromium)")
    return browser


CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars",
                  "--allow-file-access-from-files", "--window-size=1280,900", "--virtual-time-budget=5000"]
# records where the report's images are once the page has loaded, in the DOM --dump-dom prints
LAYOUT_PROBE = ("<script>window.addEventListener('load',function(){var r=[].slice.call(document.images).map("
                "function(i){var b=i.getBoundingClientRect();return {src:i.getAttribute('src'),top:b.top,"
                "bottom:b.bottom,left:b.left,right:b.right,loaded:i.complete&&i.naturalWidth>0}});"
                "var p=document.createElement('pre');p.id='layout';p.textContent=JSON.stringify({images:r,"
                "width:window.innerWidth,height:window.innerHeight});document.body.appendChild(p);});</script>")


def first_screen_problems(page, browser: str, tmp_path) -> list[str]:
    """What keeps the report's first screen (1280 x 900) from showing the overview figure: the figure is not the
    page's first image, not loaded, not inside the first screen, or its colours are missing from a screenshot of
    the first screen. Empty when it shows."""
    import json
    import re

    import numpy as np
    from PIL import Image

    from analysis.palette import OKABE_ITO

    probe = page.with_name("layout_probe.html")  # beside the report, so that its images load
    probe.write_text(page.read_text().replace("</body>", LAYOUT_PROBE + "</body>"))
    try:
        dom = subprocess.run([browser, *CHROMIUM_FLAGS, "--dump-dom", probe.as_uri()], capture_output=True, text=True,
                             timeout=120)
    finally:
        probe.unlink()
    assert dom.returncode == 0, dom.stderr[-2000:]
    assert "<title>report: ok</title>" in dom.stdout, dom.stdout[:500]  # every image loaded
    found = re.search(r'<pre id="layout">(.*?)</pre>', dom.stdout, re.S)
    assert found, dom.stdout[-1000:]
    layout = json.loads(found.group(1).replace("&quot;", '"').replace("&amp;", "&"))
    problems = []
    first = layout["images"][0] if layout["images"] else None
    if first is None or first["src"] != "overview.png":
        problems.append(f"the first image is {first and first['src']}, not overview.png")
    elif not first["loaded"]:
        problems.append("overview.png did not load")
    elif first["top"] < 0 or first["bottom"] > layout["height"] or first["right"] > layout["width"]:
        problems.append(f"overview.png at {first} is not inside the first screen {layout['width']}x{layout['height']}")
    shot = tmp_path / "first_screen.png"
    res = subprocess.run([browser, *CHROMIUM_FLAGS, f"--screenshot={shot}", page.as_uri()], capture_output=True,
                         text=True, timeout=120, cwd=tmp_path)
    assert res.returncode == 0 and shot.exists(), res.stderr[-2000:]
    pixels = np.asarray(Image.open(shot).convert("RGB"), dtype=int)
    assert pixels.shape[:2] == (900, 1280), pixels.shape
    # the overview draws each group in a palette colour: the first three groups' colours must be on screen
    for colour in OKABE_ITO[:3]:
        rgb = np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])
        near = int((np.abs(pixels - rgb).sum(axis=2) < 40).sum())
        if near < 100:
            problems.append(f"the first screen has {near} pixels of the overview's colour {colour}")
    return problems


def test_report_html_renders_in_headless_chromium(small_sweep, tmp_path):
    """Every image loads, and the first screen of a 1280 x 900 window shows the overview figure."""
    browser = _chromium()
    page = small_sweep[0] / "report" / "report.html"
    assert first_screen_problems(page, browser, tmp_path) == []


def test_the_first_screen_check_fails_when_the_overview_is_not_first(small_sweep, tmp_path):
    """The check above can fail: the same report with a long table moved above the overview, and with the
    overview's picture missing."""
    browser = _chromium()
    rep = small_sweep[0] / "report"
    text = (rep / "report.html").read_text()
    pushed = rep / "pushed_down.html"
    pushed.write_text(text.replace("<h1>", "<table>" + "<tr><td>row</td></tr>" * 60 + "</table><h1>", 1))
    broken = rep / "no_overview.html"
    broken.write_text(text.replace('src="overview.png"', 'src="missing.png"'))
    try:
        assert any("not inside the first screen" in p for p in first_screen_problems(pushed, browser, tmp_path))
        with pytest.raises(AssertionError, match="broken image"):
            first_screen_problems(broken, browser, tmp_path)
    finally:
        pushed.unlink()
        broken.unlink()


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
    # log paths are relative to the table's folder
    print(list(episodes["log"]), out, dirs)
    assert sorted(episodes["seed"]) == [0, 1] and all(
        str((out / log).resolve()).startswith(str(dirs["a"][0].resolve())) and (out / log).is_file()
        for log in episodes["log"])
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


def test_metric_thresholds_are_flags_and_recorded_in_the_report(small_sweep, tmp_path):
    from analysis.report import main as report_main

    out, _ = small_sweep
    assert report_main([str(out), "--out", str(tmp_path / "wide"), "--near-miss-cm", "500",
                        "--personal-space-cm", "0", "--jobs", "1"]) == 0
    default = pd.read_csv(out / "report" / "episodes.csv")
    wide = pd.read_csv(tmp_path / "wide" / "episodes.csv")
    assert wide["near_miss_steps"].sum() > default["near_miss_steps"].sum()
    assert (wide["personal_space_intrusion_s"] <= default["personal_space_intrusion_s"]).all()
    md = (tmp_path / "wide" / "report.md").read_text()
    assert "a near miss a clearance below 500 cm" in md and "personal space 0 cm" in md
    assert "a near miss a clearance below 20 cm" in (out / "report" / "report.md").read_text()
