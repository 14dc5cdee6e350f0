"""Which files an analysis reads: every log file once, every episode once, whatever the paths given.

:func:`find_logs` turns command-line paths into the list of logs the analysis reads:

1. A directory stands for its ``*.mcap`` files (the extension in any case: ``*.MCAP`` too) at any depth, in
   sorted order, except hidden ones and those in hidden directories (``.hydra/``, a sweep's ``.fuzzynav/`` with
   the logs a resume has set aside); symlinked directories are not followed (no loops). A file stands for
   itself, whatever its name.
2. Something that is not a regular file (a FIFO, device, socket or directory named ``*.mcap``), a dangling link
   or a directory that cannot be listed is never opened: it comes back as a :class:`RejectedLog` whose reason
   the analysis lists with the logs left out.
3. The same file reached twice (``D`` and ``D/0``, a symlink, a hard link, a path given twice) is read once.
4. The same episode — the same :func:`fuzzynav.episode_identity.episode_key` (config without the seed batching,
   seed, fuzzynav version: the identity the sweep's resume uses), written by the same code (git commit, library
   versions) — in two different files is compared: when their verified content is the same (apart from the
   decision compute times, which no run reproduces, and the config's batching keys and ``config_hash``, which say
   how the seeds were split into jobs) the first is read and the others are left out as copies; when it differs,
   every one of them is left out, listing the others, because nothing says which is right. Only logs that pass
   every check are compared: a damaged copy is left out for its damage and does not cast doubt on the good log.
   So ``seed=0 episodes=4`` in one directory and ``seed=0,2 episodes=2`` in another are four episodes, not eight.
"""

from __future__ import annotations

import hashlib
import os
import re
import stat
from collections.abc import Iterable
from pathlib import Path

from analysis.episode_log import load_episode
from analysis.file_names import is_utf8
from analysis.logs import RUN_METADATA, LogError, LogFile, RejectedLog, file_kind
from analysis.mcap_verify import peek_metadata
from fuzzynav.episode_identity import counted_key_of
from fuzzynav.params.names import reads_h_wait

_BATCHING_METADATA = ("config", "config_hash")  # depend on the seed batching: the episode key stands for them


def is_provenance_key(key: str) -> bool:
    """Metadata keys that say which code wrote the log (versions, git commit)."""
    return key in ("fuzzynav_version", "git_commit") or key.endswith("_version")

_COMPUTE_TIME = re.compile(rb'"compute_time_us":[-+0-9.eE]+')  # the one field no re-run reproduces
_H_WAIT_SAID = re.compile(rb"h_wait [^,\")]*|hWait=[^,\")]*")  # in a /log line: "h_wait 2", "hWait=2"
_H_WAIT_PLANNED = re.compile(rb'"h_wait":[-+0-9.eE]+')  # in a plan of /planner/decision


def find_logs(paths: Iterable[str | Path]) -> list[Path]:
    """The logs under the given files or directories, in order: each file once, each episode once (see the module
    docstring); what must not be read comes back as a :class:`RejectedLog` with the reason."""
    out: list[Path] = []
    seen: set[tuple[int, int] | str] = set()
    for path in _expand(paths):
        if isinstance(path, RejectedLog):
            key: tuple[int, int] | str = str(path)
        elif not is_utf8(str(path)):
            path = RejectedLog.with_reason(path, "the file name is not UTF-8 text: skipped, not opened (rename the "
                                                 "file)", "bad-name")
            key = str(path)
        else:
            try:
                st = os.stat(path)
            except OSError as err:
                path = RejectedLog.with_reason(path, f"cannot read: {err.strerror or err}", "cannot-read")
                key = str(path)
            else:
                if not stat.S_ISREG(st.st_mode):
                    path = RejectedLog.with_reason(path, f"{file_kind(st.st_mode)}, not a regular file: skipped, "
                                                         "not opened", "not-regular-file")
                    key = str(path)
                else:
                    key = (st.st_dev, st.st_ino)
        if key not in seen:
            seen.add(key)
            out.append(path)
    return _one_per_episode(out)


def _is_mcap(name: str) -> bool:
    return name.lower().endswith(".mcap")


