"""Faults of a real sweep, through the real command in a subprocess: a second sweep into the same directory, SIGINT
and SIGTERM to the launching process (joblib/loky and Submitit launchers), a worker killed with SIGKILL, resumes
(including one whose jobs overlap an earlier sweep's, with damaged and failed logs), a full disk and a read-only
file system. Each asserts the exit status, at most two lines on stderr and no traceback, no process of the sweep
left behind, and that every episode is in the directory once: nothing lost, nothing counted twice."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pandas as pd
import pytest
import yaml

from analysis.logs import LogFile, episode_summary, is_complete, read_metadata
from fuzzynav.episode_identity import episode_key_of
from runners.progress import is_progress_line
from tests.conftest import ROOT, load_controller, load_scenario
from tests.tmpfs import tmpfs_mounter

# a 20 km corridor (tests/scenarios/scenario/endless_corridor.yaml): episodes that only a stop or max_steps ends
SEARCH = f"hydra.searchpath=[file://{ROOT / 'tests' / 'scenarios'}]"


def start(args: list[str]) -> subprocess.Popen:
    """``python -m runners.sweep ARGS`` in a new session: its process group is the launcher's pid, and holds every
    process of the sweep (loky and Submitit do not start sessions of their own)."""
    return subprocess.Popen([sys.executable, "-m", "runners.sweep", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


@contextlib.contextmanager
def running(args: list[str]) -> Iterator[subprocess.Popen]:
    """:func:`start` the sweep; on leaving, whatever happened, kill every process of it that is still alive."""
    proc = start(args)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)


def stop_with(proc: subprocess.Popen, sig: signal.Signals) -> tuple[str, str, float]:
    """Send ``sig`` to the launching process only; its stdout, stderr and the seconds it took to exit."""
    tic = time.monotonic()
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=90)
    return out, err, time.monotonic() - tic


def sweep(args: list[str], timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "runners.sweep", *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)


def wait_for(predicate: Callable[[], bool], timeout: float = 120.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def group(pgid: int) -> list[tuple[int, str]]:
    """Live (not zombie) processes of the process group ``pgid``: (pid, command line)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            if int(fields[2]) == pgid and fields[0] != "Z":
                found.append((int(entry.name), (entry / "cmdline").read_text().replace("\0", " ")[:120]))
        except (OSError, IndexError, ValueError):
            continue
    return found


def orphans(pgid: int) -> list[tuple[int, str]]:
    """Processes of the sweep still alive 5 s after its launcher exited (killed ones may take a moment to go)."""
    wait_for(lambda: not group(pgid), 5.0)
    return group(pgid)


def partials(sweep_dir: Path, pattern: str = "") -> list[Path]:
    return sorted(sweep_dir.glob(f"*/.{pattern}*.mcap.partial"))


def logs(sweep_dir: Path) -> list[Path]:
    return sorted(p for p in sweep_dir.rglob("*.mcap") if ".fuzzynav" not in p.parts)



def problem_lines(stderr: str) -> list[str]:
    """stderr without Hydra's own log lines and the periodic progress lines (stderr is not a terminal)."""
    return [line for line in stderr.splitlines()
            if line.strip() and "[HYDRA]" not in line and not is_progress_line(line)]


def identities(paths: list[Path]) -> list[str]:
    """Each log's episode (config without the seed batching, seed, version: fuzzynav.episode_identity)."""
    return [episode_key_of(read_metadata(p)) for p in paths]


