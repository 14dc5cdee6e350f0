"""The trajectory small multiples draw a group's failed episodes first, then the others by seed, within the cap; the
box plots draw matplotlib's box plot statistics."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from analysis.plots import boxes, panel_episodes


def test_failed_episodes_first_then_lowest_seeds_within_the_cap():
    rows = []
    for variant, failed_seeds in (("a", {7, 3, 12}), ("b", set()), ("c", set(range(10)))):
        for seed in range(10, -1, -1) if variant == "a" else range(10):  # any row order
            rows.append({"scenario_label": "s", "variant": variant, "seed": seed, "success": seed not in failed_seeds,
                         "log": f"{variant}{seed}.mcap"})
    df = pd.DataFrame(rows)
    chosen = panel_episodes(df, max_seeds=4)
    assert list(chosen.columns) == list(df.columns)
    per = {v: list(g["seed"]) for v, g in chosen.groupby("variant", sort=False)}
    assert per == {"a": [3, 7, 0, 1], "b": [0, 1, 2, 3], "c": [0, 1, 2, 3]}
    assert list(panel_episodes(df, max_seeds=20).groupby("variant").size()) == [11, 10, 10]  # under the cap: all


samples = st.lists(st.lists(st.floats(-1e6, 1e6, allow_nan=False) | st.sampled_from([0.0, 1.0, 7.0]), max_size=12),
                   min_size=1, max_size=5)


@settings(max_examples=40, deadline=None)
@given(samples)
def test_box_plots_show_what_matplotlibs_box_plot_shows(data):
    """Quartiles, median, whiskers, caps, outliers and the axis limits of plots.boxes are those of Axes.boxplot on
    the same samples (an empty sample: nothing at its place)."""
    arrays = [np.asarray(x, dtype=float) for x in data]
    fig, (mine, theirs) = plt.subplots(1, 2)
    try:
        boxes(mine, arrays, ["C0"] * len(arrays))
        drawn = theirs.boxplot(arrays, patch_artist=True, widths=0.6)
        polygons, whiskers, medians = (c.get_paths() if i == 0 else c.get_segments()
                                       for i, c in enumerate(mine.collections))
        full = [i for i, x in enumerate(arrays) if len(x)]
        assert len(polygons) == len(medians) == len(full) and len(whiskers) == 4 * len(full)
        for k, i in enumerate(full):
            box = drawn["boxes"][i].get_path().vertices
            assert (polygons[k].vertices[:4, 1].min(), polygons[k].vertices[:4, 1].max()) == (box[:, 1].min(),
                                                                                              box[:, 1].max())
            assert list(medians[k][:, 1]) == list(drawn["medians"][i].get_ydata())
            ends = sorted({y for seg in whiskers[4 * k:4 * k + 2] for y in seg[:, 1]})
            theirs_ends = sorted({y for w in drawn["whiskers"][2 * i:2 * i + 2] for y in w.get_ydata()})
            assert ends == theirs_ends
        outliers = sorted(y for line in mine.get_lines() for y in line.get_ydata())
        assert outliers == sorted(y for f in drawn["fliers"] for y in f.get_ydata())
        assert mine.get_ylim() == pytest.approx(theirs.get_ylim()) and mine.get_xlim() == theirs.get_xlim()
    finally:
        plt.close(fig)
