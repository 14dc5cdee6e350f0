"""Where a study lives: Optuna's storage in the study folder.

- ``sqlite`` (default): ``<study>/study.db``, Optuna's RDB storage on SQLite. Every trial's state is written
  as it changes, so a killed command loses only the trials in flight. SQLite serialises writers; a handful of
  local workers share it (each waits up to :data:`SQLITE_TIMEOUT_S` for the file). The database is in WAL mode
  with ``synchronous=NORMAL`` (:func:`sqlite_connection`): a commit is an append to ``study.db-wal`` without an
  fsync, which cut the storage's share of a trial from ~150 ms to ~25 ms (six commits a trial then; a seventh
  now records the trial's worker). A killed process loses nothing it committed; only a crash of the machine
  itself may lose the last commits. WAL needs a local file system (its index is shared memory): on a shared file
  system use the journal (Slurm workers must: :mod:`runners.tuning.slurm_workers`).
- ``journal``: ``<study>/study.journal``, Optuna's append-only journal file (file-lock based), meant for many
  workers at once (also on a shared file system).

A file that is not a study storage (corrupt, truncated, another program's) is one :class:`StorageError` line
naming it; the file is left as it was.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

KINDS = ("sqlite", "journal")
FILES = {"sqlite": "study.db", "journal": "study.journal"}
SQLITE_TIMEOUT_S = 60.0
SQLITE_MAGIC = b"SQLite format 3\x00"

TRIALS_DIR = "trials"  # <study>/trials/<number>/: each trial's episode logs


def trial_dir(study_dir: Path, number: int) -> Path:
    """The folder of trial ``number``'s episode logs."""
    return study_dir / TRIALS_DIR / f"{number:05d}"


class StorageError(Exception):
    """The study's storage cannot be opened or used (the message names the file)."""


def storage_path(study_dir: Path, kind: str) -> Path:
    return study_dir / FILES[kind]


def existing_kind(study_dir: Path) -> str | None:
    """The storage kind a study folder already has (None for a new folder); both is an error."""
    found = [kind for kind in KINDS if storage_path(study_dir, kind).exists()]
    if len(found) > 1:
        raise StorageError(f"{study_dir}: holds both {FILES['sqlite']} and {FILES['journal']}: keep one")
    return found[0] if found else None


def _check_sqlite(path: Path) -> None:
    """A SQLite file that exists must be a SQLite database (Optuna would otherwise print a long traceback)."""
    if not path.exists():
        return
    if not path.is_file():
        raise StorageError(f"{path}: not a regular file")
    with path.open("rb") as f:
        head = f.read(len(SQLITE_MAGIC))
    if head and head != SQLITE_MAGIC:
        raise StorageError(f"{path}: not a SQLite database (corrupt, or another program's file): move it away to "
                           "start a new study")
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=SQLITE_TIMEOUT_S) as db:
            problem = db.execute("PRAGMA quick_check").fetchone()[0]
    except sqlite3.DatabaseError as err:
        raise StorageError(f"{path}: {err}") from None
    if problem != "ok":
        raise StorageError(f"{path}: damaged database ({str(problem)[:120]})")


def _check_journal(path: Path) -> None:
    """Every complete line of a journal file must be one of Optuna's operations (a JSON object with ``op_code``).
    Optuna skips a line that does not parse when it is the last one (a write in flight), and then appends after
    it: a corrupt file would be written to, and fail later with a bare JSON message."""
    if not path.exists():
        return
    if not path.is_file():
        raise StorageError(f"{path}: not a regular file")
    with path.open("rb") as f:
        for number, line in enumerate(f, 1):
            if not line.endswith(b"\n"):
                break  # the last line of a write that a killed worker left unfinished: Optuna ignores it
            try:
                ok = isinstance(op := json.loads(line), dict) and "op_code" in op
            except ValueError:
                ok = False
            if not ok:
                raise StorageError(f"{path}:{number}: not an Optuna journal operation (corrupt file, or another "
                                   "program's): move it away to start a new study")


def sqlite_connection(path: Path) -> sqlite3.Connection:
    """A connection to the study database in WAL mode, ``synchronous=NORMAL`` (see the module docstring).
    ``check_same_thread`` off: SQLAlchemy's pool hands connections between threads, one at a time."""
    db = sqlite3.connect(str(path), timeout=SQLITE_TIMEOUT_S, check_same_thread=False)
    db.execute("PRAGMA journal_mode=WAL")  # kept in the file; a no-op once set
    db.execute("PRAGMA synchronous=NORMAL")  # per connection
    return db


def open_storage(study_dir: Path, kind: str) -> Any:
    """Optuna's storage of the study folder (created if new), read once through: a corrupt file is a
    :class:`StorageError` here, not a traceback later."""
    import optuna
    from optuna.storages.journal import JournalFileBackend, JournalStorage

    path = storage_path(study_dir, kind)
    try:
        if kind == "sqlite":
            _check_sqlite(path)
            storage = optuna.storages.RDBStorage(f"sqlite:///{path}",
                                                 engine_kwargs={"creator": lambda: sqlite_connection(path)})
        else:
            _check_journal(path)
            storage = JournalStorage(JournalFileBackend(str(path)))
        storage.get_all_studies()
    except StorageError:
        raise
    except Exception as err:  # sqlalchemy's, a journal line that is not JSON, an operation Optuna does not know
        what = "an Optuna study database" if kind == "sqlite" else "an Optuna journal"
        raise StorageError(f"{path}: not readable as {what} (corrupt, truncated or locked?): "
                           f"{' '.join(str(err).split())[:200]}") from None
    return storage


def storage_problem(err: BaseException) -> bool:
    """Whether an exception raised while trials run comes from the storage (the file, its lock, the database)."""
    import optuna

    module = type(err).__module__ or ""
    return isinstance(err, OSError | optuna.exceptions.StorageInternalError) or module.startswith("sqlalchemy")