def kill_a_worker_mid_episode(args: list[str], sweep_dir: Path, long_running: str) -> None:
    """Start the sweep, SIGKILL one of its two loky workers while both run a ``long_running`` episode, and check
    the outcome: exit 1, one line naming the lost worker (two at most), no traceback and no process left, the lost
    episodes and the resume command on stdout."""
    with running(args) as proc:
        assert wait_for(lambda: len(partials(sweep_dir, long_running)) == 2), "the episodes did not start"
        workers = [pid for pid, cmd in group(proc.pid) if "popen_loky_posix" in cmd]
        assert len(workers) == 2, group(proc.pid)
        os.kill(workers[0], signal.SIGKILL)
        out, err = proc.communicate(timeout=90)
    assert proc.returncode == 1, err[-2000:]
    lines = problem_lines(err)
    assert "Traceback" not in err and 1 <= len(lines) <= 2 and "a worker process was lost" in lines[0], err
    assert not orphans(proc.pid)
    assert "lost: " in out and "to complete the sweep: python -m runners.sweep" in out and "resume=true" in out


def test_second_sweep_is_refused_and_sigterm_stops_submitit_jobs(tmp_path):
    """The Submitit launcher (every job its own process): the lock names the holder; SIGTERM to the launcher
    ends the episodes in flight as interrupted, writes the summary, exits 143 and leaves no process."""
    sweep_dir = tmp_path / "s"
    with running(["sweep=quick", SEARCH, "scenario=endless_corridor", "planner=auto,none", "episodes=2",
                  "hydra/launcher=local_processes", f"hydra.sweep.dir={sweep_dir}"]) as proc:
        assert wait_for(lambda: len(partials(sweep_dir)) == 2), "the episodes did not start"
        second = sweep(["sweep=quick", "scenario=head_on", "planner=auto", "episodes=1",
                        f"hydra.sweep.dir={sweep_dir}"])
        assert second.returncode == 1
        lines = problem_lines(second.stderr)
        assert len(lines) == 1 and "is in use by another sweep" in lines[0] and f"pid {proc.pid} on " in lines[0], \
            second.stderr
        assert "endless_corridor" in (sweep_dir / "multirun.yaml").read_text()  # the first sweep's, untouched
        out, err, took = stop_with(proc, signal.SIGTERM)
    assert proc.returncode == 143, err[-2000:]
    assert "Traceback" not in err and len(problem_lines(err)) == 1  # "SIGTERM: stopping the sweep ..."
    assert not orphans(proc.pid)
    assert took < 60
    finished = logs(sweep_dir)
    assert len(finished) == 2 and not partials(sweep_dir)
    assert all(is_complete(p) and episode_summary(p)["outcome"] == "interrupted" for p in finished)
    summary = pd.read_csv(sweep_dir / "summary.csv")
    assert len(summary) == 2 and set(summary["outcome"]) == {"interrupted"}
    assert "stopped by SIGTERM: 0 episode(s) finished, 2 interrupted, 0 lost, 2 not run (of 4)" in out
    assert "resume=true" in out and not (sweep_dir / "report").exists()
    print(f"submitit: SIGTERM to exit {took:.1f} s")


