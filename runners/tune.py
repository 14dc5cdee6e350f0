"""Tune a method by optimisation: ``python -m runners.tune STUDY`` (issue #39; docs/tuning.md).

    python -m runners.tune h_wait_margin           # conf/tune/h_wait_margin.yaml, into studies/h_wait_margin/
    python -m runners.tune my_study.yaml --out studies/x --trials 40 --workers 2
    python -m runners.tune h_wait_margin --storage journal --workers 8   # Optuna's journal file for many workers
    python -m runners.tune h_wait_margin --no-heldout          # trials only (held-out evaluation later)
    python -m runners.tune h_wait_margin --workers 8 --launcher slurm hydra.launcher.partition=cpu  # a job array
    python -m runners.tune --compare suite_v2         # conf/tune/compare/suite_v2.yaml: every study, one report
    python -m runners.tune h_wait_margin --to-journal  # its SQLite study moved to the journal file (for Slurm)

The study file names the search space (Hydra's override grammar), the objectives (metrics of the analysis),
the scenarios and the training and held-out seeds (:mod:`runners.tuning.study_file`). The study lives in Optuna's
storage in the study folder; re-running the command resumes it (the trials a stopped command left in flight run
again), if the study file still describes the stored study: a file changed in what scores a trial is refused in
one line (:mod:`runners.tuning.study_record`). After the trials the best trial (each evaluated Pareto trial for
two objectives) and the default are run on the held-out seeds, and ``<study>/report/`` gets the study report
with its figures (:mod:`runners.tuning.report`). Exit status: 0 done, 1 no trial completed or a run failed,
2 bad input, 130/143 stopped.
"""

from __future__ import annotations

import argparse
import multiprocessing
import sys
import time
from pathlib import Path

from runners.tuning.slurm_workers import LAUNCHERS, OVERRIDE_PREFIXES
from runners.tuning.storage import KINDS
from runners.tuning.worker import print_trial, worker

EXIT_INPUT = 2


def parse_args(argv: list[str]) -> argparse.Namespace:
    from analysis.cli_args import OneLineParser

    parser = OneLineParser(prog="python -m runners.tune", description=__doc__.split("\n\n")[0])
    parser.add_argument("study", nargs="?", help="a study name (conf/tune/<name>.yaml) or a study file")
    parser.add_argument("--compare", metavar="COMPARISON",
                        help="instead of one study, every study of a comparison (conf/tune/compare/<name>.yaml or a "
                             "file) and one report (runners.tuning.comparison)")
    parser.add_argument("--out", help="the study folder (default: studies/<name>)")
    parser.add_argument("--trials", type=int, help="trials in all (default: the study file's)")
    parser.add_argument("--workers", type=int, default=1, help="worker processes (or Slurm tasks) sharing the study")
    parser.add_argument("--storage", choices=KINDS, help="sqlite (default) or journal (many workers, Slurm)")
    parser.add_argument("--launcher", choices=LAUNCHERS, default="local", help="where the workers run: local "
                        "processes, or a Slurm job array (conf/hydra/launcher/slurm.yaml)")
    parser.add_argument("launcher_options", nargs="*", metavar="hydra.launcher.KEY=VALUE",
                        help="with --launcher slurm: options of the Slurm preset (partition, account, timeout_min ...)")
    parser.add_argument("--no-heldout", action="store_true", help="no held-out evaluation and report")
    parser.add_argument("--to-journal", action="store_true",
                        help="only move the study folder's SQLite study (study.db) to the journal file that Slurm "
                             "workers share, checked trial by trial; the database is kept as study.db.converted "
                             "(runners.tuning.storage_copy)")
    args = parser.parse_intermixed_args(argv)
    if args.compare is not None and args.study is not None and args.study.startswith(OVERRIDE_PREFIXES):
        args.study, args.launcher_options = None, [args.study, *args.launcher_options]  # no study: an option
    if (args.study is None) == (args.compare is None):
        parser.error("name a study, or a comparison with --compare (not both)")
    if args.compare is not None and args.no_heldout:
        parser.error("--no-heldout: a comparison compares held-out results")
    if args.launcher_options and args.launcher != "slurm":
        parser.error(f"{args.launcher_options[0][:80]!r}: launcher options need --launcher slurm")
    if args.to_journal:
        given = [flag for flag, on in (("--compare", args.compare is not None), ("--trials", args.trials is not None),
                                       ("--workers", args.workers != 1), ("--storage", args.storage is not None),
                                       ("--launcher", args.launcher != "local"), ("--no-heldout", args.no_heldout))
                 if on]
        if given or args.launcher_options:
            parser.error(f"--to-journal only converts the study's storage: leave out "
                         f"{given[0] if given else args.launcher_options[0][:80]!r}, then run the study again")
    if args.launcher == "slurm" and args.storage == "sqlite":
        parser.error("--storage sqlite: Slurm workers share the study through the journal file (SQLite locks badly "
                     "over a shared file system); leave --storage out")
    if args.out is not None and not args.out.strip():  # "" would be the current folder
        parser.error("--out: an empty path; name the study folder")
    args.out = Path(args.out) if args.out is not None else None
    if args.trials is not None and not 1 <= args.trials <= 100_000:
        parser.error(f"--trials: {args.trials} is outside [1, 100000]")
    if not 1 <= args.workers <= 256:
        parser.error(f"--workers: {args.workers} is outside [1, 256]")
    return args


