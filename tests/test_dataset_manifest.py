"""A dataset manifest is checked field by field before any episode runs: each hostile manifest (issue 14) is
refused by ``build`` and ``verify`` with one line ``error: <manifest path>: <field>: <problem>``, exit 2.

The manifests are mutated copies of the committed ``paper_fig5`` manifest (seed 0 only, under a temporary
``--root``); no episode runs."""

from __future__ import annotations

import copy
import functools
import os
import resource
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from runners import dataset
from tests.conftest import ROOT

NAME = "dsx"


@functools.cache
def _paper_fig5() -> dict[str, Any]:
    return yaml.safe_load((dataset.DATASETS / "paper_fig5" / "manifest.yaml").read_text())


def base() -> dict[str, Any]:
    """``paper_fig5`` as dataset ``dsx`` with seed 0 only: its seven episode entries, the log of seed 0 kept."""
    m = copy.deepcopy(_paper_fig5())
    m["name"] = NAME
    m["sweep"]["seeds"] = [0, 1]
    m["keep_logs"] = [0]
    m["episodes"] = {f: e for f, e in m["episodes"].items() if f.endswith("__s0.mcap")}
    assert len(m["episodes"]) == 7
    return m


def write(root: Path, data: dict[str, Any]) -> Path:
    path = root / NAME / "manifest.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(yaml.safe_dump(data, sort_keys=False, width=200))
    return path


def test_the_unmutated_manifest_is_accepted(tmp_path):
    """The base of every case below passes, so each refusal is its mutation's."""
    write(tmp_path, base())
    manifest = dataset.load_manifest(NAME, tmp_path)
    dataset.check_sweep(manifest, dataset.manifest_path(NAME, tmp_path))
    assert len(dataset.jobs(manifest)) == 7


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_the_first_bad_entry_in_the_manifests_order_is_named_when_checked_in_parallel(tmp_path, n_jobs):
    """The sweep's entries are composed on ``n_jobs`` processes; the error is the first bad one's in the manifest's
    order (variants before other scenarios), not the first to finish."""
    data = base()
    data["sweep"]["scenarios"] = ["paper_fig5", "head_on", "no_such_scenario", "corridor", "neither_this_one"]
    data["sweep"]["variants"] = [*data["sweep"]["variants"][:3], "planner.h_wait=-4"]
    write(tmp_path, data)
    manifest = dataset.load_manifest(NAME, tmp_path)
    with pytest.raises(dataset.DatasetError, match=r"manifest\.yaml: sweep\.variants\[3\]: .*h_wait"):
        dataset.check_sweep(manifest, dataset.manifest_path(NAME, tmp_path), n_jobs=n_jobs)
    data["sweep"]["variants"] = data["sweep"]["variants"][:3]
    write(tmp_path, data)
    manifest = dataset.load_manifest(NAME, tmp_path)
    with pytest.raises(dataset.DatasetError, match=r"sweep\.scenarios\[2\]: .*no_such_scenario"):
        dataset.check_sweep(manifest, dataset.manifest_path(NAME, tmp_path), n_jobs=n_jobs)


def test_an_entry_without_the_behaviour_record_is_read(tmp_path):
    """Manifests built before the behaviour record existed hold outcome, steps and digests only."""
    data = base()
    for entry in data["episodes"].values():
        for key in ("decision_digest", "discrete_digest", "modes", "float_sums"):
            del entry[key]
    write(tmp_path, data)
    assert dataset.load_manifest(NAME, tmp_path)["episodes"] == data["episodes"]


def _set(*keys: Any, value: Any) -> Callable[[dict[str, Any]], None]:
    """A mutation setting the field at ``keys`` (the first episode entry for ``"<episode>"``)."""
    def mutate(m: dict[str, Any]) -> None:
        node = m
        for k in keys[:-1]:
            node = node[next(iter(node)) if k == "<episode>" else k]
        node[keys[-1]] = value
    return mutate


def _drop(*keys: str) -> Callable[[dict[str, Any]], None]:
    """A mutation removing the field at ``keys`` (as :func:`_set`)."""
    def mutate(m: dict[str, Any]) -> None:
        node = m
        for k in keys[:-1]:
            node = node[next(iter(node)) if k == "<episode>" else k]
        del node[keys[-1]]
    return mutate


def _both(*mutations: Callable[[dict[str, Any]], None]) -> Callable[[dict[str, Any]], None]:
    """The mutations one after the other."""
    def mutate(m: dict[str, Any]) -> None:
        for each in mutations:
            each(m)
    return mutate


