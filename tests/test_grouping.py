"""Groups are defined by every run parameter that differs among the logs (issue 13, item 4: reports never
pool two settings), with one definition of success shared by the sweep's summary and the metrics."""

from __future__ import annotations

import math
import subprocess
import sys

import matplotlib.pyplot as plt
import pandas as pd
import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from analysis import plots
from analysis.metrics import analyse_logs, metrics_table
from analysis.report import build_report
from analysis.run_parameters import (
    differing_parameters,
    find_grouping,
    format_value,
    is_success,
    parameters_of,
    provenance_warning,
    short_names,
)
from fuzzynav.episode_identity import config_hash
from runners.sweeping.summary import summarise
from tests.conftest import ROOT
from tests.handmade import write_log

BASE = {"scenario": {"name": "head_on", "max_steps": 150, "obstacles": [{"id": "walker", "speed": 20}]},
        "controller": {"name": "table1", "rules": ["a -> b", "c -> d"]},
        "planner": {"strategy": "auto", "h_wait": 2, "safety_margin_cm": 10.0, "successor_speeds": [10, 25, 40]},
        "sensors": {"sonar": {"range_cm": 130.0}, "laser": {"range_cm": 250.0}},
        "perception": {"mode": "laser"}, "seed": 0, "episodes": 5, "dt": 1.0, "resume": False}
PROVENANCE = {"fuzzynav_version": "0.2.0", "git_commit": "ea0c422f7455e44b123699f1c6d71426d28936fa",
              "numpy_version": "2.4.6"}


def meta(edit=None, seed: int = 0, **extra) -> dict[str, str]:
    """A log's ``fuzzynav.run`` metadata as runners.run writes it: ``edit(config)`` changes the config."""
    config = yaml.safe_load(yaml.safe_dump(BASE))
    config["seed"] = seed
    if edit:
        edit(config)
    out = {"config": yaml.safe_dump(config, sort_keys=False), "seed": str(seed),
           "scenario": config["scenario"]["name"], "strategy": config["planner"]["strategy"],
           "h_wait": str(config["planner"]["h_wait"]), "controller": config["controller"]["name"],
           "perception": config["perception"]["mode"], "scenario_yaml": f"seed {seed}", **PROVENANCE}
    out.update(extra)
    if "config_hash" not in extra:  # as runners.run computes it: the analysis checks it
        out["config_hash"] = config_hash(out["config"], out["seed"], out["fuzzynav_version"])
    return out


def setter(path: str, value):
    def edit(config):
        *parents, leaf = path.split(".")
        node = config
        for p in parents:
            node = node[p]
        node[leaf] = value
    return edit


def runs(*metas):
    return [parameters_of(m) for m in metas]


# -- the differing-parameter function on hand-made metadata ------------------------------------------------
def test_a_parameter_no_list_names_is_a_dimension_and_bookkeeping_is_not():
    logs = runs(*(meta(setter("planner.safety_margin_cm", m), seed=s) for m in (5.0, 30.0) for s in (0, 1, 2)))
    assert differing_parameters(logs) == ["planner.safety_margin_cm"]  # not seed, config_hash, scenario_yaml
    grouping = find_grouping(logs)
    assert grouping.variant_keys == ("planner.safety_margin_cm",) and grouping.scenario_keys == ()
    assert {grouping.variant_label(r) for r in logs} == {"auto(h=2) · safety_margin_cm=5",
                                                         "auto(h=2) · safety_margin_cm=30"}
    episodes_and_resume = runs(meta(setter("episodes", 1)), meta(setter("resume", True)), meta(seed=7))
    assert differing_parameters(episodes_and_resume) == []
    assert find_grouping(episodes_and_resume).variant_label(episodes_and_resume[0]) == "auto(h=2)"