def _expand(paths: Iterable[str | Path]) -> list[Path]:
    out: list[Path] = []
    for p in map(Path, paths):
        if not p.is_dir():
            out.append(p)
            continue
        found: list[Path] = []
        unlistable: list[Path] = []

        def failed(err: OSError, unlistable: list[Path] = unlistable) -> None:
            unlistable.append(RejectedLog.with_reason(err.filename, f"directory cannot be listed: "
                                                                    f"{err.strerror or err}", "cannot-read"))

        for root, dirs, files in os.walk(p, onerror=failed):
            base = Path(root)
            dirs[:] = [d for d in dirs if not d.startswith(".")]  # .hydra, a sweep's .fuzzynav/ control files
            # the extension in any case: b.MCAP beside a.mcap was skipped without a word
            found.extend(base / name for name in files if _is_mcap(name) and not name.startswith("."))
            found.extend(base / name for name in dirs if _is_mcap(name))  # rejected below: a directory
        out.extend(sorted(found))
        out.extend(unlistable)
    return out


def _identity(path: Path) -> tuple[tuple[str, ...], str] | None:
    """((episode key, provenance...), seed) from the unverified metadata, or None (no config, seed or version;
    unreadable): only used to choose which files to compare."""
    try:
        with open(path, "rb") as f:
            meta = peek_metadata(f, RUN_METADATA)
    except OSError:
        return None
    key = counted_key_of(meta)
    if meta is None or key is None:
        return None
    return (key, *sorted(f"{k}={v}" for k, v in meta.items() if is_provenance_key(k))), meta["seed"]


def _content_digest(path: Path) -> str | None:
    """SHA-256 of a complete, verified log's metadata and messages, compute times masked and the config's seed
    batching replaced by the episode key; None when the log is truncated, unreadable or fails a check (its own
    reading reports it): a damaged or edited log is never believed, so it must not make a good log of the same
    episode a conflict."""
    try:
        load_episode(path)  # every check the analysis makes (metadata, messages, the episode as a whole)
        log = LogFile(path)
        if not log.complete:
            return None
        digest = hashlib.sha256()
        meta = log.metadata()
        digest.update(f"episode={counted_key_of(meta)}\0".encode())
        off = () if reads_h_wait(meta.get("strategy")) else ("h_wait",)  # as in the key: a setting not read
        for key, value in sorted(meta.items()):
            if key not in _BATCHING_METADATA and key not in off:
                digest.update(f"{key}={value}\0".encode())
        for topic, log_time, data in log.raw_messages():
            digest.update(f"{topic}@{log_time}\0".encode())
            # a setting not read is still named where the episode starts ("..., h_wait 2, seed 0") and in each plan
            if topic == "/planner/decision":
                data = _COMPUTE_TIME.sub(b'"compute_time_us":0', data)
                if off:
                    data = _H_WAIT_PLANNED.sub(b'"h_wait":null', data)
            elif topic == "/log" and off:
                data = _H_WAIT_SAID.sub(b"h_wait", data)
            digest.update(data)
    except LogError:
        return None
    return digest.hexdigest()


def _one_per_episode(paths: list[Path]) -> list[Path]:
    groups: dict[tuple[str, ...], list[int]] = {}
    seeds: dict[tuple[str, ...], str] = {}
    for i, path in enumerate(paths):
        if not isinstance(path, RejectedLog):
            found = _identity(path)
            if found is not None:
                groups.setdefault(found[0], []).append(i)
                seeds[found[0]] = found[1]
    out = list(paths)
    for identity, members in groups.items():
        if len(members) < 2:
            continue
        digests = {i: _content_digest(paths[i]) for i in members}
        compared = [i for i in members if digests[i] is not None]
        if len(compared) < 2:
            continue
        episode = f"episode key {identity[0][:12]}…, seed {seeds[identity]}"
        first = compared[0]
        if len({digests[i] for i in compared}) == 1:
            for i in compared[1:]:
                out[i] = RejectedLog.with_reason(paths[i], f"a copy of {paths[first]} (the same episode: {episode}, "
                                                           "same content): counted once", "duplicate",
                                                 copy_of=str(paths[first]))
            continue
        for i in compared:
            others = ", ".join(str(paths[j]) for j in compared if j != i)
            out[i] = RejectedLog.with_reason(paths[i], f"the same episode ({episode}, same code) as {others}, but "
                                                       "different content: none of them is counted", "conflict")
    return out
