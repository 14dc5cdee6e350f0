"""Issue 14: an interrupt at any point of an entry point's start-up (imports, checks, Hydra starting) ends the
command with one line and exit 128 + signal (130 for SIGINT, 143 for SIGTERM), never a traceback."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from analysis.interrupts import Interrupted
from tests.conftest import ROOT

DELAYS_S = (0.2, 0.5, 1.0, 2.0)


def commands(tmp_path: Path) -> dict[str, list[str]]:
    """Each entry point, with arguments that make it start up and then work for a while."""
    out = tmp_path / "out"
    return {
        "run": ["runners.run", f"hydra.run.dir={out}", "episodes=3"],
        "sweep": ["runners.sweep", f"hydra.sweep.dir={out}", "scenario=head_on", "episodes=1",
                  "hydra.launcher.n_jobs=1"],
        "replay": ["runners.replay", str(tmp_path / "missing.mcap"), "--quiet"],
        "dataset": ["runners.dataset", "verify", "tiny", "--root", str(out)],
        "report": ["analysis.report", str(tmp_path), "--out", str(out)],
    }


def interrupt(args: list[str], delay: float, signum: int, cwd: Path) -> tuple[int, str]:
    """(exit code, stderr) of ``python -m ARGS`` sent ``signum`` after ``delay`` seconds."""
    proc = subprocess.Popen([sys.executable, "-m", *args], cwd=cwd, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)})
    time.sleep(delay)
    proc.send_signal(signum)
    try:
        _, err = proc.communicate(timeout=120)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise AssertionError(f"{args[0]} did not end within 120 s of the signal") from None
    return proc.returncode, err


@pytest.mark.parametrize("entry", ["run", "sweep", "replay", "dataset", "report"])
@pytest.mark.parametrize("delay", DELAYS_S)
def test_sigint_during_start_up_is_one_line_and_exit_130(entry, delay, tmp_path):
    args = commands(tmp_path)[entry]
    code, err = interrupt(args, delay, signal.SIGINT, tmp_path)
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err and len(lines) <= 2, err[-3000:]
    if code != 130:  # the command had already ended on its own: then normally, not killed by the signal
        assert code >= 0, err[-3000:]
    elif entry != "sweep":  # the sweep says it is stopping, then what it leaves (e.g. no episode ran): two lines
        assert len(lines) == 1, err  # the interrupt named by the entry point


@pytest.mark.parametrize("entry", ["run", "replay", "report"])
def test_sigterm_during_start_up_is_one_line_and_exit_143(entry, tmp_path):
    code, err = interrupt(commands(tmp_path)[entry], 0.5, signal.SIGTERM, tmp_path)
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err and len(lines) <= 2, (code, err[-3000:])
    if code != 143:  # on a fast machine the command may have ended on its own before the signal: normally then
        assert code >= 0, (code, err[-3000:])
        return
    assert len(lines) == 1 and "terminated (SIGTERM)" in lines[0], err[-3000:]


def ends_as_interrupted(code: str) -> subprocess.CompletedProcess:
    """Run ``code`` in a fresh interpreter: it must end with exit 130 and one line on stderr, no traceback."""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 130, proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    return proc


def test_an_error_raised_while_an_interrupt_unwinds_still_exits_as_interrupted():
    """A signal landing inside a library's clean-up (OmegaConf restoring its flags while Hydra stores the config
    schema) can leave it half-done, so another error follows with the interrupt as its context: still one line
    and exit 130, not that error's traceback."""
    code = ("from analysis import interrupts\n"
            "interrupts.guard_startup()\n"
            "try:\n"
            "    raise KeyboardInterrupt()\n"
            "except KeyboardInterrupt:\n"
            "    raise AttributeError('half-done clean-up')\n")
    ends_as_interrupted(code)


def test_an_interrupt_where_python_ignores_exceptions_still_ends_the_command():
    """A signal landing in a weak reference's callback (the import system's module locks run one after each
    import): Python printed "Exception ignored in ..." with a traceback and the command went on (a flaky start-up
    test caught it); it ends with one line and exit 130."""
    code = ("from analysis import interrupts\n"
            "interrupts.guard_startup()\n"
            "import signal, weakref\n"
            "class Thing: pass\n"
            "thing = Thing()\n"
            "def callback(ref): raise interrupts.Interrupted(signal.SIGINT)\n"
            "ref = weakref.ref(thing, callback)\n"
            "del thing\n"
            "print('went on')\n")
    proc = ends_as_interrupted(code)
    assert "went on" not in proc.stdout, proc.stdout