EPISODE = "episodes.paper_fig5__planner-auto_h1__s0.mcap"
CASES = [  # id, mutation, the message after "error: <manifest path>: "
    ("d_version_2", _set("version", value=2),
     "version: 2 is not a manifest version this fuzzynav reads (only 1)"),
    ("version_text", _set("version", value="1"), "version: '1' is not a manifest version this fuzzynav reads"),
    ("version_bool", _set("version", value=True), "version: True is not a manifest version this fuzzynav reads"),
    ("version_missing", _drop("version"), "version: missing (this fuzzynav reads manifest version 1)"),
    ("d_name_mismatch", _set("name", value="other"), "name: 'other' is not the dataset's directory name 'dsx'"),
    ("name_missing", _drop("name"), "name: missing"),
    ("d_unknown_top", _set("zzz", value=1), "zzz: unknown field (allowed: name, description, version, source, sweep, "),
    ("bool_key", _set(True, value=1), "True: unknown field (allowed: "),  # YAML 1.1's ``on:``
    ("unknown_sweep_key", _set("sweep", "seed", value=[0, 1]), "sweep.seed: unknown field (allowed: scenarios, "),
    ("sweep_not_mapping", _set("sweep", value=[1]), "sweep: expected a mapping, got list"),
    ("description_not_text", _set("description", value=["a"]), "description: expected text of at most 10,000 "),
    ("description_long", _set("description", value="x" * 10_001), "description: expected text of at most 10,000 "),
    ("metrics_sha256_short", _set("metrics_sha256", value="abc"),
     "metrics_sha256: expected 64 lowercase hex digits, got 'abc'"),
    ("seeds_bool", _set("sweep", "seeds", value=[False, True]),
     "sweep.seeds: expected [first, end) as two integers, got [False, True]"),
    ("seeds_float", _set("sweep", "seeds", value=[0, 1e12]), "sweep.seeds: expected [first, end) as two integers"),
    ("seeds_one", _set("sweep", "seeds", value=[3]), "sweep.seeds: expected [first, end) as two integers"),
    ("too_many_episodes", _both(_set("sweep", "scenarios", value=["a", "b"]), _set("sweep", "seeds", value=[0, 1072])),
     "sweep: 2 scenarios x 7 variants x 1,072 seeds is 15,008 episodes, more than the limit of 15,000 per dataset"),
    ("d_verify_keep_logs_99", _set("keep_logs", value=[99]),
     "keep_logs[0]: 99 is not a seed of the sweep (sweep.seeds: 0 to 0)"),
    ("keep_logs_negative", _set("keep_logs", value=[0, -1]), "keep_logs[1]: -1 is not a seed of the sweep"),
    ("keep_logs_bool", _set("keep_logs", value=[True]), "keep_logs[0]: True is not a seed of the sweep"),
    ("keep_logs_text", _set("keep_logs", value=["0"]), "keep_logs[0]: '0' is not a seed of the sweep"),
    ("keep_logs_repeated", _set("keep_logs", value=[0, 0]), "keep_logs[1]: repeats seed 0"),
    ("keep_logs_not_list", _set("keep_logs", value=0), "keep_logs: expected a list of seeds, got 0"),
    ("d_verify_extra_field", _set("episodes", "<episode>", "zzz", value=1),
     f"{EPISODE}.zzz: unknown field (allowed: outcome, steps, sha256, "),
    *[(f"entry_without_{key}", _drop("episodes", "<episode>", key),
       f"{EPISODE}.{key}: missing (an entry has outcome, steps, sha256, topics, step_digests)")
      for key in ("outcome", "steps", "sha256", "topics", "step_digests")],
    ("entry_without_modes", _drop("episodes", "<episode>", "modes"),
     f"{EPISODE}.modes: missing (the behaviour record is decision_digest, discrete_digest, modes, float_sums, all "),
    ("int_file_name", _set("episodes", 5, value={}), "episodes: 5: expected a log file name (a string)"),
    ("entry_not_mapping", _set("episodes", "a.mcap", value=[1]), "episodes.a.mcap: expected a mapping, got [1]"),
    ("outcome_unknown", _set("episodes", "<episode>", "outcome", value="won"),
     f"{EPISODE}.outcome: expected one of goal, collision, timeout, error, interrupted, got 'won'"),
    *[(f"steps_{v!r}", _set("episodes", "<episode>", "steps", value=v),
       f"{EPISODE}.steps: expected an integer from 0 to 100,000, got {v!r}") for v in (-1, 100_001, True, "47", 4.5)],
    ("sha256_short", _set("episodes", "<episode>", "sha256", value="abc"),
     f"{EPISODE}.sha256: expected 64 lowercase hex digits, got 'abc'"),
    ("decision_digest_int", _set("episodes", "<episode>", "decision_digest", value=12),
     f"{EPISODE}.decision_digest: expected 16 lowercase hex digits, got 12"),
    ("topics_list", _set("episodes", "<episode>", "topics", value=["/tpt"]),
     f"{EPISODE}.topics: expected a mapping of topic (/...) to 8 hex digits"),
    ("topics_bad_digest", _set("episodes", "<episode>", "topics", value={"/tpt": 5}),
     f"{EPISODE}.topics: expected a mapping of topic (/...) to 8 hex digits"),
    ("step_digests_int", _set("episodes", "<episode>", "step_digests", value=7),
     f"{EPISODE}.step_digests: expected 8 hex digits per step, separated by spaces, got 7"),
    ("step_digests_many", _set("episodes", "<episode>", "step_digests", value=" ".join(["0" * 8] * 100_002)),
     f"{EPISODE}.step_digests: 100,002 steps, more than 100,001"),
    ("modes_unreadable", _set("episodes", "<episode>", "modes", value="direct*x"),
     f"{EPISODE}.modes: expected runs MODE*COUNT separated by spaces, got 'direct*x'"),
    ("modes_huge", _set("episodes", "<episode>", "modes", value="direct*1000000000"),
     f"{EPISODE}.modes: more than 100,001 steps"),
    ("float_sums_odd", _set("episodes", "<episode>", "float_sums", value="/tpt 1.0 /sonar"),
     f"{EPISODE}.float_sums: expected pairs TOPIC SUM separated by spaces, each topic (/...) once"),
    ("float_sums_nan", _set("episodes", "<episode>", "float_sums", value="/tpt nan"),
     f"{EPISODE}.float_sums: 'nan' is not a finite number"),
]


