"""The parts of a sweep's fault handling, in this process: the directory lock, the stop file, log files written
under a temporary name and a failed write, files written whole or not at all (summary, report), the end of a sweep
that fails, and the resume's setting aside and restoring of logs. The same faults through the real commands:
tests/test_sweep_faults.py."""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from omegaconf import OmegaConf

from analysis import interrupts
from analysis.logs import episode_summary, is_complete, iter_messages, read_metadata
from fuzzynav.config import episode_config_from_dict
from fuzzynav.controller.fuzzy_fast import FastEvaluator
from fuzzynav.episode_identity import episode_key, episode_key_of
from runners.logs.mcap_log import SDK_LOGGER, EpisodeLogWriter, LogWriteError, partial_path
from runners.run import run_episode
from runners.sweeping import control as sweep_control
from runners.sweeping import lock as sweep_lock
from runners.sweeping import resume as sweep_resume
from runners.sweeping import stop
from tests.conftest import ROOT, load_controller, load_scenario
from tests.tmpfs import tmpfs_mounter

EVALUATOR = FastEvaluator(load_controller("table1"))


def episode(path: Path, seed: int = 0, scenario: str = "head_on", config: str = "dt: 1.0\n") -> dict:
    """One real episode (about 45 steps) logged at ``path``; its config hash is that of ``config`` and ``seed``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return run_episode(load_scenario(scenario), EVALUATOR, episode_config_from_dict({}), seed, path, config)


@pytest.fixture
def tmpfs(tmp_path):
    yield from tmpfs_mounter(tmp_path)


def test_the_lock_names_its_holder_and_dies_with_it(tmp_path):
    code = ("import sys, time; from pathlib import Path; from runners.sweeping.lock import acquire; "
            "acquire(Path(sys.argv[1])); print('held', flush=True); time.sleep(60)")
    holder = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], cwd=ROOT, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(sweep_lock.SweepLockError, match=rf"in use by another sweep \(pid {holder.pid} on "):
            sweep_lock.acquire(tmp_path)
    finally:
        holder.kill()
        holder.wait()
    sweep_lock.acquire(tmp_path)  # the lock file is still there, the lock is not: a dead holder blocks nobody
    assert f"pid {os.getpid()} on " in (tmp_path / ".fuzzynav" / "lock").read_text()
    sweep_lock.release(tmp_path)


def test_the_stop_file_ends_the_episode_in_flight_as_interrupted(tmp_path):
    sweep_dir = tmp_path / "sweep"
    restore = stop.install(sweep_dir)
    stop.check()  # no stop file: nothing happens
    restore()
    assert stop.request_sweep_stop(sweep_dir, signal.SIGTERM, "sweep stopped (SIGTERM to the launching process)")
    restore = stop.install(sweep_dir)  # a job starting now looks at the stop file at its first check
    log = sweep_dir / "0" / "x.mcap"
    try:
        with pytest.raises(interrupts.Interrupted) as raised:
            episode(log)
    finally:
        restore()
        stop.clear_sweep_stop(sweep_dir)
    assert raised.value.signum == signal.SIGTERM and interrupts.exit_code(raised.value) == 143
    assert is_complete(log) and not partial_path(log).exists()
    row = episode_summary(log)
    assert row["outcome"] == "interrupted" and row["steps"] == 1  # stopped after its first step
    (_topic, _t, message), = iter_messages(log, ["/episode"])
    assert message["reason"] == "sweep stopped (SIGTERM to the launching process)"
    assert stop.read_sweep_stop(sweep_dir / ".fuzzynav" / "stop") is None


def test_a_log_is_written_under_a_temporary_name_until_it_is_finished(tmp_path):
    from fuzzynav.episode import Episode

    path = tmp_path / "x.mcap"
    ep = Episode(load_scenario("head_on"), EVALUATOR, episode_config_from_dict({}), seed=0)
    log = EpisodeLogWriter(path, ep, {"seed": "0"}, "auto", "laser")
    for record in ep.run():
        log.step(record)
        assert not path.exists() and partial_path(path).exists()
    log.finish(ep.outcome or "error")
    assert is_complete(path) and not partial_path(path).exists()
    assert partial_path(path).name == ".x.mcap.partial"


def test_a_failed_write_is_one_error_naming_the_log_and_leaves_no_file(tmp_path, monkeypatch):
    """The SDK reports a failed write (here: simulated, as it reports ENOSPC) on its logger instead of raising."""
    written = []
    original = EpisodeLogWriter._write

    def failing(self, topic, t, message):
        written.append(topic)
        if len(written) == 200:
            logging.getLogger(SDK_LOGGER).warning('error logging message: McapError(Io(Os { code: 28, kind: '
                                                  'StorageFull, message: "No space left on device" }))')
        original(self, topic, t, message)

    monkeypatch.setattr(EpisodeLogWriter, "_write", failing)
    path = tmp_path / "x.mcap"
    with pytest.raises(LogWriteError) as raised:
        episode(path)
    err = raised.value
    assert str(err) == f"{path}: cannot write the log: No space left on device"
    assert err.errno == errno.ENOSPC and err.filename == str(path)
    assert not path.exists() and not partial_path(path).exists()
    monkeypatch.undo()
    assert episode(tmp_path / "next.mcap")["outcome"] == "goal"  # the process's log slot was released


def test_a_full_disk_is_one_error_naming_the_log(tmpfs):
    """The same on a real 96 KB file system: the first log fits, the second does not."""
    disk = tmpfs("96k")
    assert episode(disk / "first.mcap")["outcome"] == "goal"
    with pytest.raises(LogWriteError, match=rf"^{disk / 'second.mcap'}: cannot write the log: No space left on "):
        episode(disk / "second.mcap", seed=1)
    assert sorted(p.name for p in disk.iterdir()) == ["first.mcap"] and is_complete(disk / "first.mcap")


def test_summary_and_report_are_written_whole_or_not_at_all(tmp_path, monkeypatch):
    import analysis.report as report_module
    from analysis.metrics import analyse_logs
    from runners.sweeping.outputs import write_report, write_whole

    for seed in (0, 1):
        episode(tmp_path / "0" / f"s{seed}.mcap", seed)
    analysed = analyse_logs([tmp_path])
    report = write_report(tmp_path, analysed)
    assert (report / "report.html").exists() and (report / "episodes.csv").exists()

    def half_written(paths, out, **kwargs):
        out.mkdir(parents=True)
        (out / "box.png").write_bytes(b"png")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(report_module, "build_report", half_written)
    with pytest.raises(OSError) as raised:
        write_report(tmp_path, analysed)
    assert raised.value.filename == str(tmp_path / "report") and "No space left on device" in str(raised.value)
    assert (report / "report.html").exists() and not (report / "box.png").exists()  # the earlier report, whole
    assert not (tmp_path / ".report.partial").exists()

    def full(f):
        f.write("log,outcome\n")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OSError) as raised:
        write_whole(tmp_path / "summary.csv", full)
    assert raised.value.filename == str(tmp_path / "summary.csv")
    assert not (tmp_path / "summary.csv").exists() and not (tmp_path / ".summary.csv.partial").exists()


@pytest.mark.parametrize("failure, line", [
    (ValueError("boom"), "error: writing the summary failed: ValueError: boom"),
    (OSError(errno.ENOSPC, "No space left on device", "/data/s/summary.csv"),
     "error: /data/s/summary.csv: No space left on device")])
def test_a_failing_end_of_sweep_exits_non_zero_with_one_line(tmp_path, monkeypatch, capsys, failure, line):
    """Hydra turns an exception raised in a callback into a warning (and the sweep would exit 0 without a
    summary): the callback makes it one line and exit status 1."""
    import runners.sweep
    import runners.sweeping.end

    def broken(config, run, plan):
        raise failure

    monkeypatch.setattr(runners.sweeping.end, "end_of_sweep", broken)
    monkeypatch.setattr(sweep_control, "_CURRENT", [sweep_control.SweepRun(tmp_path, time.time())])
    config = OmegaConf.create({"hydra": {"sweep": {"dir": str(tmp_path)}}})
    with pytest.raises(SystemExit) as exited:
        runners.sweep.SweepProgress().on_multirun_end(config)
    assert exited.value.code == 1
    assert capsys.readouterr().err.splitlines() == [line]


def test_resume_sets_logs_aside_each_episode_once_and_restores_the_others(tmp_path):
    """Four logs: episode a (good), a copy of a in another job, episode b (good), episode c (truncated)."""
    sweep_dir = tmp_path
    a, b, c = sweep_dir / "0" / "a.mcap", sweep_dir / "1" / "b.mcap", sweep_dir / "1" / "c.mcap"
    episode(a, 0), episode(b, 1), episode(c, 2)
    copy = sweep_dir / "2" / "a.mcap"
    copy.parent.mkdir()
    shutil.copy2(a, copy)
    c.write_bytes(c.read_bytes()[: c.stat().st_size // 2])
    key = {p.stem: episode_key_of(read_metadata(p)) for p in (a, b)}
    key["c"] = sweep_resume._peek_key(c)  # from the unverified metadata of the truncated log
    assert key["c"] is not None and len(set(key.values())) == 3

    plan = sweep_resume.prepare(sweep_dir)
    assert plan == sweep_resume.ResumePlan(kept=2, rerun=1, removed=1, unreadable=0)
    assert not list(sweep_dir.glob("[0-9]/*.mcap"))  # every log set aside until a job takes it back

    moved = sweep_dir / "5" / "a.mcap"  # episode a belongs to job 5 in this sweep
    moved.parent.mkdir()
    assert sweep_resume.keep(moved, key["a"], sweep_dir)["outcome"] == "goal"
    assert sweep_resume.keep(sweep_dir / "6" / "a.mcap", key["a"], sweep_dir) is None  # taken once only
    sweep_resume.supersede(sweep_dir, key["c"])  # c was run again
    b.write_bytes(b"another episode now has this name")
    assert sweep_resume.held_count(sweep_dir) == 1
    assert sweep_resume.restore(sweep_dir) == (0, 1, 0)  # b is not part of this sweep: kept, under earlier/
    assert is_complete(sweep_dir / "earlier" / "1" / "b.mcap") and not c.exists()
    assert episode_key_of(read_metadata(sweep_dir / "earlier" / "1" / "b.mcap")) == key["b"]


def test_the_launcher_does_not_start_jobs_after_a_stop(tmp_path):
    run = sweep_control.SweepRun(tmp_path, time.time())
    jobs = sweep_control.StoppableJobs([["a=1"], ["a=2"], ["a=3"]], run)
    taken = []
    for job in jobs:
        taken.append(job)
        stop.request_sweep_stop(tmp_path, signal.SIGINT, "test")
    assert taken == [["a=1"]] and len(jobs) == 3 and run.stop_signal() == signal.SIGINT
    stop.request_sweep_stop(tmp_path, 0, "sweep stopped: disk full")
    assert run.stop_signal() is None  # a failure, not a signal: exit 1, not 128 + n


def test_an_episode_is_the_same_whatever_the_seed_batching():
    """``seed=0 episodes=4`` and ``seed=2 episodes=2`` both run the episode of seed 3: one key; any other change
    of the config, the seed or the version is another episode."""
    config = "scenario:\n  name: head_on\nseed: {first}\nepisodes: {n}\nresume: {resume}\ndt: 1.0\n"
    key = episode_key
    same = key(config.format(first=0, n=4, resume="false"), 3, "1.0")
    assert key(config.format(first=2, n=2, resume="true"), 3, "1.0") == same
    assert key(config.format(first=0, n=4, resume="false").replace("dt: 1.0", "dt: 0.5"), 3, "1.0") != same
    assert key(config.format(first=0, n=4, resume="false"), 2, "1.0") != same
    assert key(config.format(first=0, n=4, resume="false"), 3, "1.1") != same
    import analysis.log_inputs
    from fuzzynav import episode_identity

    # one identity, defined once: the resume's, and the analysis' that leaves out the settings of a part that is off
    assert sweep_resume.episode_key_of is episode_identity.episode_key_of
    assert analysis.log_inputs.counted_key_of is episode_identity.counted_key_of
    meta = {"config": config.format(first=0, n=4, resume="false"), "seed": "3", "fuzzynav_version": "1.0"}
    assert episode_identity.counted_key_of(meta) == episode_identity.episode_key_of(meta) == same


def test_resume_never_opens_a_fifo_named_like_a_log(tmp_path):
    """A FIFO named ``x.mcap`` in the sweep directory: opening it would block until someone writes to it. The
    resume skips it with a line naming it, leaves it in place, and sets the real log aside. Run in a subprocess
    under a timeout, so that a regression fails instead of hanging the suite."""
    log = tmp_path / "0" / "a.mcap"
    episode(log, 0)
    fifo = tmp_path / "1" / "x.mcap"
    fifo.parent.mkdir()
    os.mkfifo(fifo)
    code = ("import sys; from pathlib import Path; from runners.sweeping.resume import prepare; "
            "plan = prepare(Path(sys.argv[1])); print(plan.kept, plan.rerun, plan.unreadable); "
            "print(*plan.skipped, sep='\\n')")
    try:
        done = subprocess.run([sys.executable, "-c", code, str(tmp_path)], cwd=ROOT, capture_output=True, text=True,
                              timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("the resume blocked on the FIFO")
    assert done.returncode == 0 and not done.stderr, done.stderr
    assert done.stdout.splitlines() == ["1 0 0", f"{fifo}: a FIFO, not a regular file: skipped, not opened"]
    assert fifo.is_fifo() and not log.exists() and sweep_resume.held_count(tmp_path) == 1
    assert sweep_resume.restore(tmp_path) == (1, 0, 0) and is_complete(log)


@pytest.mark.parametrize("phase", ["starting", "in_flight", "idle"])
def test_a_launcher_killed_with_sigkill_leaves_no_process(tmp_path, phase):
    """issue 14: kill -9 of the sweep's launching process left its loky workers (which ignore SIGTERM when idle)
    and their resource trackers alive for ever, holding the caller's pipes. Workers now end within a second of
    their launcher (runners.sweeping.process_tree.exit_with_parent): with episodes in flight, idle after their
    jobs, and starting (killed as soon as they exist, before any job: they waited for loky's five-minute idle
    timeout, holding the pipes; runners.sweeping.process_tree.worker_started)."""
    from tests.test_sweep_faults import SEARCH, group, partials, running, wait_for

    sweep_dir = tmp_path / "s"
    scenario = "endless_corridor" if phase == "in_flight" else "head_on"
    # idle: two quick jobs, then the sweep waits on a third (one worker idle, the other busy; both must go)
    seeds = "0,1" if phase == "in_flight" else "0,1,2"
    args = ["sweep=quick", SEARCH, f"scenario={scenario}", "planner=auto", f"seed={seeds}", "episodes=1",
            "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep_dir}"]
    with running(args) as proc:
        if phase == "starting":
            assert wait_for(lambda: len([p for p, cmd in group(proc.pid) if "popen_loky_posix" in cmd]) == 2,
                            timeout=60.0), "no workers started"
        elif phase == "in_flight":
            assert wait_for(lambda: len(partials(sweep_dir, scenario)) == 2), "the episodes did not start"
        else:
            assert wait_for(lambda: len(list(sweep_dir.rglob("head_on*.mcap"))) >= 2), "the episodes did not end"
        workers = [pid for pid, cmd in group(proc.pid) if "popen_loky_posix" in cmd]
        assert len(workers) == 2, group(proc.pid)
        os.kill(proc.pid, signal.SIGKILL)
        try:
            proc.communicate(timeout=30)  # returns only once no process holds the pipes any more
            assert wait_for(lambda: not group(proc.pid), 10.0), group(proc.pid)
        finally:  # whatever happened, leave nothing behind (running() only kills a live launcher's group)
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)


def test_a_sweep_that_wrote_no_log_does_not_report_success(tmp_path):
    """issue 14: a sweep with no log at all wrote an empty summary and report and exited 0."""
    from runners.sweeping import end as sweep_end

    run = sweep_control.SweepRun(tmp_path, time.time())
    sweep_end.end_of_sweep(OmegaConf.create({}), run, None)
    assert run.errors == [f"no logs found in {tmp_path}: the sweep ran no episode"]
    assert not (tmp_path / "report").exists() and not (tmp_path / "summary.csv").exists()


def test_a_time_limit_warning_between_two_episodes_ends_the_next_one_as_interrupted(tmp_path):
    """Submitit's time-limit warning (SIGUSR2) that arrives between two episodes of a Slurm job: the check before
    the next episode lets it start, and its first step ends it as interrupted with the time limit as the reason,
    so the sweep names the time limit (a job that returned without that log looked complete: its later seeds
    were silently missing)."""
    stop._TIME_LIMIT.append(True)
    try:
        stop.check_between_episodes()  # does not raise for the time limit ...
        with pytest.raises(KeyboardInterrupt):
            stop.check()  # ... which every step's check does
        log = tmp_path / "ep.mcap"
        with pytest.raises(interrupts.Interrupted) as err:
            episode(log)
        assert err.value.reason == stop.TIME_LIMIT_REASON
        summary = episode_summary(log)
        assert summary["outcome"] == "interrupted" and summary["steps"] == 1, summary
        stop._PENDING.append(signal.SIGTERM)
        with pytest.raises(interrupts.Interrupted):
            stop.check_between_episodes()  # a signal still stops before the next episode
    finally:
        stop._TIME_LIMIT.clear()
        stop._PENDING.clear()


def test_a_resume_into_a_folder_holding_other_sweeps_and_runs_leaves_them_whole(tmp_path):
    """``resume=true`` into ``parent/`` that holds an earlier sweep (``parent/old``) and a single run
    (``parent/run``) of the same episodes: it took their logs as its own (moved into parent/0, parent/1) and their
    summary and report named files that had gone. Their logs stay; this sweep runs and counts its own."""
    from runners.sweeping.paths import is_other_output, job_logs, other_outputs

    def command(module: str, *args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", module, "scenario=head_on", *args], cwd=ROOT,
                              capture_output=True, text=True, timeout=600)

    parent = tmp_path / "parent"
    assert command("runners.sweep", "planner=auto,wait", "episodes=1", f"hydra.sweep.dir={parent / 'old'}",
                   "hydra.launcher.n_jobs=1").returncode == 0
    assert command("runners.run", "planner=wait", f"hydra.run.dir={parent / 'run'}").returncode == 0
    before = {p: p.read_bytes() for p in parent.rglob("*.mcap")}
    assert len(before) == 3 and other_outputs(parent) == [parent / "old", parent / "run"]
    res = command("runners.sweep", "planner=auto,wait", "episodes=1", f"hydra.sweep.dir={parent}", "resume=true",
                  "hydra.launcher.n_jobs=1")
    assert res.returncode == 0, res.stderr
    assert {p: p.read_bytes() for p in before} == before  # every earlier log where it was, as it was
    assert "0 complete episode(s) kept, 2 run" in res.stdout and "2 episode logs in" in res.stdout
    assert [p.relative_to(parent).parts[0] for p in job_logs(parent)] == ["0", "1"]
    assert not is_other_output(parent / "0") and is_other_output(parent / "old") and is_other_output(parent / "run")


def test_a_sweep_into_the_folder_of_an_earlier_one_summarises_its_own_episodes_only(tmp_path):
    """A sweep of 2 seeds into the folder of a sweep of 3 (without resume, then with it): the summary held the
    earlier sweep's seed 2 (and, without resume, its other groups) as this sweep's episodes."""
    def sweep(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "runners.sweep", "scenario=head_on", *args,
                               f"hydra.sweep.dir={tmp_path}", "hydra.launcher.n_jobs=1"], cwd=ROOT,
                              capture_output=True, text=True, timeout=600)

    assert sweep("planner=auto,wait", "episodes=3").returncode == 0
    res = sweep("planner=wait", "episodes=2")
    assert res.returncode == 0, res.stderr
    # the earlier sweep's 6 logs: job 0 was its auto, job 1 its wait; this sweep's job 0 (wait) writes others
    assert "6 log(s) of episodes outside this sweep" in res.stdout and "2 episode logs in" in res.stdout, res.stdout
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert sorted(summary["seed"]) == [0, 1] and set(summary["strategy"]) == {"wait"}
    res = sweep("planner=auto,wait", "episodes=2", "resume=true")
    assert res.returncode == 0, res.stderr
    # kept: seeds 0, 1 of both (the second sweep's wait copies removed); outside: the first sweep's seeds 2
    assert "2 log(s) of episodes outside this sweep left in the directory, not in this summary" in res.stdout, \
        res.stdout
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert sorted(summary["seed"]) == [0, 0, 1, 1] and len(list(tmp_path.rglob("*.mcap"))) == 6