def test_scenario_and_controller_keys_implied_by_their_name_are_not_repeated():
    def other_scenario(config):
        config["scenario"] = {"name": "crossing_right", "max_steps": 200, "obstacles": [{"id": "c", "speed": 30}]}

    def listing(config):
        config["controller"] = {"name": "listing", "rules": ["x -> y"]}

    logs = runs(meta(), meta(other_scenario), meta(listing))
    assert differing_parameters(logs) == ["scenario", "controller"]
    grouping = find_grouping(logs)
    assert grouping.variant_label(logs[2]) == "auto(h=2) · controller=listing"
    assert grouping.scenario_label(logs[1]) == "crossing_right"


def test_same_scenario_name_with_other_parameters_splits_the_scenario():
    def mixed(n):
        def edit(config):
            config["scenario"] = {"name": "random_mixed", "generator": "random_mixed",
                                  "params": {"n_dynamic": n, "speed": [10, 30]}}
        return edit

    logs = runs(meta(mixed(3)), meta(mixed(5)), meta(mixed(5), seed=1))
    grouping = find_grouping(logs)
    assert grouping.scenario_keys == ("scenario.params.n_dynamic",) and grouping.variant_keys == ()
    assert [grouping.scenario_label(r) for r in logs] == ["random_mixed · n_dynamic=3"] + [
        "random_mixed · n_dynamic=5"] * 2
    assert grouping.variant_label(logs[0]) == "auto(h=2)"


def test_an_edited_controller_under_the_same_name_is_a_dimension_with_a_short_unique_value():
    logs = runs(meta(), meta(setter("controller.rules", ["a -> b", "c -> e"])))
    grouping = find_grouping(logs)
    assert grouping.variant_keys == ("controller.rules",)
    labels = {grouping.variant_label(r) for r in logs}
    assert len(labels) == 2 and all(label.startswith("auto(h=2) · rules=") and len(label) < 40 for label in labels)


def test_a_key_missing_from_some_logs_differs_and_shows_as_unset():
    def older(config):
        del config["planner"]["successor_speeds"]

    logs = runs(meta(), meta(older))
    grouping = find_grouping(logs)
    assert grouping.variant_keys == ("planner.successor_speeds",)
    assert [grouping.variant_label(r) for r in logs] == ["auto(h=2) · successor_speeds=[10,25,40]",
                                                         "auto(h=2) · successor_speeds=unset"]


def test_a_log_without_config_differs_in_config_only():
    logs = runs(meta(), meta(setter("planner.safety_margin_cm", 5.0)), meta(config=""))
    assert differing_parameters(logs) == ["config", "planner.safety_margin_cm"]


def test_provenance_is_pooled_with_a_warning_unless_split():
    logs = runs(meta(), meta(seed=1, git_commit="1234567890abcdef1234567890abcdef12345678-dirty"))
    assert differing_parameters(logs) == ["git_commit"]
    pooled = find_grouping(logs)
    assert pooled.dimensions == () and pooled.pooled_provenance == ("git_commit",)
    warning = provenance_warning(pooled, logs)
    assert warning is not None and "git_commit" in warning and "(1 episodes)" in warning
    split = find_grouping(logs, split_provenance=True)
    assert split.variant_keys == ("git_commit",) and provenance_warning(split, logs) is None
    assert len({split.variant_label(r) for r in logs}) == 2


def test_provenance_that_differs_only_between_groups_is_not_said_to_be_pooled():
    """A _target_ policy's source digest beside fuzzynav's own policies: each value in groups of its own (the policy
    tutorial's sweep warned that they were pooled)."""
    logs = runs(meta(setter("planner.safety_margin_cm", 5.0), policy_source_sha256="ab" * 32),
                meta(setter("planner.safety_margin_cm", 30.0)))
    grouping = find_grouping(logs)
    assert grouping.pooled_provenance == ("policy_source_sha256",)
    assert provenance_warning(grouping, logs) is None