@pytest.mark.parametrize("command", ["build", "verify"])
@pytest.mark.parametrize("mutate, problem", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_a_hostile_manifest_is_refused_in_one_line(tmp_path, capsys, monkeypatch, command, mutate, problem):
    monkeypatch.setattr(dataset, "record_all", lambda *a, **k: pytest.fail("episodes ran"))
    data = base()
    mutate(data)
    path = write(tmp_path, data)
    before = path.read_text()
    code = dataset.main([command, NAME, "--root", str(tmp_path), "--jobs", "1"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1, err
    assert err.startswith(f"error: {path}: {problem}"), err
    assert path.read_text() == before  # build rewrote nothing


@pytest.mark.parametrize("command", ["build", "verify"])
def test_a_manifest_with_a_key_twice_is_refused(tmp_path, capsys, monkeypatch, command):
    """dst_dup_key_sweep: with ``sweep:`` twice the second block won and build rewrote the manifest without the
    first; now the line of the second is named and nothing is rewritten."""
    monkeypatch.setattr(dataset, "record_all", lambda *a, **k: pytest.fail("episodes ran"))
    path = write(tmp_path, base())
    text = path.read_text()
    sweep = yaml.safe_dump({"sweep": base()["sweep"]}, sort_keys=False)
    path.write_text(text + sweep.replace("seeds:\n  - 0\n  - 1", "seeds:\n  - 0\n  - 2"))
    line = text.count("\n") + 1
    before = path.read_text()
    code = dataset.main([command, NAME, "--root", str(tmp_path), "--jobs", "1"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err == f"error: {path}:{line}: top level: duplicate key 'sweep'\n"
    assert path.read_text() == before


def _bounded_memory() -> None:
    """In the child: at most 4 GB of address space, so a manifest read for ever fails instead of filling RAM."""
    resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))


@pytest.mark.parametrize("target", ["/dev/zero", "dir"])
def test_a_manifest_that_is_not_a_regular_file_is_refused(tmp_path, target):
    """dst_manifest_devzero: a manifest linked to /dev/zero was read for ever (RSS growing by ~250 MB/s)."""
    path = tmp_path / NAME / "manifest.yaml"
    path.parent.mkdir()
    if target == "dir":
        (tmp_path / "d").mkdir()
        target = str(tmp_path / "d")
    os.symlink(target, path)
    for command in (["verify", NAME], ["build", NAME], ["list"]):
        done = subprocess.run([sys.executable, "-m", "runners.dataset", *command, "--root", str(tmp_path)],
                              capture_output=True, text=True, timeout=120, cwd=ROOT, preexec_fn=_bounded_memory)
        want = f"{path}: not a regular file"
        if command == ["list"]:  # listed as a dataset that cannot be read
            assert done.returncode == 0 and want in done.stdout and done.stderr == "", done
        else:
            assert done.returncode == 2 and done.stdout == "" and done.stderr == f"error: {want}\n", done
