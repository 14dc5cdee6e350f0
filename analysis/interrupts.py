"""Interrupts of a command-line entry point, ``python -m runners.<entry>`` and ``python -m analysis.<entry>``: the
:class:`Interrupted` exception that a SIGINT or SIGTERM becomes, and the start-up guard that both packages install
when they are imported by ``python -m`` (:func:`guard_startup`).

It lives in the analysis because the analysis imports nothing of the runners (the runners import the analysis: a
sweep writes its report); :mod:`runners.sweeping.stop` builds the stop between two steps of an episode on it.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib
import os
import signal
import sys
import threading
from typing import Any

SIGNAL_NAMES = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}


class Interrupted(KeyboardInterrupt):
    """A stop request: ``signum`` is the signal behind it (the exit code is 128 + signum: 130 for SIGINT, 143 for
    SIGTERM) and ``reason`` the words the log records."""

    def __init__(self, signum: int = signal.SIGTERM, reason: str = "") -> None:
        super().__init__(reason or describe(signum))
        self.signum = signum
        self.reason = reason or describe(signum)


def describe(signum: int) -> str:
    return "interrupted (Ctrl-C)" if signum == signal.SIGINT else f"terminated ({SIGNAL_NAMES.get(signum, signum)})"


def exit_code(err: BaseException) -> int:
    """The exit status of a process stopped by ``err``: 128 + the signal number (a plain KeyboardInterrupt is a
    Ctrl-C: 130)."""
    return 128 + (err.signum if isinstance(err, Interrupted) else signal.SIGINT)


def reason_of(err: BaseException) -> str:
    return err.reason if isinstance(err, Interrupted) else describe(signal.SIGINT)


# -- start-up of a command-line entry point -----------------------------------------------------------------------
_GUARDED: list[bool] = []  # guard_startup has run in this process


def interrupt_in_chain(err: BaseException | None) -> BaseException | None:
    """The interrupt behind ``err``: itself, or one it was raised while handling. A signal that lands inside a
    library's clean-up (OmegaConf's flag restore during Hydra's config store, say) can leave it half-done, and the
    error that follows hides the interrupt behind it."""
    seen: set[int] = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


UNINTERRUPTIBLE_IMPORTS = ("orjson",)
"""Extension modules whose initialisation crashes the process when an interrupt is raised inside it: orjson 3's
(it imports Python modules from Rust and does not check the result), SIGSEGV with no word, about 1 run in 100 of
``python -m runners.replay`` sent SIGINT 0.2 s after its start (CI's test_interrupts met one)."""


def _import_uninterrupted(names: tuple[str, ...]) -> None:
    """Import ``names`` with SIGINT and SIGTERM held back (blocked, not lost): a signal that arrives meanwhile is
    delivered once the imports are done, where raising is safe. A module that is not installed is left to its
    importer's own error."""
    block = getattr(signal, "pthread_sigmask", None)  # POSIX only
    held = block(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM}) if block is not None else None
    try:
        for name in names:
            with contextlib.suppress(ImportError):
                importlib.import_module(name)
    finally:
        if block is not None and held is not None:
            block(signal.SIG_SETMASK, held)


def guard_startup() -> None:
    """For ``python -m runners.<entry>`` and ``python -m analysis.report``, from their package's import on: a
    SIGINT or SIGTERM raises :class:`Interrupted` (later handlers, such as :func:`install` during a job or the
    sweep's, take over and restore this one), and an interrupt that nothing handled ends the process with one
    line and exit 128 + signal instead of a traceback through the imports, Hydra or the checks. Without it,
    SIGINT during the imports printed a 20-line traceback and SIGTERM killed the process without a word."""
    if _GUARDED:
        return
    _GUARDED.append(True)
    _import_uninterrupted(UNINTERRUPTIBLE_IMPORTS)
    for signum in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError):  # not the main thread: signals act as before
            signal.signal(signum, _raise_interrupted)
    previous = sys.excepthook

    def excepthook(kind: type[BaseException], value: BaseException, tb: Any) -> None:
        interrupt = interrupt_in_chain(value) or (Interrupted(_RECEIVED[0]) if _RECEIVED else None)
        if interrupt is None:
            previous(kind, value, tb)
            return
        _exit_interrupted(interrupt)

    sys.excepthook = excepthook
    previous_unraisable = sys.unraisablehook

    def unraisablehook(unraisable: Any) -> None:
        # an interrupt raised where Python ignores exceptions (a weak reference's callback, such as the import
        # system's module locks): printed as "Exception ignored in ..." with a traceback, and the command went on
        interrupt = interrupt_in_chain(unraisable.exc_value) if unraisable.exc_value is not None else None
        if interrupt is None:
            previous_unraisable(unraisable)
            return
        _exit_interrupted(interrupt)

    sys.unraisablehook = unraisablehook
    # once the command has ended, a signal must not replace its exit status: from the threads' shutdown (the
    # first step of the interpreter's exit) a signal is only noted, and after the exit handlers ignored, since
    # the interpreter then puts back the default action, which killed the exiting process (status -2, no word)
    threading._register_atexit(_while_exiting)  # type: ignore[attr-defined]
    atexit.register(_ignore_signals)  # registered first, so run last of the exit handlers