def test_a_parameter_of_a_part_that_is_off_is_no_dimension():
    """h_wait is read by auto only, and planner=none reads no planner parameter: logs that differ only there are
    one group (tests/test_parameters_off.py shows their episodes are the same bits); auto's h_wait still splits."""
    def planner(strategy, h, **more):
        def edit(config):
            config["planner"].update(strategy=strategy, h_wait=h, **more)
        return edit

    logs = runs(meta(planner("wait", 1)), meta(planner("wait", 3)), meta(planner("auto", 1)), meta())
    grouping = find_grouping(logs)
    assert [grouping.variant_label(r) for r in logs] == ["wait", "wait", "auto(h=1)", "auto(h=2)"]
    assert [r["h_wait"] for r in logs] == [None, None, 1, 2]
    logs = runs(meta(planner("none", 1, safety_margin_cm=0.0)), meta(planner("none", 4, safety_margin_cm=30.0)))
    grouping = find_grouping(logs)
    assert grouping.variant_keys == () and len({grouping.variant_label(r) for r in logs}) == 1
    logs = runs(meta(planner("auto", 2, safety_margin_cm=0.0)), meta(planner("auto", 2, safety_margin_cm=30.0)),
                meta(planner("none", 2)))
    grouping = find_grouping(logs)
    assert grouping.variant_keys == ("planner.safety_margin_cm",)
    assert [grouping.variant_label(r) for r in logs] == ["auto(h=2) · safety_margin_cm=0",
                                                         "auto(h=2) · safety_margin_cm=30", "none"]
    logs = runs(meta(planner("wait", 2, safety_margin_cm=0.0)), meta(planner("wait", 2, safety_margin_cm=30.0)))
    assert find_grouping(logs).variant_keys == ("planner.safety_margin_cm",)  # read by wait: still a dimension


def test_short_names_are_unambiguous_suffixes():
    assert short_names(["planner.safety_margin_cm", "sensors.sonar.range_cm", "sensors.laser.range_cm",
                        "controller.fallback.v", "planner.strategy_x"]) == {
        "planner.safety_margin_cm": "safety_margin_cm", "sensors.sonar.range_cm": "sonar.range_cm",
        "sensors.laser.range_cm": "laser.range_cm", "controller.fallback.v": "fallback.v",
        "planner.strategy_x": "strategy_x"}
    assert short_names(["scenario.params.seed"]) == {"scenario.params.seed": "params.seed"}  # not "seed"


def test_values_format_short_and_groups_sort_by_number():
    assert [format_value(v) for v in (5.0, 0.25, 3, True, None, "laser")] == ["5", "0.25", "3", "true", "null",
                                                                              "laser"]
    logs = runs(*(meta(setter("planner.safety_margin_cm", m)) for m in (20.0, 5.0, 10.0)))
    grouping = find_grouping(logs)
    ordered = sorted(logs, key=grouping.sort_key)
    assert [r["planner.safety_margin_cm"] for r in ordered] == [5.0, 10.0, 20.0]  # not "10" < "20" < "5"


def test_success_needs_goal_no_contact_and_a_finite_time_to_goal():
    assert is_success("goal", 0, 12.0)
    assert not is_success("goal", 1, 12.0)
    assert not is_success("goal", 0, math.nan)  # the positions never reach the goal: not shown to succeed
    assert not is_success("goal", None, 12.0) and not is_success("goal", math.nan, 12.0)  # unknown contacts
    assert not is_success("timeout", 0, 12.0) and not is_success("collision", 0, 3.0)


# -- hand-made logs: analysis, summary and report ------------------------------------------------------------
def margin_logs(tmp_path):
    """Six logs of one configuration but the safety margin (5 or 30 cm): the same path, a moving obstacle
    passing 30 cm from the robot's surface with margin 5 and 80 cm with margin 30 (in the regression this
    issue reports, both pooled into one group whose clearance was the mean of the two)."""
    poses = [(0.0, 0.0, 0.0), (50.0, 0.0, 0.0), (100.0, 0.0, 0.0)]
    for margin, gap in ((5.0, 30.0), (30.0, 80.0)):
        y = 20 + 10 + gap  # robot radius 20, obstacle radius 10
        for seed in range(3):
            m = meta(setter("planner.safety_margin_cm", margin), seed=seed)
            write_log(tmp_path / f"m{int(margin)}_s{seed}.mcap", poses, goal=(100.0, 0.0),
                      obstacles=[[("o", 0, y, 50, y, 10)], [("o", 50, y, 100, y, 10)]], meta=m)


