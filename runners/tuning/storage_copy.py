"""``python -m runners.tune STUDY --to-journal``: a study stored in SQLite (``<study>/study.db``) moved to Optuna's
journal file (``<study>/study.journal``), the storage that Slurm workers share (:mod:`runners.tuning.slurm_workers`).

The study is copied with Optuna's :func:`optuna.copy_study` into a journal file written aside, every trial of the
copy is checked against the database's (number, state, values, parameters and their distributions, attributes,
intermediate values) and so are the study's directions and attributes, and only then does the journal file take
its name. The database is kept as ``<study>/study.db.converted`` (SQLite's backup of it, checked like the journal;
then ``study.db`` goes, so that the folder holds one study storage: :func:`runners.tuning.storage.existing_kind`).
A copy that does not check out leaves the folder as it was.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

from runners.tuning.storage import FILES, SQLITE_TIMEOUT_S, StorageError, existing_kind, open_storage, storage_path

CONVERTED_SUFFIX = ".converted"  # study.db -> study.db.converted once its study is in the journal file


def converted_path(study_dir: Path) -> Path:
    """Where the SQLite database of a converted study is kept."""
    return study_dir / (FILES["sqlite"] + CONVERTED_SUFFIX)


def _trial_record(trial: Any) -> tuple:
    """What a copy must keep of a trial (its datetimes too: the report's history is drawn from them)."""
    return (trial.number, trial.state, trial.values, trial.params, trial.distributions, trial.user_attrs,
            trial.system_attrs, trial.intermediate_values, trial.datetime_start, trial.datetime_complete)


def _study_record(storage: Any, name: str) -> tuple:
    import optuna

    study = optuna.load_study(study_name=name, storage=storage)
    return (study.directions, study.user_attrs, storage.get_study_system_attrs(storage.get_study_id_from_name(name)),
            [_trial_record(t) for t in study.get_trials(deepcopy=False)])


def _keep(db: Path, kept: Path) -> None:
    """Write the database, as one self-contained file (its write-ahead log folded in, not in WAL mode), to
    ``kept``: SQLite's online backup, which reads a consistent snapshot whoever else has the file open."""
    partial = kept.with_name(f".{kept.name}.partial")
    source, target = sqlite3.connect(str(db), timeout=SQLITE_TIMEOUT_S), sqlite3.connect(str(partial))
    try:
        source.backup(target)
        target.execute("PRAGMA journal_mode=DELETE")
    finally:
        source.close()
        target.close()
    partial.replace(kept)


def to_journal(study_dir: Path, name: str) -> tuple[int, Path]:
    """Copy study ``name`` of ``<study_dir>/study.db`` into ``<study_dir>/study.journal`` and keep the database as
    ``study.db.converted``; returns (trials copied, journal file). The caller holds the study folder's lock.
    Raises :class:`StorageError` (one line naming the file) when there is nothing to convert, the folder already
    has a journal file, the database is not readable, or the copy differs from it."""
    import optuna
    from optuna.storages.journal import JournalFileBackend, JournalStorage

    db, journal = storage_path(study_dir, "sqlite"), storage_path(study_dir, "journal")
    kind = existing_kind(study_dir)  # both files: one line, keep one
    if kind == "journal":
        raise StorageError(f"{journal}: the study is already stored in the journal file"
                           + (f" (its SQLite database is kept as {converted_path(study_dir).name})"
                              if converted_path(study_dir).exists() else "") + ": nothing to convert")
    if kind is None:
        raise StorageError(f"{db}: no such file: there is no SQLite study to convert in {study_dir}")
    if converted_path(study_dir).exists():
        raise StorageError(f"{converted_path(study_dir)}: a converted database is already kept here: move it away "
                           "before converting again")
    source = open_storage(study_dir, "sqlite")
    names = [s.study_name for s in source.get_all_studies()]
    if name not in names:
        raise StorageError(f"{db}: holds no study named {name!r} (it holds {', '.join(map(repr, names)) or 'none'})")
    partial = study_dir / f".{FILES['journal']}.partial"
    for leftover in (partial, partial.with_name(partial.name + ".lock")):  # of a conversion that was stopped
        leftover.unlink(missing_ok=True)
    try:
        target = JournalStorage(JournalFileBackend(str(partial)))
        optuna.copy_study(from_study_name=name, from_storage=source, to_storage=target, to_study_name=name)
        copied = _study_record(JournalStorage(JournalFileBackend(str(partial))), name)
        if copied != _study_record(source, name):
            raise StorageError(f"{db}: the copy of study {name!r} into the journal file differs from the database: "
                               "nothing converted")
        source.engine.dispose()
        _keep(db, converted_path(study_dir))
        kept = optuna.storages.RDBStorage(f"sqlite:///{converted_path(study_dir)}")
        try:
            if _study_record(kept, name) != copied:
                raise StorageError(f"{converted_path(study_dir)}: the kept copy of {db} differs from it: nothing "
                                   "converted")
        finally:
            kept.engine.dispose()
        partial.replace(journal)  # first the journal: a stop before the database goes leaves both, never neither
        for path in (db, db.with_name(db.name + "-wal"), db.with_name(db.name + "-shm")):
            path.unlink(missing_ok=True)
    except StorageError:
        partial.unlink(missing_ok=True)
        if db.exists():  # the database is still the study: a kept copy of it made here would block a retry
            converted_path(study_dir).unlink(missing_ok=True)
        raise
    except (optuna.exceptions.OptunaError, sqlite3.Error, ValueError) as err:
        partial.unlink(missing_ok=True)
        if db.exists():
            converted_path(study_dir).unlink(missing_ok=True)
        raise StorageError(f"{db}: could not be copied to the journal file: {' '.join(str(err).split())[:200]}") \
            from None
    return len(copied[3]), journal
