"""The report's figures drawn together in forked worker processes (analysis.drawing, analysis.forked, issue #36):
the same files as one process draws, every error raised in the report's process, a dead worker's figures drawn by
the report's process, no fork where other threads run."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import pytest

from analysis import forked
from analysis.drawing import Figures
from analysis.report import build_report
from tests.test_report_layout import many_seeds  # noqa: F401 - a fixture

PARENT = os.getpid()


def _write(path: Path, text: str, seconds: float = 0.0) -> Path:
    time.sleep(seconds)
    path.write_text(f"{text} by {'parent' if os.getpid() == PARENT else 'worker'}")
    return path


def _fail(path: Path) -> Path:
    raise OSError(28, "No space left on device", str(path))


def _die_in_worker(path: Path) -> Path:
    if os.getpid() != PARENT:
        os._exit(3)  # a worker killed while drawing: nothing sent back
    return _write(path, "redrawn")


needs_fork = pytest.mark.usefixtures("forkable")  # tests/conftest.py



@needs_fork
def test_every_figure_is_drawn_once_and_gets_its_file(tmp_path):
    figures = Figures()
    planned = [figures.add(_write, tmp_path / f"f{i}.txt", f"figure {i}", 0.05, cost=i % 3) for i in range(12)]
    meanwhile: list[int] = []  # the report's text, composed in this process while the workers draw
    figures.draw(jobs=2, meanwhile=lambda: meanwhile.append(os.getpid()))
    assert meanwhile == [PARENT]
    assert [f.path for f in planned] == [tmp_path / f"f{i}.txt" for i in range(12)]
    texts = [f.path.read_text() for f in planned]
    assert all(t.startswith(f"figure {i} by ") for i, t in enumerate(texts))
    assert {t.split(" by ")[1] for t in texts} == {"parent", "worker"}  # both took figures


@needs_fork
def test_the_first_error_is_raised_in_the_reports_process_after_the_others_are_drawn(tmp_path):
    figures = Figures()
    ok = [figures.add(_write, tmp_path / f"ok{i}.txt", "x") for i in range(4)]
    figures.add(_fail, tmp_path / "full.png")
    figures.add(_fail, tmp_path / "second.png")
    with pytest.raises(OSError) as err:
        figures.draw(jobs=2)
    assert err.value.errno == 28 and err.value.filename == str(tmp_path / "full.png")  # type and file kept
    assert all(f.path is not None and f.path.exists() for f in ok)


@needs_fork
def test_a_dead_workers_figures_are_drawn_by_the_reports_process(tmp_path):
    figures = Figures()
    planned = [figures.add(_die_in_worker, tmp_path / f"d{i}.txt", cost=10) for i in range(3)]
    figures.draw(jobs=2)
    assert all(f.path is not None and f.path.read_text() == "redrawn by parent" for f in planned)


def test_no_worker_is_forked_with_other_threads_running_or_one_job(tmp_path):
    assert forked.worker_count(1, 10) == 1 and forked.worker_count(-1, 1) == 1 and forked.worker_count(3, 2) == 2
    stop = threading.Event()
    thread = threading.Thread(target=stop.wait)
    thread.start()
    try:
        assert not forked.can_fork()
        figures = Figures()
        planned = [figures.add(_write, tmp_path / f"t{i}.txt", "x") for i in range(3)]
        figures.draw(jobs=2, meanwhile=lambda: not list(tmp_path.glob("t*.txt")) or pytest.fail("drawn before"))
        assert all(f.path.read_text() == "x by parent" for f in planned)
    finally:
        stop.set()
        thread.join()


@needs_fork
def test_a_report_drawn_in_workers_is_the_report_drawn_in_one_process(many_seeds, tmp_path):  # noqa: F811
    outs = {}
    for jobs in (1, 2):
        outs[jobs] = tmp_path / f"jobs{jobs}"
        build_report([many_seeds], outs[jobs], jobs=jobs)
    names = sorted(p.name for p in outs[1].iterdir())
    assert names == sorted(p.name for p in outs[2].iterdir())
    assert {"overview.png", "box_metrics.png", "trajectories_head_on.png", "failures.png"} <= set(names)
    for name in names:
        assert (outs[1] / name).read_bytes() == (outs[2] / name).read_bytes(), name


def test_the_collector_is_back_after_drawing(tmp_path):
    import gc

    figures = Figures()
    figures.add(_write, tmp_path / "g.txt", "x")
    figures.draw(jobs=1)
    assert gc.get_freeze_count() == 0 and gc.isenabled()


@needs_fork
def test_logs_read_in_forked_workers_give_the_same_analysis_and_traces(many_seeds):  # noqa: F811
    """24 logs in chunks over 2 processes (analysis.logs.FORK_MIN_LOGS): the same episodes, and the traces each
    process kept joined into those one process keeps."""
    from analysis.metrics import analyse_logs

    one, two = analyse_logs([many_seeds], jobs=1, traces=True), analyse_logs([many_seeds], jobs=2, traces=True)
    assert one.episodes.equals(two.episodes) and one.excluded.equals(two.excluded)
    assert list(one.traces) == list(two.traces) and one.first_contacts == two.first_contacts
    assert all((one.traces[log].positions == two.traces[log].positions).all() for log in one.traces)


def test_matplotlib_is_imported_when_a_figure_is_drawn_not_with_the_report():
    """The report plans its figures without matplotlib and imports it while its workers read the logs (a quarter
    of a second that was spent before anything else)."""
    import subprocess
    import sys

    code = ("import sys, analysis.report, analysis.gallery, analysis.density, analysis.overview; "
            "print('matplotlib' in sys.modules); from analysis import plots; plots.plt.figure(); "
            "import matplotlib; print(matplotlib.get_backend())")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "MPLBACKEND": ""})
    assert res.returncode == 0 and res.stdout.lower().split() == ["false", "agg"], res.stderr


def test_the_report_starts_its_readers_before_pandas_and_pyarrow_are_loaded():
    """Importing the report leaves pandas and pyarrow unloaded (analysis.deferred): its forked log readers start
    without them and the report's process loads pandas while they read; the tables are the same."""
    import subprocess
    import sys

    code = ("import sys, analysis.report, analysis.tables; "
            "print(any(m.startswith(('pandas.', 'pyarrow.')) for m in sys.modules)); "
            "from analysis.report import pd; print(pd.DataFrame({'a': [1]}).shape); "
            "print('pandas.core.frame' in sys.modules)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.split() == ["False", "(1,", "1)", "True"], res.stderr


def test_a_deferred_module_is_the_module_once_used():
    import subprocess
    import sys

    code = ("import sys; from analysis.deferred import deferred, load; import json; "
            "assert deferred('json') is json; m = deferred('colorsys'); "
            "print('colorsys' in sys.modules, hasattr(m, 'rgb_to_hsv'), m.rgb_to_hsv(1, 0, 0)); "
            "n = deferred('wave'); load(n); print(n.Wave_read.__module__)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and res.stdout.split() == ["True", "True", "(0.0,", "1.0,", "1)", "wave"], res.stderr
    from analysis.deferred import deferred

    with pytest.raises(ModuleNotFoundError):
        deferred("no_such_module_anywhere")


STOPPED_WHILE_DRAWING = """
import os, sys, time
from pathlib import Path
from analysis import interrupts, plots
from analysis.report import main
interrupts.guard_startup()  # as python -m analysis.report has it
pids = Path(sys.argv[3])

def slow(fig, path):  # every process that draws says so, then draws for a long time
    with open(pids, "a") as f:
        f.write(f"{os.getpid()}\\n")
    time.sleep(60)
    return path

plots._save = slow
main([sys.argv[1], "--out", sys.argv[2], "--jobs", "2"])
"""


@pytest.mark.parametrize("signum, code", [(2, 130), (15, 143)])
def test_a_report_stopped_while_its_workers_draw_ends_them_with_one_line(many_seeds, tmp_path, signum, code,  # noqa: F811
                                                                         forkable):
    """SIGINT or SIGTERM to the report's process while it and its forked workers draw: its workers end with it, one
    line, exit 128 + signal, no report left behind."""
    import subprocess
    import sys

    from tests.conftest import ROOT

    out, pids = tmp_path / "rep", tmp_path / "pids"
    proc = subprocess.Popen([sys.executable, "-c", STOPPED_WHILE_DRAWING, str(many_seeds), str(out), str(pids)],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while (not pids.exists() or len(pids.read_text().split()) < 2) and time.monotonic() < deadline:
        time.sleep(0.05)
    drawing = [int(p) for p in pids.read_text().split()]
    assert len(drawing) == 2 and proc.pid in drawing  # the report's process and its worker
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    lines = [line for line in err.splitlines() if line.strip()]
    assert proc.returncode == code and len(lines) == 1 and "stopped before it finished" in lines[0], err
    worker = next(p for p in drawing if p != proc.pid)
    with pytest.raises(ProcessLookupError):
        os.kill(worker, 0)  # ended (and reaped) with the report's process
    assert not out.exists() or not list(out.iterdir())  # whole or nothing


def _bug(path: Path) -> Path:
    raise ValueError("x and y must have the same\nfirst dimension")


def test_a_figure_that_raises_is_named_in_one_line_after_the_others_are_drawn(tmp_path):
    from analysis.drawing import FigureError

    figures = Figures()
    ok = figures.add(_write, tmp_path / "ok.txt", "x")
    figures.add(_bug, tmp_path / "bug.png")
    with pytest.raises(FigureError, match=r"^figure '_bug' could not be drawn: ValueError: x and y must have the "
                                          r"same first dimension$") as err:
        figures.draw(jobs=1)
    assert isinstance(err.value.__cause__, ValueError) and ok.path is not None and ok.path.exists()


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_report_whose_figure_raises_is_one_line_and_writes_nothing(many_seeds, tmp_path, monkeypatch,  # noqa: F811
                                                                     capsys, jobs):
    """A figure that raises something else than an OSError (a bug, ours or a library's, on these data): the report
    command says which figure and what in one line, exits 1 and leaves no file (HYDRA_FULL_ERROR=1: the traceback)."""
    from analysis import plots
    from analysis.report import main

    def broken(*args, **kwargs):
        raise ValueError("cannot draw this")

    monkeypatch.setattr(plots, "box_by_variant", broken)
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)
    out = tmp_path / "rep"
    assert main([str(many_seeds), "--out", str(out), "--jobs", jobs]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"error: {out}: cannot write the report: figure 'broken' could not be drawn: ValueError: "
                          "cannot draw this (nothing written"), err
    assert list(out.iterdir()) == []
    monkeypatch.setenv("HYDRA_FULL_ERROR", "1")
    with pytest.raises(Exception, match="could not be drawn"):
        main([str(many_seeds), "--out", str(out), "--jobs", jobs])


def test_a_sweeps_report_whose_figure_raises_leaves_the_earlier_report_and_no_partial_one(many_seeds, tmp_path,  # noqa: F811
                                                                                         monkeypatch):
    import shutil

    from analysis import plots
    from analysis.drawing import FigureError
    from analysis.metrics import analyse_logs
    from runners.sweeping.outputs import write_report

    sweep = tmp_path / "sweep"
    shutil.copytree(many_seeds, sweep)
    analysis = analyse_logs([sweep], jobs=1, traces=True)
    earlier = write_report(sweep, analysis)
    before = {p.name: p.read_bytes() for p in earlier.iterdir()}

    def broken(*args, **kwargs):
        raise ValueError("cannot draw this")

    monkeypatch.setattr(plots, "box_by_variant", broken)
    with pytest.raises(FigureError, match="'broken' could not be drawn: ValueError: cannot draw this"):
        write_report(sweep, analysis)
    assert {p.name: p.read_bytes() for p in (sweep / "report").iterdir()} == before
    assert sorted(p.name for p in sweep.iterdir() if p.name.startswith(".report")) == []
