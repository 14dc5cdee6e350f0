"""The report's figures, drawn together once everything else is known: in worker processes on every core, or in
this process (issue #36: drawing them one after the other was half of a report's time).

A figure is planned with :meth:`Figures.add` (the function that draws it and returns its file, its arguments, a
rough cost) where the report shows it; :meth:`Figures.draw` then draws them all, the costliest first, in workers
forked from this process (:mod:`analysis.forked`: they inherit the tables and traces, and take the next figure
as they finish one, this process drawing its share too). Where this process cannot fork (other threads run: a
notebook, a caller's worker pool) or with ``jobs=1``, every figure is drawn here. Either way the files are the
same.
"""

from __future__ import annotations

import gc
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from analysis import forked
from analysis.logs import collector_paused

COLLECT_EVERY = 8
"""Figures a process draws between two runs of the garbage collector, which is off while they are drawn (a
matplotlib figure is thousands of objects in reference cycles: the collector ran again and again while they were
built, a tenth of the drawing time; collected every few figures, they do not pile up)."""


@dataclass
class Figure:
    """One planned figure: ``draw(*args)`` writes it and returns its file (``path`` once drawn); ``cost``: its
    drawing time relative to the others (its number of panels), the costliest are started first."""

    draw: Callable[..., Path]
    args: tuple[Any, ...]
    cost: float = 1.0
    path: Path | None = None


@dataclass
class Figures:
    """The figures of a report, drawn together by :meth:`draw`."""

    planned: list[Figure] = field(default_factory=list)

    def add(self, draw: Callable[..., Path], *args: Any, cost: float = 1.0) -> Figure:
        """Plan ``draw(*args)``; the returned :class:`Figure` gets its ``path`` when drawn."""
        figure = Figure(draw, args, cost)
        self.planned.append(figure)
        return figure

    def draw(self, jobs: int = -1, meanwhile: Callable[[], object] | None = None) -> None:
        """Draw every planned figure: in ``jobs`` processes (-1: every core; 1: this one only), forked from this one
        (:mod:`analysis.forked`; in this process alone where it cannot fork). ``meanwhile``: work of this process's
        own, done while the workers draw (before it draws its share; without workers, before the figures). The
        first error (in the figures' order) is raised once every figure has been tried."""
        order = sorted(range(len(self.planned)), key=lambda i: -self.planned[i].cost)
        workers = forked.worker_count(jobs, len(order)) if forked.can_fork() else 1
        drawn = [0]  # by this process (each worker counts its own)

        def draw(position: int) -> Path:
            figure = self.planned[order[position]]
            path = Path(figure.draw(*figure.args))
            drawn[0] += 1
            if drawn[0] % COLLECT_EVERY == 0:
                gc.collect()  # the closed figures' cycles: the collector is off while drawing
            return path

        with collector_paused():
            if workers > 1:
                results = forked.run(draw, len(order), workers, meanwhile)
            else:
                if meanwhile is not None:
                    meanwhile()
                with forked.collector_frozen():
                    results = [forked.attempt(draw, position) for position in range(len(order))]
        by_figure = dict(zip(order, results, strict=True))
        for i, result in by_figure.items():
            if isinstance(result, Path):
                self.planned[i].path = result
        errors = [(i, by_figure[i]) for i in range(len(self.planned)) if isinstance(by_figure[i], BaseException)]
        if errors:
            i, error = errors[0]
            if isinstance(error, OSError):  # (a full disk, a folder gone: the callers name the file)
                raise error
            name = getattr(self.planned[i].draw, "__name__", "figure")
            raise FigureError(f"figure {name!r} could not be drawn: {type(error).__name__}: "
                              f"{' '.join(str(error).split())[:300]}") from error


class FigureError(RuntimeError):
    """A figure whose drawing raised something other than an ``OSError``: which one, and what it raised, in one
    line (the drawing's own exception is its ``__cause__``)."""