def test_sigint_then_a_killed_worker_then_resume_completes_every_episode_once(tmp_path):
    """The joblib launcher (loky workers), four one-episode jobs. The two head_on episodes finish, then two long
    ones are in flight: SIGINT to the launcher only ends them as interrupted (130); the resume keeps the two and,
    while running the long ones, loses a worker to SIGKILL (1, lost episodes and how to resume, no traceback); the
    next resume completes the sweep with every episode once."""
    sweep_dir = tmp_path / "s"
    args = ["sweep=quick", SEARCH, "scenario=head_on,endless_corridor", "scenario.max_steps=4000", "planner=auto",
            "seed=0,1", "episodes=1", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep_dir}"]
    long_running = "endless_corridor"

    with running(args) as proc:
        assert wait_for(lambda: len(partials(sweep_dir, long_running)) == 2)
        out, err, took = stop_with(proc, signal.SIGINT)
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err and not orphans(proc.pid)
    assert "stopped by SIGINT: 2 episode(s) finished, 2 interrupted, 0 lost, 0 not run (of 4)" in out, out[-2000:]
    summary = pd.read_csv(sweep_dir / "summary.csv")
    assert sorted(summary["outcome"]) == ["goal", "goal", "interrupted", "interrupted"]
    assert not partials(sweep_dir)
    kept = {p: p.stat().st_mtime_ns for p in logs(sweep_dir) if p.name.startswith("head_on")}
    assert len(kept) == 2

    kill_a_worker_mid_episode([*args, "resume=true"], sweep_dir, long_running)
    assert 1 <= len(partials(sweep_dir)) <= 2  # the killed worker's episode, and the other if loky killed it too
    assert all(is_complete(p) for p in logs(sweep_dir))  # a killed episode never leaves a log that looks complete

    done = sweep([*args, "resume=true"])
    assert done.returncode == 0, done.stderr[-2000:]
    assert "resume: 2 complete episode(s) kept, 2 run" in done.stdout, done.stdout[-2000:]
    final = logs(sweep_dir)
    assert len(final) == 4 and len(set(identities(final))) == 4 and not partials(sweep_dir)
    assert all(p.stat().st_mtime_ns == t for p, t in kept.items())  # kept, not run again
    summary = pd.read_csv(sweep_dir / "summary.csv")
    assert len(summary) == 4 and len(set(summary["log"])) == 4
    assert sorted(summary["outcome"]) == ["goal", "goal", "timeout", "timeout"]
    assert (sweep_dir / "report" / "report.html").exists()
    print(f"loky: SIGINT to exit {took:.1f} s")


def test_hydra_basic_sweeper_also_reports_a_killed_worker_in_one_line(tmp_path):
    """``hydra/sweeper=basic``: Hydra's sweeper composes every job up front, and a worker killed with SIGKILL is
    the same outcome as with fuzzynav's sweeper: exit 1, one line naming the lost worker, no traceback, the lost
    episodes and the resume command."""
    sweep_dir = tmp_path / "s"
    kill_a_worker_mid_episode(["sweep=quick", SEARCH, "scenario=endless_corridor", "planner=auto,none", "episodes=1",
                               "hydra/sweeper=basic", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep_dir}"],
                              sweep_dir, "endless_corridor")
    assert "FaultTolerantSweeper" in (sweep_dir / "multirun.yaml").read_text()


