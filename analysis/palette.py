"""Colours, markers and line styles of the report's groups: colour-blind safe, distinct per group, the same group
in the same colour in every figure of a report.

Colours come from Okabe & Ito's palette ("Color Universal Design", 2008) for up to seven groups and from Paul Tol's
*muted* scheme (https://personal.sron.nl/~pault/, nine colours) for up to nine: both stay distinguishable under
the common colour-vision deficiencies. Their pale yellows, which vanish on the report's white background, are
replaced by a dark grey. Black is left out of both (contacts are marked with a black ``x``) and so is
red-like vermillion next to the red of moving obstacles where it can be (Okabe–Ito's vermillion is its 7th colour).
Beyond nine groups the colours repeat, and the marker and line style (which change with every repeat) keep the
series apart. Every group also has a marker (dot plots) and its strategy's line style (lines), so that a figure
read in grey or by someone who cannot tell two colours apart still separates the series.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

GREY = "#666666"
"""A neutral dark grey (contrast 5.7:1 on white), in place of the palettes' pale yellows."""
OKABE_ITO = ("#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", GREY)
"""Blue, orange, bluish green, reddish purple, sky blue, vermillion, and grey in place of Okabe–Ito's yellow
(#F0E442, contrast 1.3:1 on white: the detour group of the default sweep was barely visible); black left out."""
TOL_MUTED = ("#332288", "#88CCEE", "#44AA99", "#117733", "#999933", GREY, "#CC6677", "#882255", "#AA4499")
"""Indigo, cyan, teal, green, olive, grey in place of Tol's sand (#DDCC77, 1.6:1 on white), rose, wine, purple."""


def contrast_on_white(colour: str) -> float:
    """WCAG 2 contrast ratio of ``colour`` (``#RRGGBB``) against white: 1 (invisible) to 21 (black)."""
    channels = [int(colour[i:i + 2], 16) / 255 for i in (1, 3, 5)]
    linear = [c / 12.92 if c <= 0.03928 else ((c + 0.055) / 1.055) ** 2.4 for c in channels]
    luminance = 0.2126 * linear[0] + 0.7152 * linear[1] + 0.0722 * linear[2]
    return 1.05 / (luminance + 0.05)
MARKERS = ("o", "s", "D", "^", "v", "P", "X", "<", ">")
LINESTYLES = ("-", "--", "-.", ":")
STRATEGY_LINES = {"auto": "-", "wait": "--", "detour": "-.", "none": ":"}
CONTACT = "black"
"""Colour of the contact markers (an ``x``): in no palette, so never mistaken for a group."""
OBSTACLE = "#BB5566"
"""Moving obstacles' paths (dotted): a muted red, faint in the figures."""


@dataclass(frozen=True)
class Style:
    """How one group is drawn: ``color`` (hex), ``marker`` for dots, ``linestyle`` for lines."""

    color: str
    marker: str
    linestyle: str

    def line(self) -> dict[str, str]:
        """Keyword arguments of ``Axes.plot`` for this group's lines."""
        return {"color": self.color, "linestyle": self.linestyle}


def colours(n: int) -> tuple[str, ...]:
    """The palette for ``n`` groups: Okabe–Ito up to 7, Tol muted up to 9, then Tol muted repeated."""
    return OKABE_ITO if n <= len(OKABE_ITO) else TOL_MUTED


def group_styles(groups: Iterable[str], strategies: Mapping[str, str] | None = None) -> dict[str, Style]:
    """A :class:`Style` per group label, in the order given (the groups' natural order, so that the same set of
    groups gets the same colours in every figure). ``strategies``: group label -> strategy, for the line style
    (``auto`` solid, ``wait`` dashed, ``detour`` dash-dot, ``none`` dotted); a repeat of the colours (more than
    nine groups) shifts the line style and the marker, so that no two groups are drawn alike."""
    labels = list(dict.fromkeys(groups))
    palette = colours(len(labels))
    out = {}
    for i, label in enumerate(labels):
        repeat = i // len(palette)
        strategy = (strategies or {}).get(label, "")
        base = LINESTYLES.index(STRATEGY_LINES[strategy]) if strategy in STRATEGY_LINES else 0
        out[label] = Style(color=palette[i % len(palette)], marker=MARKERS[(i + repeat) % len(MARKERS)],
                           linestyle=LINESTYLES[(base + repeat) % len(LINESTYLES)])
    return out
