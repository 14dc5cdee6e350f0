"""One worker of a study (a local process of ``python -m runners.tune --workers N``, or a Slurm array task):
open the study and run trials until the budget is reached; and how each trial is printed as it ends."""

from __future__ import annotations

import sys
from pathlib import Path


def worker(study_file: str, study_dir: str, kind: str, budget: int, index: int) -> None:
    """One worker process: open the study and run trials until the budget is reached (a Ctrl-C or SIGTERM ends
    the trial in flight as interrupted)."""
    from analysis.interrupts import Interrupted
    from runners.sweeping import process_tree, stop
    from runners.tuning.storage import FILES, open_storage, storage_problem
    from runners.tuning.study import create_or_load, run_trials
    from runners.tuning.study_file import load_study_file

    process_tree.exit_with_parent()
    stop.install(None)
    spec = load_study_file(Path(study_file))
    study = create_or_load(spec, open_storage(Path(study_dir), kind), index, Path(study_dir))
    try:
        run_trials(study, spec, Path(study_dir), budget, print_trial(spec))
    except (KeyboardInterrupt, Interrupted):
        sys.exit(130)
    except Exception as err:
        if not storage_problem(err):
            raise
        print(f"error: worker {index}: {Path(study_dir) / FILES[kind]}: the study storage failed: "
              f"{' '.join(str(err).split())[:300]}", file=sys.stderr)
        sys.exit(1)


def print_trial(spec):
    from optuna.trial import TrialState

    from runners.tuning.controller_space import PREFIX
    from runners.tuning.rule_space import PREFIX as RULE_PREFIX
    from runners.tuning.study import FAIL_REASON, OVERRIDES

    def show(t) -> None:
        shown = t.user_attrs.get(OVERRIDES, [])[len(spec.base):len(spec.base) + len(spec.space)]
        partition = sum(k.startswith(PREFIX) for k in t.params)
        outputs = sum(k.startswith(RULE_PREFIX) for k in t.params)
        params = " ".join([*shown, *([f"+ {partition} controller partition coordinates"] if partition else []),
                           *([f"+ {outputs} rule outputs"] if outputs else [])])
        seconds = (t.datetime_complete - t.datetime_start).total_seconds() if t.datetime_complete else 0.0
        if t.state == TrialState.COMPLETE:
            values = " ".join(f"{o.name}={v:.4g}" for o, v in zip(spec.objectives, t.values, strict=True))
            print(f"trial {t.number}: {values}  ({params}) [{seconds:.1f} s]", flush=True)
        else:
            print(f"trial {t.number} failed: {t.user_attrs.get(FAIL_REASON, 'interrupted')}  ({params})", flush=True)
    return show
