"""The report's palette, its caps for large sweeps and its failures gallery, on hand-made logs and tables (fast: no
sweep). The report of a real sweep in a browser: tests/test_replay_report.py."""

from __future__ import annotations

from pathlib import Path

import hypothesis
import matplotlib.pyplot as plt
import pandas as pd
import pytest
from hypothesis import strategies as st

from analysis import gallery, plots
from analysis.palette import OKABE_ITO, TOL_MUTED, contrast_on_white, group_styles
from analysis.report import INLINE_ROWS, _bounded, build_report
from tests.handmade import write_log
from tests.test_grouping import meta, setter


def test_every_group_has_its_own_colour_and_keeps_it():
    """Distinct colours per group (the two auto settings were both blue), from the colour-blind-safe palettes, in
    the groups' order: the same groups get the same colours in every figure."""
    groups = ["auto(h=1)", "auto(h=2)", "auto(h=3)", "auto(h=4)", "wait", "detour", "none"]
    styles = group_styles(groups, {g: g.split("(")[0] for g in groups})
    assert [s.color for s in styles.values()] == list(OKABE_ITO)
    assert styles["wait"].linestyle == "--" and styles["none"].linestyle == ":" and styles["auto(h=2)"].linestyle == "-"
    assert group_styles(groups) == group_styles(groups)
    nine = group_styles([f"g{i}" for i in range(9)])
    assert len({s.color for s in nine.values()}) == 9 and {s.color for s in nine.values()} == set(TOL_MUTED)
    # readable on the white background: no pale yellow (Okabe–Ito's was 1.3:1, and drew the detour group)
    assert min(contrast_on_white(c) for c in (*OKABE_ITO, *TOL_MUTED)) >= 1.7  # yellow 1.3, sand 1.6
    assert contrast_on_white("#F0E442") < 1.4 and contrast_on_white("#000000") == pytest.approx(21.0)
    many = group_styles([f"g{i}" for i in range(20)])  # beyond nine: no two groups drawn alike
    assert len({(s.color, s.marker, s.linestyle) for s in many.values()}) == 20


def test_long_tables_are_capped_inline_and_name_their_file():
    table = pd.DataFrame({"x": range(INLINE_ROWS + 5)})
    shown, note = _bounded(table, "paired.csv", "differences")
    assert len(shown) == INLINE_ROWS and note == f"The first {INLINE_ROWS} of {INLINE_ROWS + 5} differences are " \
        "shown; all of them: paired.csv."
    shown, note = _bounded(table.head(3), "paired.csv", "differences")
    assert len(shown) == 3 and note == ""


def test_the_gallery_pictures_the_first_failures_of_each_group_and_lists_all():
    df = pd.DataFrame({"scenario_label": ["s"] * 9, "variant": ["a"] * 7 + ["b"] * 2, "seed": [*range(7), 0, 1],
                       "success": [False] * 7 + [True, False], "log": [f"l{i}" for i in range(9)]})
    shown = gallery.shown(df, max_per_group=3)
    assert list(shown["log"]) == ["l0", "l1", "l2", "l8"]
    assert gallery.logs_to_read(df, 3) == [f"l{i}" for i in range(7)] + ["l8"]  # few failures: all read


@pytest.fixture
def crash_logs(tmp_path):
    """Two groups on three seeds: with a 5 cm margin the robot reaches the goal; with 30 cm it drives into a box
    (in contact from step 1)."""
    box = [(200, -40), (300, -40), (300, 40), (200, 40)]
    for seed in range(3):
        write_log(tmp_path / f"ok_{seed}.mcap", [(0, 0, 0), (50, 0, 0), (100, 0, 0)], goal=(100.0, 0.0),
                  meta=meta(setter("planner.safety_margin_cm", 5.0), seed=seed))
        write_log(tmp_path / f"crash_{seed}.mcap", [(100, 0, 0), (150, 0, 0), (190, 0, 0), (200, 0, 0)], statics=[box],
                  goal=(400.0, 0.0), contacts_static=[False, True, True], outcome="collision",
                  meta=meta(setter("planner.safety_margin_cm", 30.0), seed=seed))
    return tmp_path


