"""Resuming a sweep: every episode once, each kept log verified in full, failed episodes run again.

An episode is identified by :func:`fuzzynav.episode_identity.episode_key`, computed from its ``fuzzynav.run``
metadata (the resolved config without the seed-batching keys, its seed and the fuzzynav version) — the same
identity by which the analysis counts each episode once. Not by where its log lies: a resume whose jobs are
numbered or batched differently from the earlier sweep's (an overlapping but different sweep into the same
directory) must still find each episode, and must not count it twice.

Before any job runs, the launching process (holding the directory's lock) verifies every log of the sweep
directory in full — every chunk's CRC, the summary, the metadata and every message against its schema
(:mod:`analysis.logs`, :mod:`analysis.log_check`) — and sets them aside in ``.fuzzynav/resume/``:

- ``<episode key>.mcap``: the one complete log of an episode that ended ``goal``, ``collision`` or ``timeout``;
  the job that runs this episode takes it back into its own directory (an atomic rename: one job gets it) instead
  of running it again;
- ``<episode key>.rerun``: the log of an episode to run again (outcome ``error`` or ``interrupted``, truncated,
  damaged); removed when the episode has been run again;
- other logs of an episode that has a log above (copies) are removed; logs whose metadata cannot be read at all
  stay where they are (a re-run of the same name replaces them);
- something named ``*.mcap`` that is not a regular file (a FIFO, a device, a directory) is never opened — opening
  a FIFO blocks until someone writes to it — and stays where it is; :attr:`ResumePlan.skipped` says why.

At the end of the sweep (:func:`restore`) what no job took back — episodes the sweep does not include — returns
to where it was, or to ``earlier/<that path>`` if a log of this sweep now has that name. ``index.json`` in the
same directory remembers the original places, so a launcher that dies in between loses nothing: the next sweep
into the directory restores them first.
"""

from __future__ import annotations

import contextlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fuzzynav.episode_identity import RECORDING, episode_key, episode_key_of
from runners.sweeping.paths import holding_dir, job_logs

FINAL_OUTCOMES = ("goal", "collision", "timeout")  # the outcomes a resume keeps; error/interrupted run again
INDEX = "index.json"
EARLIER = "earlier"
SUPERSEDED = "superseded"  # in the control folder .fuzzynav/: logs of episodes re-run with other code


@dataclass(frozen=True)
class Verdict:
    """What a full verification of one log found: ``key`` (its episode key, None when not even the
    metadata is readable), ``ok`` (complete, intact, valid, with a final outcome) and otherwise ``reason``;
    ``skipped``: not a regular file, never opened."""

    path: Path
    key: str | None
    ok: bool
    outcome: str | None = None
    reason: str = ""
    skipped: bool = False


@dataclass(frozen=True)
class ResumePlan:
    """Counts of :func:`prepare`: logs set aside to keep, episodes to run again, copies removed, logs left in
    place because they are unreadable; ``skipped``: one line for each path that is not a regular file (left in
    place, not opened)."""

    kept: int
    rerun: int
    removed: int
    unreadable: int
    skipped: tuple[str, ...] = ()


def verify(path: Path) -> Verdict:
    """Read one log in full and decide whether a resume may keep it (see :class:`Verdict`)."""
    from analysis.log_check import CheckError, check_message, check_metadata
    from analysis.logs import LogError, LogFile, regular_file_problem

    problem = regular_file_problem(path)  # before anything opens it: opening a FIFO blocks
    if problem:
        return Verdict(path, None, False, None, problem, skipped=True)
    key = _peek_key(path)
    try:
        log = LogFile(path)  # every chunk decompressed and CRC-checked, the summary CRC-checked
        meta = log.metadata()
        check_metadata(meta)  # includes: the config hash is the hash of the config and seed
        key = episode_key_of(meta)
        if not log.complete:
            return Verdict(path, key, False, None, "truncated (no MCAP summary)")
        outcome = None
        for topic, _t, msg in log.messages():
            check_message(topic, msg)
            if topic == "/episode":
                outcome = msg["outcome"]
    except (LogError, CheckError) as err:
        return Verdict(path, key, False, None, str(err))
    if key is None:
        return Verdict(path, None, False, outcome, "no config, seed or fuzzynav version in the metadata")
    if outcome not in FINAL_OUTCOMES:
        return Verdict(path, key, False, outcome, f"outcome {outcome or 'missing'}")
    return Verdict(path, key, True, outcome)


