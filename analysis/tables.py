"""The report's tables as CSV and as Parquet (pyarrow), side by side.

``episodes.parquet``, ``groups.parquet`` and ``paired.parquet`` hold what ``episodes.csv``, ``groups.csv`` and
``paired.csv`` hold, with column types kept (CSV turns a boolean into text and NaN into an empty field) and, in the
file's key-value metadata:

- ``fuzzynav.schema_version``: :data:`SCHEMA_VERSION`, raised when a column is renamed, removed or changes meaning
  (adding a column does not raise it);
- ``fuzzynav.table``: ``episodes``, ``groups`` or ``paired``;
- ``fuzzynav.units``: JSON object column -> unit (:func:`analysis.metrics.column_unit`; ``""`` for labels, counts
  and ratios). In ``groups`` the ``mean``, ``ci_low`` and ``ci_high`` columns, in ``paired`` the ``mean_a_minus_b``,
  ``ci_low`` and ``ci_high`` columns are in the unit of the row's metric: ``fuzzynav.metric_units`` maps each metric
  to its unit.

Each column's unit is also in its Arrow field metadata (``unit``), so tools that show field metadata see it.

A ``log`` column (in these tables, ``failures.csv``, ``left_out.csv`` and a sweep's ``summary.csv``) holds each
log's path relative to the folder of the table (:func:`relative_log`).
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from analysis.deferred import deferred
from analysis.metrics import column_unit

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)
pa = deferred("pyarrow")

SCHEMA_VERSION = "2"
#: units of the groups table's own columns (``mean``/``ci_low``/``ci_high``: the unit of the row's metric)
GROUP_UNITS = {"metric": "", "n": "episodes", "mean": "unit of metric", "ci_low": "unit of metric",
               "ci_high": "unit of metric", "interval": ""}
#: units of the paired table's own columns (the difference and its interval: the unit of the row's metric)
PAIRED_UNITS = {"A": "", "B": "", "metric": "", "pairs": "seeds", "mean_a_minus_b": "unit of metric",
                "ci_low": "unit of metric", "ci_high": "unit of metric", "excludes_zero": ""}
TABLE_UNITS = {"groups": GROUP_UNITS, "paired": PAIRED_UNITS}


def _units(df: pd.DataFrame, extra: dict[str, str]) -> dict[str, str]:
    """Unit of each column of ``df`` (``""`` for a label or a column without a unit)."""
    return {str(c): extra[str(c)] if str(c) in extra else column_unit(str(c)) for c in df.columns}


def _arrow_ready(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` with each object column Arrow cannot type (a group label that is a number in one row and text in
    another) as text, missing values kept missing: the CSV writes such a column as text too."""
    out = df
    for column in [c for c in df.columns if pd.api.types.is_object_dtype(df[c])]:
        try:
            pa.array(df[column], from_pandas=True)
        except (pa.ArrowInvalid, pa.ArrowTypeError):
            out = out.copy() if out is df else out
            out[column] = [None if v is None or (isinstance(v, float) and v != v) else str(v) for v in df[column]]
    return out


def write_parquet(df: pd.DataFrame, path: Path, table: str, extra_metadata: dict[str, str] | None = None) -> None:
    """Write ``df`` to ``path`` as Parquet with the schema version, the table name and each column's unit in the
    file metadata (see the module docstring)."""
    units = _units(df, TABLE_UNITS.get(table, {}))
    arrow = pa.Table.from_pandas(_arrow_ready(df), preserve_index=False)
    fields = [f.with_metadata({"unit": units.get(f.name, "")}) for f in arrow.schema]
    metadata = {**(arrow.schema.metadata or {}), b"fuzzynav.schema_version": SCHEMA_VERSION.encode(),
                b"fuzzynav.table": table.encode(), b"fuzzynav.units": json.dumps(units).encode()}
    metadata.update({k.encode(): v.encode() for k, v in (extra_metadata or {}).items()})
    import pyarrow.parquet as pq

    # Encoded in memory, written by Python: a full disk is then an OSError with its errno and strerror ("No space
    # left on device"), not Arrow's own message without them. The tables are small (kilobytes per thousand rows).
    sink = pa.BufferOutputStream()
    pq.write_table(arrow.cast(pa.schema(fields, metadata=metadata)), sink)
    Path(path).write_bytes(sink.getvalue().to_pybytes())


def _metric_units(table: pd.DataFrame) -> dict[str, str]:
    """``fuzzynav.metric_units`` of a table of one row per metric: each metric's unit (``success``: ``""``)."""
    units = {m: column_unit(str(m)) for m in table["metric"].unique()} if "metric" in table else {}
    return {"fuzzynav.metric_units": json.dumps(units)}


def relative_log(log: str, folder: Path) -> str:
    """``log`` (a path as the analysis read it: absolute, or relative to the working directory) relative to
    ``folder``, where the table naming it is written: a table's log paths open from the table's own folder,
    whichever folder the sweep or report was started from, and stay valid when the sweep's folder is moved whole.
    Absolute where no relative path exists (another drive)."""
    try:
        return os.path.relpath(os.path.abspath(log), os.path.abspath(folder))
    except ValueError:
        return os.path.abspath(log)


def with_relative_logs(df: pd.DataFrame, folder: Path) -> pd.DataFrame:
    """``df`` with its ``log`` column (if any) relative to ``folder`` (:func:`relative_log`)."""
    if "log" not in df.columns or df.empty:
        return df
    return df.assign(log=[relative_log(str(p), folder) for p in df["log"]])


def write_tables(out: Path, episodes: pd.DataFrame, groups: pd.DataFrame, paired: pd.DataFrame | None = None,
                 logs_from: Path | None = None) -> None:
    """``episodes``/``groups``/``paired`` (when given) as ``.csv`` and ``.parquet`` in ``out``; log paths relative
    to ``logs_from`` (the folder the tables end up in, when ``out`` is where they are built; default ``out``)."""
    episodes = with_relative_logs(episodes, logs_from or out)
    episodes.to_csv(out / "episodes.csv", index=False)
    groups.to_csv(out / "groups.csv", index=False)
    write_parquet(episodes, out / "episodes.parquet", "episodes")
    write_parquet(groups, out / "groups.parquet", "groups", _metric_units(groups))
    if paired is not None:
        paired.to_csv(out / "paired.csv", index=False)
        write_parquet(paired, out / "paired.parquet", "paired", _metric_units(paired))


def read_units(path: Path) -> dict[str, str]:
    """Column -> unit of a Parquet table written by :func:`write_parquet`."""
    import pyarrow.parquet as pq

    return json.loads(pq.read_schema(path).metadata[b"fuzzynav.units"])