def test_the_report_opens_with_the_overview_and_pictures_each_failure(crash_logs, tmp_path, monkeypatch):
    drawn: dict[str, plt.Figure] = {}

    def keep(fig, path):
        drawn[path.name] = ([a.get_title() for a in fig.axes] + [t.get_text() for t in fig.texts]
                            + [t.get_text() for a in fig.axes for t in a.texts])
        plt.close(fig)
        path.write_bytes(b"")
        return path

    monkeypatch.setattr(plots, "_save", keep)
    out = tmp_path / "rep"
    build_report([crash_logs], out, jobs=1)
    md = (out / "report.md").read_text()
    assert md.startswith("# fuzzynav report\n\n![overview](overview.png)\n")
    failures = pd.read_csv(out / "failures.csv")
    assert sorted(failures["seed"]) == [0, 1, 2]
    assert set(failures["variant"]) == {"auto(h=2) · safety_margin_cm=30"}
    assert list(failures["first_contact_step"]) == [1, 1, 1] and failures["log_read"].all()
    assert set(failures["picture"]) == {"failures.png"} and "![failures](failures.png)" in md  # one gallery figure
    group = "head_on · auto(h=2) · safety_margin_cm=30"
    assert drawn["failures.png"] == ["", group, *(f"seed {s}: collision, contact at step 1" for s in range(3))]
    listed = md[md.index("![failures](failures.png)"):]
    assert [listed.index(str(crash_logs / f"crash_{s}.mcap").split("/")[-1]) for s in range(3)] == sorted(
        listed.index(str(crash_logs / f"crash_{s}.mcap").split("/")[-1]) for s in range(3))  # in the panels' order
    assert "3 of 6 episodes failed" in md
    html = (out / "report.html").read_text()
    assert html.index('<img id="overview" src="overview.png"') < html.index("<h2>")


def test_the_gallery_has_a_row_per_group_and_goes_on_in_a_second_figure(monkeypatch, tmp_path):
    """A row of panels per failing group, in the groups' order, at most ROWS_PER_FIGURE rows a figure (a figure of
    hundreds of rows would be too high to draw): the next groups are in failures_2.png, and failures.csv names the
    figure of each failure's panel."""
    import numpy as np

    from analysis.trace import Trace, World

    rows = []
    for g in range(3):
        for seed in range(2):
            rows.append({"scenario_label": "s", "variant": f"g{g}", "strategy": "auto", "seed": seed, "success": False,
                         "outcome": "timeout", "steps": 9, "collisions_static": 0, "collisions_dynamic": 0,
                         "log": f"l{g}{seed}"})
    df = pd.DataFrame(rows)
    world = World(bounds=(0.0, 0.0, 100.0, 50.0), polygons=(), goal=(90.0, 25.0), goal_tolerance=5.0)
    traces = {r["log"]: Trace(r["log"], np.array([[5.0, 25.0], [40.0, 25.0]]), (), None, (), world, 10.0, "timeout", 9)
              for r in rows}
    drawn: dict[str, list[str]] = {}

    def keep(fig, path):
        drawn[path.name] = [t.get_text() for a in fig.axes for t in a.texts]
        plt.close(fig)
        return path

    monkeypatch.setattr(plots, "_save", keep)
    monkeypatch.setattr(gallery, "ROWS_PER_FIGURE", 2)
    pictures, counts, figures = gallery.gallery(df, traces, tmp_path)
    assert figures == [tmp_path / "failures.png", tmp_path / "failures_2.png"]
    assert drawn["failures.png"] == ["s · g0", "seed 0: timeout", "seed 1: timeout", "s · g1", "seed 0: timeout",
                                     "seed 1: timeout"]
    assert drawn["failures_2.png"] == ["s · g2", "seed 0: timeout", "seed 1: timeout"]
    assert [f.picture for f in pictures] == ["failures.png"] * 4 + ["failures_2.png"] * 2
    assert list(pd.read_csv(tmp_path / "failures.csv")["picture"]) == [f.picture for f in pictures]
    assert list(counts["pictured"]) == [2, 2, 2]


