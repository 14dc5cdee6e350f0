"""Report figures (matplotlib, PNG): the effect of h_wait, distributions per group, trajectories per scenario group.

Every figure draws one series per group (variant label from :mod:`analysis.run_parameters`), so each value of a
differing run parameter is its own point, box or panel, in the group's colour from :mod:`analysis.palette` (the
same in every figure of a report). PNGs are small (90 dpi): a report of many scenarios stays light. matplotlib is
imported when the first figure is drawn (:func:`pyplot`), not with this module: the report plans its figures
without it, and imports it while its worker processes read the logs."""

from __future__ import annotations

import functools
import hashlib
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from analysis.deferred import deferred
from analysis.palette import CONTACT, OBSTACLE, Style, group_styles
from analysis.run_parameters import SEP
from analysis.stats import bootstrap_mean, wilson
from analysis.trace import MAX_SEEDS_PER_PANEL, Trace, World

pd = deferred("pandas")  # loaded once the logs are being read (analysis.deferred)

DPI = 90


@functools.cache
def pyplot() -> Any:
    """matplotlib's ``pyplot`` on the Agg backend (files only), with the parts the figures use, imported on first
    use (a quarter of a second)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.collections
    import matplotlib.patches
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    return plt


def __getattr__(name: str) -> Any:
    if name == "plt":  # plots.plt, as when pyplot was imported with this module
        return pyplot()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def panel_episodes(df: pd.DataFrame, max_seeds: int = MAX_SEEDS_PER_PANEL) -> pd.DataFrame:
    """The episodes a trajectory panel draws, per group (scenario label and variant) in the groups' order: its failed
    episodes first (the ones a reader wants to see), then the others, each by seed; at most ``max_seeds``."""
    order = df.assign(_ok=df["success"].astype(bool)).sort_values(["_ok", "seed"], kind="stable")
    return order.groupby(["scenario_label", "variant"], sort=False).head(max_seeds).drop(columns="_ok")


def palette(df: pd.DataFrame) -> dict[str, Style]:
    """The :class:`analysis.palette.Style` of every group (variant) of ``df``, in the groups' natural order."""
    first = df.drop_duplicates("variant")
    return group_styles(first["variant"], dict(zip(first["variant"], first["strategy"].astype(str), strict=True)))


def styles(df: pd.DataFrame) -> dict[str, dict]:
    """``Axes.plot`` keywords (colour, line style) of every group: a distinct colour-blind-safe colour per group,
    the line style of its strategy (auto solid, wait dashed, detour dash-dot, none dotted)."""
    return {variant: style.line() for variant, style in palette(df).items()}


FILE_PART_MAX = 60
"""Characters of a label in a file name: a label of many differing parameters (a controller's whole rule base)
would exceed the file system's 255 bytes."""


def _file_part(label: str) -> str:
    """A label as part of a file name (``random_mixed · n_dynamic=5`` -> ``random_mixed__n_dynamic=5``), one file
    per label: where characters had to be replaced (``x y`` and ``x_y`` would both be ``x_y``), where ``__`` was
    already in the label, or where letters are upper case (one file on a case-insensitive file system), the name
    ends in a hash of the label; a long one is its first 40 characters and that hash."""
    plain = label.replace(SEP, "__")
    part = re.sub(r"[^A-Za-z0-9_.=-]+", "_", plain)
    digest = hashlib.sha1(label.encode()).hexdigest()[:10]
    if len(part) > FILE_PART_MAX:
        return f"{part[:40]}_{digest}"
    return part if part == plain and "__" not in label and part == part.lower() else f"{part}_{digest}"


PNG_COMPRESS_LEVEL = 1
"""zlib's level for the PNGs: the fastest, a quarter larger files than the default 6, which spent a tenth of a
report's drawing time compressing (issue #36)."""


