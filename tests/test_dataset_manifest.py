"""A dataset manifest is checked field by field before any episode runs: each hostile manifest (issue 14) is
refused by ``build`` and ``verify`` with one line ``error: <manifest path>: <field>: <problem>``, exit 2.

The manifests are mutated copies of the committed ``paper_fig5`` manifest (seed 0 only, under a temporary
``--root``); no episode runs."""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from runners import dataset

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


EPISODE = "episodes.paper_fig5__planner-auto_h1__s0.mcap"
CASES = [  # id, mutation, the message after "error: <manifest path>: "
    ("d_name_mismatch", _set("name", value="other"), "name: 'other' is not the dataset's directory name 'dsx'"),
    ("name_missing", _drop("name"), "name: missing"),
    ("d_unknown_top", _set("zzz", value=1), "zzz: unknown field (allowed: name, description, version, sweep, "),
    ("bool_key", _set(True, value=1), "True: unknown field (allowed: "),  # YAML 1.1's ``on:``
    ("unknown_sweep_key", _set("sweep", "seed", value=[0, 1]), "sweep.seed: unknown field (allowed: scenarios, "),
    ("sweep_not_mapping", _set("sweep", value=[1]), "sweep: expected a mapping, got list"),
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
