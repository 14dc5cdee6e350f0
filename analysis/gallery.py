"""The report's failures gallery: every failed episode (not a success: a collision, a timeout, or the goal reached
after a contact) with a small picture of its run, its log and the step of its first contact.

``failures.csv`` lists every failed episode; the report pictures the first :data:`MAX_PER_GROUP` failures (lowest
seeds) of each group and counts the rest, so that a sweep of thousands of episodes still gives a page one can read.
The pictures are panels of one figure, ``failures.png`` (a row per group headed by its scenario and group, a panel
per failure titled with its seed, outcome and first contact; :data:`ROWS_PER_FIGURE` groups a figure, further ones
``failures_2.png``, ...): one figure draws in a fraction of the time of a file per failure (issue #36). The first
contact step is the first step the simulator flagged as in contact in the log (``/robot/state``
``contact_static``/``contact_dynamic``; the report's collision cross-check lists any episode where these flags and
the contacts recomputed from the geometry disagree).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from analysis import plots
from analysis.deferred import deferred
from analysis.drawing import Figure, Figures
from analysis.run_parameters import SEP
from analysis.tables import relative_log
from analysis.trace import Trace

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

MAX_PER_GROUP = 5
"""Failures pictured per group (scenario label and variant); the others are counted and listed in failures.csv."""
READ_ALL_MAX = 400
"""Up to this many failures, every failed episode's log is read for its first contact step (``failures.csv``);
beyond, only the pictured ones' (reading a log costs about 10-25 ms: thousands would dominate the report's time)."""
ROWS_PER_FIGURE = 40
"""Groups (rows of panels) per gallery figure: beyond, the next figure (a figure of hundreds of rows would exceed
the 65,536 pixels a PNG drawn by matplotlib may be high)."""
PANEL_WIDTH_IN = 2.45
"""A panel's width (inches: 220 px at the report's 90 dpi)."""
COLUMNS = ["scenario", "variant", "seed", "outcome", "steps", "collisions_static", "collisions_dynamic",
           "first_contact_step", "log_read", "log", "picture"]


@dataclass(frozen=True)
class Failure:
    """One pictured failure: its row of ``failures.csv`` and the file of the figure that has its panel."""

    row: dict
    picture: str


@dataclass(frozen=True)
class Panel:
    """One failure's panel: its episode, its group's colour and its title."""

    trace: Trace
    color: str
    title: str


def failed(df: pd.DataFrame) -> pd.DataFrame:
    """The failed episodes (``success`` false) in the groups' order, lowest seed first within a group."""
    return df[~df["success"].astype(bool)]


def shown(df: pd.DataFrame, max_per_group: int = MAX_PER_GROUP) -> pd.DataFrame:
    """The failures the report pictures: the first ``max_per_group`` of each group (the rows are in the groups'
    natural order, then by seed)."""
    return failed(df).groupby(["scenario_label", "variant"], sort=False).head(max_per_group)


def logs_to_read(df: pd.DataFrame, max_per_group: int = MAX_PER_GROUP) -> list[str]:
    """The logs the gallery reads: every failure's up to :data:`READ_ALL_MAX` failures, else the pictured ones."""
    every = failed(df)
    return list((every if len(every) <= READ_ALL_MAX else shown(df, max_per_group))["log"])


def _aspect(trace: Trace) -> float:
    """A panel's height over its width: the walls' (with a margin), within 0.25-1.5."""
    if trace.world.bounds is None:
        return 0.6
    xmin, ymin, xmax, ymax = trace.world.bounds
    return max(0.25, min(1.5, (ymax - ymin + 40) / max(xmax - xmin + 40, 1e-9)))


def gallery_figure(rows: list[tuple[str, str, list[Panel]]], path: Path) -> Path:
    """A figure of failures: per (heading, colour, panels) a row headed by the group's name in its colour, then a
    panel per failure (world, robot path, contacts, moving obstacles' paths: :func:`analysis.plots.draw_world`,
    :func:`analysis.plots.draw_traces`) titled with its seed and outcome; each row as high as its highest world.
    The panels are placed on one :func:`analysis.plots.sheet` (:func:`analysis.plots.panel_placement`)."""
    heading_in, title_in, gap_in, margin_in = 0.24, 0.2, 0.1, 0.08
    cols = max(len(panels) for _, _, panels in rows)
    heights = [PANEL_WIDTH_IN * max(_aspect(p.trace) for p in panels) for _, _, panels in rows]
    width = 2 * margin_in + cols * PANEL_WIDTH_IN + (cols - 1) * gap_in
    height = 2 * margin_in + sum(heights) + len(rows) * (heading_in + title_in)
    fig, ax = plots.sheet(width, height)
    top = height - margin_in
    for (heading, color, panels), panel_h in zip(rows, heights, strict=True):
        ax.text(margin_in, top - heading_in / 2, heading, color=color, fontsize=8, va="center")
        top -= heading_in + title_in + panel_h
        for col, panel in enumerate(panels):
            cell = (margin_in + col * (PANEL_WIDTH_IN + gap_in), top, PANEL_WIDTH_IN, panel_h)
            limits = plots.world_limits(panel.trace.world) or plots.paths_limits([panel.trace])
            placement = plots.panel_placement(ax, cell, limits)
            plots.draw_world(ax, panel.trace.world, placement)
            plots.draw_traces(ax, [panel.trace], panel.color, placement, lw=1.4)
            ax.text(cell[0] + PANEL_WIDTH_IN / 2, top + panel_h + 0.03, panel.title, fontsize=7, ha="center",
                    va="baseline")
    return plots._save(fig, path)


