"""The fields of a dataset manifest (``<root>/<name>/manifest.yaml``), their types and ranges.

Every problem is a :class:`DatasetError` whose message is one line ``<manifest path>: <field>: <problem>``,
raised before any episode runs (``runners.dataset`` prints it as ``error: ...`` and exits 2). Whether the sweep's
scenarios, variants and overrides compose as a run config is checked by :func:`runners.dataset.check_sweep`;
this module checks the manifest as data.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

from analysis.log_check import OUTCOMES
from fuzzynav.params import limits

VERSION = 1  # of the manifest's layout, which build writes and verify reads
#: the top-level fields of a manifest (README "Datasets"); ``build`` writes ``metrics_columns`` (one digest per
#: metrics column) and ``episodes``; ``metrics_sha256`` (the whole table) is read from manifests built before;
#: ``source``: the recordings a dataset is built from (:mod:`runners.datasets.recorded_source`)
FIELDS = ("name", "description", "version", "source", "sweep", "keep_logs", "metrics_sha256", "metrics_columns",
          "episodes")
#: the fields of ``sweep``: scenarios x variants x seeds, plus Hydra overrides for every episode
SWEEP_FIELDS = ("scenarios", "variants", "seeds", "overrides")

#: what ``build`` writes for each episode besides ``step_digests`` (:func:`runners.dataset.content_digests`)
EPISODE_FIELDS = ("outcome", "steps", "sha256", "decision_digest", "discrete_digest", "modes", "float_sums", "topics")
ENTRY_FIELDS = (*EPISODE_FIELDS, "step_digests")
#: the fields every entry has; the behaviour record (:class:`runners.logs.fields.BehaviourRecord`) is newer
ENTRY_REQUIRED = ("outcome", "steps", "sha256", "topics", "step_digests")
BEHAVIOUR_RECORD = ("decision_digest", "discrete_digest", "modes", "float_sums")
DIGEST = re.compile(r"[0-9a-f]{8}")
MODE_RUN = re.compile(r"(\S+)\*([1-9][0-9]{0,9})")  # a mode and how many steps in a row it was decided
MAX_LOG_TIMES = limits.MAX_STEPS + 1  # steps 0 to max_steps
#: episodes per dataset: a built manifest holds about 1.3 kB per episode, and one of more than
#: :data:`fuzzynav.params.limits.MAX_MANIFEST_BYTES` (about 15,000 episodes) could not be read back
MAX_EPISODES = 15_000


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
    # first: another version may have other fields, and its episodes would be compared as this version's
    version = data.get("version")
    if "version" not in data:
        raise DatasetError(f"{path}: version: missing (this fuzzynav reads manifest version {VERSION})")
    if not (isinstance(version, int) and not isinstance(version, bool) and version == VERSION):
        raise DatasetError(f"{path}: version: {version!r:.40} is not a manifest version this fuzzynav reads "
                           f"(only {VERSION})")
    _check_keys(data, FIELDS, "", path)
    # the directory names the dataset (``<root>/<name>/manifest.yaml``): a manifest naming another dataset was
    # built, verified and listed under the directory's name while its own said otherwise
    got = data.get("name")
    if got != name:
        raise DatasetError(f"{path}: name: {got!r:.80} is not the dataset's directory name {name!r} (a dataset "
                           "is <root>/<name>/manifest.yaml)" if "name" in data else f"{path}: name: missing")
    description = data.get("description", "")
    if not (isinstance(description, str) and len(description) <= limits.MAX_TEXT_CHARS):
        raise DatasetError(f"{path}: description: expected text of at most {limits.MAX_TEXT_CHARS:,} characters, "
                           f"got {description!r:.40}")
    digest = data.get("metrics_sha256")
    if digest is not None and not (isinstance(digest, str) and re.fullmatch("[0-9a-f]{64}", digest)):
        raise DatasetError(f"{path}: metrics_sha256: expected 64 lowercase hex digits, got {digest!r:.70}")
    columns = data.get("metrics_columns")
    if columns is not None:
        if not isinstance(columns, dict):
            raise DatasetError(f"{path}: metrics_columns: expected a mapping of metrics column to digest")
        for column, value in columns.items():
            if not (isinstance(column, str) and isinstance(value, str) and re.fullmatch("[0-9a-f]{16}", value)):
                raise DatasetError(f"{path}: metrics_columns: {column!s:.60}: expected 16 lowercase hex digits, "
                                   f"got {value!r:.40}")
    _check_sweep_fields(data.get("sweep"), path)
    _check_keep_logs(data.get("keep_logs"), data["sweep"]["seeds"], path)
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
    if not (isinstance(seeds, list) and len(seeds) == 2 and
            all(isinstance(s, int) and not isinstance(s, bool) for s in seeds) and
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
    episodes = len(sweep["scenarios"]) * len(sweep["variants"]) * (seeds[1] - seeds[0])
    if episodes > MAX_EPISODES:  # 1,000 scenarios x 1,000 variants x 10,000 seeds: a few lines, 1e10 episodes
        raise DatasetError(f"{path}: sweep: {len(sweep['scenarios']):,} scenarios x {len(sweep['variants']):,} "
                           f"variants x {seeds[1] - seeds[0]:,} seeds is {episodes:,} episodes, more than the "
                           f"limit of {MAX_EPISODES:,} per dataset")


def _check_keep_logs(keep: Any, seeds: list[int], path: Path) -> None:
    """``keep_logs``: the seeds (of ``sweep.seeds``, each once) whose logs ``build`` keeps in ``<name>/logs/``; a
    seed outside the sweep kept nothing without a word."""
    if keep is None:
        return
    if not isinstance(keep, list):
        raise DatasetError(f"{path}: keep_logs: expected a list of seeds, got {keep!r:.60}")
    for i, seed in enumerate(keep):
        if not (isinstance(seed, int) and not isinstance(seed, bool) and seeds[0] <= seed < seeds[1]):
            raise DatasetError(f"{path}: keep_logs[{i}]: {seed!r:.40} is not a seed of the sweep (sweep.seeds: "
                               f"{seeds[0]} to {seeds[1] - 1})")
        if seed in keep[:i]:
            raise DatasetError(f"{path}: keep_logs[{i}]: repeats seed {seed}")


def _check_episodes(episodes: Any, path: Path) -> None:
    """The recorded episodes, if any: a mapping of log file name to its entry (:func:`_check_entry`). A wrong
    or missing value would otherwise surface as a traceback after every episode has been regenerated."""
    if episodes is None:
        return
    if not isinstance(episodes, dict):
        raise DatasetError(f"{path}: episodes: expected a mapping of log file names, got {type(episodes).__name__}")
    for file, entry in episodes.items():
        if not isinstance(file, str):  # sorting int and str file names was a traceback
            raise DatasetError(f"{path}: episodes: {file!r:.60}: expected a log file name (a string)")
        _check_entry(entry, f"episodes.{file}", path)


def _check_entry(entry: Any, where: str, path: Path) -> None:
    """One episode entry as ``build`` writes it (:data:`ENTRY_FIELDS`); an entry without the behaviour record
    (:data:`BEHAVIOUR_RECORD`, from manifests built before it existed) is read too."""
    if not isinstance(entry, dict):
        raise DatasetError(f"{path}: {where}: expected a mapping, got {entry!r:.40}")
    _check_keys(entry, ENTRY_FIELDS, f"{where}.", path)
    for key in ENTRY_REQUIRED:
        if key not in entry:
            raise DatasetError(f"{path}: {where}.{key}: missing (an entry has {', '.join(ENTRY_REQUIRED)})")
    record = [k for k in BEHAVIOUR_RECORD if k in entry]
    if record and len(record) < len(BEHAVIOUR_RECORD):  # each is read with the others (a KeyError otherwise)
        key = next(k for k in BEHAVIOUR_RECORD if k not in entry)
        raise DatasetError(f"{path}: {where}.{key}: missing (the behaviour record is {', '.join(BEHAVIOUR_RECORD)}, "
                           "all or none)")

    def fail(key: str, problem: str) -> NoReturn:
        raise DatasetError(f"{path}: {where}.{key}: {problem}, got {entry[key]!r:.60}")

    if entry["outcome"] not in OUTCOMES:
        fail("outcome", f"expected one of {', '.join(OUTCOMES)}")
    steps = entry["steps"]
    if not (isinstance(steps, int) and not isinstance(steps, bool) and 0 <= steps <= limits.MAX_STEPS):
        fail("steps", f"expected an integer from 0 to {limits.MAX_STEPS:,}")
    for key, digits in (("sha256", 64), ("decision_digest", 16), ("discrete_digest", 16)):
        if key in entry and not (isinstance(entry[key], str) and re.fullmatch(f"[0-9a-f]{{{digits}}}", entry[key])):
            fail(key, f"expected {digits} lowercase hex digits")
    topics = entry["topics"]
    if not (isinstance(topics, dict) and all(isinstance(t, str) and t.startswith("/") and isinstance(d, str) and
                                             DIGEST.fullmatch(d) for t, d in topics.items())):
        fail("topics", "expected a mapping of topic (/...) to 8 hex digits")
    words = entry["step_digests"].split() if isinstance(entry["step_digests"], str) else None
    if words is None or not all(DIGEST.fullmatch(w) for w in words):
        fail("step_digests", "expected 8 hex digits per step, separated by spaces")
    elif len(words) > MAX_LOG_TIMES:
        fail("step_digests", f"{len(words):,} steps, more than {MAX_LOG_TIMES:,}")
    if record:
        _check_record(entry, fail)


def _check_record(entry: dict[str, Any], fail: Callable[[str, str], NoReturn]) -> None:
    """The behaviour record's run-length encoded modes and float sums, in the form their readers
    (:func:`runners.logs.fields.expand_runs`, :func:`runners.logs.fields.parse_sums`) take."""
    runs = [MODE_RUN.fullmatch(w) for w in entry["modes"].split()] if isinstance(entry["modes"], str) else [None]
    if not all(runs):
        fail("modes", "expected runs MODE*COUNT separated by spaces")
    # expanded when a decision differs: modes: direct*1000000000000 was a MemoryError after every episode ran
    elif sum(int(m.group(2)) for m in runs if m) > MAX_LOG_TIMES:
        fail("modes", f"more than {MAX_LOG_TIMES:,} steps")
    words = entry["float_sums"].split() if isinstance(entry["float_sums"], str) else ["?"]
    topics, sums = words[0::2], words[1::2]
    if len(topics) != len(sums) or not all(t.startswith("/") for t in topics) or len(set(topics)) < len(topics):
        fail("float_sums", "expected pairs TOPIC SUM separated by spaces, each topic (/...) once")
    for text in sums:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            fail("float_sums", f"{text!r:.40} is not a finite number")
