"""``python -m runners.tune STUDY --to-journal`` (issue #39): a study stored in SQLite moved to the journal file that
Slurm workers share, checked trial by trial, the database kept; then resumed from the journal to its budget without
running a finished trial again. Converting twice, a folder that already has a journal file, a corrupt database:
one line, nothing changed."""

from __future__ import annotations

import hashlib

import optuna
import pytest

import runners.tuning.study as study_module
from runners.sweeping import lock
from runners.tuning.storage import open_storage
from runners.tuning.storage_copy import _study_record, converted_path
from runners.tuning.study import counted
from tests.test_tune import study_file
from tests.test_tune_bad_inputs import one_line_error, run_main


def sqlite_study(tmp_path, trials: int = 2):
    """A tiny study of ``trials`` trials stored in SQLite (``<tmp>/study/study.db``)."""
    out, path = tmp_path / "study", study_file(tmp_path, trials=trials)
    code, _, err = run_main(str(path), "--out", str(out), "--no-heldout")
    assert code == 0 and (out / "study.db").exists(), err
    return out, path


def digest(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_converted_study_resumes_from_the_journal_without_running_a_finished_trial(tmp_path, monkeypatch):
    out, path = sqlite_study(tmp_path)
    before = _study_record(open_storage(out, "sqlite"), "tiny")
    assert [t[1].name for t in before[3]] == ["COMPLETE", "COMPLETE"]
    code, stdout, err = run_main(str(path), "--out", str(out), "--to-journal")
    assert code == 0 and err == "", err
    assert "2 trials copied" in stdout and "--to-journal" not in stdout
    assert (out / "study.journal").exists() and not (out / "study.db").exists()
    assert not list(out.glob(".study.journal.partial*"))
    # the copy is the study; the database is kept, whole (its WAL folded in), and still holds the same study
    assert _study_record(open_storage(out, "journal"), "tiny") == before
    kept = optuna.storages.RDBStorage(f"sqlite:///{converted_path(out)}")
    assert _study_record(kept, "tiny") == before
    kept.engine.dispose()
    # resumed locally from the journal (found by itself: no --storage) to a budget of 3: one trial runs
    calls = []
    real = study_module.run_configuration

    def counting(*args, **kwargs):
        calls.append(args[0])
        return real(*args, **kwargs)

    monkeypatch.setattr(study_module, "run_configuration", counting)
    code, stdout, err = run_main(str(path), "--out", str(out), "--trials", "3", "--no-heldout")
    assert code == 0, err
    assert "study.journal; 2 of 3 trials done" in stdout and len(calls) == 1
    after = _study_record(open_storage(out, "journal"), "tiny")
    assert after[3][:2] == before[3] and sum(counted(t) for t in optuna.load_study(
        study_name="tiny", storage=open_storage(out, "journal")).get_trials()) == 3
    assert not (out / "study.db").exists()
    # converting again: already in the journal, one line, nothing changed
    journal = digest(out / "study.journal")
    code, _, err = run_main(str(path), "--out", str(out), "--to-journal")
    one_line_error(code, err, str(out / "study.journal"), "already stored in the journal file", "study.db.converted")
    assert code == 2 and digest(out / "study.journal") == journal
    lock.release(out)


def test_a_folder_with_a_journal_file_already_is_not_converted(tmp_path):
    out, path = sqlite_study(tmp_path, trials=1)
    (out / "study.journal").write_text("")
    database = digest(out / "study.db")
    code, _, err = run_main(str(path), "--out", str(out), "--to-journal")
    one_line_error(code, err, str(out), "holds both study.db and study.journal")
    assert code == 2 and digest(out / "study.db") == database and (out / "study.journal").read_text() == ""
    assert not converted_path(out).exists()
    lock.release(out)


def test_a_kept_database_is_not_overwritten(tmp_path):
    out, path = sqlite_study(tmp_path, trials=1)
    converted_path(out).write_bytes(b"an earlier conversion")
    code, _, err = run_main(str(path), "--out", str(out), "--to-journal")
    one_line_error(code, err, str(converted_path(out)), "already kept")
    assert code == 2 and converted_path(out).read_bytes() == b"an earlier conversion"
    assert not (out / "study.journal").exists() and (out / "study.db").exists()
    lock.release(out)


@pytest.mark.parametrize("content", [b"garbage{{{\n", b"SQLite format 3\x00" + b"\x01" * 500])
def test_a_corrupt_database_is_one_line_and_nothing_written(tmp_path, content):
    out, path = tmp_path / "study", study_file(tmp_path, trials=1)
    out.mkdir()
    (out / "study.db").write_bytes(content)
    code, _, err = run_main(str(path), "--out", str(out), "--to-journal")
    one_line_error(code, err, str(out / "study.db"))
    assert code == 2 and (out / "study.db").read_bytes() == content
    assert {p.name for p in out.iterdir()} <= {"study.db", ".fuzzynav"}  # .fuzzynav: the folder's lock
    lock.release(out)


def test_nothing_to_convert_and_other_options_are_one_line(tmp_path):
    path = study_file(tmp_path, trials=1)
    code, _, err = run_main(str(path), "--out", str(tmp_path / "none"), "--to-journal")
    one_line_error(code, err, str(tmp_path / "none" / "study.db"), "no SQLite study to convert")
    assert code == 2 and not (tmp_path / "none" / "study.journal").exists()
    lock.release(tmp_path / "none")
    for extra in (["--trials", "3"], ["--storage", "journal"], ["--launcher", "slurm"], ["--no-heldout"],
                  ["--workers", "2"]):
        code, _, err = run_main(str(path), "--out", str(tmp_path / "other"), "--to-journal", *extra)
        one_line_error(code, err, "--to-journal only converts", extra[0])
        assert code == 2 and not (tmp_path / "other").exists()


def test_a_study_of_another_name_is_not_converted(tmp_path):
    out, _ = sqlite_study(tmp_path, trials=1)
    (tmp_path / "x").mkdir()
    other = study_file(tmp_path / "x", trials=1, name="renamed")
    database = digest(out / "study.db")
    code, _, err = run_main(str(other), "--out", str(out), "--to-journal")
    one_line_error(code, err, str(out / "study.db"), "no study named 'renamed'", "'tiny'")
    assert code == 2 and digest(out / "study.db") == database and not (out / "study.journal").exists()
    lock.release(out)


def test_a_copy_that_differs_is_one_line_and_the_folder_is_as_it_was(tmp_path, monkeypatch):
    """The check after the copy (here made to see a trial differ) refuses the conversion: no journal file, no kept
    copy, the database as it was."""
    from runners.tuning import storage_copy

    out, path = sqlite_study(tmp_path, trials=1)
    names = {p.name for p in out.iterdir()}
    real, calls = storage_copy._study_record, []

    def differing(storage, name):
        record = real(storage, name)
        calls.append(1)
        return record if len(calls) != 1 else (*record[:3], [])  # the copy's record, read first, lacks its trials

    monkeypatch.setattr(storage_copy, "_study_record", differing)
    database = digest(out / "study.db")
    code, _, err = run_main(str(path), "--out", str(out), "--to-journal")
    one_line_error(code, err, str(out / "study.db"), "differs from the database", "nothing converted")
    assert code == 2 and digest(out / "study.db") == database and {p.name for p in out.iterdir()} == names
    lock.release(out)