def _while_exiting() -> None:
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _on_signal_while_exiting)


def _on_signal_while_exiting(signum: int, frame: Any) -> None:
    """A signal while the exit handlers run: the first is ignored (the command has ended), a second one ends
    the process at once, in case an exit handler hangs."""
    if _EXIT_SIGNALS:
        os._exit(128 + signum)
    _EXIT_SIGNALS.append(signum)


_EXIT_SIGNALS: list[int] = []


def _ignore_signals() -> None:
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, signal.SIG_IGN)


def _raise_interrupted(signum: int, frame: Any) -> None:
    _RECEIVED.append(signum)
    raise Interrupted(signum)


#: signals the start-up guard raised: an error that ends the command after one (a library whose import it cut
#: short caught it or was left half-loaded: pyarrow without ``large_string``) is the interrupt's consequence
_RECEIVED: list[int] = []


# -- a library that must not be interrupted midway -----------------------------------------------------------------
_DEFERRED: list[int] = []  # signals noted while deferring
_DEFERRING: list[bool] = []


def defer() -> None:
    """From now until :func:`resume`, a SIGINT or SIGTERM is noted instead of raised, and a second one ends the
    process at once with the one line. For Hydra's start of a run (composing the config, making the output
    folder): Hydra reports any ``Exception`` itself, and an interrupt raised inside OmegaConf's clean-up left it
    half-done, so Hydra printed the ``AttributeError`` that followed with exit 1 instead of the interrupt.
    Only where the start-up guard is in charge (not under a sweep's handlers, not in another thread)."""
    if _DEFERRING or threading.current_thread() is not threading.main_thread():
        return
    if any(signal.getsignal(signum) is not _raise_interrupted for signum in (signal.SIGINT, signal.SIGTERM)):
        return
    _DEFERRED.clear()
    _DEFERRING.append(True)
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _note_deferred)


def _note_deferred(signum: int, frame: Any) -> None:
    if _DEFERRED:
        _exit_interrupted(Interrupted(_DEFERRED[0]))
    _DEFERRED.append(signum)


def resume() -> None:
    """End :func:`defer`: signals raise again, and one that came meanwhile is raised now as :class:`Interrupted`.
    Without a :func:`defer` before it, nothing."""
    if not _DEFERRING:
        return
    _DEFERRING.clear()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _raise_interrupted)
    if _DEFERRED:
        raise Interrupted(_DEFERRED.pop())


def _exit_interrupted(err: BaseException) -> None:
    """One line naming the command, the exit handlers (loky's workers, logging), exit 128 + signal. The
    interpreter would otherwise end an unhandled interrupt by killing itself with SIGINT (status -2, not 130)."""
    for signum in (signal.SIGINT, signal.SIGTERM):  # a second signal must not interrupt the clean-up
        signal.signal(signum, signal.SIG_IGN)
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    command = f"python -m {spec.name}" if spec is not None else "the command"
    with contextlib.suppress(BaseException):
        sys.stdout.flush()
    with contextlib.suppress(OSError):
        os.write(2, f"{reason_of(err)}: {command} stopped before it finished\n".encode())
    with contextlib.suppress(BaseException):
        atexit._run_exitfuncs()
    os._exit(exit_code(err))
