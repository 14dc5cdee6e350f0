"""A resumed study is the same study: a study file changed in what scores its trials (scenarios, seeds,
objectives, base, space) since the study in ``--out`` began is one line naming the file and the field, exit 2,
nothing run; a change the study allows (budget, description, sampler, held-out seeds) resumes it
(:mod:`runners.tuning.study_record`)."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
import yaml

from runners.sweeping import lock
from runners.tuning.storage import open_storage
from runners.tuning.study import counted, create_or_load
from runners.tuning.study_file import load_study_file
from runners.tuning.study_record import DEFINITION, StudyChangedError
from tests.test_tune import TINY, trials_of
from tests.test_tune_bad_inputs import one_line_error, run_main


def write(path: Path, **changes) -> Path:
    path.write_text(yaml.safe_dump({**TINY, **changes}, sort_keys=False))
    return path


def test_changed_scenarios_are_refused_not_resumed_with_the_old_trials(tmp_path):
    """The tester's repro: tiny2.yaml is tiny.yaml with paper_fig5 for cyclist_crossing, same name, same --out.
    Resuming would report the old scenarios' scores under the new ones."""
    out = tmp_path / "x" / "t"
    first = write(tmp_path / "tiny.yaml", scenarios=["head_on", "cyclist_crossing"], trials=1)
    code, _, err = run_main(str(first), "--out", str(out), "--no-heldout")
    assert code == 0, err
    second = write(tmp_path / "tiny2.yaml", scenarios=["head_on", "paper_fig5"], trials=1)
    code, out_text, err = run_main(str(second), "--out", str(out))
    lock.release(out)
    one_line_error(code, err, str(second), "scenarios: head_on, cyclist_crossing → head_on, paper_fig5",
                   str(out), "restore the file", "another --out")
    assert code == 2 and "trials done" not in out_text
    assert len(trials_of(out)) == 1 and not (out / "heldout").exists() and not (out / "report").exists()


def test_a_change_the_study_allows_resumes_it(tmp_path):
    out = tmp_path / "study"
    code, _, err = run_main(str(write(tmp_path / "tiny.yaml", trials=1)), "--out", str(out), "--no-heldout")
    assert code == 0, err
    changed = write(tmp_path / "more.yaml", trials=2, description="a longer budget", sampler="random",
                    sampler_seed=7, heldout_seeds={"start": 200, "count": 2})
    code, out_text, err = run_main(str(changed), "--out", str(out), "--no-heldout", "--workers", "1")
    assert code == 0, err
    assert "1 of 2 trials done" in out_text
    assert sum(map(counted, trials_of(out))) == 2


@pytest.mark.parametrize(("change", "words"), [
    ({"scenarios": ["head_on", "paper_fig5"]}, ["scenarios: head_on → head_on, paper_fig5"]),
    ({"train_seeds": {"start": 0, "count": 3}}, ["train_seeds: 0..1 → 0..2"]),
    ({"base": ["planner=wait"]}, ["base: planner=auto → planner=wait"]),
    ({"space": ["planner.h_wait=int(range(1,5))", "planner.safety_margin_cm=interval(0,30)"]},
     ["space: planner.h_wait=int(range(1,4))", "→ planner.h_wait=int(range(1,5))"]),
    ({"objectives": [{"name": "score", "direction": "maximize", "terms": {"success": 1.0}}]},
     ["objectives: score maximize +1*success -0.005*time_to_goal_s fill time_to_goal_s=120 → "
      "score maximize +1*success"]),
    ({"objectives": [{"name": "score", "direction": "minimize", "terms": {"success": 1.0}}]}, ["objectives: "]),
    ({"name": "tiny_b"}, ["name: 'tiny' → 'tiny_b'"]),
    ({"scenarios": ["paper_fig5"], "train_seeds": {"start": 5, "count": 2}},
     ["scenarios: head_on → paper_fig5; train_seeds: 0..1 → 5..6"]),
])
def test_each_field_that_scores_a_trial_is_compared(tmp_path, change, words):
    out = tmp_path / "study"
    out.mkdir()
    create_or_load(load_study_file(write(tmp_path / "tiny.yaml")), open_storage(out, "sqlite"), study_dir=out)
    changed = load_study_file(write(tmp_path / "changed.yaml", **change))
    with pytest.raises(StudyChangedError) as caught:
        create_or_load(changed, open_storage(out, "sqlite"), study_dir=out)
    message = str(caught.value)
    assert message.startswith(f"{changed.path}: ") and "\n" not in message and "another --out" in message
    for word in words:
        assert word in message, message


def test_allowed_fields_are_not_compared(tmp_path):
    out = tmp_path / "study"
    out.mkdir()
    create_or_load(load_study_file(write(tmp_path / "tiny.yaml")), open_storage(out, "sqlite"), study_dir=out)
    allowed = load_study_file(write(tmp_path / "allowed.yaml", trials=40, description="x", sampler="nsga2",
                                    sampler_seed=3, heldout_seeds={"start": 500, "count": 9}))
    study = create_or_load(allowed, open_storage(out, "sqlite"), study_dir=out)
    assert study.user_attrs[DEFINITION]["scenarios"] == ["head_on"]


def forget_record(out: Path) -> None:
    """Make the folder look like one the code before records wrote: no ``definition`` attribute."""
    with sqlite3.connect(out / "study.db") as db:
        db.execute("DELETE FROM study_user_attributes WHERE key = ?", (DEFINITION,))


def test_a_study_stored_before_records_resumes_if_its_logs_agree(tmp_path):
    """A folder without a record is checked against its last completed trial's logs: other scenarios are refused,
    the same file resumes and is recorded from then on; without the logs it cannot be confirmed: refused."""
    out, path = tmp_path / "study", write(tmp_path / "tiny.yaml", trials=1)
    code, _, err = run_main(str(path), "--out", str(out), "--no-heldout")
    assert code == 0, err
    forget_record(out)
    for change, words in (({"scenarios": ["paper_fig5"]}, ["scenarios: head_on → paper_fig5 (trial 0's logs)"]),
                          ({"train_seeds": {"start": 3, "count": 2}}, ["train_seeds: 0..1 → 3..4"]),
                          ({"objectives": [{"metric": "spl", "direction": "maximize"}]}, ["objectives: score → spl"]),
                          ({"objectives": [{"name": "score", "direction": "maximize", "terms": {"spl": 1.0}}]},
                           ["objectives: score of trial 0 is", "from its logs by the file's objective"])):
        code, _, err = run_main(str(write(tmp_path / "changed.yaml", trials=1, **change)), "--out", str(out))
        lock.release(out)
        one_line_error(code, err, "changed.yaml", *words)
        assert code == 2
    code, out_text, err = run_main(str(write(tmp_path / "tiny.yaml", trials=2)), "--out", str(out), "--no-heldout")
    assert code == 0, err
    assert "1 of 2 trials done" in out_text
    study = create_or_load(load_study_file(path), open_storage(out, "sqlite"), study_dir=out)
    assert study.user_attrs[DEFINITION]["scenarios"] == ["head_on"]
    forget_record(out)
    for log in (out / "trials" / "00001").glob("*.mcap"):
        log.unlink()
    code, _, err = run_main(str(path), "--out", str(out), "--no-heldout")
    lock.release(out)
    one_line_error(code, err, str(path), "without a record", "trial 1", "missing", "another --out")
