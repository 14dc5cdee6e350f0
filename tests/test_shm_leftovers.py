"""The loky/joblib entries a hard-stopped sweep leaves in /dev/shm are removed by the next sweep
(runners/sweeping/shm_leftovers.py; hostile14c flt_sigterm_twice_resume)."""

from __future__ import annotations

import os
import subprocess
import sys

from runners.sweeping.shm_leftovers import remove_stale


def dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_entries_of_dead_processes_are_removed_and_others_kept(tmp_path):
    dead, live = dead_pid(), os.getpid()
    stale = [tmp_path / f"joblib_memmapping_folder_{dead}_{'a' * 32}_{'b' * 32}", tmp_path / f"sem.loky-{dead}-x1y2"]
    kept = [tmp_path / f"joblib_memmapping_folder_{live}_{'c' * 32}_{'d' * 32}", tmp_path / f"sem.loky-{live}-z9",
            tmp_path / "other_program_file", tmp_path / f"joblib_memmapping_folder{dead}"]
    stale[0].mkdir()
    (stale[0] / "array.pkl").write_bytes(b"x")
    stale[1].write_bytes(b"")
    kept[0].mkdir()
    for path in kept[1:]:
        path.write_bytes(b"")
    assert remove_stale(tmp_path) == 2
    assert not any(p.exists() for p in stale) and all(p.exists() for p in kept)
    assert remove_stale(tmp_path / "missing") == 0  # no such directory: nothing to do