def _verify_all(paths: list[Path]) -> list[Verdict]:
    return [verify(p) for p in paths]


def _peek_key(path: Path) -> str | None:
    """The episode key from the unverified metadata: which episode a damaged log belongs to (never believed for
    anything else)."""
    from analysis.logs import RUN_METADATA, regular_file_problem
    from analysis.mcap_verify import peek_metadata

    if regular_file_problem(path):  # never open a FIFO (it blocks) or a device
        return None
    try:
        # O_NONBLOCK: should the path have become a FIFO since the check, opening it still returns at once
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(fd, "rb") as f:
            meta = peek_metadata(f, RUN_METADATA)
    except Exception:  # unverified bytes: whatever goes wrong, the answer is "unknown"
        return None
    return episode_key_of(meta)


# -- the launching process -----------------------------------------------------------------------------------------
def prepare(sweep_dir: Path, jobs: int = 1) -> ResumePlan:
    """Verify every log of the sweep directory and set them aside (see the module docstring). ``jobs``: worker
    processes for the verification (:func:`analysis.logs.read_logs`). Call with the directory's lock held, before
    any job runs."""
    from analysis.logs import read_logs

    restore(sweep_dir)  # what an earlier launcher set aside and could not restore
    hold = holding_dir(sweep_dir)
    hold.mkdir(parents=True, exist_ok=True)
    verdicts = [v for chunk in read_logs(_verify_all, job_logs(sweep_dir), jobs) for v in chunk]
    by_episode: dict[str, list[Verdict]] = {}
    unreadable = 0
    skipped = tuple(f"{v.path}: {v.reason}" for v in verdicts if v.skipped)
    for verdict in verdicts:
        if verdict.skipped:
            continue
        if verdict.key is None:
            unreadable += 1
        else:
            by_episode.setdefault(verdict.key, []).append(verdict)
    index: dict[str, str] = {}
    kept = rerun = removed = 0
    for key, found in by_episode.items():
        good = [v for v in found if v.ok]
        chosen = (good or found)[0]
        name = f"{key}.mcap" if good else f"{key}.rerun"
        os.replace(chosen.path, hold / name)
        index[name] = chosen.path.relative_to(sweep_dir).as_posix()
        kept, rerun = kept + bool(good), rerun + (not good)
        for other in found:
            if other is not chosen:  # a copy of the kept log, or an older failed attempt of the same episode
                other.path.unlink()
                removed += 1
    _write_index(hold, index)
    return ResumePlan(kept, rerun, removed, unreadable, skipped)


def restore(sweep_dir: Path) -> tuple[int, int, int]:
    """Return what is still set aside to where it was (``earlier/<path>`` if that name is taken now). A log whose
    name is taken by a log of the same episode (the same config and seed) run by other code (a changed plug-in, a
    newer fuzzynav) is superseded: it goes to ``.fuzzynav/superseded/<path>``, kept but not analysed, since counted
    beside its re-run every seed of its group was there twice. Returns (restored in place, moved to ``earlier/``,
    superseded)."""
    hold = holding_dir(sweep_dir)
    if not hold.is_dir():
        return 0, 0, 0
    index = _read_index(hold)
    in_place = earlier = superseded = 0
    for held in sorted(hold.iterdir()):
        if held.suffix not in (".mcap", ".rerun"):
            continue
        rel = _safe_relative(index.get(held.name)) or Path(EARLIER) / f"{held.stem}.mcap"
        target = sweep_dir / rel
        if target.exists() and _same_episode(held, target):
            target = _free_name(hold.parent / SUPERSEDED / rel)
            superseded += 1
        elif target.exists():
            target = _free_name(sweep_dir / EARLIER / rel)
            earlier += 1
        else:
            in_place += 1
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(held, target)
    with contextlib.suppress(FileNotFoundError):
        (hold / INDEX).unlink()
    return in_place, earlier, superseded


