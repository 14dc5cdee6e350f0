"""The report's failures gallery: every failed episode (not a success: a collision, a timeout, or the goal reached
after a contact) with a small picture of its run, its log and the step of its first contact.

``failures.csv`` lists every failed episode; the report shows the pictures of the first :data:`MAX_PER_GROUP`
failures (lowest seeds) of each group and counts the rest, so that a sweep of thousands of episodes still gives a
page one can read. The first contact step is the first step the simulator flagged as in contact in the log
(``/robot/state`` ``contact_static``/``contact_dynamic``; the report's collision cross-check lists any episode where
these flags and the contacts recomputed from the geometry disagree).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from analysis import plots
from analysis.deferred import deferred
from analysis.drawing import Figures
from analysis.tables import relative_log
from analysis.trace import Trace

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

MAX_PER_GROUP = 5
"""Failures pictured per group (scenario label and variant); the others are counted and listed in failures.csv."""
READ_ALL_MAX = 400
"""Up to this many failures, every failed episode's log is read for its first contact step (``failures.csv``);
beyond, only the pictured ones' (reading a log costs about 10-25 ms: thousands would dominate the report's time)."""
COLUMNS = ["scenario", "variant", "seed", "outcome", "steps", "collisions_static", "collisions_dynamic",
           "first_contact_step", "log_read", "log", "picture"]


@dataclass(frozen=True)
class Failure:
    """One pictured failure: its row of ``failures.csv`` and the picture's file name."""

    row: dict
    picture: str


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


def thumbnail(trace: Trace, color: str, title: str, path: Path) -> Path:
    """A small PNG (about 220 px wide) of one episode: world, robot path, contacts, moving obstacles' paths."""
    world = trace.world
    aspect = 0.6
    if world.bounds is not None:
        xmin, ymin, xmax, ymax = world.bounds
        aspect = max(0.25, min(1.5, (ymax - ymin + 40) / max(xmax - xmin + 40, 1e-9)))
    width = 2.45  # inches: 220 px at the report's 90 dpi
    fig = plots.pyplot().figure(figsize=(width, width * aspect + 0.25))
    ax = fig.add_axes((0.01, 0.01, 0.98, 0.98 - 0.25 / (width * aspect + 0.25)))
    plots.draw_world(ax, world)
    plots.draw_traces(ax, [trace], color, lw=1.4)
    ax.set_axis_off()  # the walls are the frame
    plots.set_title(ax, title, fontsize=7, pad=2)
    return plots._save(fig, path)


def gallery(df: pd.DataFrame, traces: Mapping[str, Trace], out: Path, max_per_group: int = MAX_PER_GROUP,
            logs_from: Path | None = None, contacts: Mapping[str, int | None] | None = None,
            figures: Figures | None = None) -> tuple[list[Failure], pd.DataFrame]:
    """Write ``failures.csv`` (every failure; ``first_contact_step`` where its log was read, i.e. in ``contacts``,
    log -> first contact step (default: those of ``traces``): :func:`logs_to_read`; empty for a failure without a
    flagged contact, a timeout; ``log`` relative to ``logs_from``, the folder ``failures.csv`` ends up in, default
    ``out``) and a picture ``failure_<scenario>__<variant>__s<seed>.png`` of each failure :func:`shown` picks
    whose trace is in ``traces`` (drawn now, or planned in ``figures``: :mod:`analysis.drawing`); returns the
    pictured failures and the counts per group (``failed``, ``pictured``, ``not pictured``)."""
    if contacts is None:
        contacts = {log: trace.first_contact_step for log, trace in traces.items()}
    pal = plots.palette(df)
    every = failed(df)
    pictured = set(shown(df, max_per_group).index)
    rows, pictures = [], []
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
            name = (f"failure_{plots._file_part(episode['scenario_label'])}__{plots._file_part(episode['variant'])}"
                    f"__s{episode['seed']}.png")
            contact = (f", contact at step {trace.first_contact_step}" if trace.first_contact_step is not None
                       else "")
            args = (trace, pal[episode["variant"]].color, f"seed {episode['seed']}: {episode['outcome']}{contact}",
                    out / name)
            if figures is None:
                thumbnail(*args)
            else:
                figures.add(thumbnail, *args, cost=0.6)
            row["picture"] = name
            pictures.append(Failure(row=row, picture=name))
        rows.append(row)
    table = pd.DataFrame(rows, columns=COLUMNS)
    table["first_contact_step"] = table["first_contact_step"].astype("Int64")  # integers, missing stays missing
    table.to_csv(out / "failures.csv", index=False)
    counts = every.groupby(["scenario_label", "variant"], sort=False).size().rename("failed").reset_index()
    drawn = Counter((f.row["scenario"], f.row["variant"]) for f in pictures)
    counts["pictured"] = [drawn[(s, v)] for s, v in zip(counts["scenario_label"], counts["variant"],
                                                                     strict=True)]
    counts["not pictured"] = counts["failed"] - counts["pictured"]
    return pictures, counts.rename(columns={"scenario_label": "scenario"})
