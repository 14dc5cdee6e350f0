"""The fields of a dataset manifest (``<root>/<name>/manifest.yaml``), their types and ranges.

Every problem is a :class:`DatasetError` whose message is one line ``<manifest path>: <field>: <problem>``,
raised before any episode runs (``runners.dataset`` prints it as ``error: ...`` and exits 2). Whether the sweep's
scenarios, variants and overrides compose as a run config is checked by :func:`runners.dataset.check_sweep`;
this module checks the manifest as data.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fuzzynav import limits

#: the top-level fields of a manifest (README "Datasets"); ``build`` writes ``metrics_sha256`` and ``episodes``
FIELDS = ("name", "description", "version", "sweep", "keep_logs", "metrics_sha256", "episodes")
#: the fields of ``sweep``: scenarios x variants x seeds, plus Hydra overrides for every episode
SWEEP_FIELDS = ("scenarios", "variants", "seeds", "overrides")


class DatasetError(Exception):
    """A manifest is missing or malformed; the message names the file and the field."""


def _check_keys(mapping: dict[Any, Any], allowed: tuple[str, ...], where: str, path: Path) -> None:
    """No field beyond ``allowed``: an unknown one (a misspelt ``keep_log``) was silently ignored and kept."""
    for key in mapping:
        if key not in allowed:
            raise DatasetError(f"{path}: {where}{key!s:.60}: unknown field (allowed: {', '.join(allowed)})")


def check_manifest(data: Any, path: Path, name: str) -> None:
    """Check a parsed manifest of the dataset ``name`` (read from ``path``); :class:`DatasetError` on the first
    problem."""
    if not isinstance(data, dict):
        raise DatasetError(f"{path}: expected a mapping")
    _check_keys(data, FIELDS, "", path)
    # the directory names the dataset (``<root>/<name>/manifest.yaml``): a manifest naming another dataset was
    # built, verified and listed under the directory's name while its own said otherwise
    got = data.get("name")
    if got != name:
        raise DatasetError(f"{path}: name: {got!r:.80} is not the dataset's directory name {name!r} (a dataset "
                           "is <root>/<name>/manifest.yaml)" if "name" in data else f"{path}: name: missing")
    _check_sweep_fields(data.get("sweep"), path)
    _check_episodes(data.get("episodes"), path)


def _check_sweep_fields(sweep: Any, path: Path) -> None:
    """``sweep``: scenarios and variants (non-empty lists) and seeds ``[first, end)``; what the entries mean is
    checked by :func:`runners.dataset.check_sweep`."""
    if not isinstance(sweep, dict):
        raise DatasetError(f"{path}: sweep: missing" if sweep is None else
                           f"{path}: sweep: expected a mapping, got {type(sweep).__name__}")
    _check_keys(sweep, SWEEP_FIELDS, "sweep.", path)
    for key in ("scenarios", "variants", "seeds"):
        if key not in sweep:
            raise DatasetError(f"{path}: sweep.{key}: missing")
    seeds = sweep["seeds"]
    if not (isinstance(seeds, list) and len(seeds) == 2 and all(isinstance(s, int) for s in seeds) and
            seeds[0] < seeds[1]):
        raise DatasetError(f"{path}: sweep.seeds: expected [first, end) as two integers, got {seeds!r}")
    if seeds[0] < 0:
        raise DatasetError(f"{path}: sweep.seeds: {seeds[0]}: seeds are non-negative")
    if seeds[1] - 1 > limits.MAX_SEED:  # a seed beyond 2^53 - 1 is not exact in the analysis' float64 tables
        raise DatasetError(f"{path}: sweep.seeds: end {seeds[1]} is beyond the largest seed {limits.MAX_SEED:,} + 1")
    if seeds[1] - seeds[0] > limits.MAX_EPISODES_PER_RUN:  # [0, 2^53] ran (silently) for ever
        raise DatasetError(f"{path}: sweep.seeds: [{seeds[0]}, {seeds[1]}) is {seeds[1] - seeds[0]:,} seeds, more than "
                           f"the limit of {limits.MAX_EPISODES_PER_RUN:,} per scenario and variant")
    for key in ("scenarios", "variants"):
        if not isinstance(sweep[key], list) or not sweep[key]:
            raise DatasetError(f"{path}: sweep.{key}: expected a non-empty list")


def _check_episodes(episodes: Any, path: Path) -> None:
    """The recorded episodes, if any: a mapping of log file name to a mapping holding at least its SHA-256 (a
    wrong type would otherwise surface as a traceback after every episode has been regenerated)."""
    if episodes is None:
        return
    if not isinstance(episodes, dict):
        raise DatasetError(f"{path}: episodes: expected a mapping of log file names, got {type(episodes).__name__}")
    for file, entry in episodes.items():
        if not isinstance(entry, dict):
            raise DatasetError(f"{path}: episodes.{file}: expected a mapping, got {entry!r:.40}")
        if not isinstance(entry.get("sha256"), str):
            raise DatasetError(f"{path}: episodes.{file}.sha256: missing or not a string")
