"""Crowds in the analysis: the TPT's prediction error per obstacle model (from real logs) and the density table."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from analysis.density import count_key, density_table
from analysis.metrics import column_unit, metrics_table
from analysis.report import tpt_error_table
from analysis.tpt_errors import STANDING_MODELS, model_columns, models_of_columns
from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.pedestrians.base import MODELS
from fuzzynav.scenarios.scenario import scenario_from_dict
from runners.run import run_episode
from tests.conftest import ROOT


def _mixed_scenario():
    return scenario_from_dict({
        "name": "mixed_models", "bounds": [0, 0, 1200, 800],
        "robot": {"start": [100, 400], "heading": 0, "goal": [1100, 400], "radius": 20},
        "dynamic_obstacles": [
            {"id": "scripted_one", "radius": 20, "start": [600, 150], "velocity": [0, 20]},
            {"id": "pedestrian", "radius": 20, "waypoints": [[750, 700], [750, 100]], "speed": 25,
             "model": "social_force"}],
        "max_steps": 120})


@pytest.fixture(scope="module")
def mixed_log(tmp_path_factory, table1):
    path = tmp_path_factory.mktemp("crowd") / "mixed.mcap"
    cfg = episode_config_from_dict({"perception": {"mode": "ground_truth"}, "planner": {"strategy": "auto"},
                                    "terminate_on_collision": False})
    run_episode(_mixed_scenario(), FastEvaluator(table1), cfg, 0, path, "")
    return path


def test_tpt_errors_are_split_by_the_obstacles_models(mixed_log):
    row = metrics_table([str(mixed_log)])[0].iloc[0]
    # ground truth and a constant-velocity scripted obstacle: the TPT's prediction is exact
    assert row["tpt_ade_cm_scripted"] == pytest.approx(0.0, abs=1e-6)
    # the pedestrian slows down, turns and avoids: the constant-velocity prediction is off
    assert row["tpt_ade_cm_social_force"] > 1.0
    assert row["tpt_fde_cm_social_force"] >= row["tpt_ade_cm_social_force"] * 0.5
    assert math.isnan(row["tpt_ade_cm_orca"]) and math.isnan(row["tpt_ade_cm_random_walk"])
    # the overall error lies between the models' (a mean of both sets of errors)
    assert row["tpt_ade_cm_scripted"] <= row["tpt_ade_cm"] <= row["tpt_ade_cm_social_force"]


def _plugin_scenario():
    return scenario_from_dict({
        "name": "plugin_model", "bounds": [0, 0, 1200, 800],
        "robot": {"start": [100, 400], "heading": 0, "goal": [1100, 400], "radius": 20},
        "dynamic_obstacles": [
            {"id": "walker", "radius": 20, "start": [750, 650], "velocity": [0, -25], "model": "test_plugin_walk"}],
        "max_steps": 80})


def test_a_model_from_outside_fuzzynav_has_its_own_columns(mixed_log, tmp_path, table1, monkeypatch):
    """A model that is not one of fuzzynav's built-ins (here: the random walk registered under another name, as a
    plug-in would be) gets its own TPT error columns from the logs that name it, NaN in the other logs' rows; the
    built-in models' columns stay in every row (the datasets' manifests hash them)."""
    monkeypatch.setitem(MODELS, "test_plugin_walk", MODELS["random_walk"])
    cfg = episode_config_from_dict({"perception": {"mode": "ground_truth"}, "planner": {"strategy": "auto"},
                                    "terminate_on_collision": False})
    plugin_log = tmp_path / "plugin.mcap"
    run_episode(_plugin_scenario(), FastEvaluator(table1), cfg, 1, plugin_log, "")  # not the mixed log's identity
    table, left_out = metrics_table([str(mixed_log), str(plugin_log)])
    assert left_out.empty, left_out.to_dict("records")
    assert models_of_columns(table.columns) == [*STANDING_MODELS, "test_plugin_walk"]
    assert column_unit("tpt_ade_cm_test_plugin_walk") == column_unit("tpt_fde_cm_test_plugin_walk") == "cm"
    plugin, mixed = (table.set_index("log").loc[str(log)] for log in (plugin_log, mixed_log))
    assert plugin["tpt_ade_cm_test_plugin_walk"] > 0 and plugin["tpt_ade_cm"] == plugin["tpt_ade_cm_test_plugin_walk"]
    assert math.isnan(mixed["tpt_ade_cm_test_plugin_walk"]) and math.isnan(mixed["tpt_fde_cm_test_plugin_walk"])
    assert all(math.isnan(plugin[f"tpt_ade_cm_{m}"]) for m in STANDING_MODELS)
    by_model = tpt_error_table(table.assign(scenario_label=["mixed", "plugin"], variant="auto"))
    assert "test_plugin_walk" in set(by_model["obstacle model"])


def test_model_columns_of_a_row():
    """The built-in models' columns always, other models' by name; a name no model can have gets none."""
    row = model_columns({"social_force": (3.0, 4.0), "zeta": (1.0, 2.0), "Not A Name": (5.0, 6.0)}, ["alpha"])
    assert models_of_columns(row) == [*STANDING_MODELS, "alpha", "zeta"]
    assert row["tpt_ade_cm_social_force"] == 3.0 and row["tpt_fde_cm_zeta"] == 2.0
    assert math.isnan(row["tpt_ade_cm_alpha"]) and math.isnan(row["tpt_fde_cm_orca"])


def test_density_table_lines_up_groups_without_pooling():
    rows = []
    for n, successes in ((5, [1, 1, 1, 1]), (20, [1, 0, 0, 0])):
        for seed, ok in enumerate(successes):
            for variant in ("auto(h=2)", "none"):
                rows.append({"scenario": "crowd_crossing", "scenario.params.n": n, "variant": variant,
                             "success": bool(ok) if variant != "none" else False,
                             "min_clearance_dynamic_cm": 10.0 * n + seed})
    df = pd.DataFrame(rows)
    assert count_key(df) == "scenario.params.n"
    table = density_table(df)
    assert len(table) == 4 and set(table["episodes"]) == {4}
    auto20 = table[(table["variant"] == "auto(h=2)") & (table["pedestrians"] == 20)].iloc[0]
    assert auto20["success"] == 0.25 and auto20["success_lo"] < 0.25 < auto20["success_hi"]
    assert auto20["min_clearance_dynamic_cm"] == pytest.approx(np.mean([200, 201, 202, 203]))
    assert count_key(df[df["scenario.params.n"] == 5]) is None
    # another differing scenario parameter (the pedestrians' model) is its own line, never pooled
    two_models = pd.concat([df.assign(**{"scenario.params.model": "social_force"}),
                            df.assign(**{"scenario.params.model": "orca"})])
    lines = density_table(two_models)
    assert len(lines) == 8 and set(lines["episodes"]) == {4}
    assert set(lines["scenario"]) == {"crowd_crossing · model=social_force", "crowd_crossing · model=orca"}


def test_a_crowd_density_sweep_runs_and_reports(tmp_path):
    """The issue's command, small: two crowd densities x two strategies, one seed; the report lines the densities
    up and tabulates the TPT's error for the social-force pedestrians."""
    out = subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=crowd_crossing",
                          "scenario.params.n=2,4", "planner=auto,none", "episodes=1", "scenario.params.max_steps=60",
                          f"hydra.sweep.dir={tmp_path}", "hydra.launcher.n_jobs=2"],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert len(summary) == 4
    report = (tmp_path / "report" / "report.md").read_text()
    assert "## Crowd density" in report and "## TPT prediction error by obstacle model" in report
    assert "social_force" in report
    density = pd.read_csv(tmp_path / "report" / "density.csv")
    assert sorted(set(density["pedestrians"])) == [2, 4] and set(density["episodes"]) == {1}
    assert (tmp_path / "report" / "density.png").stat().st_size > 0


def test_foxglove_shows_a_reactive_pedestrian_with_its_heading(mixed_log):
    from analysis.logs import iter_messages

    arrows: dict[str, list] = {"obstacle/scripted_one": [], "obstacle/pedestrian": []}
    for _, _, msg in iter_messages(mixed_log, ["/scene"]):
        for ent in msg["entities"]:
            if ent["id"] in arrows:
                arrows[ent["id"]].append(ent["arrows"])
    assert arrows["obstacle/pedestrian"] and all(len(a) == 1 for a in arrows["obstacle/pedestrian"][:5])
    # scripted obstacles are drawn as before models existed (their logs unchanged): a disc, no arrow
    assert arrows["obstacle/scripted_one"] and not any(arrows["obstacle/scripted_one"])