def check_space(spec) -> None:
    """Compose and validate the base configuration on each scenario, and each parameter at its bounds (each
    choice), before any trial: an unknown key, an option that does not exist or a bound outside a field's range
    is one line naming the study file and the entry."""
    from optuna.distributions import CategoricalDistribution

    from runners.tuning.episodes import ConfigurationError, check_configuration, hydra_conf
    from runners.tuning.space import format_value
    from runners.tuning.study_file import StudyFileError

    with hydra_conf():
        for i, scenario in enumerate(spec.scenarios):
            try:
                check_configuration(spec.base, scenario, spec.train)
            except ConfigurationError as err:
                raise StudyFileError(f"{spec.path}: scenarios[{i}] ({scenario}) with base: {err}") from None
        if spec.controller_space:  # the base controller's variables, as partitions, and Table 1 back from them
            from runners.tuning import controller_space
            from runners.tuning.study import partition_groups

            try:
                groups = partition_groups(spec)
                check_configuration([*spec.base, *controller_space.overrides(
                    groups, controller_space.start_values(groups))], spec.scenarios[0], spec.train)
            except (controller_space.ControllerSpaceError, ConfigurationError) as err:
                raise StudyFileError(f"{spec.path}: {err}") from None
        if spec.controller_rules:  # the base controller's rules, and Table 1 back from their outputs
            from runners.tuning import rule_space
            from runners.tuning.study import rule_outputs

            try:
                space = rule_outputs(spec)
                check_configuration([*spec.base, *rule_space.overrides(space, rule_space.start_values(space))],
                                    spec.scenarios[0], spec.train)
            except (rule_space.RuleSpaceError, ConfigurationError) as err:
                raise StudyFileError(f"{spec.path}: {err}") from None
        for i, p in enumerate(spec.space):
            d = p.distribution
            points = d.choices if isinstance(d, CategoricalDistribution) else (d.low, d.high)
            for value in points:
                try:
                    check_configuration([*spec.base, f"{p.key}={format_value(value)}"], spec.scenarios[0], spec.train)
                except ConfigurationError as err:
                    raise StudyFileError(f"{spec.path}: space[{i}] ({p.key}={format_value(value)}): {err}") from None