def test_two_margins_are_two_groups_in_every_table(tmp_path, monkeypatch):
    monkeypatch.setattr(plots, "_save", lambda fig, path: plt.close(fig) or path)  # tables only: no PNGs
    margin_logs(tmp_path)
    analysis = analyse_logs([tmp_path])
    df = analysis.episodes
    assert list(pd.unique(df["variant"])) == ["auto(h=2) · safety_margin_cm=5", "auto(h=2) · safety_margin_cm=30"]
    clearance = df.groupby("planner.safety_margin_cm")["min_clearance_dynamic_cm"].mean()
    assert clearance[5.0] == pytest.approx(30.0) and clearance[30.0] == pytest.approx(80.0)

    build_report([tmp_path], tmp_path / "rep", analysis=analysis)
    groups = pd.read_csv(tmp_path / "rep" / "groups.csv")
    clearance_rows = groups[groups["metric"] == "min_clearance_dynamic_cm"]
    assert sorted(zip(clearance_rows["planner.safety_margin_cm"], clearance_rows["mean"], strict=True)) == [
        (5.0, pytest.approx(30.0)), (30.0, pytest.approx(80.0))]
    episodes = pd.read_csv(tmp_path / "rep" / "episodes.csv")
    assert sorted(episodes["planner.safety_margin_cm"]) == [5.0] * 3 + [30.0] * 3
    md = (tmp_path / "rep" / "report.md").read_text()
    assert "| head_on    | auto(h=2) · safety_margin_cm=5  |          3 |" in md
    assert "| head_on    | auto(h=2) · safety_margin_cm=30 |          3 |" in md
    paired = pd.read_csv(tmp_path / "rep" / "paired.csv")
    pair = paired[paired["metric"] == "min_clearance_dynamic_cm"].iloc[0]
    assert (pair["A"], pair["B"], pair["pairs"]) == ("auto(h=2) · safety_margin_cm=5",
                                                      "auto(h=2) · safety_margin_cm=30", 3)
    assert pair["mean_a_minus_b"] == pytest.approx(-50.0)

    _, table = summarise(tmp_path)
    assert list(table["variant"]) == ["auto(h=2) · safety_margin_cm=5", "auto(h=2) · safety_margin_cm=30"]
    assert list(table["episodes"]) == [3, 3]


def test_neighbouring_h_wait_settings_are_paired_and_distant_ones_are_not(tmp_path, monkeypatch):
    """auto with h_wait 1, 2 and 4 on three seeds: the report pairs h=1 with h=2 and h=2 with h=4 (the next
    setting present), not h=1 with h=4; the robot of h=1 passes the obstacle 10 cm closer than the others."""
    monkeypatch.setattr(plots, "_save", lambda fig, path: plt.close(fig) or path)
    poses = [(0.0, 0.0, 0.0), (50.0, 0.0, 0.0), (100.0, 0.0, 0.0)]
    for h in (1, 2, 4):
        y = 20 + 10 + (30.0 if h == 1 else 40.0)
        for seed in range(3):
            write_log(tmp_path / f"h{h}_s{seed}.mcap", poses, goal=(100.0, 0.0),
                      obstacles=[[("o", 0, y, 50, y, 10)], [("o", 50, y, 100, y, 10)]],
                      meta=meta(setter("planner.h_wait", h), seed=seed))
    build_report([tmp_path], tmp_path / "rep")
    paired = pd.read_csv(tmp_path / "rep" / "paired.csv")
    assert set(zip(paired["A"], paired["B"], strict=True)) == {("auto(h=1)", "auto(h=2)"), ("auto(h=2)", "auto(h=4)")}
    clearance = paired[paired["metric"] == "min_clearance_dynamic_cm"].set_index("A")
    assert clearance.loc["auto(h=1)", "mean_a_minus_b"] == pytest.approx(-10.0)
    assert clearance.loc["auto(h=1)", "excludes_zero"]
    assert clearance.loc["auto(h=2)", "mean_a_minus_b"] == pytest.approx(0.0)