@pytest.fixture
def many_seeds(tmp_path):
    """One group on 24 seeds, more than a trajectory panel draws, failing (into a box) on seeds 5, 17 and 22: the
    panel draws the failed first, so seed 22 is drawn and seeds 18-23 that reached the goal are not."""
    box = [(200, -40), (300, -40), (300, 40), (200, 40)]
    for seed in range(24):
        if seed in (5, 17, 22):
            write_log(tmp_path / f"crash_{seed}.mcap", [(100, 0, 0), (150, 0, 0), (190, 0, 0), (200, 0, 0)],
                      statics=[box], goal=(400.0, 0.0), contacts_static=[False, True, True], outcome="collision",
                      meta=meta(seed=seed))
        else:
            write_log(tmp_path / f"ok_{seed}.mcap", [(0, 0, 0), (50, 0, 0), (100, 0, 0)], goal=(100.0, 0.0),
                      meta=meta(seed=seed))
    return tmp_path


def test_the_report_reads_each_log_once_and_pictures_the_same(many_seeds, tmp_path, monkeypatch):
    """The metrics pass keeps what the pictures need (analyse_logs(traces=True)): the report reads no log again,
    and its files are the same as when it reads the pictured logs again (an analysis without them)."""
    import analysis.report as report
    from analysis.metrics import Analysis, analyse_logs

    analysis = analyse_logs([many_seeds], traces=True)
    df = analysis.episodes
    drawn = set(plots.panel_episodes(df)["log"])
    assert len(drawn) == plots.MAX_SEEDS_PER_PANEL and str(many_seeds / "crash_22.mcap") in drawn
    assert set(analysis.traces) == drawn  # the first 20 in a panel's order, nothing more
    assert analysis.first_contacts == {str(many_seeds / f"crash_{s}.mcap"): 1 for s in (5, 17, 22)}
    bare = Analysis(analysis.episodes, analysis.excluded, analysis.grouping, analysis.runs)
    outs = {}
    for name, given in (("reread", bare), ("once", analysis)):
        if name == "once":
            def refuse(paths, jobs=-1):
                raise AssertionError(f"read again: {paths}")
            monkeypatch.setattr(report, "load_traces", refuse)
        outs[name] = tmp_path / name
        build_report([many_seeds], outs[name], analysis=given, jobs=1)
    files = sorted(p.name for p in outs["reread"].iterdir())
    assert files == sorted(p.name for p in outs["once"].iterdir())
    for name in files:
        if name.endswith((".md", ".html", ".csv", ".png")):
            assert (outs["reread"] / name).read_bytes() == (outs["once"] / name).read_bytes(), name


def test_kept_traces_are_the_first_of_each_run_in_a_panels_order_whatever_the_chunks(many_seeds):
    """Worker processes keep the first episodes of each run configuration of their part of the logs; joined, they are
    the first of all (failed first, then by seed), as if one process had read every log."""
    import random

    from analysis.episode_log import load_episode
    from analysis.trace import KeptTraces

    logs = sorted(many_seeds.glob("*.mcap"))
    random.Random(1).shuffle(logs)
    parts = [KeptTraces(per_run=4) for _ in range(3)]
    for i, path in enumerate(logs):
        log = load_episode(path)
        run = "b" if int(log.meta["seed"]) % 2 else "a"
        parts[i % 3].offer(run, log.outcome == "goal", int(log.meta["seed"]), log, str(path))
    joined = KeptTraces(per_run=4)
    for part in parts:
        joined.merge(part)
    assert {run: [key[1] for key, _ in kept] for run, kept in joined.runs.items()} == {"a": [22, 0, 2, 4],
                                                                                        "b": [5, 17, 1, 3]}
    assert joined.contacts == {str(many_seeds / f"crash_{s}.mcap"): 1 for s in (5, 17, 22)}
    assert all(trace.log == key[2] for kept in joined.runs.values() for key, trace in kept)


def test_an_infinite_value_gives_an_infinite_mean_and_interval_end_without_a_warning():
    """min_ttc_s is inf for an episode never on a collision course: its group's interval was inf - inf (NaN, with a
    RuntimeWarning from numpy in every sweep)."""
    import math
    import warnings

    from analysis.stats import bootstrap_mean

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mean, lo, hi = bootstrap_mean([1.0, 2.0, math.inf, 3.0])
        assert mean == math.inf and lo == pytest.approx(1.5) and hi == math.inf
        assert all(math.isnan(v) for v in bootstrap_mean([math.inf, -math.inf]))