def main(argv: list[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.compare is not None:
        from runners.tuning.comparison import compare_command

        return compare_command(args, main, check_space)
    from runners.sweeping import lock
    from runners.sweeping.paths import lock_file
    from runners.tuning.storage import StorageError, existing_kind, open_storage
    from runners.tuning.study import create_or_load
    from runners.tuning.study_file import StudyFileError, find_study_file, load_study_file

    try:
        spec = load_study_file(find_study_file(args.study))
        study_dir = args.out if args.out is not None else Path("studies") / spec.name
        if args.launcher == "slurm":  # composed and checked before anything is written
            from runners.tuning import slurm_workers

            args.slurm = slurm_workers.prepare(args.launcher_options, study_dir, spec.name)
        try:
            lock.acquire(study_dir)
        except lock.SweepLockError:
            holder = lock_file(study_dir).read_text(errors="replace").strip()[:200] or "another process"
            raise StorageError(f"{study_dir}: the study folder is in use by {holder} (lock {lock_file(study_dir)}): "
                               "wait for it to finish (or add workers to it with --workers) or choose another --out") \
                from None
        if args.to_journal:
            try:
                return convert_to_journal(spec, study_dir)
            finally:
                lock.release(study_dir)
        from runners.tuning.slurm_workers import refuse_live_array

        refuse_live_array(study_dir)
        kind = existing_kind(study_dir)
        if kind is not None and args.storage not in (None, kind):
            raise StorageError(f"{study_dir}: the study is stored in {kind}; --storage {args.storage} would start "
                               "another one")
        kind = kind or args.storage or ("journal" if args.launcher == "slurm" else "sqlite")
        if args.launcher == "slurm":
            slurm_workers.storage_kind(kind, study_dir, args.study)
        check_space(spec)
        study = create_or_load(spec, open_storage(study_dir, kind), study_dir=study_dir)
    except (StudyFileError, StorageError, ValueError) as err:
        print(f"error: {' '.join(str(err).split())}"[:600], file=sys.stderr)
        return EXIT_INPUT
    except OSError as err:
        print(f"error: {err.filename or study_dir}: {err.strerror or err}", file=sys.stderr)
        return EXIT_INPUT
    try:
        return study_command(args, spec, study, study_dir, kind)
    finally:
        lock.release(study_dir)  # the kernel releases it at exit too; a caller in the same process may go on


def convert_to_journal(spec, study_dir: Path) -> int:
    """``--to-journal``: the study folder's SQLite study copied to its journal file (the folder locked)."""
    from runners.tuning.storage_copy import converted_path, to_journal

    trials, journal = to_journal(study_dir, spec.name)
    print(f"study {spec.name}: {trials} trials copied to {journal} and checked; the SQLite database is kept as "
          f"{converted_path(study_dir)}. Resume it with: python -m runners.tune {spec.path} --out {study_dir} "
          "[--launcher slurm]", flush=True)
    return 0


def study_command(args: argparse.Namespace, spec, study, study_dir: Path, kind: str) -> int:
    """The trials, the held-out evaluation and the report of a study whose folder this process has locked."""
    from runners.tuning.storage import FILES, storage_problem
    from runners.tuning.study import counted, fail_interrupted

    stale = fail_interrupted(study)
    if stale:
        print(f"trials {', '.join(map(str, stale))} were left in flight by a stopped command: marked interrupted, "
              "run again", file=sys.stderr)
    budget = args.trials or spec.trials
    done = sum(counted(t) for t in study.get_trials(deepcopy=False))
    print(f"study {spec.name}: {study_dir / ('study.db' if kind == 'sqlite' else 'study.journal')}; {done} of "
          f"{budget} trials done; {len(spec.scenarios)} scenarios x {spec.train.count} training seeds per trial",
          flush=True)
    tic = time.perf_counter()
    try:
        code = run_workers(args, spec, study, study_dir, kind, budget)
    except Exception as err:
        if not storage_problem(err):
            raise
        print(f"error: {study_dir / FILES[kind]}: the study storage failed: {' '.join(str(err).split())[:300]}; "
              "the trials told so far are kept: re-run the command to resume", file=sys.stderr)
        return 1
    if code:
        return code
    trials = study.get_trials(deepcopy=False)
    complete = [t for t in trials if t.state.name == "COMPLETE"]
    failed = [t for t in trials if counted(t) and t.state.name == "FAIL"]
    print(f"{len(complete)} trials completed, {len(failed)} failed ({time.perf_counter() - tic:.0f} s)", flush=True)
    if not complete:
        first = failed[0].user_attrs.get("fail_reason", "") if failed else "no trial ran"
        print(f"error: no trial completed; first failure: {first}"[:600], file=sys.stderr)
        return 1
    if args.no_heldout:
        return 0
    from runners.tuning.heldout import evaluate
    from runners.tuning.report import write_report

    try:
        with_heldout = evaluate(study, spec, study_dir)
        report = write_report(study, spec, study_dir, with_heldout)
    except KeyboardInterrupt:
        print("interrupted: held-out evaluation stopped; re-run the command to do it again", file=sys.stderr)
        return 130
    print(f"report: {report}")
    return 0


def run_workers(args: argparse.Namespace, spec, study, study_dir: Path, kind: str, budget: int) -> int:
    """Run the trials in this process (one worker), in ``--workers`` processes sharing the study, or in a Slurm
    job array of ``--workers`` tasks (:mod:`runners.tuning.slurm_workers`)."""
    from analysis.interrupts import Interrupted
    from runners.sweeping import stop
    from runners.tuning.study import run_trials

    if args.launcher == "slurm":
        from runners.tuning.slurm_workers import run_on_slurm

        return run_on_slurm(args.slurm, spec, study, study_dir, kind, budget, args.workers, print_trial(spec))
    if args.workers == 1:
        restore = stop.install(None)
        try:
            run_trials(study, spec, study_dir, budget, print_trial(spec))
        except (KeyboardInterrupt, Interrupted):
            print("interrupted: the trial in flight is marked interrupted; re-run the command to resume",
                  file=sys.stderr)
            return 130
        finally:
            restore()
        return 0
    context = multiprocessing.get_context("spawn")  # fresh processes: no SQLite connection crosses a fork
    procs = [context.Process(target=worker, args=(str(spec.path), str(study_dir), kind, budget, i))
             for i in range(args.workers)]
    for p in procs:
        p.start()
    try:
        for p in procs:
            p.join()
    except KeyboardInterrupt:  # the terminal's Ctrl-C reached the workers too: wait for their trials to end
        for p in procs:
            p.join()
        print("interrupted: the trials in flight are marked interrupted; re-run the command to resume",
              file=sys.stderr)
        return 130
    bad = [p.exitcode for p in procs if p.exitcode]
    if bad:
        print(f"error: {len(bad)} of {len(procs)} workers failed (exit {bad[0]}); re-run the command to resume",
              file=sys.stderr)
        return 130 if bad[0] in (130, -2) else 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
