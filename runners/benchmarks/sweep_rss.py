"""Memory over a long sweep: the resident set (RSS) of the sweep's processes while ``runners.sweep`` runs thousands
of episodes, sampled from outside through ``/proc``.

``python -m runners.benchmarks.sweep_rss [--episodes 10000] [--scenario head_on] [--jobs 2]``

The sweep is the real command (``python -m runners.sweep scenario=<s> planner=<jobs strategies>
episodes=<per job>``): each job runs its episodes one after the other in one worker process, so a per-episode leak
grows that worker. Every 0.5 s the resident set of the sweep and of every process below it is read. Reported:

* when 10 %, 50 % and 100 % of the episodes have their logs (files counted in the job directories): the RSS of
  each worker and of the sweep's own process, and each worker's growth from 10 % to 100 %;
* the sweep process's peak after that, while it writes the summary and the report (which hold one table row per
  episode: that part grows with the sweep by design).

Linux only (``/proc``). The logs go to a temporary directory, removed at the end.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
STRATEGIES = ("auto_h2", "wait", "detour", "none", "auto_h1", "auto_h3", "auto_h4")
SAMPLE_S = 0.5


@dataclass
class Sample:
    """One look at the sweep: seconds since it started, logs written so far, RSS (MB) of each process by pid."""

    seconds: float
    episodes_done: int
    rss_mb: dict[int, float] = field(default_factory=dict)


def _children() -> dict[int, list[int]]:
    """Parent pid -> child pids, for every process readable in /proc."""
    out: dict[int, list[int]] = {}
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            stat = Path(entry.path, "stat").read_text()
        except OSError:
            continue
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        out.setdefault(ppid, []).append(int(entry.name))
    return out


def _rss_mb(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def _tree(root: int) -> list[int]:
    children, out, todo = _children(), [], [root]
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo.extend(children.get(pid, ()))
    return out


def _episodes_done(sweep_dir: Path) -> int:
    """Logs in the sweep's job directories (the one being written counts: one per worker at most)."""
    if not sweep_dir.is_dir():
        return 0
    return sum(1 for job in os.scandir(sweep_dir) if job.is_dir()
               for entry in os.scandir(job.path) if entry.name.endswith(".mcap"))


def measure(episodes: int, scenario: str, jobs: int) -> dict:
    """Run the sweep and sample its processes; the summary dict (see the module docstring)."""
    if not 1 <= jobs <= len(STRATEGIES):
        raise ValueError(f"--jobs: must be in [1, {len(STRATEGIES)}], got {jobs}")
    per_job = -(-episodes // jobs)
    samples: list[Sample] = []
    with tempfile.TemporaryDirectory(prefix="fuzzynav-rss-") as tmp:
        sweep_dir = Path(tmp, "sweep")
        cmd = [sys.executable, "-m", "runners.sweep", f"scenario={scenario}",
               f"planner={','.join(STRATEGIES[:jobs])}", f"episodes={per_job}", f"hydra.sweep.dir={sweep_dir}"]
        start = time.perf_counter()
        errors = Path(tmp, "sweep.stderr")  # a file, not a pipe: a long sweep's progress bar would fill a pipe
        with errors.open("w") as stderr:
            proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=stderr, text=True)
        try:
            while proc.poll() is None:
                sample = Sample(time.perf_counter() - start, _episodes_done(sweep_dir))
                for pid in _tree(proc.pid):
                    rss = _rss_mb(pid)
                    if rss is not None:
                        sample.rss_mb[pid] = rss
                samples.append(sample)
                time.sleep(SAMPLE_S)
        finally:  # interrupted: stop the sweep before its directory is removed
            if proc.poll() is None:
                proc.terminate()
                proc.wait()
        err = errors.read_text(errors="replace")
        seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"the sweep failed (exit {proc.returncode}): {err.strip().splitlines()[-1:]}")
    return summary(samples, proc.pid, per_job * jobs, jobs=jobs, scenario=scenario, seconds=seconds)


