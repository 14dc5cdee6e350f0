"""Recorded pedestrians (fuzzynav.scenarios.recordings, runners.recordings): the two text formats, their errors,
resampling, and the TPT's prediction error — on small files the tests write in the recordings' formats."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzynav.scenarios.recordings import RecordingError, parse, prediction_errors, resample
from runners import recordings as cli
from tests.conftest import ROOT


def obsmat(rows: list[tuple[int, int, float, float]]) -> str:
    """ETH's obsmat layout: frame id x z y vx vz vy (metres; z, velocities unused)."""
    return "".join(f"   {f:.7e}   {i:.7e}   {x:.7e}   0.0000000e+00   {y:.7e}   0.0e+00   0.0e+00   0.0e+00\n"
                   for f, i, x, y in rows)


def xy(rows: list[tuple[int, int, float, float]], sep: str = "\t") -> str:
    return "".join(sep.join(str(v) for v in row) + "\n" for row in rows)


WALKER = [(10 * k, 1, 0.5 * k, 2.0) for k in range(30)]  # 0.5 m per annotation (0.4 s): 125 cm/s along +x


def test_obsmat_and_xy_give_the_same_tracks_in_cm_and_s():
    a = parse(obsmat(WALKER), "obsmat", "a.txt")
    b = parse(xy(WALKER, " "), "xy", "b.txt")
    for rec in (a, b):
        (track,) = rec.tracks
        assert track.id == "1" and rec.annotation_dt_s == pytest.approx(0.4)
        np.testing.assert_allclose(track.t_s, 0.4 * np.arange(30))
        np.testing.assert_allclose(track.xy_cm[:3], [[0, 200], [50, 200], [100, 200]])
    assert a.duration_s == pytest.approx(11.6)


def test_a_file_sorted_by_pedestrian_reads_as_one_sorted_by_frame():
    rows = [(f, i, 0.1 * f + i, float(i)) for i in (1, 2) for f in range(0, 60, 6)]  # 6 frames apart (15 fps)
    by_ped = parse(xy(rows), "xy", "p.txt")
    by_frame = parse(xy(sorted(rows)), "xy", "f.txt")
    for t1, t2 in zip(by_ped.tracks, by_frame.tracks, strict=True):
        np.testing.assert_array_equal(t1.t_s, t2.t_s)
        np.testing.assert_array_equal(t1.xy_cm, t2.xy_cm)


@pytest.mark.parametrize("text, fmt, message", [
    ("1 2 3\n", "xy", "x.txt: line 1: 3 columns, the xy format has 4"),
    ("0 1 0 0\n10 1 nan 0\n", "xy", "x.txt: line 2, column 3: nan is not a finite number"),
    ("0 1 0 0\n10 1 ? 0\n", "xy", "x.txt: line 2, column 3: '?' is not a number"),
    ("0 1 0 0\n0 1 1 0\n", "xy", "x.txt: line 2: pedestrian 1 at frame 0 again (first at line 1)"),
    ("10 1 0 0\n0 1 1 0\n", "xy", "x.txt: line 2: pedestrian 1's frame 0 comes after its frame 10 (line 1)"),
    ("0 1 0 0\n10 2 0 0\n20 1 1 0\n", "xy", "x.txt: line 3: pedestrian 1 reappears at frame 20 after frame 0 (line 1): "
                                          "1 annotation(s) missing"),
    ("0.5 1 0 0\n", "xy", "x.txt: line 1: frame 0.5 is not a whole number"),
    ("# only a comment\n\n", "xy", "x.txt: no annotation"),
    ("0 1 0 0 0 0 0 0\n", "csv", "x.txt: unknown format 'csv'"),
    ("0 1 0 0 1e9 0 0 0\n", "obsmat", "x.txt: line 1, column 5: 1e9 is not a finite number within ±1e7"),
])
def test_bad_files_are_one_line_naming_file_and_line(text, fmt, message):
    with pytest.raises(RecordingError) as err:
        parse(text, fmt, "x.txt")
    assert str(err.value).startswith(message) and "\n" not in str(err.value)


def test_max_gap_allows_that_many_missing_annotations_interpolated():
    rows = [(0, 1, 0.0, 0.0), (10, 1, 1.0, 0.0), (30, 1, 3.0, 0.0), (40, 2, 0.0, 0.0), (50, 2, 0.0, 0.0)]
    with pytest.raises(RecordingError, match="1 annotation"):
        parse(xy(rows), "xy", "g.txt")
    rec = parse(xy(rows), "xy", "g.txt", max_gap=1)
    res = resample(rec, 0.4)
    np.testing.assert_allclose(res.xy_cm[0, :4, 0], [0, 100, 200, 300])  # frame 20 interpolated


def test_resample_interpolates_and_marks_absence_without_extrapolating():
    rows = [(0, 1, 0.0, 0.0), (10, 1, 1.0, 0.0), (20, 1, 2.0, 0.0), (20, 2, 5.0, 5.0), (30, 2, 5.0, 4.0)]
    res = resample(parse(xy(rows), "xy", "r.txt"), dt_s=0.2)
    assert res.ids == ("1", "2")
    np.testing.assert_allclose(res.times_s, [0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2])
    np.testing.assert_allclose(res.xy_cm[0, :5, 0], [0, 50, 100, 150, 200])
    assert res.present[0].tolist() == [True] * 5 + [False] * 2 and np.isnan(res.xy_cm[0, 5:]).all()
    assert res.present[1].tolist() == [False] * 4 + [True] * 3
    np.testing.assert_allclose(res.xy_cm[1, 4:, 1], [500, 450, 400])
    cropped = resample(parse(xy(rows), "xy", "r.txt"), 0.2, crop_cm=(0, 0, 120, 100))
    assert cropped.ids == ("1",) and cropped.present[0].tolist() == [True, True, True, False, False, False, False]
    window = resample(parse(xy(rows), "xy", "r.txt"), 0.4, start_s=0.4, duration_s=0.4)
    np.testing.assert_allclose(window.times_s, [0.0, 0.4])
    np.testing.assert_allclose(window.xy_cm[0, :, 0], [100, 200])


