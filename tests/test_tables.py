"""The report's Parquet tables hold what its CSV tables hold, with the schema version and each column's unit."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq

from analysis.metrics import COLUMN_UNITS, STANDARD_METRICS
from analysis.report import build_report
from analysis.report import main as report_main
from analysis.tables import SCHEMA_VERSION, read_units, write_parquet
from tests.handmade import write_log


def test_parquet_tables_equal_the_csv_tables_and_carry_units(tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    for seed in range(3):
        for offset in (0, 1):  # two variants (h_wait 2 and 3), distinct paths: identical logs count once
            line = [(0, 0, 0), (25, offset, 0), (50, 0, 0), (75, offset, 0), (100, 0, 0)]
            write_log(logs / f"h{offset}_{seed}.mcap", line[: 3 + seed], goal=(100.0, 0.0), tolerance=20.0 + offset,
                      meta={"seed": str(seed), "h_wait": str(2 + offset),
                            "config": f"dt: 1.0\nplanner:\n  h_wait: {2 + offset}\n"},
                      outcome="goal" if seed == 2 else "timeout")
    out = tmp_path / "report"
    build_report([logs], out)
    for table in ("episodes", "groups", "paired"):
        csv_text = (out / f"{table}.csv").read_text()
        frame = pd.read_parquet(out / f"{table}.parquet")
        assert frame.to_csv(index=False) == csv_text  # same columns, rows and values, to the last digit
        meta = pq.read_schema(out / f"{table}.parquet").metadata
        assert meta[b"fuzzynav.schema_version"].decode() == SCHEMA_VERSION
        assert meta[b"fuzzynav.table"].decode() == table
    episodes = pd.read_parquet(out / "episodes.parquet")
    assert set(STANDARD_METRICS) <= set(episodes.columns) and len(episodes) == 6
    assert episodes["success"].dtype == bool  # typed, not text
    units = read_units(out / "episodes.parquet")
    assert list(units) == list(episodes.columns)
    assert units["spl"] == "" and units["jerk_max_cm_s3"] == "cm/s^3" and units["min_ttc_s"] == "s"
    assert pq.read_schema(out / "episodes.parquet").field("path_length_cm").metadata == {b"unit": b"cm"}
    groups = pd.read_parquet(out / "groups.parquet")
    assert set(STANDARD_METRICS) <= set(groups["metric"])
    metric_units = json.loads(pq.read_schema(out / "groups.parquet").metadata[b"fuzzynav.metric_units"])
    assert metric_units["accel_mean_cm_s2"] == COLUMN_UNITS["accel_mean_cm_s2"] == "cm/s^2"
    assert read_units(out / "groups.parquet")["mean"] == "unit of metric"
    paired = pd.read_parquet(out / "paired.parquet")
    assert len(paired) > 0 and paired["excludes_zero"].dtype == bool
    assert read_units(out / "paired.parquet")["mean_a_minus_b"] == "unit of metric"
    paired_units = json.loads(pq.read_schema(out / "paired.parquet").metadata[b"fuzzynav.metric_units"])
    assert paired_units["path_length_cm"] == "cm" and set(paired_units) == set(paired["metric"])
    assert "paired.parquet" in (out / "report.md").read_text()
    for table in ("episodes", "groups", "paired"):  # identifiers: usable as SQL and pandas attribute names
        assert all(re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.]*", str(c)) for c in pd.read_parquet(
            out / f"{table}.parquet").columns), table
    # the rate of each outcome beside the success rate: 2 timeouts of 3 per variant, no collision
    rates = groups[groups["metric"].isin(["success", "collision_rate", "timeout_rate"])]
    assert rates.groupby("metric")["mean"].agg(lambda x: sorted(x.round(4))).to_dict() == {
        "collision_rate": [0.0, 0.0], "success": [0.3333, 0.3333], "timeout_rate": [0.6667, 0.6667]}
    assert set(rates["interval"]) == {"wilson"}
    md = (out / "report.md").read_text()
    assert "collision rate [95% Wilson]" in md and "timeout rate [95% Wilson]" in md
    # log paths relative to the table's folder, built in a temporary folder or not
    assert all((out / p).resolve() == (logs / Path(p).name).resolve() for p in episodes["log"])


def test_log_paths_are_relative_to_the_tables_folder_from_any_working_directory(tmp_path, monkeypatch):
    logs = tmp_path / "sweep" / "0"
    logs.mkdir(parents=True)
    write_log(logs / "a.mcap", [(0, 0, 0), (25, 0, 0), (50, 0, 0)], goal=(50.0, 0.0), meta={"seed": "0"})
    monkeypatch.chdir(tmp_path / "sweep")
    assert report_main(["0", "--out", "rep", "--jobs", "1"]) == 0
    for table in ("episodes.csv", "failures.csv", "left_out.csv"):
        frame = pd.read_csv(tmp_path / "sweep" / "rep" / table)
        assert all(p == "../0/a.mcap" for p in frame.get("log", [])), (table, list(frame.get("log", [])))
    assert list(pd.read_csv(tmp_path / "sweep" / "rep" / "episodes.csv")["log"]) == ["../0/a.mcap"]


def test_a_column_of_numbers_and_text_is_written_as_text(tmp_path):
    df = pd.DataFrame({"variant": [1, "a", None], "path_length_cm": [1.0, float("nan"), 3.0]})
    write_parquet(df, tmp_path / "t.parquet", "episodes")
    back = pd.read_parquet(tmp_path / "t.parquet")
    assert back["variant"].tolist()[:2] == ["1", "a"] and back["variant"].isna().tolist() == [False, False, True]
    assert back.to_csv(index=False) == df.to_csv(index=False)