WORKER_MIN_MB = 50.0  # a process below the sweep this large runs episodes (multiprocessing's helpers are smaller)
MARKS = (0.1, 0.5, 1.0)  # fractions of the episodes at which the RSS is reported


def summary(samples: list[Sample], root: int, episodes: int, **facts) -> dict:
    """RSS of the sweep's process and of each worker when 10 %, 50 % and all of the ``episodes`` had their logs,
    and the sweep's peak after that (summary and report). A worker: a process below the sweep that reached
    ``WORKER_MIN_MB`` while episodes ran; one that finished its job (and may have exited) before a mark is reported
    with the last RSS it was seen with."""
    out: dict = {"episodes": episodes, **facts}
    marks: dict[float, int] = {}
    for fraction in MARKS:
        at = next((i for i, s in enumerate(samples) if s.episodes_done >= fraction * episodes), None)
        if at is not None:
            marks[fraction] = at
    running = [s for s in samples if s.episodes_done < episodes]
    workers = sorted({pid for s in running for pid, mb in s.rss_mb.items() if pid != root and mb >= WORKER_MIN_MB})

    def last_seen(pid: int, upto: int) -> float | None:
        # A worker whose job ended before the mark (its process may be gone) counts with its last RSS seen.
        return next((samples[i].rss_mb[pid] for i in range(upto, -1, -1) if pid in samples[i].rss_mb), None)

    out["marks"] = [{"fraction": f, "seconds": samples[i].seconds, "sweep_rss_mb": samples[i].rss_mb.get(root),
                     "workers_rss_mb": [last_seen(pid, i) for pid in workers]} for f, i in marks.items()]
    done = marks.get(1.0)
    after = [s.rss_mb[root] for s in samples[done + 1:] if root in s.rss_mb] if done is not None else []
    out["sweep_rss_mb_peak_after"] = max(after, default=None)
    first = marks.get(MARKS[0])
    if first is not None and done is not None:
        pairs = [(last_seen(pid, first), last_seen(pid, done)) for pid in workers]
        out["worker_growth_10_to_100"] = [b / a - 1.0 for a, b in pairs if a and b]
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m runners.benchmarks.sweep_rss",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=10_000, help="episodes in all (default 10000)")
    parser.add_argument("--scenario", default="head_on", help="scenario of every episode (default head_on)")
    parser.add_argument("--jobs", type=int, default=2, help="jobs (worker processes), one strategy each (default 2)")
    parser.add_argument("--out", type=Path, help="also write the result as JSON here")
    args = parser.parse_args(argv)
    if not 1 <= args.jobs <= len(STRATEGIES):
        parser.error(f"--jobs: must be in [1, {len(STRATEGIES)}], got {args.jobs}")
    if args.episodes < 10 * args.jobs:
        parser.error(f"--episodes: at least 10 per job, got {args.episodes} for {args.jobs} jobs")
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # unwinds: the sweep is stopped, its logs removed
    try:
        result = measure(args.episodes, args.scenario, args.jobs)
    except (RuntimeError, ValueError) as err:
        print(f"bench_sweep_rss: {err}", file=sys.stderr)
        return 1
    for mark in result["marks"]:
        workers = ", ".join(f"{mb:.1f}" if mb is not None else "gone" for mb in mark["workers_rss_mb"])
        print(f"{mark['fraction']:.0%} of the episodes logged ({mark['seconds']:.0f} s): sweep process "
              f"{mark['sweep_rss_mb'] or 0:.1f} MB, workers {workers} MB")
    if result.get("worker_growth_10_to_100"):
        growth = ", ".join(f"{g:+.1%}" for g in result["worker_growth_10_to_100"])
        print(f"workers' growth from 10 % to 100 %: {growth}")
    if result["sweep_rss_mb_peak_after"] is not None:
        print(f"sweep process peak while writing the summary and report: {result['sweep_rss_mb_peak_after']:.1f} MB")
    print(f"{result['episodes']} episodes of {result['scenario']} in {result['seconds']:.0f} s")
    if args.out:
        args.out.write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