def test_paired_differences_are_those_of_each_seeds_mean(tmp_path):
    """Margin 5 on seeds 0, 1 (twice in the table: 30 and 50 cm from the obstacle, as two runs of one configuration
    are) and 2, margin 30 on seeds 0, 1 and 3: the pairs are the common seeds 0 and 1, seed 1 of margin 5 the mean
    of its two episodes, as pandas' group mean of each seed gives them (the table's own arithmetic is plain arrays
    where no seed repeats)."""
    from analysis.report import PAIRED_METRICS, paired_table
    from analysis.stats import bootstrap_mean

    poses = [(0.0, 0.0, 0.0), (50.0, 0.0, 0.0), (100.0, 0.0, 0.0)]
    for name, margin, seed, gap in (("a0", 5.0, 0, 30.0), ("a1", 5.0, 1, 30.0), ("a2", 5.0, 2, 30.0),
                                    ("b0", 30.0, 0, 80.0), ("b1", 30.0, 1, 70.0), ("b3", 30.0, 3, 80.0)):
        y = 20 + 10 + gap
        write_log(tmp_path / f"{name}.mcap", poses, goal=(100.0, 0.0),
                  obstacles=[[("o", 0, y, 50, y, 10)], [("o", 50, y, 100, y, 10)]],
                  meta=meta(setter("planner.safety_margin_cm", margin), seed=seed))
    analysis = analyse_logs([tmp_path])
    again = analysis.episodes[analysis.episodes["log"].str.endswith("a1.mcap")].assign(min_clearance_dynamic_cm=50.0)
    df = pd.concat([analysis.episodes, again], ignore_index=True)
    paired = paired_table(df, analysis.grouping)
    a, b = pd.unique(df["variant"])
    per_seed = {v: g.groupby("seed")[PAIRED_METRICS].mean() for v, g in df.groupby("variant")}
    common = per_seed[a].index.intersection(per_seed[b].index)
    assert list(common) == [0, 1]
    for metric in PAIRED_METRICS:
        diff = per_seed[a].loc[common, metric].astype(float) - per_seed[b].loc[common, metric].astype(float)
        row = paired[paired["metric"] == metric].iloc[0]
        assert (row["A"], row["B"], row["pairs"]) == (a, b, int(diff.notna().sum()))
        assert (row["mean_a_minus_b"], row["ci_low"], row["ci_high"]) == pytest.approx(bootstrap_mean(diff),
                                                                                       nan_ok=True, rel=0, abs=0)
    clearance = paired[paired["metric"] == "min_clearance_dynamic_cm"].iloc[0]
    assert clearance["mean_a_minus_b"] == pytest.approx(((30 - 80) + ((30 + 50) / 2 - 70)) / 2)


