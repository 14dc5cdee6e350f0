"""The trajectory small multiples draw a group's failed episodes first, then the others by seed, within the cap."""

from __future__ import annotations

import pandas as pd

from analysis.plots import panel_episodes


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
