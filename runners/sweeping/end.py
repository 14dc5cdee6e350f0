"""The end of a sweep, in its launching process: account for every episode, write the summary (and, when the
sweep is complete, the report), and say how to complete a sweep that is not.

Episodes are counted from the sweep directory itself, so that the count is right whatever happened to the jobs'
results (a lost worker loses them): kept by a resume (taken back from ``.fuzzynav/resume/``), run by this sweep (a
log written since it started: finished, or ``interrupted`` by a stop), lost (a ``.*.mcap.partial`` left by a process
that died), and not run (the rest of the episodes the sweep was to run).
"""

from __future__ import annotations

import contextlib
import shlex
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from omegaconf import DictConfig

from analysis.interrupts import SIGNAL_NAMES
from runners.sweeping import control as sweep_control
from runners.sweeping import resume as sweep_resume
from runners.sweeping.outputs import write_report
from runners.sweeping.paths import holding_dir, job_logs, other_outputs, partial_logs
from runners.sweeping.size import count_episodes
from runners.sweeping.summary import write_summary

if TYPE_CHECKING:
    from analysis.metrics import Analysis


def end_of_sweep(config: DictConfig, run: sweep_control.SweepRun, plan: sweep_resume.ResumePlan | None) -> None:
    """Account for every episode (kept, run, interrupted, lost, not run), write ``summary.csv`` and, when the sweep
    completed without a failure, the report. Failures are noted in ``run``; an error writing the summary or the
    report propagates (an ``OSError`` names the file)."""
    from analysis import plots
    from analysis.metrics import analyse_logs

    sweep_dir = run.sweep_dir
    kept = plan.kept - sweep_resume.held_count(sweep_dir) if plan is not None else 0  # taken back by the jobs
    # this sweep's logs: before the resume's leftovers go back, every log but those found at the start and not
    # written again (a sweep into a folder of an earlier one counted the earlier one's other episodes as its own)
    ours = [p for p in job_logs(sweep_dir)
            if str(p) not in run.found or sweep_control.log_fingerprint(p) != run.found[str(p)]]
    in_place, earlier, superseded = sweep_resume.restore(sweep_dir)  # episodes this sweep does not include
    if plan is not None:
        fresh = [p for p in job_logs(sweep_dir) if _written_since(p, run.started)]
        print(f"resume: {kept} complete episode(s) kept, {len(fresh)} run (incomplete, missing or changed)")
        if plan.rerun or plan.removed or in_place or earlier:
            print(f"resume: {plan.rerun} failed or damaged log(s) run again, {plan.removed} extra copies of an "
                  f"episode removed, {in_place + earlier} log(s) of episodes outside this sweep left in the "
                  "directory, not in this summary and report"
                  + (f" ({earlier} moved to {sweep_dir / sweep_resume.EARLIER}: their name is taken)" if earlier
                     else ""))
        if superseded:
            print(f"resume: {superseded} log(s) of episodes this sweep ran again with other code (a changed plug-in "
                  f"or fuzzynav version) kept in {holding_dir(sweep_dir).parent / sweep_resume.SUPERSEDED}, not "
                  "analysed")
    # the launcher's pool shut down first: its threads kept this process from forking the log readers (a sweep of
    # fewer than analysis.logs.PARALLEL_MIN_LOGS logs was read in this process alone); keeping what the report's
    # pictures need (it reads no log again)
    release_worker_pool()
    # a complete sweep gets its report: matplotlib (~0.3 s) is imported while the forked readers read, so that the
    # figures' workers, forked after it, do not each import it again
    report_next = run.stop_signal() is None and not run.errors
    # another sweep's or run's folder inside this one is not this sweep's: its logs stay out of the summary, as do
    # the logs of other episodes an earlier sweep left in this one
    others = len(job_logs(sweep_dir)) - len(ours)
    if others and plan is None:  # (a resume said so above)
        print(f"{others} log(s) of episodes outside this sweep (of an earlier run into {sweep_dir}) left where they "
              f"are, not in this summary and report (python -m analysis.report {shlex.quote(str(sweep_dir))} reads "
              "every log)")
    sources = ours if others or other_outputs(sweep_dir) else [sweep_dir]
    analysis = analyse_logs(sources, jobs=-1, traces=True, meanwhile=plots.pyplot if report_next else None)
    signum = run.stop_signal()
    lost = partial_logs(sweep_dir)
    if signum is None and not run.errors:
        _note_interrupted(run, analysis)
    if analysis.episodes.empty and analysis.excluded.empty and not lost:
        # nothing to summarise: an empty summary and report with exit 0 would look like a result
        run.errors.append(f"no logs found in {sweep_dir}: the sweep ran no episode")
        return
    if signum is None and not run.errors and not lost:
        write_summary(sweep_dir, analysis=analysis)
        report = write_report(sweep_dir, analysis)
        print(f"report: {report / 'report.html'} (and report.md)")
        return
    written = True
    try:  # the summary of what completed; then how to complete the rest, even when the summary cannot be written
        write_summary(sweep_dir, analysis=analysis)
    except OSError as err:
        run.errors.append(sweep_control.io_line(err))
        written = False
    _report_incomplete(config, run, analysis, kept, lost, written)


