"""Datasets built from the user's copy of pedestrian recordings (issue #38 item 3): ``runners.dataset build NAME
--source DIR`` records each input file's SHA-256 in the manifest and ``verify`` checks them; on small recordings
the test writes in ETH's obsmat format (fuzzynav ships no recording)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from runners import dataset
from runners.datasets.manifest import DatasetError
from runners.datasets.recorded_source import check_source
from tests.conftest import ROOT
from tests.test_recorded import crossing_file

MANIFEST = {
    "name": "tiny_rec", "version": 1, "description": "two windows of a synthetic recording",
    "source": {"scenes": {"plaza": {"file": ["seq_plaza/obsmat.txt", "plaza/obsmat.txt"]},
                          "hall": {"file": "hall/obsmat.txt", "max_gap": 1}},
               "params": {"duration_s": 20, "path_length": 600, "max_steps": 20}, "windows": [0, 1]},
    "sweep": {"scenarios": ["plaza", "hall"], "variants": ["navigator=fuzzy_tpt"], "seeds": [0, 1], "overrides": []},
    "keep_logs": []}


def run(*args):
    return subprocess.run([sys.executable, "-m", "runners.dataset", *args, "--jobs", "1"], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)


@pytest.fixture()
def setup(tmp_path):
    root, source = tmp_path / "datasets", tmp_path / "copy"
    (root / "tiny_rec").mkdir(parents=True)
    (root / "tiny_rec" / "manifest.yaml").write_text(yaml.safe_dump(MANIFEST, sort_keys=False))
    (source / "plaza").mkdir(parents=True)
    crossing_file(source / "plaza" / "obsmat.txt", people=6, frames=150)  # no hall/: the user lacks that scene
    return root, source


def test_build_records_the_files_sha256_and_verify_checks_them(setup):
    root, source = setup
    built = run("build", "tiny_rec", "--root", str(root), "--source", str(source))
    assert built.returncode == 0, built.stdout + built.stderr[-2000:]
    assert "scene hall: none of" in built.stdout and "left out" in built.stdout
    m = dataset.load_manifest("tiny_rec", root)
    import hashlib
    assert m["source"]["sha256"] == {"plaza": hashlib.sha256((source / "plaza" / "obsmat.txt").read_bytes())
                                     .hexdigest()}
    assert sorted(m["episodes"]) == ["plaza_w0__navigator-fuzzy_tpt__s0.mcap", "plaza_w1__navigator-fuzzy_tpt__s0.mcap"]
    assert m["sweep"]["scenarios"] == ["plaza", "hall"]  # the definition is kept as written
    ok = run("verify", "tiny_rec", "--root", str(root), "--source", str(source))
    assert ok.returncode == 0 and "all episodes and the metrics table of the dataset match" in ok.stdout, \
        ok.stdout + ok.stderr[-2000:]
    # another copy of the recording (one coordinate changed): refused before anything runs, naming the file
    path = source / "plaza" / "obsmat.txt"
    path.write_text(path.read_text().replace("0.0000000e+00", "1.0000000e-03", 1))
    changed = run("verify", "tiny_rec", "--root", str(root), "--source", str(source))
    assert changed.returncode == 2 and f"error: {path}: sha256 " in changed.stderr
    assert "is not the manifest's" in changed.stderr and len(changed.stderr.strip().splitlines()) == 1
    missing = run("verify", "tiny_rec", "--root", str(root))
    assert missing.returncode == 2 and "source: this dataset is built from recordings" in missing.stderr


def test_a_dataset_of_recordings_needs_its_source(setup, tmp_path):
    root, _ = setup
    res = run("build", "tiny_rec", "--root", str(root), "--source", str(tmp_path / "nowhere"))
    assert res.returncode == 2 and "--source" in res.stderr and "not a directory" in res.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    res = run("build", "tiny_rec", "--root", str(root), "--source", str(empty))
    assert res.returncode == 2 and "none of the scenes' files is there" in res.stderr
    res = run("verify", "tiny_rec", "--root", str(root), "--source", str(empty))
    assert res.returncode == 2 and "episodes: missing (run: python -m runners.dataset build tiny_rec --source DIR)" \
        in res.stderr


def test_source_is_refused_for_a_dataset_without_recordings(tmp_path):
    res = run("verify", "paper_fig5", "--seeds", "0:1", "--source", str(tmp_path))
    assert res.returncode == 2 and "is not built from recordings" in res.stderr


def test_the_committed_eth_ucy_definition_is_not_built():
    """The definition only: no recording, no log and no digest of one is committed (CI has no recordings)."""
    m = dataset.load_manifest("eth_ucy_v1")
    assert "episodes" not in m and "sha256" not in m["source"] and "metrics_columns" not in m
    assert not (dataset.DATASETS / "eth_ucy_v1" / "logs").exists()
    rows = {r["name"]: r for r in dataset.list_datasets()}
    # students03 has three windows of its own
    assert rows["eth_ucy_v1"]["episodes"] == (4 * 5 + 3) * 7 * 3 and not rows["eth_ucy_v1"]["built"]


@pytest.mark.parametrize("edit, message", [
    (lambda s: s.pop("windows"), "source.windows: expected a list of distinct window numbers"),
    (lambda s: s.update(windows=[1, 1]), "source.windows: expected a list of distinct"),
    (lambda s: s["scenes"]["plaza"].update(windows=[]), "source.scenes.plaza.windows: expected a list of distinct"),
    (lambda s: s.update(colour=1), "source.colour: unknown field"),
    (lambda s: s["scenes"]["plaza"].update(file="../../etc/passwd"), "source.scenes.plaza.file: expected a relative"),
    (lambda s: s["scenes"]["plaza"].update(file="/etc/passwd"), "source.scenes.plaza.file: expected a relative"),
    (lambda s: s["scenes"]["plaza"].update(max_gap=-1), "source.scenes.plaza.max_gap: expected a whole number"),
    (lambda s: s["scenes"]["plaza"].update(format="csv"), "source.scenes.plaza.format: expected one of"),
    (lambda s: s.update(params={"recording": "x"}), "source.params.recording: set by the dataset"),
    (lambda s: s.update(sha256={"nowhere": "0" * 64}), "source.sha256: expected a mapping of scenes"),
    (lambda s: s.update(scenes={}), "source.scenes: expected a mapping of scene name"),
])
def test_a_bad_source_field_is_one_line_naming_it(edit, message):
    import copy
    source = copy.deepcopy(MANIFEST["source"])
    edit(source)
    with pytest.raises(DatasetError) as err:
        check_source(source, Path("m.yaml"))
    assert str(err.value).startswith(f"m.yaml: {message}"), str(err.value)


_VALUES = st.recursive(st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(), st.text(max_size=8)),
                       lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                                   max_size=3), max_leaves=10)


@settings(max_examples=200, deadline=None)
@given(source=st.one_of(_VALUES, st.fixed_dictionaries({"scenes": _VALUES, "windows": _VALUES},
                                                       optional={"params": _VALUES, "sha256": _VALUES})))
def test_fuzz_source_field(source):
    """Any ``source`` value: accepted, or one DatasetError line naming the manifest — never another exception."""
    try:
        check_source(source, Path("m.yaml"))
    except DatasetError as err:
        assert str(err).startswith("m.yaml: source") and "\n" not in str(err)


def test_a_scene_may_have_windows_of_its_own(setup, tmp_path):
    """students03 is 216 s long: three 60-s windows where the other scenes have five."""
    import copy

    from runners.datasets import recorded_source

    root, source = setup
    manifest = copy.deepcopy(MANIFEST)
    manifest["source"]["scenes"]["plaza"]["windows"] = [1]
    recorded_source.check_source(manifest["source"], root / "m.yaml")
    run_manifest, overrides, notes = recorded_source.prepare(manifest, root / "m.yaml", source, tmp_path / "conf",
                                                             building=True)
    assert run_manifest["sweep"]["scenarios"] == ["plaza_w1"] and overrides and notes
    written = yaml.safe_load((tmp_path / "conf" / "scenario" / "plaza_w1.yaml").read_text())
    assert written["params"]["window"] == 1 and written["params"]["duration_s"] == 20
    assert recorded_source.scene_windows(manifest["source"], "plaza") == 1
    assert recorded_source.scene_windows(manifest["source"], "hall") == 2