def test_file_names_of_long_labels_stay_short_and_distinct():
    """A group label of many differing parameters (a controller's rule base) made a picture's name longer than the
    file system allows: the report failed with 'File name too long'."""
    a, b = "auto(h=2) · " + "rules=x" * 60 + "a", "auto(h=2) · " + "rules=x" * 60 + "b"
    assert len(plots._file_part(a)) <= plots.FILE_PART_MAX and plots._file_part(a) != plots._file_part(b)
    assert plots._file_part("random_mixed · n_dynamic=5") == "random_mixed__n_dynamic=5"


def test_the_h_wait_panels_do_not_magnify_noise():
    """matplotlib zoomed a panel of path lengths into 996-1,000 cm: equal results looked like an effect."""
    from analysis.plots import MIN_SPAN, honest_ylim

    low, high = honest_ylim(996.0, 1000.0, "path_length_cm")
    assert high - low == pytest.approx(MIN_SPAN * 1000.0) and low < 996.0 and high > 1000.0
    assert honest_ylim(0.0, 300.0, "time_to_goal_s") == (0.0, 300.0)  # a real spread is kept
    assert honest_ylim(0.98, 1.0, "success") == (-0.05, 1.05)
    assert honest_ylim(0.0, 0.0, "wait_steps") == (0.0, 0.0)
    low, high = honest_ylim(-30.0, -29.0, "min_clearance_dynamic_cm")
    assert high - low == pytest.approx(6.0)


def test_what_the_data_says_leads_with_who_reaches_the_goal():
    """It read like machine output ("highest 1.00 with auto(h=1), ..., none (lowest 1.00 with ...)")."""
    from analysis.report import who_reaches_the_goal

    def episodes(variant, outcomes, contacts=None):
        return [{"variant": variant, "outcome": o, "success": o == "goal" and not c,
                 "collisions_static": 0, "collisions_dynamic": int(c or o == "collision")}
                for o, c in zip(outcomes, contacts or [0] * len(outcomes), strict=True)]

    rows = (episodes("detour", ["goal"] * 10) + episodes("auto(h=2)", ["goal"] * 10)
            + episodes("wait", ["collision"] * 9 + ["timeout"]))
    assert who_reaches_the_goal("head_on", pd.DataFrame(rows)) == (
        "head_on: goal reached 10/10 by detour and auto(h=2); 0/10 by wait (failures: 9 collisions, 1 timeout). "
        "The best and the worst differ clearly (their 95 % intervals do not overlap).")
    few = pd.DataFrame(episodes("detour", ["goal"] * 2) + episodes("wait", ["goal", "collision"]))
    assert who_reaches_the_goal("x", few) == (
        "x: goal reached 2/2 by detour; 1/2 by wait (failures: 1 collision). The best and the worst are not "
        "separable with 2 episodes per group (their 95 % intervals overlap).")
    same = pd.DataFrame(episodes("a", ["goal"]) + episodes("b", ["goal"]))
    assert who_reaches_the_goal("y", same) == "y: goal reached 1/1 by a and b. No group differs from another."
    # terminate_on_collision=false: the robot went on through the obstacle to the goal
    through = pd.DataFrame(episodes("none", ["goal"] * 3, [1, 1, 1]) + episodes("auto", ["goal"] * 3))
    assert who_reaches_the_goal("z", through) == (
        "z: goal reached without a contact 3/3 by auto; 0/3 by none (failures: 3 goals after a contact). The best "
        "and the worst are not separable with 3 episodes per group (their 95 % intervals overlap).")


def test_the_collision_rate_counts_every_episode_with_a_contact():
    """With terminate_on_collision=false episodes that touched the obstacle end as "goal": the collision rate read
    0.00 beside a success rate of 0.00."""
    from analysis.report import touched

    g = pd.DataFrame({"collisions_static": [0, 0, 2], "collisions_dynamic": [1, 0, 0]})
    assert list(touched(g)) == [True, False, True]


