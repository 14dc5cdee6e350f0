"""Shared-memory objects that a hard-stopped sweep leaves behind, removed by the next sweep.

The joblib launcher's process pool (loky) creates ``joblib_memmapping_folder_<pid>_*`` directories and
``sem.loky-<pid>-*`` semaphores in ``/dev/shm`` and removes them when the pool shuts down. A launcher stopped
hard (a second SIGTERM or Ctrl-C, SIGKILL) never does, and nothing else would: they accumulate with every hard
stop. A sweep starting removes those whose creating process (``<pid>``) no longer exists and that belong to the
same user; an entry of a live process — another sweep running — is left alone (a reused pid only keeps an entry
longer).
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

SHM = Path("/dev/shm")
_LEFTOVER = re.compile(r"(?:joblib_memmapping_folder_|sem\.loky-)(\d+)[_-]")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's process: alive
        return True
    return True


def remove_stale(shm: Path = SHM) -> int:
    """Remove the loky/joblib entries of dead processes of this user in ``shm``; how many were removed."""
    removed = 0
    try:
        entries = list(shm.iterdir())
    except OSError:  # no /dev/shm (another OS): nothing to clean
        return 0
    uid = os.getuid()
    for entry in entries:
        match = _LEFTOVER.match(entry.name)
        if not match or _alive(int(match.group(1))):
            continue
        try:
            if entry.lstat().st_uid != uid:
                continue
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
            removed += 1
        except OSError:  # removed meanwhile, or not ours to remove
            continue
    return removed