def _same_episode(a: Path, b: Path) -> bool:
    """Whether two logs record the same episode (config and seed, the seed batching aside: the identity without the
    fuzzynav version and the plug-ins' code, which a re-run replaces); False when either's metadata cannot be read.
    The recording's digest stays in: people read from another recording of the same file name are another world
    (a dimension of the report), so the old log goes to ``earlier/``, analysed beside the new, not superseded."""
    from analysis.logs import RUN_METADATA
    from analysis.mcap_verify import peek_metadata

    metas = []
    for path in (a, b):
        try:
            with path.open("rb") as f:
                metas.append(peek_metadata(f, RUN_METADATA))
        except OSError:
            return False
    keys = [episode_key(m["config"], m["seed"], "", recording=str(m.get(RECORDING, "")))
            if m and isinstance(m.get("config"), str) and isinstance(m.get("seed"), str) else None
            for m in metas]  # no version, no plug-in code
    return keys[0] is not None and keys[0] == keys[1]


def held_count(sweep_dir: Path) -> int:
    """Logs still set aside to keep (not taken back by a job)."""
    hold = holding_dir(sweep_dir)
    return sum(1 for _ in hold.glob("*.mcap")) if hold.is_dir() else 0


# -- a job ---------------------------------------------------------------------------------------------------------
def keep(path: Path, key: str, sweep_dir: Path | None) -> dict[str, Any] | None:
    """The summary row of a kept log of the episode ``key``, now at ``path``, or None when it must run: in a
    sweep, the log set aside for it is taken back; otherwise (a single run, or a sweep whose launcher did not
    prepare the resume) the log already at ``path`` is verified in full."""
    from analysis.logs import LogError, episode_summary

    taken = False
    if sweep_dir is not None:
        try:
            os.replace(holding_dir(sweep_dir) / f"{key}.mcap", path)  # atomic: exactly one job takes it
            taken = True
        except FileNotFoundError:
            pass
    if not taken:
        if not path.is_file():
            return None
        verdict = verify(path)
        if not verdict.ok or verdict.key != key:
            return None
    try:
        return episode_summary(path)
    except LogError:
        return None


def supersede(sweep_dir: Path | None, key: str) -> None:
    """The episode ``key`` has been run again: its earlier failed log is no longer needed."""
    if sweep_dir is not None:
        with contextlib.suppress(FileNotFoundError):
            (holding_dir(sweep_dir) / f"{key}.rerun").unlink()


# -- helpers -------------------------------------------------------------------------------------------------------
def _read_index(hold: Path) -> dict[str, str]:
    try:
        data = json.loads((hold / INDEX).read_text())
    except (OSError, ValueError):
        return {}
    return {str(k): str(v) for k, v in data.items()} if isinstance(data, dict) else {}


def _write_index(hold: Path, index: dict[str, str]) -> None:
    """Written whole or not at all (temporary file + rename): a torn index would misplace logs."""
    tmp = hold / f".{INDEX}.tmp"
    tmp.write_text(json.dumps(index, indent=0, sort_keys=True))
    os.replace(tmp, hold / INDEX)


def _safe_relative(text: str | None) -> Path | None:
    """A path from the index, if it stays inside the sweep directory."""
    if not text:
        return None
    rel = Path(text)
    return None if rel.is_absolute() or ".." in rel.parts else rel


def _free_name(path: Path) -> Path:
    """``path``, or ``path`` with ``.1``, ``.2``, ... before ``.mcap`` when taken."""
    candidate, k = path, 0
    while candidate.exists():
        k += 1
        candidate = path.with_name(f"{path.stem}.{k}{path.suffix}")
    return candidate