def test_a_swept_parameter_that_changed_no_episode_is_said():
    """h_wait 1-4 gave identical outcomes and steps on 6 of 7 unseen scenarios; the report showed equal bars."""
    from analysis.report import unchanged_by
    from analysis.run_parameters import Grouping

    rows = []
    for h in (1, 2, 3):
        for seed in (0, 1):
            # head_on: h_wait changes nothing; crossing: h=1 detours (longer), h>=2 waits
            rows.append({"scenario_label": "head_on", "variant": f"auto(h={h})", "strategy": "auto", "h_wait": h,
                         "seed": seed, "outcome": "goal", "steps": 40 + seed, "path_length_cm": 1000.0})
            rows.append({"scenario_label": "crossing", "variant": f"auto(h={h})", "strategy": "auto", "h_wait": h,
                         "seed": seed, "outcome": "goal", "steps": 44 if h == 1 else 41,
                         "path_length_cm": 1100.0 if h == 1 else 1000.0})
    rows += [{"scenario_label": s, "variant": "wait", "strategy": "wait", "h_wait": None, "seed": seed,
              "outcome": "goal", "steps": 40 + seed, "path_length_cm": 1000.0}
             for s in ("head_on", "crossing") for seed in (0, 1)]
    lines = unchanged_by(pd.DataFrame(rows), Grouping())
    assert lines == ["head_on: h_wait changed no episode (auto(h=1), auto(h=2), auto(h=3): the same outcome, steps "
                     "and path on each of 2 common seeds)."]


