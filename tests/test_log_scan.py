"""``runners.sweeping.paths.LogScan``: the sweep's progress finds new logs by listing only directories that changed."""

from __future__ import annotations

import os
from pathlib import Path

from hypothesis import given, settings
from hypothesis import strategies as st

from runners.sweeping.paths import CONTROL_DIR, LogScan, job_logs


def _touch(path: Path) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"x")
    return str(path)


def _age(directory: Path, seconds: float = 60.0) -> None:
    """Set a directory's modification time back (as if listed long ago)."""
    st = os.stat(directory)
    os.utime(directory, ns=(st.st_atime_ns, st.st_mtime_ns - int(seconds * 1e9)))


def test_the_first_scan_finds_every_log_but_the_control_directorys(tmp_path):
    logs = {_touch(tmp_path / "0" / "a.mcap"), _touch(tmp_path / "1" / "deep" / "b.mcap")}
    _touch(tmp_path / CONTROL_DIR / "resume" / "0" / "c.mcap")
    _touch(tmp_path / "0" / ".a.mcap.partial")
    assert set(LogScan(tmp_path).scan()) == logs == {str(p) for p in job_logs(tmp_path)}


def test_an_old_unchanged_directory_is_not_listed_again_and_a_changed_one_is(tmp_path):
    _touch(tmp_path / "0" / "a.mcap")
    _touch(tmp_path / "1" / "b.mcap")
    for d in (tmp_path / "0", tmp_path / "1", tmp_path):
        _age(d)
    scan = LogScan(tmp_path)
    assert len(scan.scan()) == 2
    assert scan.scan() == []  # nothing changed
    new = _touch(tmp_path / "1" / "c.mcap")
    assert sorted(scan.scan()) == sorted([str(tmp_path / "1" / "b.mcap"), new])
    later = _touch(tmp_path / "2" / "nested" / "d.mcap")  # a new job directory below an old root
    assert later in scan.scan()


def test_a_recent_directory_is_listed_again_even_with_its_time_unchanged(tmp_path):
    # a file system with coarse timestamps: a file added within the same tick leaves the directory's time as it was
    _touch(tmp_path / "0" / "a.mcap")
    scan = LogScan(tmp_path)
    scan.scan()
    mtime = os.stat(tmp_path / "0").st_mtime_ns
    new = _touch(tmp_path / "0" / "b.mcap")
    os.utime(tmp_path / "0", ns=(mtime, mtime))
    assert new in scan.scan()


def test_a_vanished_directory_is_no_error(tmp_path):
    _touch(tmp_path / "0" / "a.mcap")
    scan = LogScan(tmp_path)
    scan.scan()
    (tmp_path / "0" / "a.mcap").unlink()
    (tmp_path / "0").rmdir()
    assert scan.scan() == []
    assert LogScan(tmp_path / "missing").scan() == []


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["0", "1", "2/x", CONTROL_DIR, "1/" + CONTROL_DIR]),
                          st.sampled_from(["a.mcap", "b.mcap", "c.txt", ".d.mcap.partial"])), max_size=12),
       st.lists(st.booleans(), max_size=12))
def test_every_log_written_between_scans_is_found_by_the_next_one(tmp_path_factory, writes, ages):
    root = tmp_path_factory.mktemp("sweep")
    scan = LogScan(root)
    seen: set[str] = set(scan.scan())
    for i, (directory, name) in enumerate(writes):
        path = _touch(root / directory / f"{i}{name}")
        if ages and ages[i % len(ages)]:
            for d in {root, *(p for p in Path(path).parents if root in p.parents)}:
                if d.exists() and d != root / directory:
                    _age(d)
        seen |= set(scan.scan())
    assert {str(p) for p in job_logs(root)} <= seen
    assert all(CONTROL_DIR not in Path(p).relative_to(root).parts for p in seen)