def test_a_difference_of_rounding_alone_is_no_difference(tmp_path):
    """Four seeds whose path lengths differ by a few ulps (999.9999999999989 against 1000: the same straight path
    summed another way) and one by 4 cm: the interval of the mean difference ends at 0, which it includes (it
    was [-4, -7e-13], "excluding zero", in the default sweep's report)."""
    from analysis.report import paired_table

    poses = [(0.0, 0.0, 0.0), (50.0, 0.0, 0.0), (100.0, 0.0, 0.0)]
    for seed in range(5):
        for margin in (5.0, 30.0):
            write_log(tmp_path / f"m{margin:g}_s{seed}.mcap", poses, goal=(100.0, 0.0), obstacles=[[], []],
                      meta=meta(setter("planner.safety_margin_cm", margin), seed=seed))
    analysis = analyse_logs([tmp_path])
    df = analysis.episodes.copy()
    a, _ = pd.unique(df["variant"])
    at_a = df["variant"] == a
    df.loc[at_a, "path_length_cm"] = [999.9999999999989 if s else 996.0 for s in df.loc[at_a, "seed"]]
    df.loc[~at_a, "path_length_cm"] = 1000.0
    row = paired_table(df, analysis.grouping).set_index("metric").loc["path_length_cm"]
    assert row["ci_low"] < 0 and row["ci_high"] == 0.0 and not row["excludes_zero"]
    assert row["mean_a_minus_b"] == pytest.approx(-0.8)


@pytest.mark.parametrize(("strategy", "setting", "values", "counted"), [
    ("wait", "planner.h_wait", (1, 2, 3), 1),  # wait does not read h_wait: one episode run three times
    ("none", "planner.safety_margin_cm", (5.0, 15.0), 1),  # the planner is off: none of its settings counts
    ("auto", "planner.h_wait", (1, 2, 3), 3),  # three episodes
])
def test_an_episode_run_again_with_a_setting_it_does_not_read_is_counted_once(tmp_path, strategy, setting, values,
                                                                              counted):
    """``planner=wait planner.h_wait=1,2,3`` ran each seed's episode three times: the groups leave h_wait out for
    wait, so they held 15 episodes of 5 (a Wilson interval of 15)."""
    poses = [(0.0, 0.0, 0.0), (50.0, 0.0, 0.0), (100.0, 0.0, 0.0)]
    for value in values:
        def edit(config, value=value):
            config["planner"]["strategy"] = strategy
            setter(setting, value)(config)

        write_log(tmp_path / f"{strategy}_{value}.mcap", poses, goal=(100.0, 0.0), obstacles=[[], []],
                  meta=meta(edit, seed=3))
    analysis = analyse_logs([tmp_path])
    assert len(analysis.episodes) == counted, analysis.excluded[["log", "kind", "reason"]].to_string()
    assert list(analysis.excluded["kind"]) == ["duplicate"] * (len(values) - counted)


def test_summary_and_metrics_agree_on_success(tmp_path):
    """Logs where the two former definitions disagreed: a goal outcome with a contact seen only in the geometry
    (the simulator's flags and /episode say none), and a goal outcome whose positions never reach the goal."""
    box = [(200, 30), (300, 30), (300, 100), (200, 100)]
    touch = [(100, 0, 0), (150, 0, 0), (200, 15, 0), (230, 0, 0), (400, 0, 0)]
    write_log(tmp_path / "unflagged_touch.mcap", touch, statics=[box], goal=(400.0, 0.0))
    write_log(tmp_path / "flagged_touch.mcap", touch, statics=[box], goal=(400.0, 0.0),
              contacts_static=[False, True, True, False])
    write_log(tmp_path / "short_of_goal.mcap", [(0, 0, 0), (50, 0, 0)], goal=(400.0, 0.0))
    write_log(tmp_path / "clean.mcap", [(0, 0, 0), (50, 0, 0)], goal=(50.0, 0.0))
    write_log(tmp_path / "slow.mcap", [(0, 0, 0), (50, 0, 0)], goal=(400.0, 0.0), outcome="timeout")
    write_log(tmp_path / "raised.mcap", [(0, 0, 0), (50, 0, 0)], outcome="error")
    metrics, _ = metrics_table([tmp_path])
    episodes, table = summarise(tmp_path)
    by_log = dict(zip(metrics["log"].str.rsplit("/", n=1).str[-1], metrics["success"], strict=True))
    assert by_log == {"unflagged_touch.mcap": False, "flagged_touch.mcap": False, "short_of_goal.mcap": False,
                      "clean.mcap": True, "slow.mcap": False}
    summary = episodes.dropna(subset=["success"]).set_index("log")["success"].astype(bool)
    assert summary.to_dict() == metrics.set_index("log")["success"].to_dict()
    assert table["success_rate"].iloc[0] == pytest.approx(1 / 5) and table["left_out"].iloc[0] == 1
    assert episodes.loc[episodes["log"].str.endswith("raised.mcap"), "outcome"].item() == "error"


