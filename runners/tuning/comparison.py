"""``python -m runners.tune --compare NAME``: every study of a comparison file tuned on the same budget, evaluated
on the same held-out seeds, and one comparison report (issue #39; docs/tuning.md).

The comparison file (:mod:`runners.tuning.comparison_file`) and every study's space are checked before any trial.
Then each study runs, or resumes, in ``<out>/<study name>/`` through the study command itself
(:func:`runners.tune.main`, trials only), and is evaluated on the held-out seeds (:mod:`runners.tuning.heldout`,
with its own study report). A study whose held-out evaluation is complete for its current best trial is not
evaluated again: ``<study>/heldout/evaluated.json`` records it, written once the evaluation and the study report
are done, and its logs are read back. So re-running the command after a kill continues where it stopped. Last,
``<out>/report/`` gets the comparison report (:mod:`runners.tuning.comparison_report`).

Exit status: 0 done, 1 a study failed, 2 bad input, 130/143 stopped.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from pathlib import Path
from typing import Any

from runners.tuning.comparison_file import Comparison, ComparisonFileError, find_comparison_file, load_comparison
from runners.tuning.study_file import StudyFileError, StudySpec

EXIT_INPUT = 2
EVALUATED = "evaluated.json"  # in <study>/heldout/: the held-out evaluation that is complete


class ComparisonStopped(RuntimeError):
    """A study of the comparison ended with a non-zero exit status (its command printed why)."""

    def __init__(self, code: int) -> None:
        super().__init__(code)
        self.code = code


def _error(text: str) -> int:
    print(f"error: {' '.join(text.split())}"[:600], file=sys.stderr)
    return EXIT_INPUT


def compare_command(args: argparse.Namespace, main: Any, check_space: Any) -> int:
    """The comparison command (``args`` as :func:`runners.tune.parse_args` parses them, ``args.compare`` set)."""
    from runners.sweeping import lock

    try:
        comparison = load_comparison(find_comparison_file(args.compare), args.trials)
    except ComparisonFileError as err:
        return _error(str(err))
    out = args.out if args.out is not None else Path("studies") / comparison.name
    try:
        lock.acquire(out)
    except lock.SweepLockError:
        return _error(f"{out}: the comparison folder is in use by another command: wait for it to finish or choose "
                      "another --out")
    except OSError as err:
        return _error(f"{err.filename or out}: {err.strerror or err}")
    try:
        return run_comparison(args, comparison, out, main, check_space)
    except KeyboardInterrupt as err:  # Ctrl-C (or SIGTERM: analysis.interrupts.Interrupted) between two steps
        signum = getattr(err, "signum", signal.SIGINT)
        print(f"interrupted: comparison {comparison.name} stopped; re-run the command to resume", file=sys.stderr)
        return 128 + signum
    except ComparisonStopped as err:
        return err.code
    finally:
        lock.release(out)


def check_before_trials(comparison: Comparison, out: Path, storage: str | None, check_space: Any) -> None:
    """What :func:`runners.tune.main` checks for one study, for every study before the first runs: each space
    composes and validates, and a study folder that exists already holds a study of this name, directions and
    space in storage of the kind asked for."""
    from runners.tuning.storage import StorageError, existing_kind, open_storage
    from runners.tuning.study import create_or_load

    for spec in comparison.studies:
        try:
            check_space(spec)
            kind = existing_kind(out / spec.name)
            if kind is None:
                continue
            if storage not in (None, kind):
                raise StorageError(f"{out / spec.name}: the study is stored in {kind}; --storage {storage} would "
                                   "start another one")
            create_or_load(spec, open_storage(out / spec.name, kind), study_dir=out / spec.name)
        except (StudyFileError, StorageError, ValueError) as err:
            raise ComparisonFileError(f"{err} (comparison {comparison.path})") from None


def run_comparison(args: argparse.Namespace, comparison: Comparison, out: Path, main: Any, check_space: Any) -> int:
    from runners.tuning.comparison_report import write_comparison_report
    from runners.tuning.storage import StorageError

    try:
        check_before_trials(comparison, out, args.storage, check_space)
    except ComparisonFileError as err:
        return _error(str(err))
    n = len(comparison.studies)
    print(f"comparison {comparison.name}: {n} studies, each {comparison.reference.trials} trials x "
          f"{len(comparison.reference.scenarios)} scenarios x {comparison.reference.train.count} training seeds = "
          f"{comparison.budget} episodes; held-out seeds {comparison.reference.heldout.text()}; in {out}", flush=True)
    results = []
    for i, spec in enumerate(comparison.studies, 1):
        print(f"== study {i} of {n}: {spec.name} ({spec.path})", flush=True)
        argv = [str(spec.path), "--out", str(out / spec.name), "--trials", str(spec.trials), "--workers",
                str(args.workers), "--no-heldout", *(["--storage", args.storage] if args.storage else []),
                "--launcher", args.launcher, *args.launcher_options]
        code = main(argv)
        if code:
            raise ComparisonStopped(code)
        try:
            results.append(heldout_results(spec, out / spec.name))
        except (StorageError, OSError) as err:  # the storage or the disk failed after the trials: kept, resumable
            what = f"{err.filename}: {err.strerror or err}" if isinstance(err, OSError) and err.filename else err
            print(f"error: {' '.join(str(what).split())[:400]}; the trials are kept: re-run the command to resume",
                  file=sys.stderr)
            return 1
    report = write_comparison_report(comparison, out, results)
    print(f"report: {report}")
    return 0


def _labels(chosen: list[int]) -> list[str]:
    """The held-out folders' names, as :func:`runners.tuning.heldout.evaluate` names them."""
    return ["default", *("tuned" if len(chosen) == 1 else f"trial_{n}" for n in chosen)]