def _flip_a_byte_inside_a_chunk(path: Path) -> None:
    """Damage a log as two writers interleaving would: a changed byte in the middle of the data (a chunk), the
    file still ending with the MCAP magic."""
    data = bytearray(path.read_bytes())
    data[len(data) // 3] ^= 0x5A
    path.write_bytes(bytes(data))


def _rewrite_as_error(path: Path, monkeypatch) -> None:
    """The same episode (same config hash and seed), logged again as ended by a transient MemoryError."""
    import fuzzynav.planning.layer as nav
    from fuzzynav.controller.fuzzy_fast import FastEvaluator
    from runners.run import episode_config, run_episode

    meta = read_metadata(path)

    def out_of_memory(self, *args, **kwargs):
        raise MemoryError("transient")

    monkeypatch.setattr(nav.PlanningLayer, "decide", out_of_memory)
    plain = yaml.safe_load(meta["config"])
    row = run_episode(load_scenario(meta["scenario"]), FastEvaluator(load_controller(meta["controller"])),
                      episode_config(plain), int(meta["seed"]), path, meta["config"], meta["config_hash"])
    assert row["outcome"] == "error" and read_metadata(path)["config_hash"] == meta["config_hash"]


def test_resume_of_an_overlapping_sweep_keeps_each_episode_once_and_reruns_failures(tmp_path, monkeypatch):
    """Sweep A (planner none, auto; two seeds per job) then a resume B with planner auto, wait, none and one seed
    per job: jobs are numbered and batched differently (A's job 0 is none seeds 0-1, B's is auto seed 0), one of
    A's logs is damaged although it ends with the MCAP magic, one ended with outcome error. The resume verifies
    every log in full, keeps the two good ones where B's jobs expect them, runs the damaged and the failed
    episode again and the new ones once: six logs, six episodes."""
    sweep_dir = tmp_path / "s"
    base = ["sweep=quick", "scenario=head_on", "episodes=2", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep_dir}"]
    first = sweep([*base, "planner=none,auto"])
    assert first.returncode == 0, first.stderr[-2000:]
    before = {p.name: p for p in logs(sweep_dir)}
    assert len(before) == 4
    damaged = before["head_on__auto__h2__table1__laser__s0.mcap"]
    _flip_a_byte_inside_a_chunk(damaged)
    assert is_complete(damaged)  # looks complete; only reading it all shows the damage
    _rewrite_as_error(before["head_on__none__table1__laser__s1.mcap"], monkeypatch)
    good = {name: identities([p])[0] for name, p in before.items()
            if name in ("head_on__none__h2__table1__laser__s0.mcap", "head_on__auto__h2__table1__laser__s1.mcap")}

    second = sweep([*base, "planner=auto,wait,none", "seed=0,1", "episodes=1", "resume=true"])
    assert second.returncode == 0, second.stderr[-2000:]
    assert "resume: 2 complete episode(s) kept, 4 run" in second.stdout, second.stdout[-3000:]
    assert "resume: 2 failed or damaged log(s) run again" in second.stdout
    final = logs(sweep_dir)
    assert len(final) == 6 and len(set(identities(final))) == 6, final
    for path in final:
        LogFile(path)  # every log verifies in full
    assert {p.name: identities([p])[0] for p in final if p.name in good} == good
    summary = pd.read_csv(sweep_dir / "summary.csv")
    assert len(summary) == 6 and "error" not in set(summary["outcome"])
    assert (summary.groupby("strategy").size() == 2).all() and set(summary["strategy"]) == {"auto", "wait", "none"}
    jobs = {p.parent.name: p.name.split("__")[1] + p.name.split("__")[-1][:-5] for p in final}
    assert jobs == {"0": "autos0", "1": "autos1", "2": "waits0", "3": "waits1", "4": "nones0", "5": "nones1"}


@pytest.fixture
def tmpfs(tmp_path):
    yield from tmpfs_mounter(tmp_path)


def test_disk_full_is_one_line_naming_the_log_and_leaves_no_log_that_looks_complete(tmpfs):
    """400 KB for a sweep that needs about 1 MB of logs: the first log that cannot be written stops the sweep."""
    sweep_dir = tmpfs("400k") / "s"
    proc = start(["sweep=quick", "hydra.launcher.n_jobs=2", f"hydra.sweep.dir={sweep_dir}"])
    try:
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 1, err[-2000:]
    lines = problem_lines(err)
    assert 1 <= len(lines) <= 2 and "Traceback" not in err and "Logging error" not in err, err[-3000:]
    assert lines[0].startswith(f"error: {sweep_dir}") and "No space left on device" in lines[0], lines
    assert not orphans(proc.pid)
    written = logs(sweep_dir)
    assert 0 < len(written) < 12 and not partials(sweep_dir)
    for path in written:
        assert LogFile(path).complete  # whatever has a log's name is a whole, intact log
    assert not (sweep_dir / "report").exists() and "to complete the sweep:" in out


def test_read_only_output_is_one_line_naming_the_directory(tmpfs):
    read_only = tmpfs("64k", read_only=True)
    commands = {"sweep": ["runners.sweep", "sweep=quick", f"hydra.sweep.dir={read_only / 's'}"],
                "run": ["runners.run", f"hydra.run.dir={read_only / 'r'}"]}
    procs = {name: subprocess.Popen([sys.executable, "-m", *args], cwd=ROOT, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True) for name, args in commands.items()}
    results = {name: (proc.communicate(timeout=120)[1], proc.returncode) for name, proc in procs.items()}
    assert results["sweep"] == (f"error: {read_only / 's'}: Read-only file system\n", 1)
    assert results["run"] == (f"error: {read_only / 'r'}: cannot write the output directory: Read-only file system\n",
                              1)