def test_a_straight_walker_is_predicted_exactly_and_standing_is_off_by_speed_times_time():
    errors = prediction_errors(parse(xy(WALKER), "xy", "w.txt"), dt_s=1.0, n_traj=3)
    assert errors.pedestrians == 1 and errors.samples == 8  # t = 1 .. 8 s: 1 s behind and 3 s ahead of 11.6 s
    for name in ("tpt", "cv"):
        np.testing.assert_allclose(errors.fde_cm[name], 0.0, atol=1e-9)
    np.testing.assert_allclose(errors.fde_cm["standing"], [125.0, 250.0, 375.0])
    np.testing.assert_allclose(errors.ade_cm["standing"], [125.0, 187.5, 250.0])


def test_a_turn_separates_the_tpts_velocity_from_the_annotations():
    """Walking +x at 1 m/s to (4.4, 0) m at t = 4.4 s, then +y. Predicting 1 s ahead from t = 1..7 s: at t = 4 both
    velocities are (1, 0) m/s and miss the turn by 84.85 cm; at t = 5 the TPT's (positions 1 s apart: (0.4, 0.6)
    m/s) misses by 56.57 cm, the baseline's (last two annotations: (0, 1) m/s) is exact; otherwise both are."""
    rows = [(10 * k, 1, min(0.4 * k, 4.4), max(0.0, 0.4 * k - 4.4)) for k in range(21)]
    errors = prediction_errors(parse(xy(rows), "xy", "t.txt"), dt_s=1.0, n_traj=1)
    assert errors.samples == 7
    turn = math.hypot(60, 60)
    assert errors.fde_cm["tpt"][0] == pytest.approx((turn + math.hypot(40, 40)) / 7)
    assert errors.fde_cm["cv"][0] == pytest.approx(turn / 7)


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_any_text_gives_a_recording_or_one_line_naming_the_file(data):
    lines = data.draw(st.lists(st.one_of(
        st.tuples(st.integers(0, 200), st.integers(0, 5), st.floats(-10, 10), st.floats(-10, 10)).map(
            lambda r: f"{r[0] * 10} {r[1]} {r[2]} {r[3]}"),
        st.text(alphabet=" \t0123456789.-+eEnaif?#x", max_size=20),
        st.sampled_from(["", "1e400 1 0 0", "10 1 0", "10 1 0 0 0", "-10 1 0 0", "10 1.5 0 0", "\x00"])),
        max_size=30))
    fmt = data.draw(st.sampled_from(["xy", "obsmat"]))
    try:
        rec = parse("\n".join(lines), fmt, "fuzz.txt", max_gap=data.draw(st.integers(0, 2)))
    except RecordingError as err:
        assert str(err).startswith("fuzz.txt: ") and "\n" not in str(err)
        return
    for track in rec.tracks:
        assert np.all(np.diff(track.t_s) > 0) and np.isfinite(track.xy_cm).all()
    res = resample(rec, data.draw(st.sampled_from([0.1, 0.4, 1.0, 2.5])))
    assert np.isnan(res.xy_cm[~res.present]).all() and np.isfinite(res.xy_cm[res.present]).all()
    errors = prediction_errors(rec, 1.0, 3)
    assert errors.samples == 0 or all(np.isfinite(errors.fde_cm[n]).all() for n in errors.fde_cm)


def test_the_command_checks_predicts_and_refuses(tmp_path, capsys):
    good = tmp_path / "obsmat.txt"
    good.write_text(obsmat(WALKER))
    assert cli.main(["check", str(good)]) == 0
    assert "1 pedestrians, 30 annotations every 0.4 s over 11.6 s; sha256" in capsys.readouterr().out
    out_csv = tmp_path / "e.csv"
    assert cli.main(["predict", str(good), "--n-traj", "3", "--csv", str(out_csv)]) == 0
    text = capsys.readouterr().out
    assert "8 predictions of 1 pedestrians, dt 1 s, n_traj 3" in text
    assert len(out_csv.read_text().splitlines()) == 1 + 3 * 3
    bad = tmp_path / "biwi.txt"
    bad.write_text("0 1 0 0\n0 1 0 0\n")
    for args in (["check", str(bad)], ["predict", str(tmp_path / "missing.txt")], ["check", str(tmp_path)]):
        assert cli.main(args) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ")
    huge = tmp_path / "huge.txt"
    with open(huge, "wb") as f:
        f.truncate(65 * 1024 * 1024)  # sparse: never read
    assert cli.main(["check", str(huge)]) == 2
    assert "more than the limit" in capsys.readouterr().err


def test_the_command_runs_as_a_module(tmp_path):
    good = tmp_path / "obsmat.txt"
    good.write_text(obsmat(WALKER[:5]))  # 1.6 s: too short for 1 s behind and 9 s ahead
    res = subprocess.run([sys.executable, "-m", "runners.recordings", "predict", str(good)], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "no pedestrian is recorded for 1 s before and 9 s after" in res.stdout