def release_worker_pool() -> None:
    """Shut down joblib's worker pool (the launcher's; its workers are idle once the jobs are done): its threads
    would keep the log readers and the report's figures from running in worker processes forked from this one
    (:mod:`analysis.forked`). A later use of joblib starts a new pool."""
    try:
        from joblib.externals.loky import reusable_executor
    except ImportError:
        return
    executor = getattr(reusable_executor, "_executor", None)
    if executor is not None:
        with contextlib.suppress(Exception):  # a pool that is already broken or shutting down
            executor.shutdown(wait=True)


def _note_interrupted(run: sweep_control.SweepRun, analysis: Analysis) -> None:
    """A job that stopped on its own before it finished (a Slurm job at its time limit: the episode in flight is
    logged as interrupted, its later seeds are not run) leaves the sweep incomplete, though no one stopped the
    sweep: one error line naming the first such log and why."""
    from analysis.logs import LogFile

    logs = sorted(str(log) for frame in (analysis.episodes, analysis.excluded) if not frame.empty
                  for log, outcome in zip(frame["log"], frame["outcome"], strict=True)
                  if outcome == "interrupted" and _written_since(Path(log), run.started))
    if logs:
        reason = "interrupted"
        try:  # the reason the job logged (the /episode message), e.g. its time limit
            for _topic, _t, msg in LogFile(logs[0], ["/episode"]).messages(["/episode"]):
                reason = str(msg.get("reason") or reason)[:200]
        except Exception:  # the log was analysed a moment ago; whatever happened since, the count stands
            pass
        run.fail(f"{len(logs)} episode(s) stopped before they finished ({reason}), e.g. {logs[0]}; their jobs did "
                 "not run their later seeds")


def _written_since(path: Path, started: float) -> bool:
    """``path`` was written after ``started`` (s since the epoch): by this sweep, not kept from an earlier one."""
    try:
        return path.stat().st_mtime >= started
    except OSError:
        return False


def _report_incomplete(config: DictConfig, run: sweep_control.SweepRun, analysis: Analysis, kept: int,
                       lost: list[Path], summary_written: bool) -> None:
    """What did not complete and how to complete it (stdout); the report is left for the complete sweep.
    ``kept``: episodes a resume kept; ``lost``: partial logs of episodes whose process died."""
    outcomes = {str(log): outcome for frame in (analysis.episodes, analysis.excluded) if not frame.empty
                for log, outcome in zip(frame["log"], frame["outcome"], strict=True)}
    fresh = [outcomes.get(str(p)) for p in job_logs(run.sweep_dir) if _written_since(p, run.started)]
    interrupted = sum(1 for o in fresh if o == "interrupted")
    total = count_episodes(config)
    not_run = f", {max(total - kept - len(fresh) - len(lost), 0)} not run (of {total})" if total is not None else ""
    signum = run.stop_signal()
    what = f"stopped by {SIGNAL_NAMES[signum]}" if signum is not None else "incomplete"
    summary = run.sweep_dir / "summary.csv"
    print(f"{what}: {len(fresh) - interrupted} episode(s) finished, {interrupted} interrupted, {len(lost)} lost"
          f"{not_run}" + (f"; every log is in {summary}" if summary_written and summary.exists() else ""))
    if lost:
        shown = ", ".join(str(p) for p in lost[:3]) + (f" and {len(lost) - 3} more" if len(lost) > 3 else "")
        print(f"lost: {len(lost)} episode(s) did not finish because their process died (partial logs, readable by "
              f"runners.replay: {shown})")
    print(f"to complete the sweep: {resume_command(run.sweep_dir)}")


def resume_command(sweep_dir: Path) -> str:
    """This sweep's command line with ``hydra.sweep.dir=<sweep_dir> resume=true``."""
    args = [a for a in sys.argv[1:]
            if a not in ("--multirun", "-m") and not a.startswith(("hydra.sweep.dir=", "resume="))]
    return shlex.join(["python", "-m", "runners.sweep", *args, f"hydra.sweep.dir={sweep_dir}", "resume=true"])