# -- the real sweep command -----------------------------------------------------------------------------------
MARGINS = ("5", "30")


@pytest.fixture(scope="module")
def margin_sweep(tmp_path_factory):
    """A sweep over a parameter that no list in the code names: head_on, auto and wait, two margins, one seed."""
    out = tmp_path_factory.mktemp("margins")
    res = subprocess.run([sys.executable, "-m", "runners.sweep", "sweep=quick", "scenario=head_on",
                          "planner=auto,wait", f"planner.safety_margin_cm={','.join(MARGINS)}", "episodes=1",
                          f"hydra.sweep.dir={out}", "hydra.launcher.n_jobs=2"],
                         cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    return out, res.stdout


def labels(strategy: str) -> set[str]:
    return {f"{strategy} · safety_margin_cm={m}" for m in MARGINS}


VARIANTS = {f"auto(h=2) · safety_margin_cm={m}" for m in MARGINS} | labels("wait")


def test_sweep_summary_and_report_tables_have_one_row_per_margin(margin_sweep):
    out, stdout = margin_sweep
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 4 and set(summary["variant"]) == VARIANTS
    assert sorted(summary["planner.safety_margin_cm"]) == [5.0, 5.0, 30.0, 30.0]
    printed = [line for line in stdout.splitlines() if line.strip().startswith("head_on")]
    assert len(printed) == 4 and all(sum(v in line for v in VARIANTS) == 1 for line in printed)

    rep = out / "report"
    groups = pd.read_csv(rep / "groups.csv")
    success = groups[groups["metric"] == "success"]
    assert len(success) == 4 and set(success["variant"]) == VARIANTS
    assert sorted(success["planner.safety_margin_cm"]) == [5.0, 5.0, 30.0, 30.0]
    episodes = pd.read_csv(rep / "episodes.csv")
    assert set(episodes["variant"]) == VARIANTS
    # each table's log paths are relative to its own folder: the same logs, seen from the sweep and from report/
    summary["log"] = [str((out / p).resolve()) for p in summary["log"]]
    episodes["log"] = [str((rep / p).resolve()) for p in episodes["log"]]
    merged = summary.merge(episodes, on="log", suffixes=("_summary", "_report"))
    assert len(merged) == 4 and (merged["success_summary"] == merged["success_report"]).all()
    md = (rep / "report.md").read_text()
    for variant in VARIANTS:
        assert f"| head_on    | {variant}" in md
    paired = pd.read_csv(rep / "paired.csv")
    pairs = set(zip(paired["A"], paired["B"], strict=True))
    assert ("auto(h=2) · safety_margin_cm=5", "auto(h=2) · safety_margin_cm=30") in pairs
    assert ("wait · safety_margin_cm=5", "wait · safety_margin_cm=30") in pairs
    assert ("auto(h=2) · safety_margin_cm=5", "wait · safety_margin_cm=30") not in pairs  # two factors at once


def test_sweep_plots_have_one_series_per_margin(margin_sweep, tmp_path, monkeypatch):
    """The report rebuilt from the sweep's logs, looking at every figure instead of saving it (rendering the
    PNGs again would only cost time: the sweep's are checked to be the same files)."""
    out, _ = margin_sweep
    seen: dict[str, dict[str, list[str]]] = {}

    def spy(fig, path):
        ticks = [[t.get_text() for t in a.get_xticklabels() if t.get_text()] for a in fig.axes]
        seen[path.name] = {"legend": [t.get_text() for legend in fig.legends for t in legend.get_texts()],
                           "ticks": next((labels for labels in ticks if labels), []),  # a panel that shows them
                           "titles": [a.get_title().split("\n")[0] for a in fig.axes if a.get_title()],
                           # pictures placed on one sheet (plots.panel_placement): titles as texts, frames as patches
                           "panel titles": [t.get_text().split("\n")[0] for a in fig.axes for t in a.texts],
                           "frames": [p.get_edgecolor() for a in fig.axes for p in a.patches if not p.get_fill()],
                           "colors": {line.get_label(): line.get_color() for a in fig.axes for line in a.get_lines()
                                      if line.get_label() in VARIANTS}}
        plt.close(fig)
        return path

    monkeypatch.setattr(plots, "_save", spy)
    build_report([out], tmp_path / "rep", jobs=1)  # every figure drawn in this process, where the spy sees it
    assert set(seen) == {p.name for p in (out / "report").glob("*.png")}  # the same figures as the sweep's
    assert {"overview.png", "h_wait_effect.png", "box_metrics.png", "trajectories_head_on.png"} <= set(seen)
    series = {f"auto · safety_margin_cm={m}" for m in MARGINS}  # h_wait_effect: auto's line per margin
    for name, figure in seen.items():
        if name.startswith("box_"):
            assert figure["ticks"] == sorted(VARIANTS, key=_natural), name
        elif name.startswith("trajectories_"):  # a panel per group, framed in the group's colour
            assert sorted(figure["panel titles"]) == sorted(VARIANTS), name
            assert len({tuple(c) for c in figure["frames"]}) == len(VARIANTS), name
        elif name == "overview.png":
            assert sorted(figure["legend"]) == sorted(VARIANTS)
            assert len(set(figure["colors"].values())) == len(VARIANTS)  # a colour per group
        elif name == "h_wait_effect.png":
            assert set(figure["legend"]) == VARIANTS | series, figure["legend"]
            assert len(set(figure["colors"].values())) == len(VARIANTS)


def _natural(variant: str) -> tuple:
    """Groups' order: auto before wait, margins by number."""
    strategy, margin = variant.split(" · safety_margin_cm=")
    return (not strategy.startswith("auto"), float(margin))


MISSING = object()  # a key the log's config does not have


@pytest.mark.parametrize("a, b", [(10.0, "10"), (None, MISSING), (True, 1), (False, 0), ("true", True),
                                  ("unset", MISSING), ("null", None), (math.nan, "nan"), ("'10'", "10"),
                                  ("1e3", 1000.0), (10**30, "1" + "0" * 30)])
def test_values_that_differ_are_two_groups_with_two_labels(a, b):
    """Values that print alike are still told apart, and labelled apart (the report groups by label): a number and
    its text, null and a missing key, a boolean and 0/1."""
    def with_margin(value):
        params = runs(meta())[0]
        params.pop("planner.safety_margin_cm")
        return params if value is MISSING else {**params, "planner.safety_margin_cm": value}

    logs = [with_margin(a), with_margin(b)]
    grouping = find_grouping(logs)
    assert "planner.safety_margin_cm" in grouping.dimensions
    labels = {grouping.variant_label(run) for run in logs}
    assert len(labels) == 2, labels


@given(st.lists(st.one_of(st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True),
                          st.text(max_size=30)), min_size=2, max_size=6))
def test_labels_split_exactly_what_the_grouping_tells_apart(values):
    """For any values of one parameter, the variant labels are as many as the values the grouping tells apart: no
    two different values share a group, no value is split in two."""
    from analysis.run_parameters import _hashable

    base = runs(meta())[0]
    logs = [{**base, "planner.safety_margin_cm": v} for v in values]
    grouping = find_grouping(logs)
    labels = {grouping.variant_label(run) for run in logs}
    assert len(labels) == len({_hashable(v) for v in values})
