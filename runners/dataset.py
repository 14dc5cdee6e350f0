"""Recorded datasets: named, versioned collections of episode logs that anyone can regenerate and verify.

    python -m runners.dataset list
    python -m runners.dataset build paper_fig5          # record every episode, write the hashes
    python -m runners.dataset verify paper_fig5         # regenerate and compare; exit 1 on any difference
    python -m runners.dataset verify paper_fig5 planner.safety_margin_cm=12   # what a behaviour change breaks
    python -m runners.dataset verify paper_fig5 --seeds 0:3 --detail           # every differing numeric field

A dataset is ``datasets/<name>/manifest.yaml`` (``--root DIR``: ``DIR/<name>/manifest.yaml``): the sweep that
produces it (scenarios × variants × seeds, plus overrides for all runs, as Hydra overrides of
``conf/config.yaml``) and, once built, for each episode the SHA-256 of its message content (every topic and
field except the timing field ``compute_time_us``; metadata excluded: it holds versions and the git commit),
a short digest per topic and per step (so that a difference can be located without the original logs), the
behaviour record of :class:`runners.logs.fields.BehaviourRecord` (digests of the decision/plan/outcome values
and of all non-float values, the decision mode per step, the sum of each topic's floats), and the SHA-256 of
the metrics table (compute-time columns excluded). ``keep_logs`` lists the seeds whose logs are committed in
``datasets/<name>/logs/``.

``verify`` says for each differing episode whether a decision, plan or outcome changed, only other discrete
values (perception, predictions), or only floating-point values, with the largest absolute difference per
topic and field: measured message by message against a committed log, else classified from the manifest's
behaviour record (in manifests built before it existed, only a changed outcome or step count is classified).

Metrics are hashed per column (``metrics_columns``: column -> 16-hex digest of its values, episodes in file-name
order): a column added since the build is reported as a new metric and passes (behaviour did not change), a
column whose values changed or that is no longer computed fails, named. Manifests built before that have one
``metrics_sha256`` of the whole table; verify compares it and says to rebuild to hash per column.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd
import yaml

from analysis.cli_args import MAX_JOBS, OneLineParser
from analysis.cli_args import jobs as cli_jobs
from analysis.logs import LogError
from analysis.metrics import metrics_table
from fuzzynav.params import limits
from runners.configuration.data_files import MANIFEST, SAFE_LOADER, DataFileError, check_data_file
from runners.datasets import recorded_source
from runners.datasets.episode_recording import (
    content_digests,
    forget_assembled,
    prepare_assembly,
    record_episode,
    resolved_config_json,
)
from runners.datasets.manifest import EPISODE_FIELDS, FIELDS, DatasetError, check_manifest
from runners.datasets.verify_report import detail_lines, episode_line, summary_lines
from runners.logs.diff import EpisodeDiff, diff_logs, diff_records

ROOT = Path(__file__).resolve().parents[1]
DATASETS = ROOT / "datasets"  # the default place of datasets; ``--root`` (tests: a temporary directory) changes it


# -- the manifest -------------------------------------------------------------------------------------------
def manifest_path(name: str, root: Path = DATASETS) -> Path:
    return root / name / "manifest.yaml"


def load_manifest(name: str, root: Path = DATASETS) -> dict[str, Any]:
    """The manifest of dataset ``name`` under ``root``, read as data and checked field by field
    (:func:`runners.datasets.manifest.check_manifest`); :class:`DatasetError` naming the file and field."""
    path = manifest_path(name, root)
    if not path.exists():
        known = ", ".join(sorted(p.parent.name for p in root.glob("*/manifest.yaml"))) or "none"
        raise DatasetError(f"{path}: no such dataset (known: {known})")
    try:
        # a manifest is data, like a scenario file: a regular file (a link to /dev/zero was read for ever) of
        # bounded size, no tags (!!python/... would be one traceback or worse), no interpolations, bounded
        # aliases, no key twice; one line naming the line and the field
        raw = check_data_file(path, MANIFEST)
        data = yaml.load(raw, Loader=SAFE_LOADER)
    except DataFileError as err:
        raise DatasetError(str(err)) from None
    except yaml.YAMLError as err:
        raise DatasetError(f"{path}: not valid YAML ({str(err).splitlines()[0]})") from None
    check_manifest(data, path, name)
    recorded_source.check_source(data.get("source"), path)
    return data


def _variant_overrides(variant: Any) -> list[str]:
    """A variant's overrides: one string or a list of them."""
    return [variant] if isinstance(variant, str) else list(variant)


