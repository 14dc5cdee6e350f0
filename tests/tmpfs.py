"""Small tmpfs file systems for disk-full and read-only tests (root only; skipped where mounting is refused)."""

from __future__ import annotations

import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest


def tmpfs_mounter(base: Path) -> Iterator[Callable[..., Path]]:
    """Yields ``mount(size, read_only=False) -> directory``; unmounts everything afterwards. ``size`` as mount
    takes it (``"400k"``: bytes of file data the file system holds)."""
    mounted: list[Path] = []

    def mount(size: str, read_only: bool = False) -> Path:
        where = base / f"fs{len(mounted)}"
        where.mkdir()
        options = f"size={size}" + (",ro" if read_only else "")
        res = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True,
                             text=True)
        if res.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here ({res.stderr.strip() or res.returncode}): disk-full and read-only "
                        "tests need root and permission to mount")
        mounted.append(where)
        return where

    yield mount
    for where in mounted:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)
