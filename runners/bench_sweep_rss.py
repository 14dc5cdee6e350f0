"""Memory over a long sweep: the resident set (RSS) of the sweep's processes while ``runners.sweep`` runs thousands
of episodes, sampled from outside through ``/proc``.

``python -m runners.bench_sweep_rss [--episodes 10000] [--scenario head_on] [--jobs 2]``

The sweep is the real command (``python -m runners.sweep scenario=<s> planner=<jobs strategies>
episodes=<per job>``): each job runs its episodes one after the other in one worker process, so a per-episode leak
grows that worker. Every 0.5 s the resident set of the sweep and of every process below it is read. Reported:

* each worker: its RSS when 10 % of its life had passed and in its last sample, and the growth between the two;
* the sweep's own process: at 10 % of the run phase (while workers run) and at its end, then its peak while it
  writes the summary and the report (which hold one table row per episode: that part grows with the sweep by
  design).

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

ROOT = Path(__file__).resolve().parents[1]
STRATEGIES = ("auto_h2", "wait", "detour", "none", "auto_h1", "auto_h3", "auto_h4")
SAMPLE_S = 0.5


@dataclass
class Series:
    """RSS samples (MB) of one process, with their times (s since the sweep started)."""

    pid: int
    times: list[float] = field(default_factory=list)
    rss_mb: list[float] = field(default_factory=list)

    def at_fraction(self, fraction: float) -> float:
        """The first sample at or after ``fraction`` of this process's sampled life."""
        start, end = self.times[0], self.times[-1]
        cut = start + fraction * (end - start)
        return next(r for t, r in zip(self.times, self.rss_mb, strict=True) if t >= cut)


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


def measure(episodes: int, scenario: str, jobs: int) -> dict:
    """Run the sweep and sample its processes; the summary dict (see the module docstring)."""
    if not 1 <= jobs <= len(STRATEGIES):
        raise ValueError(f"--jobs: must be in [1, {len(STRATEGIES)}], got {jobs}")
    per_job = -(-episodes // jobs)
    series: dict[int, Series] = {}
    with tempfile.TemporaryDirectory(prefix="fuzzynav-rss-") as tmp:
        cmd = [sys.executable, "-m", "runners.sweep", f"scenario={scenario}",
               f"planner={','.join(STRATEGIES[:jobs])}", f"episodes={per_job}", f"hydra.sweep.dir={tmp}/sweep"]
        start = time.perf_counter()
        errors = Path(tmp, "sweep.stderr")  # a file, not a pipe: a long sweep's progress bar would fill a pipe
        with errors.open("w") as stderr:
            proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=stderr, text=True)
        try:
            while proc.poll() is None:
                now = time.perf_counter() - start
                for pid in _tree(proc.pid):
                    rss = _rss_mb(pid)
                    if rss is not None:
                        s = series.setdefault(pid, Series(pid))
                        s.times.append(now)
                        s.rss_mb.append(rss)
                time.sleep(SAMPLE_S)
        finally:  # interrupted: stop the sweep before its directory is removed
            if proc.poll() is None:
                proc.terminate()
                proc.wait()
        err = errors.read_text(errors="replace")
        seconds = time.perf_counter() - start
    if proc.returncode != 0:
        raise RuntimeError(f"the sweep failed (exit {proc.returncode}): {err.strip().splitlines()[-1:]}")
    return _summary(series, proc.pid, episodes=per_job * jobs, jobs=jobs, scenario=scenario,
                    seconds=seconds)


WORKER_MIN_MB = 50.0  # a process below the sweep this large runs episodes (multiprocessing's helpers are smaller)


def _summary(series: dict[int, Series], root: int, **facts) -> dict:
    main = series[root]
    workers = [s for pid, s in series.items() if pid != root and len(s.times) >= 10 and max(s.rss_mb) >= WORKER_MIN_MB]
    out = dict(facts)
    out["workers"] = [{"pid": s.pid, "life_s": s.times[-1] - s.times[0], "rss_mb_at_10pct": s.at_fraction(0.1),
                       "rss_mb_at_end": s.rss_mb[-1], "growth": s.rss_mb[-1] / s.at_fraction(0.1) - 1.0}
                      for s in workers]
    run_end = max((s.times[-1] for s in workers), default=None)
    if run_end is not None:
        run = Series(root, [t for t in main.times if t <= run_end], [r for t, r in zip(main.times, main.rss_mb,
                                                                                     strict=True) if t <= run_end])
        out["sweep_rss_mb_at_10pct"], out["sweep_rss_mb_at_run_end"] = run.at_fraction(0.1), run.rss_mb[-1]
        after = [r for t, r in zip(main.times, main.rss_mb, strict=True) if t > run_end]
        out["sweep_rss_mb_peak_in_summary"] = max(after, default=None)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m runners.bench_sweep_rss", description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=10_000, help="episodes in all (default 10000)")
    parser.add_argument("--scenario", default="head_on", help="scenario of every episode (default head_on)")
    parser.add_argument("--jobs", type=int, default=2, help="jobs (worker processes), one strategy each (default 2)")
    parser.add_argument("--out", type=Path, help="also write the result as JSON here")
    args = parser.parse_args(argv)
    if args.episodes < 10 * args.jobs:
        parser.error(f"--episodes: at least 10 per job, got {args.episodes} for {args.jobs} jobs")
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # unwinds: the sweep is stopped, its logs removed
    try:
        result = measure(args.episodes, args.scenario, args.jobs)
    except (RuntimeError, ValueError) as err:
        print(f"bench_sweep_rss: {err}", file=sys.stderr)
        return 1
    for w in result["workers"]:
        print(f"worker {w['pid']}: RSS {w['rss_mb_at_10pct']:.1f} MB at 10 % of its {w['life_s']:.0f} s, "
              f"{w['rss_mb_at_end']:.1f} MB at its end ({w['growth']:+.1%})")
    if "sweep_rss_mb_at_10pct" in result:
        print(f"sweep process: {result['sweep_rss_mb_at_10pct']:.1f} MB at 10 % of the run, "
              f"{result['sweep_rss_mb_at_run_end']:.1f} MB when the workers ended; peak while writing the summary "
              f"and report of {result['episodes']} episodes: {result['sweep_rss_mb_peak_in_summary'] or 0:.1f} MB")
    print(f"{result['episodes']} episodes of {result['scenario']} in {result['seconds']:.0f} s")
    if args.out:
        args.out.write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
