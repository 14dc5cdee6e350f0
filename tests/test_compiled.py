"""fuzzynav.numerics.compiled: the switch that sends every run down the Python paths."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from fuzzynav.numerics import compiled
from tests.conftest import ROOT


@pytest.mark.parametrize("value, off", [("python", True), (" Python ", True), ("PYTHON", True), ("", False),
                                        ("c", False), ("pythonic", False), ("0", False)])
def test_the_switch_follows_the_environment_as_it_changes(monkeypatch, value, off):
    monkeypatch.delenv(compiled.KERNEL_ENV, raising=False)
    assert not compiled.switched_off()
    monkeypatch.setenv(compiled.KERNEL_ENV, value)
    assert compiled.switched_off() is off
    os.environ[compiled.KERNEL_ENV] = "python"  # a plain assignment, as a user's script would make
    assert compiled.switched_off()
    del os.environ[compiled.KERNEL_ENV]
    assert not compiled.switched_off()


@pytest.mark.parametrize("value, off", [(None, False), ("python", True), (" PYTHON", True), ("c", False)])
def test_the_switch_reads_an_environment_mapping_of_another_kind(monkeypatch, value, off):
    # e.g. a harness that replaces os.environ with a plain dict: the switch reads it through its public get
    monkeypatch.setattr(os, "environ", {} if value is None else {compiled.KERNEL_ENV: value})
    assert compiled.switched_off() is off


def test_the_switch_reads_the_environment_a_process_starts_with():
    code = "from fuzzynav.numerics import compiled; print(compiled.switched_off())"
    for value, expected in (("python", "True"), ("no", "False")):
        env = {**os.environ, compiled.KERNEL_ENV: value}
        out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                             check=True).stdout.strip()
        assert out == expected
