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


def test_every_log_records_which_forms_ran_and_the_bits_do_not_depend_on_it(tmp_path):
    """``kernels`` in a log's metadata says ``compiled`` or ``python`` (``FUZZYNAV_KERNEL=python``, or the one kernel
    left off by ``FUZZYNAV_KERNELS_OFF``); the messages are the same bits whichever it was. The run has orca
    pedestrians, so the kernel runs when it is on."""
    from mcap.reader import make_reader

    from runners.dataset import content_digests

    def run(name: str, env: dict[str, str]) -> tuple[str, str]:
        out = tmp_path / name
        subprocess.run([sys.executable, "-m", "runners.run", "scenario=crowd_crossing", "scenario.params.model=orca",
                        "scenario.params.n=6", "scenario.params.max_steps=40", f"hydra.run.dir={out}"], cwd=ROOT,
                       env={**os.environ, **env}, capture_output=True, text=True, check=True)
        (log,) = out.glob("*.mcap")
        with open(log, "rb") as f:
            meta = next(m.metadata for m in make_reader(f).iter_metadata() if m.name == "fuzzynav.run")
        return meta["kernels"], content_digests(log)["sha256"]

    built = compiled.built()
    all_on = run("on", {compiled.KERNEL_ENV: "", compiled.KERNELS_OFF_ENV: ""})
    python = run("python", {compiled.KERNEL_ENV: "python", compiled.KERNELS_OFF_ENV: ""})
    off = run("off", {compiled.KERNEL_ENV: "", compiled.KERNELS_OFF_ENV: "fuzzynav.pedestrians._orca"})
    assert all_on[0] == ("compiled" if all(built.values()) else "python") and python[0] == off[0] == "python"
    assert all_on[1] == python[1] == off[1]


def test_an_unknown_kernel_name_to_leave_off_is_an_error(monkeypatch):
    monkeypatch.setenv(compiled.KERNELS_OFF_ENV, "_orca,_raycast")  # a kernel that is no more is unknown too
    with pytest.raises(ValueError, match=r"unknown kernel\(s\) _raycast \(known: _orca\)"):
        compiled.kernels_off()