def _save(fig, path: Path) -> Path:
    """Write a figure and free it (one place, so that tests can look at every figure before it is saved). No
    ``Software`` entry: no version string in the file (the pixels may still change with matplotlib's rendering)."""
    fig.savefig(path, dpi=DPI, metadata={"Software": None}, pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    pyplot().close(fig)
    return path


def set_title(ax, text: str, **kwargs: Any) -> None:
    """A panel's title just above its axes. Placed there outright: matplotlib's automatic placement measures every
    tick label of the panel again at each draw to keep the title clear of decorations above the axes, which these
    panels do not have (no ticks on top, no offset text: :func:`plain_numbers`); it was a tenth of a report's
    drawing time."""
    ax.set_title(text, y=1.0, **kwargs)


def plain_numbers(ax) -> None:
    """Tick labels on the y axis as the numbers themselves, never as an offset written above the axes (where it
    would meet the title :func:`set_title` places)."""
    ax.ticklabel_format(axis="y", useOffset=False)


def _legend_entries(fig) -> dict[str, object]:
    """Each labelled series of the figure's panels once, in drawing order."""
    entries: dict[str, object] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            if not label.startswith("_"):
                entries.setdefault(label, handle)
    return entries


def legend_width_in(labels: list[str], fontsize: float = 7) -> float:
    """Width (inches) a one-column legend of ``labels`` needs: the handle, the gap and the longest label (a
    character of a sans-serif font is about 0.6 of its size on average)."""
    longest = max((len(label) for label in labels), default=0)
    return 0.55 + longest * 0.6 * fontsize / 72


def grid(rows: int, cols: int, panel_w: float, panel_h: float, left: float = 0.7, right: float = 0.15,
         top: float = 0.45, bottom: float = 0.5, wspace: float = 0.45, hspace: float = 0.35, **kwargs):
    """A figure of ``rows`` x ``cols`` panels of ``panel_w`` x ``panel_h`` inches with fixed margins (inches).
    Fixed margins instead of matplotlib's constrained layout: that measures every tick label of every panel
    several times and made a report's figures take most of its time."""
    width = left + right + cols * panel_w + (cols - 1) * wspace
    height = top + bottom + rows * panel_h + (rows - 1) * hspace
    fig, axes = pyplot().subplots(rows, cols, figsize=(width, height), squeeze=False, **kwargs)
    fig.subplots_adjust(left=left / width, right=1 - right / width, top=1 - top / height, bottom=bottom / height,
                        wspace=wspace / panel_w, hspace=hspace / panel_h)
    return fig, axes


def _legend_outside(fig, fontsize: float = 7) -> None:
    """One legend for the whole figure in its right margin (inside, a dozen series would hide the data); the
    figure must leave :func:`legend_width_in` of room there."""
    entries = _legend_entries(fig)
    if entries:
        fig.legend(list(entries.values()), list(entries), loc="upper right", fontsize=fontsize, frameon=False,
                   ncols=1 + len(entries) // 40, borderaxespad=0.2)


def _mean_interval(values: pd.Series, metric: str) -> tuple[float, float, float]:
    """(mean, low, high): the success rate with its Wilson interval, any other metric's mean with its 95 %
    percentile bootstrap interval (:mod:`analysis.stats`)."""
    if metric == "success":
        x = values.dropna().astype(bool)
        return wilson(int(x.sum()), len(x))
    return bootstrap_mean(values)


def interval(ax, position: float, mean: float, lo: float, hi: float, style: Style, label: str,
             horizontal: bool = False, size: float = 5.0, bars: list | None = None) -> None:
    """A mean as a dot and its interval as a bar from ``lo`` to ``hi`` (drawn as they are: a percentile bootstrap
    interval need not be symmetric, and a mean a rounding error outside it is not moved into it), at ``position``
    on the other axis; the legend entry shows the group's marker and colour. ``bars``: a panel's list that collects
    the bar (:func:`draw_bars` draws them all at once) instead of drawing it now."""
    if not (math.isnan(lo) or math.isnan(hi)):
        xs, ys = ([lo, hi], [position, position]) if horizontal else ([position, position], [lo, hi])
        if bars is None:
            ax.plot(xs, ys, color=style.color, lw=1.4, solid_capstyle="butt", zorder=3)
        else:
            bars.append((list(zip(xs, ys, strict=True)), style.color))
    x, y = (mean, position) if horizontal else (position, mean)
    ax.plot([x], [y], marker=style.marker, ms=size, color=style.color, linestyle="-", lw=1.4, label=label, zorder=4)


def draw_bars(ax, bars: list) -> None:
    """The interval bars :func:`interval` collected for a panel, as one collection (a line each cost as much to make
    and draw as the rest of the panel)."""
    from matplotlib.collections import LineCollection

    if bars:
        segments, colors = zip(*bars, strict=True)
        ax.add_collection(LineCollection(segments, colors=colors, linewidths=1.4, capstyle="butt", zorder=3))


H_WAIT_METRICS = ("min_clearance_dynamic_cm", "wait_steps", "spl")
"""The rows of the h_wait figure: success rate, time-to-goal and path length with the same intervals are the overview
figure's (:mod:`analysis.overview`, a row per group, auto's h_wait settings next to each other); every metric per
group is in groups.csv."""


MIN_SPAN = 0.2  # a panel's y range covers at least this fraction of its largest value's magnitude


def honest_ylim(low: float, high: float, metric: str) -> tuple[float, float]:
    """Y limits of a panel that do not magnify noise: a rate spans 0..1; another metric at least ``MIN_SPAN`` of
    its magnitude, around the data (matplotlib's own limits zoomed into 996-1,000 cm, so that equal path lengths
    looked like an effect of h_wait)."""
    if metric == "success" or metric.endswith("_rate"):
        return -0.05, 1.05
    if not (math.isfinite(low) and math.isfinite(high)):
        return low, high
    need = MIN_SPAN * max(abs(low), abs(high))
    if high - low >= need or need == 0:
        return low, high
    centre = (low + high) / 2
    return centre - need / 2, centre + need / 2


def h_wait_effect(df: pd.DataFrame, metrics: tuple[str, ...], out: Path) -> Path:
    """``h_wait_effect.png``: a row per metric, a column per scenario group. In each panel, ``auto``'s mean against
    h_wait with its 95 % interval (Wilson for the success rate, percentile bootstrap otherwise), each point in its
    group's colour and joined by a grey line per setting of the other differing parameters (settings shifted a
    little sideways so that they do not hide each other); the groups that do not read h_wait as horizontal lines
    in their colour with their interval as a band."""
    from matplotlib.ticker import MaxNLocator

    pal = palette(df)
    scenarios = list(pd.unique(df["scenario_label"]))
    settings = list(pd.unique(df["setting"]))
    dodge = 0.08 if len(settings) > 1 else 0.0
    setting_lines = ("-", "--", "-.", ":")
    labels = [*pal, *(SEP.join(["auto", s]) if s else "auto" for s in settings)]
    fig, axes = grid(len(metrics), len(scenarios), 3.0, 1.6, left=0.9, right=legend_width_in(labels) + 0.1,
                     hspace=0.25, sharex="col")
    for col, scenario in enumerate(scenarios):
        sub = df[df["scenario_label"] == scenario]
        auto = sub[sub["strategy"] == "auto"]
        hs = sorted(auto["h_wait"].dropna().unique())
        # each setting's groups and the other strategies' groups, split once for every metric's row
        auto_groups = [(i, setting, list(rows.groupby("variant", sort=False))) for i, setting in enumerate(settings)
                       if not (rows := auto[auto["setting"] == setting]).empty]
        other_groups = list(sub[sub["strategy"] != "auto"].groupby("variant", sort=False))
        for row, metric in enumerate(metrics):
            ax = axes[row][col]
            bars: list = []
            for i, setting, groups in auto_groups:
                shift = dodge * (i - (len(settings) - 1) / 2)
                points = []
                for variant, g in groups:
                    mean, lo, hi = _mean_interval(g[metric], metric)
                    if math.isnan(mean):
                        continue
                    x = float(g["h_wait"].iloc[0]) + shift
                    points.append((x, mean))
                    interval(ax, x, mean, lo, hi, pal[variant], variant, bars=bars)
                if points:
                    xs, ys = zip(*sorted(points), strict=True)
                    ax.plot(xs, ys, color="0.45", lw=1, linestyle=setting_lines[i % len(setting_lines)], zorder=2,
                            label=SEP.join(["auto", setting]) if setting else "auto")
            for variant, rows in other_groups:
                mean, lo, hi = _mean_interval(rows[metric], metric)
                if math.isnan(mean):
                    continue
                ax.axhline(mean, label=variant, lw=1.2, **pal[variant].line())
                if not math.isnan(lo):
                    ax.axhspan(lo, hi, color=pal[variant].color, alpha=0.12, lw=0)
            draw_bars(ax, bars)  # before the limits are read: they cover the bars
            ax.set_ylim(*honest_ylim(*ax.get_ylim(), metric))
            ax.yaxis.set_major_locator(MaxNLocator(4))  # fewer ticks: each costs time in every panel
            if hs:  # whole steps only, and room around a single h_wait
                ax.set_xticks(hs)
                ax.set_xlim(min(hs) - 0.5, max(hs) + 0.5)
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
            plain_numbers(ax)
            if row == 0:
                set_title(ax, scenario, fontsize=9)
            if row == len(metrics) - 1:
                ax.set_xlabel("h_wait (steps)", fontsize=8)
            if col == 0:
                ax.set_ylabel(metric, fontsize=8)
    _legend_outside(fig)
    return _save(fig, out / "h_wait_effect.png")


def boxes(ax, data: list[np.ndarray], colors: list[str], width: float = 0.6) -> None:
    """Tukey box plots at x = 1, 2, ...: a box from the lower to the upper quartile in its colour, the median, whiskers
    to the furthest values within 1.5 interquartile ranges, caps, and the values beyond as small circles (the numbers
    of matplotlib's ``boxplot``: :func:`matplotlib.cbook.boxplot_stats`). Drawn as one collection each of boxes,
    lines and outliers per panel: ``Axes.boxplot`` makes seven artists per box, which were most of the figure's
    drawing time. An empty sample draws nothing at its place."""
    from matplotlib.cbook import boxplot_stats
    from matplotlib.collections import LineCollection, PolyCollection

    polygons, faces, whiskers, medians, fliers = [], [], [], [], []
    half, cap = width / 2, width / 4
    for position, (x, color) in enumerate(zip(data, colors, strict=True), start=1):
        if not len(x):
            continue
        s = boxplot_stats(x)[0]
        left, right = position - half, position + half
        polygons.append([(left, s["q1"]), (right, s["q1"]), (right, s["q3"]), (left, s["q3"])])
        faces.append(color)
        medians.append([(left, s["med"]), (right, s["med"])])
        whiskers += [[(position, s["q1"]), (position, s["whislo"])], [(position, s["q3"]), (position, s["whishi"])],
                     [(position - cap, s["whislo"]), (position + cap, s["whislo"])],
                     [(position - cap, s["whishi"]), (position + cap, s["whishi"])]]
        fliers += [(position, y) for y in s["fliers"]]
    ax.add_collection(PolyCollection(polygons, facecolors=faces, edgecolors="black", linewidths=1.0, alpha=0.6,
                                     zorder=2))
    ax.add_collection(LineCollection(whiskers, colors="black", linewidths=1.0, zorder=2))
    ax.add_collection(LineCollection(medians, colors="C1", linewidths=1.0, zorder=2.1))
    if fliers:
        xs, ys = zip(*fliers, strict=True)
        ax.plot(xs, ys, "o", mfc="none", mec="black", ms=2, alpha=0.5, zorder=2)
    ax.set_xlim(0.5, len(data) + 0.5)
    ax.autoscale_view(scalex=False)


def box_by_variant(df: pd.DataFrame, metrics: list[str], out: Path) -> Path:
    """``box_metrics.png``: a row per metric, a column per scenario group, a box per group in its colour
    (:func:`boxes`)."""
    from matplotlib.ticker import MaxNLocator

    pal = palette(df)
    variants = list(pal)
    colors = [pal[v].color for v in variants]
    scenarios = list(pd.unique(df["scenario_label"]))
    longest = max(len(v) for v in variants)
    fig, axes = grid(len(metrics), len(scenarios), max(2.8, 0.25 * len(variants)), 1.5, left=0.9, hspace=0.2,
                     bottom=0.25 + 0.04 * longest)
    by_scenario = dict(iter(df.groupby("scenario_label", sort=False)))
    for col, scenario in enumerate(scenarios):
        by_variant = dict(iter(by_scenario[scenario].groupby("variant", sort=False)))  # once, not per metric
        for row, metric in enumerate(metrics):
            ax = axes[row][col]
            data = [by_variant[v][metric].dropna().to_numpy(dtype=float) if v in by_variant else np.empty(0)
                    for v in variants]
            boxes(ax, data, colors)
            # the groups' names under the bottom row only (the panels above are the same groups, in the same
            # columns: no ticks there, each costs time in every panel)
            ax.set_xticks(range(1, len(variants) + 1) if row == len(metrics) - 1 else [],
                          variants if row == len(metrics) - 1 else [])
            ax.grid(alpha=0.3, axis="y")
            ax.yaxis.set_major_locator(MaxNLocator(4))  # fewer ticks: each costs time in every panel
            ax.tick_params(labelsize=7)
            plain_numbers(ax)
            if row == 0:
                set_title(ax, scenario, fontsize=9)
            if col == 0:
                ax.set_ylabel(metric, fontsize=8)
            if row == len(metrics) - 1:
                ax.tick_params(axis="x", rotation=60, labelsize=6)
                for label in ax.get_xticklabels():
                    label.set_horizontalalignment("right")
                    label.set_rotation_mode("anchor")  # the label's end under its box
    return _save(fig, out / "box_metrics.png")


TITLE_PAD_IN = 6 / 72
"""Gap between a panel placed in a :func:`sheet` and its title (inches: matplotlib's 6 points above an Axes)."""


def sheet(width: float, height: float):
    """(figure, Axes) of ``width`` x ``height`` inches whose data coordinates are the figure's inches, axes off: the
    ground many small pictures are placed on (:func:`panel_placement`)."""
    fig = pyplot().figure(figsize=(width, height))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0, width)
    ax.set_ylim(0, height)
    ax.set_axis_off()
    return fig, ax


def paths_limits(traces: list[Trace], margin_cm: float = 20.0) -> tuple[float, float, float, float]:
    """(xmin, ymin, xmax, ymax) of a picture of worlds without walls: the robot's paths and goals, plus ``margin_cm``
    (cm)."""
    points = [t.positions[:, :2] for t in traces if len(t.positions)]
    points += [np.asarray([t.world.goal], dtype=float) for t in traces if t.world.goal is not None]
    if not points:
        return -100.0, -100.0, 100.0, 100.0
    xy = np.vstack(points)
    (xmin, ymin), (xmax, ymax) = xy.min(axis=0), xy.max(axis=0)
    return xmin - margin_cm, ymin - margin_cm, xmax + margin_cm, ymax + margin_cm


def world_limits(world: World, margin_cm: float = 20.0) -> tuple[float, float, float, float] | None:
    """(xmin, ymin, xmax, ymax) a picture of ``world`` shows: its walls plus ``margin_cm`` (cm; None without walls)."""
    if world.bounds is None:
        return None
    xmin, ymin, xmax, ymax = world.bounds
    return xmin - margin_cm, ymin - margin_cm, xmax + margin_cm, ymax + margin_cm


@dataclass(frozen=True)
class Placement:
    """Where a picture of a world goes in an Axes shared by many (:func:`panel_placement`): ``transform`` from the
    world's cm to the display, ``clip`` the display box it is clipped to, ``region`` (left, bottom, width, height)
    that box in the Axes' data coordinates."""

    transform: Any
    clip: Any
    region: tuple[float, float, float, float]


def panel_placement(ax, cell: tuple[float, float, float, float], limits: tuple[float, float, float, float]
                    ) -> Placement:
    """The :class:`Placement` that draws the region ``limits`` (xmin, ymin, xmax, ymax, cm) of a world into ``cell``
    (left, bottom, width, height in ``ax``'s data coordinates) at equal scale on both axes, centred, clipped to
    ``limits``: many small pictures in one Axes (an Axes each, with its ticks and spines, cost several times the
    picture)."""
    from matplotlib.transforms import Affine2D, Bbox, TransformedBbox

    left, bottom, width, height = cell
    xmin, ymin, xmax, ymax = limits
    scale = min(width / max(xmax - xmin, 1e-9), height / max(ymax - ymin, 1e-9))
    w, h = (xmax - xmin) * scale, (ymax - ymin) * scale
    region = (left + (width - w) / 2, bottom + (height - h) / 2, w, h)
    transform = Affine2D().translate(-xmin, -ymin).scale(scale).translate(region[0], region[1]) + ax.transData
    return Placement(transform, TransformedBbox(Bbox.from_bounds(*region), ax.transData), region)


def _add(ax, artist, placement: Placement):
    """``artist`` added to ``ax`` in ``placement`` (its transform and clip box; the Axes' limits are set, so nothing
    measures it as Axes.add_line, add_patch and add_collection would)."""
    artist.set_transform(placement.transform)
    ax.add_artist(artist)
    artist.set_clip_box(placement.clip)
    return artist


def draw_world(ax, world: World, placement: Placement) -> None:
    """Walls, static obstacles and the goal, in ``placement`` (:func:`panel_placement`: fitted to the walls and a
    margin, so that paths of moving obstacles that start or end outside the world do not shrink it)."""
    from matplotlib.collections import PatchCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle
    from matplotlib.patches import Polygon as PolygonPatch

    if world.polygons:
        _add(ax, PatchCollection([PolygonPatch(p, closed=True) for p in world.polygons], color="0.65", lw=0, zorder=1),
             placement)
    if world.goal is not None:
        _add(ax, Circle(world.goal, world.goal_tolerance or 20.0, color="#009E73", alpha=0.25, lw=0, zorder=1),
             placement)
    if world.bounds is not None:
        xmin, ymin, xmax, ymax = world.bounds
        _add(ax, Line2D([xmin, xmax, xmax, xmin, xmin], [ymin, ymin, ymax, ymax, ymin], color="0.3", lw=0.8, zorder=1),
             placement)


def draw_traces(ax, traces: list[Trace], color: str, placement: Placement, lw: float = 0.8) -> None:
    """Robot paths as thin lines in ``color`` (overlapping paths darken each other), contacts as black ``x``;
    the moving obstacles' true paths dotted in faint red (each distinct path once), and an obstacle that never
    moved (a dotted path of no length would not show) as a faint red circle where it stood; in ``placement``
    (:func:`panel_placement`)."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    seen: set[bytes] = set()
    for trace in traces:
        for path in trace.obstacle_paths:
            key = path.round(1).tobytes()
            if key in seen or not len(path):
                continue
            seen.add(key)
            if np.ptp(path, axis=0).max() < 1.0:
                _add(ax, Line2D(path[:1, 0], path[:1, 1], marker="o", linestyle="none", mfc="none", color=OBSTACLE,
                                alpha=0.7, ms=4, zorder=2), placement)
            elif len(path) > 1:
                _add(ax, Line2D(path[:, 0], path[:, 1], linestyle=":", color=OBSTACLE, alpha=0.5, lw=0.8, zorder=2),
                     placement)
    _add(ax, LineCollection([t.positions for t in traces if len(t.positions) > 1], colors=color, linewidths=lw,
                            alpha=0.7 if len(traces) < 5 else 0.45, zorder=3), placement)
    hits = [t.positions[list(t.contact_points)] for t in traces if t.contact_points]
    if hits:
        points = np.vstack(hits)
        _add(ax, Line2D(points[:, 0], points[:, 1], marker="x", linestyle="none", color=CONTACT, ms=5, mew=1.2,
                        zorder=4), placement)


def trajectories(df: pd.DataFrame, scenario: str, traces: dict[str, Trace], out: Path,
                 max_seeds: int = MAX_SEEDS_PER_PANEL) -> Path:
    """``trajectories_<scenario>.png``: small multiples, a panel per group of one scenario group with the robot
    paths of its seeds (at most ``max_seeds``: :func:`panel_episodes`, failed ones first) as thin lines in the group's
    colour, contacts as black ``x``, the moving obstacles' true paths dotted, over the static world (each distinct
    world of the panel's episodes; axes fitted to the walls). ``traces``: log path -> :class:`Trace`
    (:func:`analysis.trace.load_traces`)."""
    from matplotlib.patches import Rectangle

    pal = palette(df)
    sub = df.loc[df["scenario_label"] == scenario, ["scenario_label", "variant", "seed", "success", "log"]]
    variants = [v for v in pal if v in set(sub["variant"])]
    cols = min(len(variants), 4)
    rows = -(-len(variants) // cols)
    # the first episode read (in the table's order) gives the walls; not a list of thousands of them
    world0 = next((traces[log].world for log in sub["log"] if log in traces and traces[log].world.bounds is not None),
                  None)
    worlds = [world0] if world0 is not None else []
    aspect = 1.0
    if worlds:
        xmin, ymin, xmax, ymax = worlds[0].bounds  # type: ignore[misc]
        aspect = max(0.25, min(2.0, (ymax - ymin) / max(xmax - xmin, 1e-9)))
    panel_w, panel_h, left, top, wspace, hspace = 3.0, 3.0 * aspect, 0.1, 0.75, 0.15, 0.45  # inches
    fig, ax = sheet(left + 0.1 + cols * panel_w + (cols - 1) * wspace, top + 0.1 + rows * panel_h + (rows - 1) * hspace)
    height = ax.get_ylim()[1]
    chosen = panel_episodes(sub, max_seeds)
    seeds = sub.groupby("variant", sort=False).size()
    failures = (~sub["success"].astype(bool)).groupby(sub["variant"], sort=False).sum()
    for i, variant in enumerate(variants):
        mine = chosen[chosen["variant"] == variant]
        drawn = [traces[log] for log in mine["log"] if log in traces]
        drawn_worlds = {t.world.key(): t.world for t in drawn}
        row, col = divmod(i, cols)
        cell = (left + col * (panel_w + wspace), height - top - (row + 1) * panel_h - row * hspace, panel_w, panel_h)
        # the walls of the panel's last world (as drawn over each other), or around the paths without walls
        limits = next((world_limits(w) for w in reversed(drawn_worlds.values()) if w.bounds is not None), None)
        placement = panel_placement(ax, cell, limits or paths_limits(drawn))
        for world in drawn_worlds.values():
            draw_world(ax, world, placement)
        ok = set(mine.loc[mine["success"].astype(bool), "log"])
        draw_traces(ax, sorted(drawn, key=lambda t: t.log not in ok), pal[variant].color, placement)  # failed on top
        n, failed = int(seeds[variant]), int(failures[variant])
        more = ""
        if len(drawn) < n:  # the failed first (panel_episodes): say so where it made a difference
            more = f", {len(drawn)} drawn, failed first" if 0 < failed < n else f", lowest {len(drawn)} seeds drawn"
        x, y, w, h = placement.region
        ax.text(x + w / 2, y + h + TITLE_PAD_IN, f"{variant}\n{n} seeds, {failed} failed{more}", fontsize=8,
                ha="center", va="baseline")
        # the frame in the group's colour; the walls give the scale (in the title), no ticks
        ax.add_patch(Rectangle((x, y), w, h, fill=False, edgecolor=pal[variant].color, lw=2, zorder=2.5))
    size = ""
    if worlds:
        xmin, ymin, xmax, ymax = worlds[0].bounds  # type: ignore[misc]
        size = f"; walls {xmax - xmin:.0f} x {ymax - ymin:.0f} cm"
    fig.suptitle(f"{scenario}: robot paths of every seed\n(x: contact; dotted: moving obstacles; o: one standing"
                 f"{size})", fontsize=9)
    return _save(fig, out / f"trajectories_{_file_part(scenario)}.png")
