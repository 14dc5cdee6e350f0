"""Data files (scenario and controller files, dataset manifests) are checked as text before a YAML loader builds
them (runners/configuration/data_files.py): what the loaders would accept silently is one line naming the file, line and
field."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
import yaml

from runners.configuration.data_files import (
    MANIFEST,
    SCENARIO_OR_CONTROLLER,
    DataFileError,
    check_data_file,
    check_data_text,
)
from tests.conftest import ROOT

CONF = ROOT / "conf"


@pytest.mark.parametrize(("text", "message"), [
    ("sweep: {seeds: [0, 1]}\nname: x\nsweep: {seeds: [0, 2]}\n", "f.yaml:3: top level: duplicate key 'sweep'"),
    ("a:\n  b: 1\n  c: 2\n  b: 3\n", "f.yaml:4: a: duplicate key 'b'"),
    ("a:\n- {x: 1, y: 2, x: 1}\n", "f.yaml:2: a[0]: duplicate key 'x'"),
    ("a: 1\n'a': 2\n", "f.yaml:2: top level: duplicate key 'a'"),  # quoted or not, the same key
])
def test_a_duplicate_key_is_refused(text, message):
    """PyYAML keeps the last of two equal keys without a word: a manifest's first ``sweep:`` block vanished."""
    assert yaml.safe_load(text)  # what the loader alone does: accept it
    for kind in (SCENARIO_OR_CONTROLLER, MANIFEST):
        with pytest.raises(DataFileError) as err:
            check_data_text(text, "f.yaml", kind)
        assert str(err.value) == message


@pytest.mark.parametrize("text", [
    "a: {x: 1}\nb: {x: 1}\n",                      # the same key in two mappings
    "a: [{x: 1}, {x: 2}]\n",                      # ... in two items of a list
    "base: &b {p: 1}\nc:\n  <<: *b\n  p: 2\n",    # a merged key given again: YAML's way to change it
    "a: x\nb: a\n",                               # a value equal to a key
])
def test_equal_keys_in_different_mappings_are_fine(text):
    check_data_text(text, "f.yaml")


class _UniqueKeyLoader(yaml.SafeLoader):
    """A loader that refuses equal keys in one mapping: an independent check of the committed files."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict:
        keys = [self.construct_object(k, deep=deep) for k, _ in node.value]
        repeated = {k for k in keys if keys.count(k) > 1}
        assert not repeated, f"{node.start_mark}: duplicate key(s) {sorted(map(str, repeated))}"
        return super().construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _UniqueKeyLoader.construct_mapping)


def test_the_committed_files_have_no_duplicate_keys():
    """Every conf/ file and manifest has unique keys; the data files (scenarios, controllers, manifests) also pass
    the whole check, so no committed file is refused."""
    confs = sorted(CONF.rglob("*.yaml"))
    manifests = sorted((ROOT / "datasets").glob("*/manifest.yaml"))
    assert len(confs) > 20 and manifests
    for path in [*confs, *manifests]:
        yaml.load(path.read_text(), Loader=_UniqueKeyLoader)
    for path in sorted(CONF.glob("scenario/*.yaml")) + sorted(CONF.glob("controller/*.yaml")):
        check_data_file(path)
    for path in manifests:
        check_data_text(path.read_bytes(), str(path), MANIFEST)


def test_the_independent_check_finds_a_duplicate():
    """The independent loader above does see duplicates (it could otherwise pass for no reason)."""
    with pytest.raises(AssertionError, match="duplicate key"):
        yaml.load("a: 1\na: 2\n", Loader=_UniqueKeyLoader)


def test_a_scenario_file_that_is_a_device_is_refused(tmp_path):
    """A symlink to /dev/zero is not read (it never ends)."""
    link = tmp_path / "s.yaml"
    os.symlink("/dev/zero", link)
    with pytest.raises(DataFileError, match=r"s\.yaml: not a regular file"):
        check_data_file(Path(link))