def _current(spec: StudySpec, study: Any, chosen: list[int]) -> dict[str, Any]:
    """What a held-out evaluation of the study as it is now is of: its counted trials, the configurations
    evaluated (the default, then the chosen trials) and the held-out episodes."""
    from runners.tuning.study import counted

    return {"study": spec.name, "counted_trials": sum(counted(t) for t in study.get_trials(deepcopy=False)),
            "scenarios": list(spec.scenarios), "heldout_seeds": [spec.heldout.start, spec.heldout.count],
            "trials": [None, *chosen]}


def _read_back(spec: StudySpec, study: Any, study_dir: Path, chosen: list[int]) -> list | None:
    """The recorded held-out evaluation read back from its logs, if it is the one the study's current trials call
    for and its logs are all there; else None (evaluate again)."""
    from analysis.metrics import metrics_table
    from analysis.objectives import objective_value
    from runners.tuning.episodes import EpisodeResults
    from runners.tuning.heldout import HELDOUT_DIR, Evaluated
    from runners.tuning.study import OVERRIDES

    try:
        recorded = json.loads((study_dir / HELDOUT_DIR / EVALUATED).read_text())
        same = [bool(flag) for flag in recorded.pop("same_as_default")]
    except (OSError, ValueError, TypeError, KeyError, AttributeError):  # absent, or not a record of ours
        return None
    if recorded != _current(spec, study, chosen) or len(same) != len(chosen) + 1 or same[0]:
        return None
    evaluated: list[Evaluated] = []
    for label, number, same_as_default in zip(_labels(chosen), [None, *chosen], same, strict=True):
        overrides = list(spec.base) if number is None else list(study.trials[number].user_attrs[OVERRIDES])
        if same_as_default:
            first = evaluated[0]
            evaluated.append(Evaluated(label, overrides, number, first.results, first.objectives, True))
            continue
        logs = sorted((study_dir / HELDOUT_DIR / label).glob("*.mcap"))
        if len(logs) != len(spec.scenarios) * spec.heldout.count:
            return None
        episodes, excluded = metrics_table(logs)
        evaluated.append(Evaluated(label, overrides, number, EpisodeResults(episodes, excluded, logs),
                                   {o.name: objective_value(episodes, o) for o in spec.objectives}))
    return evaluated


def heldout_results(spec: StudySpec, study_dir: Path) -> tuple[StudySpec, Any, list]:
    """(spec, study, evaluated): the study's default and best trials on the held-out seeds, evaluated now (with
    the study report) unless a complete evaluation of the same trials is on disk."""
    from runners.sweeping import lock, stop
    from runners.tuning.heldout import HELDOUT_DIR, chosen_trials, evaluate
    from runners.tuning.report import write_report
    from runners.tuning.storage import existing_kind, open_storage
    from runners.tuning.study import create_or_load

    try:
        lock.acquire(study_dir)
    except lock.SweepLockError:
        print(f"error: {study_dir}: the study folder is in use by another command: wait for it to finish",
              file=sys.stderr)
        raise ComparisonStopped(EXIT_INPUT) from None
    try:
        study = create_or_load(spec, open_storage(study_dir, existing_kind(study_dir) or "sqlite"), study_dir=study_dir)
        chosen = [t.number for t in chosen_trials(study)]
        previous = _read_back(spec, study, study_dir, chosen)
        if previous is not None:
            print(f"held-out: {spec.name} already evaluated (trial {', '.join(map(str, chosen))}): its logs are read "
                  "back", flush=True)
            return spec, study, previous
        marker = study_dir / HELDOUT_DIR / EVALUATED
        marker.unlink(missing_ok=True)  # evaluated again: incomplete until the record is written
        restore = stop.install(None)  # a Ctrl-C finishes the episode's log as interrupted, then stops
        try:
            evaluated = evaluate(study, spec, study_dir)
        finally:
            restore()
        print(f"study report: {write_report(study, spec, study_dir, evaluated)}", flush=True)
        record = {**_current(spec, study, chosen), "same_as_default": [ev.same_as_default for ev in evaluated]}
        tmp = marker.with_name(f".{EVALUATED}.partial")
        tmp.write_text(json.dumps(record, indent=1))
        tmp.replace(marker)
        return spec, study, evaluated
    finally:
        lock.release(study_dir)