def test_a_signal_while_deferred_is_raised_when_resumed_and_a_second_one_ends_at_once():
    """Hydra's start of a run is deferred (``interrupts.defer``): a signal there is raised as the interrupt only
    once the task function resumes, so it never lands inside OmegaConf (whose half-done clean-up Hydra reported as
    an AttributeError, exit 1); a second signal meanwhile ends the process at once, with the same one line."""
    once = ("import os, signal\n"
            "from analysis import interrupts\n"
            "interrupts.guard_startup()\n"
            "interrupts.defer()\n"
            "os.kill(os.getpid(), signal.SIGTERM)\n"
            "print('went on', flush=True)\n"
            "interrupts.resume()\n"
            "print('not reached', flush=True)\n")
    proc = subprocess.run([sys.executable, "-c", once], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 143 and proc.stdout == "went on\n", (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "terminated (SIGTERM)" in proc.stderr
    twice = once.replace("print('went on', flush=True)\n",
                         "os.kill(os.getpid(), signal.SIGINT)\nprint('not reached either', flush=True)\n")
    proc = subprocess.run([sys.executable, "-c", twice], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 143 and proc.stdout == "", (proc.stdout, proc.stderr)
    assert len(proc.stderr.strip().splitlines()) == 1 and "terminated (SIGTERM)" in proc.stderr, proc.stderr


def test_defer_is_nothing_where_the_start_up_guard_is_not_in_charge():
    """Under a sweep's own handlers (or none of ours) ``defer`` and ``resume`` change nothing."""
    code = ("import signal\n"
            "from analysis import interrupts\n"
            "handler = lambda *_: None\n"
            "signal.signal(signal.SIGTERM, handler)\n"
            "interrupts.defer()\n"
            "assert signal.getsignal(signal.SIGTERM) is handler\n"
            "interrupts.resume()\n"
            "assert signal.getsignal(signal.SIGTERM) is handler\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr


def test_an_interrupt_inside_the_precheck_composition_is_not_reported_as_a_config_error(monkeypatch):
    """A signal inside OmegaConf's clean-up while the pre-check composes leaves an AttributeError with the
    interrupt as its context: that is the interrupt, not ``error: config: ...`` (seen with ``timeout``)."""
    from runners.configuration import precheck

    def compose(*args, **kwargs):
        try:
            raise Interrupted(signal.SIGTERM)
        except Interrupted:
            raise AttributeError("'NoneType' object has no attribute '_invalidate_flags_cache'") from None

    monkeypatch.setattr(precheck, "compose", compose)
    with pytest.raises(Interrupted):
        precheck.precheck(["planner=wait"])


def test_an_error_after_an_interrupt_that_was_swallowed_still_exits_as_interrupted():
    """SIGINT while pandas imported pyarrow (0.2 s into a report): the interrupt was lost inside the imports, and
    the half-loaded pyarrow made pandas raise AttributeError later, printed as a traceback with exit 1."""
    code = ("from analysis import interrupts\n"
            "interrupts.guard_startup()\n"
            "import os, signal\n"
            "try:\n"
            "    os.kill(os.getpid(), signal.SIGINT)\n"
            "    import time; time.sleep(5)\n"
            "except BaseException:\n"
            "    pass  # a library that swallowed it\n"
            "raise AttributeError(\"module 'pyarrow' has no attribute 'large_string'\")\n")
    ends_as_interrupted(code)


def test_the_extension_modules_whose_start_crashes_when_interrupted_are_imported_with_signals_held(monkeypatch):
    """orjson's initialisation crashed the process (SIGSEGV, no word) when SIGINT arrived inside it (CI: replay
    sent SIGINT 0.2 s after its start; 3 runs in 300 here): the guard imports it with SIGINT and SIGTERM blocked,
    so that a signal meanwhile is delivered after the import, where it raises."""
    from analysis import interrupts

    masks = []
    real = signal.pthread_sigmask

    def recording(how, mask):
        masks.append((how, set(mask)))
        return real(how, mask)

    monkeypatch.setattr(signal, "pthread_sigmask", recording)
    seen = []
    monkeypatch.setattr(interrupts.importlib, "import_module",
                        lambda name: seen.append((name, set(real(signal.SIG_BLOCK, set())))))
    interrupts._import_uninterrupted(interrupts.UNINTERRUPTIBLE_IMPORTS)
    assert "orjson" in interrupts.UNINTERRUPTIBLE_IMPORTS
    assert [name for name, _ in seen] == list(interrupts.UNINTERRUPTIBLE_IMPORTS)
    assert all({signal.SIGINT, signal.SIGTERM} <= blocked for _, blocked in seen)  # held during each import
    assert masks[0] == (signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM}) and masks[-1][0] == signal.SIG_SETMASK
    assert signal.SIGINT not in real(signal.SIG_BLOCK, set())  # and delivered again after
