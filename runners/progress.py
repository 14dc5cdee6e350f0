"""Progress over episodes, on a terminal or in a log file.

On a terminal: a tqdm bar on stderr, drawn from the first finished episode on (so it never shares a line with
the lines Hydra prints while it starts the jobs). Not a terminal (``| tee``, ``nohup``, a Slurm or tmux log):
one plain line every ``every_s`` seconds (and a last one at the end when any was written), e.g.
``sweep: 40/105 episodes (38%), 12.3 episodes/s, about 5 s left``.
"""

from __future__ import annotations

import math
import os
import re
import sys
import time
from typing import IO, Any

EVERY_S = 10.0  # seconds between two lines in a log: frequent enough to see a sweep move, few enough to read
EVERY_S_ENV = "FUZZYNAV_PROGRESS_EVERY_S"  # another interval, e.g. 60 for a long Slurm job's log


def every_s_from_env(file: IO[str]) -> float:
    """The interval between two progress lines: ``FUZZYNAV_PROGRESS_EVERY_S`` (seconds, > 0) or 10 s. A value
    that is not a positive number is named in one line on ``file`` and the default is used."""
    raw = os.environ.get(EVERY_S_ENV)
    if raw is None or raw.strip() == "":
        return EVERY_S
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        print(f"warning: {EVERY_S_ENV}: expected a positive number of seconds, got {raw[:40]!r}; using "
              f"{EVERY_S:g}", file=file, flush=True)
        return EVERY_S
    return value


_LINE = re.compile(r"[^:\n]{1,80}: \d+(/\d+)? episodes(?: \(\d+%\))?, (started .+ ago|[\d.]+ episodes/s.*)")


def is_progress_line(line: str) -> bool:
    """Whether ``line`` is one of :class:`EpisodeProgress`'s lines (to tell them from messages in a log)."""
    return _LINE.fullmatch(line.strip()) is not None


def _duration(seconds: float) -> str:
    """``seconds`` as a short duration: ``42 s``, ``3 min 05 s``, ``2 h 07 min``."""
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def progress_line(desc: str, done: int, total: int | None, elapsed_s: float) -> str:
    """One line of progress: episodes done of ``total`` (None: unknown), the rate (episodes/s) since the start
    and, when the total is known, the time left at that rate (before the first episode: the time since the
    start)."""
    rate = done / elapsed_s if elapsed_s >= 1e-3 else 0.0  # under a millisecond a rate means nothing (inf)
    text = f"{desc}: {done}" + (f"/{total} episodes ({100 * done / total:.0f}%)" if total else " episodes")
    if done == 0:
        return f"{text}, started {_duration(elapsed_s)} ago"
    text += f", {rate:.1f} episodes/s"
    if total and rate > 0 and done < total:
        text += f", about {_duration((total - done) / rate)} left"
    elif total and done >= total:
        text += f", done in {_duration(elapsed_s)}"
    return text


class EpisodeProgress:
    """Counts finished episodes and shows them (see the module docstring). Use as a context manager; call
    :meth:`update` once per finished episode."""

    def __init__(self, total: int | None, desc: str, file: IO[str] | None = None, every_s: float | None = None,
                 terminal: bool | None = None) -> None:
        self.total = total if total is None or total >= 0 else None
        self.desc = desc
        self.file = file if file is not None else sys.stderr
        if terminal is None:
            isatty = getattr(self.file, "isatty", None)
            terminal = bool(isatty and isatty())
        self.terminal = terminal
        self.every_s = every_s if every_s is not None else (EVERY_S if terminal else every_s_from_env(self.file))
        self.done = 0
        self._start = time.monotonic()
        self._last_line = self._start
        self._bar: Any = None
        self._lines = 0
        self._written_done = -1

    def __enter__(self) -> EpisodeProgress:
        self._start = self._last_line = time.monotonic()
        return self

    def update(self, n: int = 1) -> None:
        """``n`` more episodes finished."""
        self.done += n
        if self.terminal:
            if self._bar is None:
                from tqdm import tqdm

                # no monitor thread (it lives on after the bar): a process with another thread cannot fork, and the
                # sweep's report forks its workers once the bar is closed (analysis.forked)
                tqdm.monitor_interval = 0
                self._bar = tqdm(total=self.total, unit="episode", desc=self.desc, file=self.file,
                                 dynamic_ncols=True, initial=self.done - n)
            self._bar.update(n)
            return
        self.tick()

    def tick(self) -> None:
        """Write the line if ``every_s`` has passed since the last one (not on a terminal): called also while no
        episode finishes, so a log shows a sweep that stalls."""
        if self.terminal:
            return
        now = time.monotonic()
        if now - self._last_line >= self.every_s:
            self._last_line = now
            self._write()

    def _write(self) -> None:
        elapsed = time.monotonic() - self._start
        if not math.isfinite(elapsed):
            return
        self._lines += 1
        self._written_done = self.done
        print(progress_line(self.desc, self.done, self.total, elapsed), file=self.file, flush=True)

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.close()
        elif not self.terminal and self._lines and self._written_done != self.done:
            self._write()  # the last count; a run shorter than one interval prints none (its summary follows)
