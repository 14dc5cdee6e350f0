"""Work shared with worker processes forked from this one (issue #36): the report's log reading and figure drawing.

A forked worker starts in a few milliseconds with everything this process holds (modules imported, tables,
traces): nothing is pickled on the way in, only results come back. Workers and this process take the next item
from a shared counter until none is left, so a slow item does not hold back the others; each worker sends back
its results (or the exception an item raised) when it is done. A worker that dies leaves its items to this
process. An interrupt of this process ends its workers with it; a worker never prints anything.

Forking is only safe in a process without other threads (a thread holding a lock at the fork leaves the child
deadlocked): :func:`can_fork` says no where there are some (a sweep's launcher with joblib's worker pool, a
notebook), and the callers then do without (joblib's pool, or this process alone).
"""

from __future__ import annotations

import contextlib
import gc
import multiprocessing
import os
import pickle
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any


def can_fork() -> bool:
    """Whether worker processes can be forked from this process: the platform forks safely (not Windows; not macOS,
    whose system libraries do not survive a fork: Python stopped forking there by default), and no other thread
    runs."""
    return (sys.platform != "darwin" and "fork" in multiprocessing.get_all_start_methods()
            and threading.active_count() == 1)


def worker_count(jobs: int, items: int) -> int:
    """Processes (this one included) for ``items`` items with ``jobs`` (-1: every core; 1: this process only), at
    most one per item."""
    if jobs == 1 or items < 2:
        return 1
    from joblib import cpu_count  # the cores this process may use (affinity, container quota)

    return max(1, min(items, cpu_count() if jobs < 0 else jobs))


@contextlib.contextmanager
def collector_frozen() -> Iterator[None]:
    """Python's cyclic garbage collector left to the objects made from now on: everything alive before (imported
    modules, tables, traces) is set aside, so that a collection does not scan it again and again, and a forked
    worker does not copy the memory pages such a scan would touch."""
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def run(work: Callable[[int], Any], count: int, workers: int, meanwhile: Callable[[], object] | None = None,
        pack: Callable[[dict[int, Any]], dict[int, Any]] | None = None) -> list[Any]:
    """``work(i)`` for ``i`` in ``range(count)``, in this process and ``workers - 1`` forked workers (see the
    module's docstring; the caller checks :func:`can_fork`). Returns each item's result, or the exception it
    raised (an ``Exception``; an interrupt of this process propagates), in order. Items are taken in order: put
    the costliest first. ``meanwhile``: work of this process's own to do once the workers are started, before it
    takes its share (the report imports matplotlib while its workers read the logs). ``pack``: applied in each
    worker to its results ({item: result}) before they are sent back, to shrink what travels."""
    ctx = multiprocessing.get_context("fork")
    shared = (ctx.RawValue("i", 0), ctx.Lock())
    children: list[tuple[Any, Any]] = []
    with collector_frozen():
        try:
            for _ in range(workers - 1):
                receive, send = ctx.Pipe(duplex=False)
                child = ctx.Process(target=_worker, args=(work, count, shared, send, pack), daemon=True)
                child.start()
                send.close()
                children.append((child, receive))
            if meanwhile is not None:
                meanwhile()
            done = _share(work, count, shared)
            for child, receive in children:
                with contextlib.suppress(EOFError, OSError):  # a worker that died sent nothing: its items are redone
                    done.update(receive.recv())
                child.join()
        finally:
            for child, receive in children:
                if child.is_alive():  # this process was interrupted or failed: its workers end with it
                    child.kill()
                    child.join()
                receive.close()
        for i in range(count):  # taken by a worker that died before it sent its results
            if i not in done:
                done[i] = attempt(work, i)
    return [done[i] for i in range(count)]


def attempt(work: Callable[[int], Any], i: int) -> Any:
    """``work(i)``, or the exception it raised."""
    try:
        return work(i)
    except Exception as err:
        return err


def _share(work: Callable[[int], Any], count: int, shared: tuple[Any, Any]) -> dict[int, Any]:
    """Take the next item from the shared (counter, lock) and do it, until none is left: item -> result."""
    counter, lock = shared
    done: dict[int, Any] = {}
    while True:
        with lock:
            i = counter.value
            counter.value = i + 1
        if i >= count:
            return done
        done[i] = attempt(work, i)


def _travels(result: Any) -> Any:
    """A worker's result as it can be sent back: an exception that does not pickle becomes its type and message."""
    if not isinstance(result, BaseException):
        return result
    try:
        pickle.loads(pickle.dumps(result))
        return result
    except Exception:
        return RuntimeError(f"{type(result).__name__}: {result}")


def _worker(work: Callable[[int], Any], count: int, shared: tuple[Any, Any], conn: Any,
            pack: Callable[[dict[int, Any]], dict[int, Any]] | None = None) -> None:
    """A forked worker: items until none is left, then {item: result} sent back. An interrupt (this process ends
    it, or Ctrl-C reaches the whole process group) ends it at once without a word: the report's process says what
    happened."""
    try:
        done = _share(work, count, shared)
        if pack is not None:
            done = pack(done)
        conn.send({i: _travels(r) for i, r in done.items()})
        conn.close()
    except BaseException:
        os._exit(1)
