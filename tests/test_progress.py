"""Progress over episodes: a bar on a terminal, plain periodic lines in a log."""

from __future__ import annotations

import io
import threading

import pytest
from hypothesis import given
from hypothesis import strategies as st

from runners import progress as progress_mod
from runners.progress import EVERY_S_ENV, EpisodeProgress, progress_line


def test_a_line_says_done_total_rate_and_time_left():
    assert progress_line("sweep", 40, 100, 4.0) == "sweep: 40/100 episodes (40%), 10.0 episodes/s, about 6 s left"
    assert progress_line("sweep", 100, 100, 125.0) == ("sweep: 100/100 episodes (100%), 0.8 episodes/s, "
                                                       "done in 2 min 05 s")
    assert progress_line("sweep", 3, None, 1.0) == "sweep: 3 episodes, 3.0 episodes/s"
    assert progress_line("sweep", 0, 10, 0.0) == "sweep: 0/10 episodes (0%), started 0 s ago"
    assert progress_line("sweep", 1, None, 5e-324) == "sweep: 1 episodes, 0.0 episodes/s"  # not "inf episodes/s"
    assert progress_line("x", 1, 10_000, 10.0).endswith("about 27 h 46 min left")


@given(done=st.integers(0, 10**9), total=st.one_of(st.none(), st.integers(1, 10**9)),
       elapsed=st.floats(0, 1e9, allow_nan=False))
def test_every_line_is_one_line(done, total, elapsed):
    line = progress_line("sweep", done, total, elapsed)
    assert "\n" not in line and "\r" not in line and line.startswith("sweep: ")


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self):
        return self.t


def test_lines_every_interval_in_a_log_and_a_last_one(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress_mod.time, "monotonic", clock)
    out = io.StringIO()
    with EpisodeProgress(10, "sweep", file=out, every_s=5.0) as p:
        for _ in range(10):
            clock.t += 1.0
            p.update()
        clock.t += 7.0
        p.tick()  # nothing finished for a while: the log still shows the sweep is alive
    lines = out.getvalue().splitlines()
    assert lines == ["sweep: 5/10 episodes (50%), 1.0 episodes/s, about 5 s left",
                     "sweep: 10/10 episodes (100%), 1.0 episodes/s, done in 10 s",
                     "sweep: 10/10 episodes (100%), 0.6 episodes/s, done in 17 s"]


def test_a_run_shorter_than_one_interval_prints_nothing():
    out = io.StringIO()
    with EpisodeProgress(3, "sweep", file=out, every_s=60.0) as p:
        p.update(3)
    assert out.getvalue() == ""


def test_on_a_terminal_the_bar_appears_with_the_first_episode():
    out = io.StringIO()
    with EpisodeProgress(4, "sweep", file=out, terminal=True) as p:
        assert out.getvalue() == ""  # nothing drawn while Hydra prints its job lines
        p.update()
        p.update()
    assert "sweep" in out.getvalue() and "2/4" in out.getvalue()


def test_the_bar_leaves_no_thread_behind():
    """tqdm's monitor thread would outlive the bar, and the sweep's report cannot fork its workers while another
    thread runs (analysis.forked)."""
    before = set(threading.enumerate())
    with EpisodeProgress(3, "sweep", file=io.StringIO(), terminal=True) as p:
        p.update(3)
    assert set(threading.enumerate()) <= before


@pytest.mark.parametrize("raw", ["0", "-3", "nan", "inf", "ten", "1e999"])
def test_a_bad_interval_is_named_and_the_default_used(monkeypatch, raw):
    monkeypatch.setenv(EVERY_S_ENV, raw)
    out = io.StringIO()
    p = EpisodeProgress(3, "sweep", file=out)
    assert p.every_s == progress_mod.EVERY_S
    assert out.getvalue().startswith(f"warning: {EVERY_S_ENV}: expected a positive number of seconds")


def test_the_interval_from_the_environment(monkeypatch):
    monkeypatch.setenv(EVERY_S_ENV, "60")
    assert EpisodeProgress(3, "sweep", file=io.StringIO()).every_s == 60.0


@given(done=st.integers(0, 10**6), total=st.one_of(st.none(), st.integers(1, 10**6)),
       elapsed=st.floats(0, 1e7, allow_nan=False), desc=st.sampled_from(["sweep", "build suite_v2", "episodes"]))
def test_progress_lines_are_recognised(done, total, elapsed, desc):
    from runners.progress import is_progress_line

    assert is_progress_line(progress_line(desc, done, total, elapsed))


def test_messages_are_not_progress_lines():
    from runners.progress import is_progress_line

    for line in ["error: a worker process was lost (UncompletedJobError: job 7_0 has not produced any output)",
                 "SIGTERM: 5 episode(s) finished, 2 interrupted, 0 lost, 5 not run (of 12)",
                 "resume: skipped x.mcap", "sweep: stopped"]:
        assert not is_progress_line(line), line