def _override_key(text: str) -> str:
    """The key (config value or group) an override sets: ``planner`` of ``planner=auto``, ``+a.b`` -> ``a.b``."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    (override,) = OverridesParser.create().parse_overrides([text])
    return override.get_key_element().lstrip("+~")


#: the run-config keys a dataset decides itself, and why an override of one is refused: each was silently
#: ignored or overridden (``seed=5``, ``episodes=3``: every episode still ran its sweep.seeds seed) while its
#: text was recorded in the manifest, or it silently replaced what the episode's name says (``scenario=...``)
DATASET_KEYS = {
    "hydra": "hydra settings are not allowed in a dataset (the dataset decides where its episodes run)",
    "seed": "set by the dataset (each episode's seed is one of sweep.seeds; verify --seeds FIRST:END checks some)",
    "episodes": "set by the dataset (each episode is one seed of sweep.seeds)",
    "resume": "set by the dataset (every episode is recorded afresh)",
    "scenario": "set by the dataset (sweep.scenarios lists its scenarios; scenario.FIELD=VALUE changes one field)",
    "sweep": "a sweep preset is no part of a dataset (sweep.scenarios, sweep.variants and sweep.seeds are its sweep)",
}


def _check_override(text: Any, where: str) -> None:
    """One override (``where``: the manifest and its field, or the command line) is a single ``key=value`` of the
    run config, of no key the dataset decides itself (:data:`DATASET_KEYS`).

    A sweep list (``planner=auto,wait``) would be a multirun inside one episode job (Hydra's traceback), and a
    ``hydra.*`` key is no part of the episode: it was silently ignored while its text became part of the log's
    file name (``hydra.run.dir=/tmp/x``)."""
    from hydra.core.override_parser.overrides_parser import OverridesParser

    if not isinstance(text, str):
        raise DatasetError(f"{where}: expected an override key=value (a string), got {text!r:.60}")
    try:
        (override,) = OverridesParser.create().parse_overrides([text])
    except Exception as err:  # Hydra's parser errors have several types and lines
        raise DatasetError(f"{where}: cannot read {text!r:.60}: {str(err).splitlines()[0]}") from None
    key = override.get_key_element().lstrip("+~")
    if override.is_sweep_override():
        raise DatasetError(f"{where}: {text!r:.60} is a sweep; a dataset runs one value per variant "
                           "(list each value as its own variant)")
    # ``hydra.run.dir``, ``hydra/launcher``, ``scenario@x``: the first part of the key or group path
    top = re.split(r"[./@]", key, maxsplit=1)[0]
    if top == "hydra" or (top in DATASET_KEYS and re.fullmatch(rf"{top}(@.*)?", key)):
        raise DatasetError(f"{where}: {key:.60}: {DATASET_KEYS[top]}")


def check_sweep(manifest: dict[str, Any], path: Path, extra: list[str] | None = None,
                search: list[str] | None = None, n_jobs: int = 1) -> None:
    """Check the manifest's sweep before any episode runs (one line naming the field): every override is one
    ``key=value`` of the run config (see :func:`_check_override`), every scenario a name, and each scenario,
    variant, override and ``extra`` override composes and validates (:func:`runners.configuration.precheck.precheck`, as
    ``runners.run`` checks its command line) with the first scenario, variant and seed. Otherwise a bad entry
    was a traceback from every worker. ``search``: overrides every composition needs (the configuration folder of
    a dataset built from recordings, :mod:`runners.datasets.recorded_source`), not the manifest's. ``n_jobs``:
    processes that compose the entries in parallel (each ~0.3 s; -1: every core); the first failure in the order
    above is still the one reported."""

    sweep = manifest["sweep"]
    common = sweep.get("overrides") or []
    if not isinstance(common, list):
        raise DatasetError(f"{path}: sweep.overrides: expected a list")
    for i, name in enumerate(sweep["scenarios"]):
        if not (isinstance(name, str) and limits.NAME_PATTERN.fullmatch(name)):
            raise DatasetError(f"{path}: sweep.scenarios[{i}]: {name!r:.60} is not a scenario name")
    for i, variant in enumerate(sweep["variants"]):
        if not isinstance(variant, str | list):
            raise DatasetError(f"{path}: sweep.variants[{i}]: expected an override or a list of them")
        parts = _variant_overrides(variant)
        for k, text in enumerate(parts):
            _check_override(text, f"{path}: sweep.variants[{i}]" + (f"[{k}]" if len(parts) > 1 else ""))
    for i, text in enumerate(common):
        _check_override(text, f"{path}: sweep.overrides[{i}]")
    for text in extra or []:
        _check_override(text, "command line")
    _check_repeats(sweep, path)
    # a key set by a variant and by the common overrides: the latter won silently, so episodes named
    # planner-auto ran planner=wait
    variant_keys = {_override_key(t) for v in sweep["variants"] for t in _variant_overrides(v)}
    for i, text in enumerate(common):
        if (key := _override_key(text)) in variant_keys:
            raise DatasetError(f"{path}: sweep.overrides[{i}]: {key} is also set by the variants")
    extra = extra or []
    first = [f"seed={sweep['seeds'][0]}"]
    scenarios, variants = sweep["scenarios"], [_variant_overrides(v) for v in sweep["variants"]]

    # in this order each check adds one entry to entries already found good, so the first failure is that entry's
    trials = [(f"{path}: sweep.scenarios[0]", [f"scenario={scenarios[0]}", *first])]
    trials += [(f"{path}: sweep.variants[{i}]", [f"scenario={scenarios[0]}", *parts, *first])
               for i, parts in enumerate(variants)]
    trials += [(f"{path}: sweep.overrides[{i}]", [f"scenario={scenarios[0]}", *variants[0], *common[:i + 1], *first])
               for i in range(len(common))]
    # the command line's: the precheck's message names the override's key
    trials += [("", [f"scenario={scenarios[0]}", *variants[0], *common, *extra[:i + 1], *first])
               for i in range(len(extra))]
    trials += [(f"{path}: sweep.scenarios[{i}]", [f"scenario={name}", *variants[0], *common, *extra, *first])
               for i, name in enumerate(scenarios[1:], start=1)]
    workers = effective_workers(n_jobs, len(trials))  # (one pool for both checks: loky keeps its processes)
    refused = _first_refused(trials, search or [], workers)
    if refused is not None:
        where, problem = refused
        raise DatasetError(f"{where}: {problem.removeprefix('config: ')}" if where else problem)
    _check_distinct_variants(path, [*(search or []), f"scenario={scenarios[0]}"], variants, [*common, *extra, *first],
                             workers)


def _first_refused(trials: list[tuple[str, list[str]]], search: list[str], workers: int) -> tuple[str, str] | None:
    """(where, problem) of the first of ``trials`` (where, overrides) whose overrides after ``search``
    :func:`runners.configuration.precheck.precheck` refuses, or None: the first alone (a manifest broken from its
    first entry fails at once, without starting workers), then the others on ``workers`` processes, looked at in
    order."""
    import warnings

    from runners.configuration.precheck import precheck

    overrides = [[*search, *o] for _, o in trials]
    if not overrides:
        return None
    problem = precheck(overrides[0])
    if problem:
        return trials[0][0], problem
    if workers < 2 or len(overrides) < 3:
        for (where, _), o in zip(trials[1:], overrides[1:], strict=True):
            if problem := precheck(o):
                return where, problem
        return None
    from joblib import Parallel, delayed

    # (as many workers as the recording that follows: loky hands it the same processes)
    problems = Parallel(n_jobs=workers, return_as="generator")(delayed(precheck)(o) for o in overrides[1:])
    try:
        for (where, _), problem in zip(trials[1:], problems, strict=True):
            if problem:
                return where, problem
        return None
    finally:
        with warnings.catch_warnings():  # joblib's note that the checks after the failing one were not needed
            warnings.filterwarnings("ignore", category=UserWarning, module="joblib")
            problems.close()


def _check_repeats(sweep: dict[str, Any], path: Path) -> None:
    """A scenario or variant listed twice ran its episodes twice and kept one, without a word."""
    for key in ("scenarios", "variants"):
        seen: dict[str, int] = {}
        for i, entry in enumerate(sweep[key]):
            text = json.dumps(entry)
            if text in seen:
                raise DatasetError(f"{path}: sweep.{key}[{i}]: repeats sweep.{key}[{seen[text]}]")
            seen[text] = i


def _check_distinct_variants(path: Path, before: list[str], variants: list[list[str]], after: list[str],
                             workers: int = 1) -> None:
    """Two variants composing the same configuration (planner=auto and planner=auto_h2) made the same episodes
    under two names; the build failed after running them all, naming temporary files. The variants' configs are
    composed on ``workers`` processes."""
    if len(variants) < 2:
        return
    todo = [[*before, *parts, *after] for parts in variants]
    if workers > 1:
        from joblib import Parallel, delayed

        texts = Parallel(n_jobs=workers)(delayed(resolved_config_json)(o) for o in todo)
    else:
        texts = [resolved_config_json(o) for o in todo]
    seen: dict[str, int] = {}
    for i, text in enumerate(texts):
        if text in seen:
            raise DatasetError(f"{path}: sweep.variants[{i}]: the same configuration as sweep.variants[{seen[text]}]")
        seen[text] = i


def jobs(manifest: dict[str, Any]) -> list[dict[str, Any]]:
    """One job per episode: its Hydra overrides and its log file name (``_search``: the overrides every composition
    of a dataset built from recordings needs, set by :func:`runners.datasets.recorded_source.prepare`)."""
    sweep = manifest["sweep"]
    common = [str(o) for o in sweep.get("overrides") or []]
    out = []
    for scenario in sweep["scenarios"]:
        for variant in sweep["variants"]:
            extra = _variant_overrides(variant)
            for seed in range(*sweep["seeds"]):
                overrides = [*manifest.get("_search", []), f"scenario={scenario}", *extra, *common, f"seed={seed}"]
                tag = "__".join(o.replace("=", "-").replace("/", "-") for o in [*extra])
                out.append({"overrides": overrides, "file": f"{scenario}__{tag}__s{seed}.mcap", "seed": seed})
    return out


# -- content hashes ---------------------------------------------------------------------------------------
def dataset_metrics(paths: Iterable[Path]) -> pd.DataFrame:
    """The metrics table of a dataset's logs, one row per episode in the order of the log file names, compute
    times excluded (they are timings, not behaviour); ``log`` holds the file name, not its location."""
    df, bad = metrics_table(list(paths))
    if not bad.empty:
        raise DatasetError("metrics: logs could not be analysed: " + "; ".join(bad["reason"]))
    df = df.drop(columns=[c for c in df.columns if c.startswith("compute_time")])
    df["log"] = [Path(p).name for p in df["log"]]
    return df.sort_values("log", kind="stable").reset_index(drop=True)


def metrics_digest(table: pd.DataFrame) -> str:
    """SHA-256 of the whole metrics table as manifests before per-column hashing recorded it (``metrics_sha256``):
    kept to verify those manifests."""
    df = table.drop(columns=["log"]).sort_values(["scenario", "strategy", "h_wait", "controller", "perception",
                                                  "seed"])
    return hashlib.sha256(df.round(9).to_csv(index=False).encode()).hexdigest()


def metrics_column_digests(table: pd.DataFrame) -> dict[str, str]:
    """Per metrics column (``log`` excluded), 16 hex digits of the SHA-256 of its values (floats rounded to 9
    decimals, as text) in the table's episode order: a column can be added without changing the others'."""
    rounded = table.drop(columns=["log"]).round(9)
    return {column: hashlib.sha256(rounded[column].to_csv(index=False, header=False).encode()).hexdigest()[:16]
            for column in rounded.columns}


def compare_metrics(manifest: dict[str, Any], table: pd.DataFrame, name: str) -> tuple[list[str], list[str]]:
    """(problems, notes) of the regenerated metrics table against the manifest: a changed or removed column is a
    problem naming it, a new column a note naming it (behaviour did not change: the episodes matched)."""
    rebuild = f"python -m runners.dataset build {name}"
    recorded = manifest.get("metrics_columns")
    if recorded is None:
        old = manifest.get("metrics_sha256")
        if old is None:
            return [], [f"the manifest records no metrics digests (to record them: {rebuild})"]
        if metrics_digest(table) == old:
            return [], ["the metrics table matches the manifest's metrics_sha256; metrics are now hashed per column "
                        f"(a new metric then needs no rebuild): run {rebuild}"]
        return [f"metrics table differs from the manifest's metrics_sha256, one digest of the whole table (built "
                f"before metrics were hashed per column), so no column can be named; every episode matched, so "
                f"behaviour is unchanged: if a metric was added, record a digest per column with {rebuild}"], []
    now = metrics_column_digests(table)
    problems = [f"metrics column {c}: values differ from the manifest ({recorded[c]} -> {now[c]})"
                for c in recorded if c in now and now[c] != recorded[c]]
    problems += [f"metrics column {c}: in the manifest but no longer computed" for c in recorded if c not in now]
    new = [c for c in now if c not in recorded]
    notes = [f"new metrics, not in the manifest: {', '.join(new)} (behaviour unchanged; to record them: "
             f"{rebuild})"] if new else []
    return problems, notes


# -- recording --------------------------------------------------------------------------------------------
def effective_workers(n_jobs: int, n_episodes: int) -> int:
    """Worker processes for ``n_episodes``: ``--jobs`` (-1: every core), at most one per episode and per core
    (``--jobs 300`` for one episode started 300 workers, hung and left them behind when killed)."""
    cores = os.cpu_count() or 1
    wanted = cores if n_jobs == -1 else n_jobs
    return max(1, min(wanted, n_episodes, cores))


def record_all(manifest: dict[str, Any], out_dir: Path, n_jobs: int = -1, desc: str = "episodes",
               assemble: bool = False) -> list[dict]:
    """Record every episode of the dataset into ``out_dir`` in parallel, with a progress bar. ``assemble``: make the
    episodes' configs from a few composed ones where that gives Hydra's config
    (:func:`runners.datasets.episode_recording.run_config`)."""
    from joblib import Parallel, delayed

    from runners.progress import EpisodeProgress

    out_dir.mkdir(parents=True, exist_ok=True)
    todo = jobs(manifest)
    results = []
    workers = effective_workers(n_jobs, len(todo))
    with tempfile.TemporaryDirectory(prefix="fuzzynav-configs-") as shared:
        state = Path(shared) / "configs.pickle"
        with EpisodeProgress(len(todo), desc) as progress:
            token = prepare_assembly(todo, workers, state) if assemble else None
            for res in Parallel(n_jobs=workers, return_as="generator")(
                    delayed(record_episode)(j, str(out_dir), token, str(state)) for j in todo):
                results.append(res)
                progress.update(1)
        forget_assembled()  # (this process's, when it recorded: one worker)
    return sorted(results, key=lambda r: r["file"])


def build(name: str, n_jobs: int = -1, root: Path = DATASETS, source: Path | None = None,
          notes: list[str] | None = None) -> dict[str, Any]:
    """Record the dataset and write the hashes into its manifest; keep the logs of the ``keep_logs`` seeds.
    ``source``: the folder of the recordings a dataset with a ``source`` field is built from (their SHA-256 go into
    the manifest; :mod:`runners.datasets.recorded_source`); what was left out is appended to ``notes``."""
    original = load_manifest(name, root)
    keep = set(original.get("keep_logs") or [])
    log_dir = root / name / "logs"
    with tempfile.TemporaryDirectory(prefix=f"fuzzynav-{name}-") as tmp:
        manifest, search, said = recorded_source.prepare(original, manifest_path(name, root), source,
                                                         Path(tmp) / "conf", building=True)
        (notes if notes is not None else []).extend(said)
        check_sweep(manifest, manifest_path(name, root), search=search, n_jobs=n_jobs)
        manifest["_search"] = search
        results = record_all(manifest, Path(tmp), n_jobs, desc=f"build {name}")
        manifest.pop("metrics_sha256", None)  # the whole-table digest of older manifests: now one per column
        manifest["metrics_columns"] = metrics_column_digests(dataset_metrics(sorted(Path(tmp).glob("*.mcap"))))
        if log_dir.exists():
            shutil.rmtree(log_dir)
        kept = [j["file"] for j in jobs(manifest) if j["seed"] in keep]
        if kept:
            log_dir.mkdir(parents=True)
            for file in kept:
                shutil.copy(Path(tmp) / file, log_dir / file)
    manifest["episodes"] = {r["file"]: {**{k: r[k] for k in EPISODE_FIELDS},
                                        "step_digests": " ".join(r["step_digests"])} for r in results}
    manifest["sweep"] = original["sweep"]  # the scenes, not the scenarios made of them
    manifest = {k: manifest[k] for k in FIELDS if k in manifest}  # the fields in their documented order
    manifest_path(name, root).write_text(yaml.safe_dump(manifest, sort_keys=False, width=200))
    return manifest


def _locate(expected: dict[str, Any], got: dict[str, Any]) -> str:
    """Without the original log: first differing step from the step digests, differing topics."""
    old = expected.get("step_digests", "").split()
    new = got["step_digests"]
    step = next((k for k, (a, b) in enumerate(zip(old, new, strict=False)) if a != b), min(len(old), len(new)))
    topics = [t for t in sorted(set(expected.get("topics", {})) | set(got["topics"]))
              if expected.get("topics", {}).get(t) != got["topics"].get(t)]
    return f"first differing step {step}; differing topics: {', '.join(topics) or '-'}"


def parse_seeds(text: str) -> tuple[int, int]:
    """``FIRST:END`` of ``--seeds`` as (first, end); :class:`DatasetError` naming the option if malformed or
    empty."""
    try:
        first, end = (int(x) for x in text.split(":"))
    except ValueError:
        raise DatasetError(f"--seeds: expected FIRST:END (two integers, END excluded), got {text!r}") from None
    if first < 0:  # seeds are non-negative (numpy's); -1:1 silently verified seed 0 only
        raise DatasetError(f"--seeds {text}: FIRST must be 0 or more (seeds are non-negative)")
    if first >= end:
        raise DatasetError(f"--seeds {text}: selects no seed (FIRST must be below END)")
    return first, end


@dataclass
class Verification:
    """What ``verify`` found: ``problems`` as (episode file or "", one-line text), the classified difference of
    each differing episode, and how many episodes were compared."""

    problems: list[tuple[str, str]] = field(default_factory=list)
    diffs: dict[str, EpisodeDiff] = field(default_factory=dict)
    compared: int = 0
    seeds: tuple[int, int] | None = None  # the seeds actually checked (``--seeds`` clipped to the dataset's)
    notes: list[str] = field(default_factory=list)  # said whether or not it passed: new metrics, an old manifest


def _select_seeds(manifest: dict[str, Any], seeds: tuple[int, int], path: Path) -> tuple[int, int]:
    """Restrict the manifest to the seeds in ``[first, end)`` and return the seeds kept (those of the dataset);
    an error if that leaves no episode."""
    have = manifest["sweep"]["seeds"]
    first, end = max(seeds[0], have[0]), min(seeds[1], have[1])
    if first >= end:
        raise DatasetError(f"--seeds {seeds[0]}:{seeds[1]}: selects no episode ({path} has seeds {have[0]}:{have[1]})")
    wanted = {j["file"] for j in jobs(manifest) if first <= j["seed"] < end}
    manifest["sweep"]["seeds"] = [first, end]
    manifest["episodes"] = {f: e for f, e in manifest["episodes"].items() if f in wanted}
    return first, end


def verify(name: str, overrides: list[str] | None = None, n_jobs: int = -1, seeds: tuple[int, int] | None = None,
           root: Path = DATASETS, source: Path | None = None) -> Verification:
    """Regenerate the dataset (optionally with extra overrides, or only the seeds in ``[first, end)``) and
    classify every difference (no problems = ok). The metrics-table hash is checked on full verifications only.
    ``source``: the recordings of a dataset with a ``source`` field, checked against its SHA-256 first."""
    manifest = load_manifest(name, root)
    path = manifest_path(name, root)
    if not manifest.get("episodes"):
        hint = " --source DIR" if "source" in manifest else ""
        raise DatasetError(f"{path}: episodes: missing (run: python -m runners.dataset build {name}{hint})")
    log_dir = root / name / "logs"
    with tempfile.TemporaryDirectory(prefix=f"fuzzynav-{name}-") as tmp:
        manifest, search, _ = recorded_source.prepare(manifest, path, source, Path(tmp) / "conf", building=False)
        # a bad entry or override is one line before any episode runs (not a traceback from every worker)
        check_sweep(manifest, path, overrides, search=search, n_jobs=n_jobs)
        manifest["_search"] = search
        if overrides:
            manifest["sweep"]["overrides"] = [*(manifest["sweep"].get("overrides") or []), *overrides]
        checked = _select_seeds(manifest, seeds, path) if seeds is not None else None
        out = Verification(compared=len(manifest["episodes"]), seeds=checked)
        results = {r["file"]: r for r in record_all(manifest, Path(tmp), n_jobs, desc=f"verify {name}",
                                                          assemble=True)}
        for file, expected in sorted(manifest["episodes"].items()):
            got = results.get(file)
            if got is None:
                out.problems.append((file, f"{file}: not produced by the sweep"))
                continue
            if got["sha256"] == expected["sha256"]:
                # the same log: the manifest's own summary of it must agree too (steps 999 verified as matching)
                wrong = [f"{k} {expected[k]!r} -> {got[k]!r}" for k in ("outcome", "steps")
                         if k in expected and expected[k] != got[k]]
                if wrong:
                    out.problems.append((file, f"{file}: same content, but the manifest entry differs from the "
                                               f"regenerated episode: {', '.join(wrong)}"))
                continue
            recorded = log_dir / file
            if recorded.exists():  # the committed log: every message and field is compared
                diff = diff_logs(recorded, Path(tmp) / file)
                location = ("first difference: topic {} at step {}".format(*diff.first_message) if diff.first_message
                            else "the messages are equal: only their encoding differs")
            else:
                diff = diff_records(expected, got)
                location = _locate(expected, got)
            out.diffs[file] = diff
            out.problems.append((file, episode_line(file, expected, got, diff, location)))
        for file in sorted(set(results) - set(manifest["episodes"])):
            out.problems.append((file, f"{file}: produced but not in the manifest"))
        for file, expected in sorted(manifest["episodes"].items()):
            problem = committed_log_problem(log_dir / file, expected["sha256"])
            if problem:
                out.problems.append((file, f"{file}: the committed log {problem}"))
        if not out.problems and seeds is None:
            problems, out.notes = compare_metrics(manifest, dataset_metrics(sorted(Path(tmp).glob("*.mcap"))), name)
            out.problems.extend(("", text) for text in problems)
    return out


def committed_log_problem(path: Path, sha256: str) -> str | None:
    """What is wrong with a dataset's committed log ``path``, or None: it is the episode the manifest records (the
    content digest ``sha256``) and passes every check of the analysis (a replaced, damaged or edited log was never
    looked at while the regenerated episode matched the manifest). None too when the dataset commits no log of this
    episode."""
    if not os.path.lexists(path):
        return None
    if path.is_symlink() or not path.is_file():
        return f"{path} is not a regular file"
    from analysis.episode_log import load_episode

    try:
        load_episode(path)  # the metadata (its config_hash), the scenario, the messages together
        digest = content_digests(path)["sha256"]
    except (LogError, OSError) as err:
        return f"cannot be read: {' '.join(str(err).split())[:300]}"
    if digest != sha256:
        return (f"{path} is not the episode the manifest records (the SHA-256 of its messages differs: damaged, edited "
                "or replaced; python -m runners.dataset build writes it again)")
    return None


def check_root(root: Path) -> None:
    """``--root`` is an existing directory: a mistyped one listed nothing, exit 0."""
    if not root.exists():
        raise DatasetError(f"--root {root}: no such directory")
    if not root.is_dir():
        raise DatasetError(f"--root {root}: not a directory")


def list_datasets(root: Path = DATASETS) -> list[dict[str, Any]]:
    rows = []
    for path in sorted(root.glob("*/manifest.yaml")):
        name = path.parent.name
        try:
            m = load_manifest(name, root)
        except DatasetError as err:
            rows.append({"name": name, "error": str(err)})
            continue
        logs = list((path.parent / "logs").glob("*.mcap"))
        # a dataset of recordings runs each scene once per window (its own windows, or the dataset's)
        scenes = m["sweep"]["scenarios"]
        episodes = len(jobs(m))
        if "source" in m:
            episodes = episodes // max(len(scenes), 1) * sum(recorded_source.scene_windows(m["source"], s)
                                                             for s in scenes)
        rows.append({"name": name, "episodes": episodes, "built": bool(m.get("episodes")),
                     "committed_logs": len(logs), "logs_MB": round(sum(p.stat().st_size for p in logs) / 1e6, 2),
                     "description": m.get("description", "")})
    return rows


def _print_verification(name: str, result: Verification, detail: bool) -> None:
    print(f"{name}: {len(result.problems)} difference(s):")
    for file, text in result.problems:
        print(f"  {text}")
        if detail and file in result.diffs:
            for line in detail_lines(result.diffs[file]):
                print(f"      {line}")
    if result.diffs:
        for line in summary_lines(result.diffs, result.compared):
            print(f"{name}: {line}")


def main(argv: list[str] | None = None) -> int:
    # one line per bad argument, as analysis.report (the subcommands' parsers are of the same class)
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    lister = sub.add_parser("list", help="datasets with episode counts and sizes")
    b = sub.add_parser("build", help="record a dataset and write its hashes")
    b.add_argument("name")
    v = sub.add_parser("verify", help="regenerate and compare with the recorded hashes")
    v.add_argument("name")
    v.add_argument("overrides", nargs="*", help="extra Hydra overrides (to see what a behaviour change breaks)")
    v.add_argument("--seeds", help="only seeds FIRST:END (a quick partial check; skips the metrics hash)")
    v.add_argument("--detail", action="store_true",
                   help="under each differing episode, every differing numeric field with its largest |Δ|")
    for p in (b, v):
        p.add_argument("--jobs", type=cli_jobs, default=-1,
                       help=f"parallel workers: -1 (default: all cores) or 1 to {MAX_JOBS}")
        p.add_argument("--source", type=Path, help="the folder of your copy of the recordings a dataset is built "
                                                   "from (eth_ucy_v1: docs/recordings.md)")
    for p in (lister, b, v):
        p.add_argument("--root", type=Path, default=DATASETS,
                       help="directory holding the datasets (default: datasets/ of the repository)")
    # overrides may follow the options (``verify tiny --root DIR planner.h_wait=3``): argparse leaves those it
    # meets after an option unparsed, and parse_intermixed_args refuses parsers with subcommands
    args, rest = parser.parse_known_args(argv)
    if args.command == "verify":
        args.overrides += [a for a in rest if not a.startswith("-")]
        rest = [a for a in rest if a.startswith("-")]
    if rest:
        parser.error(f"unrecognized arguments: {' '.join(rest)}")
    try:
        check_root(args.root)
        if args.command == "list":
            rows = list_datasets(args.root)
            if not rows:  # an empty listing said nothing of where it looked
                print(f"no datasets in {args.root}")
            for row in rows:
                if "error" in row:
                    print(f"{row['name']:<12} error: {row['error']}")
                    continue
                print(f"{row['name']:<12} {row['episodes']:>5} episodes  built={row['built']!s:<5} "
                      f"committed logs: {row['committed_logs']} ({row['logs_MB']} MB)  {row['description']}")
            return 0
        if args.command == "build":
            notes: list[str] = []
            m = build(args.name, args.jobs, args.root, args.source, notes)
            for note in notes:
                print(f"{args.name}: {note}")
            print(f"built {args.name}: {len(m['episodes'])} episodes; hashes in {manifest_path(args.name, args.root)}")
            return 0
        seeds = parse_seeds(args.seeds) if args.seeds is not None else None
        result = verify(args.name, args.overrides, args.jobs, seeds, args.root, args.source)
    except (DatasetError, LogError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    for note in result.notes:
        print(f"{args.name}: {note}")
    if result.problems:
        _print_verification(args.name, result, args.detail)
        return 1
    if result.seeds is None:
        print(f"{args.name}: all episodes and the metrics table of the dataset match")
        return 0
    first, end = result.seeds
    # the seeds checked, not those asked: --seeds 0:9007199254740993 checked 0:20 and claimed all of them
    note = "" if (first, end) == seeds else f" (--seeds {args.seeds}: the dataset has only these)"
    print(f"{args.name}: seeds {first}:{end} of the dataset match{note}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