def figure_name(page: int) -> str:
    """The file of the gallery's ``page``-th figure (from 0): ``failures.png``, ``failures_2.png``, ..."""
    return "failures.png" if page == 0 else f"failures_{page + 1}.png"


def gallery(df: pd.DataFrame, traces: Mapping[str, Trace], out: Path, max_per_group: int = MAX_PER_GROUP,
            logs_from: Path | None = None, contacts: Mapping[str, int | None] | None = None,
            figures: Figures | None = None) -> tuple[list[Failure], pd.DataFrame, list[Figure | Path]]:
    """Write ``failures.csv`` (every failure; ``first_contact_step`` where its log was read, i.e. in ``contacts``,
    log -> first contact step (default: those of ``traces``): :func:`logs_to_read`; empty for a failure without a
    flagged contact, a timeout; ``log`` relative to ``logs_from``, the folder ``failures.csv`` ends up in, default
    ``out``; ``picture`` the figure with its panel) and the gallery's figures (:func:`gallery_figure`, named by
    :func:`figure_name`) with a panel for each failure :func:`shown` picks whose trace is in ``traces``: drawn now,
    or planned in ``figures`` (:mod:`analysis.drawing`). Returns the pictured failures (in the panels' order), the
    counts per group (``failed``, ``pictured``, ``not pictured``) and the figures (paths, or planned
    :class:`analysis.drawing.Figure`)."""
    if contacts is None:
        contacts = {log: trace.first_contact_step for log, trace in traces.items()}
    pal = plots.palette(df)
    every = failed(df)
    pictured = set(shown(df, max_per_group).index)
    rows, pictures = [], []
    groups: dict[tuple[str, str], list[tuple[Panel, dict]]] = {}  # a row of panels per group, in the groups' order
    needed = ["scenario_label", "variant", "seed", "outcome", "steps", "collisions_static", "collisions_dynamic", "log"]
    # plain records (one per failure, thousands in a large sweep): iterrows built a Series per row
    records = every[needed].astype(object).to_dict("records")
    for index, episode in zip(every.index, records, strict=True):
        trace = traces.get(episode["log"])
        read = episode["log"] in contacts
        row = {"scenario": episode["scenario_label"], "variant": episode["variant"], "seed": episode["seed"],
               "outcome": episode["outcome"], "steps": episode["steps"],
               "collisions_static": episode["collisions_static"], "collisions_dynamic": episode["collisions_dynamic"],
               "first_contact_step": contacts[episode["log"]] if read else None,
               "log_read": read,  # False: first_contact_step unknown (not "no contact")
               "log": relative_log(str(episode["log"]), logs_from or out), "picture": ""}
        if index in pictured and trace is not None:
            contact = (f", contact at step {trace.first_contact_step}" if trace.first_contact_step is not None
                       else "")
            panel = Panel(trace, pal[episode["variant"]].color,
                          f"seed {episode['seed']}: {episode['outcome']}{contact}")
            groups.setdefault((episode["scenario_label"], episode["variant"]), []).append((panel, row))
        rows.append(row)
    keys = list(groups)
    drawn: list[Figure | Path] = []
    for page, first in enumerate(range(0, len(keys), ROWS_PER_FIGURE)):
        name = figure_name(page)
        page_rows = []
        for key in keys[first:first + ROWS_PER_FIGURE]:
            for _, row in groups[key]:
                row["picture"] = name
                pictures.append(Failure(row=row, picture=name))
            page_rows.append((f"{key[0]}{SEP}{key[1]}", pal[key[1]].color, [panel for panel, _ in groups[key]]))
        if figures is None:
            drawn.append(gallery_figure(page_rows, out / name))
        else:  # a panel costs about a tenth of a figure of small multiples
            drawn.append(figures.add(gallery_figure, page_rows, out / name,
                                     cost=0.1 * sum(len(panels) for _, _, panels in page_rows)))
    table = pd.DataFrame(rows, columns=COLUMNS)
    table["first_contact_step"] = table["first_contact_step"].astype("Int64")  # integers, missing stays missing
    table.to_csv(out / "failures.csv", index=False)
    counts = every.groupby(["scenario_label", "variant"], sort=False).size().rename("failed").reset_index()
    pictured_per_group = Counter((f.row["scenario"], f.row["variant"]) for f in pictures)
    counts["pictured"] = [pictured_per_group[(s, v)] for s, v in zip(counts["scenario_label"], counts["variant"],
                                                                     strict=True)]
    counts["not pictured"] = counts["failed"] - counts["pictured"]
    return pictures, counts.rename(columns={"scenario_label": "scenario"}), drawn