def test_a_report_into_the_folder_of_an_earlier_one_leaves_none_of_its_figures(crash_logs, tmp_path):
    """The second report has no failure: the first one's failures.png goes (it pictured logs this report does not
    have); a file the report did not write stays, and a tampered list reaches nothing outside the folder."""
    from analysis.report import WRITTEN_LIST, main

    out = tmp_path / "rep"
    every = [str(p) for p in sorted(crash_logs.glob("*.mcap"))]
    assert main([*every, "--out", str(out), "--jobs", "1"]) == 0
    assert (out / "failures.png").is_file() and "failures.png" in (out / WRITTEN_LIST).read_text().split()
    (out / "mine.png").write_bytes(b"the user's")
    outside = tmp_path / "outside.txt"
    outside.write_text("keep")
    with (out / WRITTEN_LIST).open("a") as listed:
        listed.write("../outside.txt\nmine/../../outside.txt\n.hidden\n")
    successes = [p for p in every if Path(p).name.startswith("ok_")]
    assert main([*successes, "--out", str(out), "--jobs", "1"]) == 0
    assert not (out / "failures.png").exists() and "failures.png" not in (out / "report.md").read_text()
    assert (out / "mine.png").read_bytes() == b"the user's" and outside.read_text() == "keep"
    fresh = tmp_path / "fresh"
    assert main([*successes, "--out", str(fresh), "--jobs", "1"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted([*(p.name for p in fresh.iterdir()), "mine.png"])


@hypothesis.settings(max_examples=200, deadline=None,
                     suppress_health_check=[hypothesis.HealthCheck.function_scoped_fixture])
@hypothesis.given(text=st.text(alphabet=st.sampled_from(list("ab./\\\n~ \x00épngmd")), max_size=60))
def test_an_edited_file_list_names_only_plain_files_of_the_folder(tmp_path, text):
    """Whatever the hidden list holds, the names a later report may remove are plain, visible files of its folder."""
    from analysis.report import WRITTEN_LIST, previous_report_files

    (tmp_path / WRITTEN_LIST).write_text(text, encoding="utf-8")
    for name in previous_report_files(tmp_path):
        assert (tmp_path / name).parent == tmp_path and not name.startswith(".") and name not in ("", WRITTEN_LIST)
        assert name.lower().endswith((".png", ".csv", ".parquet", ".md", ".html"))  # never a log


def test_a_list_that_names_a_log_never_removes_it(crash_logs, tmp_path):
    """The report written into its logs' folder, its list edited to name one of the logs: the log stays."""
    import shutil

    from analysis.report import WRITTEN_LIST, main

    folder = tmp_path / "logs"
    shutil.copytree(crash_logs, folder)
    assert main([str(folder), "--out", str(folder), "--jobs", "1"]) == 0
    log = sorted(folder.glob("*.mcap"))[0]
    with (folder / WRITTEN_LIST).open("a") as listed:
        listed.write(f"{log.name}\n")
    before = log.read_bytes()
    assert main([str(folder), "--out", str(folder), "--jobs", "1"]) == 0
    assert log.read_bytes() == before


def test_a_report_that_cannot_be_moved_in_leaves_the_earlier_one_whole(crash_logs, tmp_path, monkeypatch, capsys):
    """A file of the report that cannot take its place (a directory of its name; a move that fails half-way):
    one line, exit 1, and the folder holds the earlier report as it was, not a mix of the two."""
    import os

    import analysis.report as report

    out = tmp_path / "rep"
    every = [str(p) for p in sorted(crash_logs.glob("*.mcap"))]
    assert report.main([every[0], "--out", str(out), "--jobs", "1"]) == 0

    def snapshot() -> dict[str, bytes | None]:
        return {p.name: p.read_bytes() if p.is_file() else None for p in sorted(out.iterdir())}

    (out / "report.md").unlink()
    (out / "report.md").mkdir()
    earlier = snapshot()
    capsys.readouterr()
    assert report.main([*every, "--out", str(out), "--jobs", "1"]) == 1
    err = capsys.readouterr().err
    assert err == f"error: {out / 'report.md'}: cannot write the report: Is a directory (nothing written)\n"
    assert snapshot() == earlier
    (out / "report.md").rmdir()
    assert report.main([every[0], "--out", str(out), "--jobs", "1"]) == 0
    earlier = snapshot()
    real_replace, calls = os.replace, []

    def failing_replace(src, dst):
        calls.append(dst)
        if len(calls) == 7:  # some files of the new report are in place, others not yet
            raise OSError(28, "No space left on device", str(dst))
        return real_replace(src, dst)

    monkeypatch.setattr(report.os, "replace", failing_replace)
    assert report.main([*every, "--out", str(out), "--jobs", "1"]) == 1
    assert snapshot() == earlier
    assert not [p for p in out.iterdir() if p.name.startswith(".report.partial")]


def test_a_log_whose_name_is_not_utf8_is_left_out_by_name(crash_logs, tmp_path, capsys):
    """A file name in bytes that are not UTF-8 (copied from another system): left out as ``bad-name`` with the name
    escaped, never opened; the other logs make the report, whether the file is found in a folder or named."""
    import os
    import shutil

    from analysis.metrics import analyse_logs
    from analysis.report import main

    folder = tmp_path / "logs"
    folder.mkdir()
    good, other = sorted(crash_logs.glob("ok_*.mcap"))[:2]
    shutil.copy(good, folder / good.name)
    odd = folder / os.fsdecode(b"bad\xff.mcap")
    shutil.copy(other, odd)
    analysis = analyse_logs([folder], jobs=1)
    assert len(analysis.episodes) == 1 and analysis.excluded["kind"].tolist() == ["bad-name"]
    assert analysis.excluded["log"].tolist() == [str(folder / "bad\\xff.mcap")]
    for given in ([str(folder)], [str(folder / good.name), str(odd)]):
        out = tmp_path / f"rep{len(given)}"
        assert main([*given, "--out", str(out), "--jobs", "1"]) == 0
        assert "1 log(s) left out (1 bad-name)" in capsys.readouterr().out
        assert "bad\\xff.mcap" in (out / "report.md").read_text(encoding="utf-8")
    out = tmp_path / "alone"
    assert main([str(odd), "--out", str(out), "--jobs", "1"]) == 1  # nothing usable: one line, the report says why
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bad\\xff.mcap: the file name is not UTF-8 text" in err, err


@hypothesis.given(labels=st.lists(st.lists(st.sampled_from([*"aAb _.=·/é(", " · "]), min_size=1, max_size=30)
                                  .map("".join), min_size=2, max_size=2, unique=True))
def test_two_labels_never_share_a_picture_file(labels):
    """Two scenario groups whose labels differ get two files, even where the file system folds case (``x y`` and
    ``x_y`` shared one trajectories picture: the first group's trajectories were never shown)."""
    a, b = (plots._file_part(label) for label in labels)
    assert a.lower() != b.lower()
    assert plots._file_part("head_on · description=x y") != plots._file_part("head_on · description=x_y")
