"""The compiled tracker kernel (fuzzynav.sensing._tracking) finds the Python form's detections, bit for bit.

Scans drawn at random: rooms of walls with discs of every size (some touching, some around the robot, some
beyond the range), polygons, beams that return nothing, range noise, all beams returning (one closed cluster),
and fsum's hard cases (points whose sums cancel). In CI (CI=true) the kernel must have been built.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzynav.sensing import tracking
from fuzzynav.sensing.laser import LaserConfig, LaserScan, beam_directions
from fuzzynav.sensing.raycast import cast_rays
from fuzzynav.sensing.tracking import TrackerConfig, detect, detect_python
from tests.conftest import require_compiled

require_compiled(tracking._tracking, "_tracking")


def _key(dets) -> list[tuple]:
    return [(repr(d.x), repr(d.y), repr(d.radius), d.beams.dtype.str, d.beams.tobytes()) for d in dets]


def _scan(x, y, heading, beams, segments, discs, noise, rng) -> LaserScan:
    config = LaserConfig(beams=beams)
    d = beam_directions(config, heading)
    ranges, hit = cast_rays(np.array([x, y]), d, segments, discs, config.range_cm)
    if noise > 0:
        noisy = ranges + rng.normal(0.0, noise, len(ranges))
        ranges = np.where(hit >= 0, np.clip(noisy, 0.0, np.nextafter(config.range_cm, 0)), ranges)
    return LaserScan(ranges=ranges, directions=d, labels=hit, origin=(float(x), float(y)), range_cm=config.range_cm)


@st.composite
def scans(draw):
    size = draw(st.sampled_from([150.0, 400.0, 1000.0]))
    x, y = draw(st.floats(5, size - 5)), draw(st.floats(5, size - 5))
    walls = draw(st.booleans())
    segments = np.array([[0, 0, size, 0], [size, 0, size, size], [size, size, 0, size], [0, size, 0, 0]], float)
    if not walls:
        segments = segments[: draw(st.integers(0, 2))]
    discs = []
    for _ in range(draw(st.integers(0, 8))):
        kind = draw(st.sampled_from(["any", "near", "touching_previous", "around"]))
        r = draw(st.floats(1.0, 80.0))
        if kind == "near":
            a = draw(st.floats(0, 2 * math.pi))
            dist = draw(st.floats(r + 1.0, r + 60.0))
            discs.append((x + dist * math.cos(a), y + dist * math.sin(a), r))
        elif kind == "touching_previous" and discs:
            px, py, pr = discs[-1]
            discs.append((px + pr + r, py, r))
        elif kind == "around":
            discs.append((x, y, r))
        else:
            discs.append((draw(st.floats(0, size)), draw(st.floats(0, size)), r))
    noise = draw(st.sampled_from([0.0, 0.0, 0.5, 3.0]))
    beams = draw(st.sampled_from([8, 90, 360, 720]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    return _scan(x, y, draw(st.floats(0, 360)), beams, segments, np.array(discs, float).reshape(-1, 3), noise, rng)


@st.composite
def configs(draw):
    return TrackerConfig(cluster_gap_cm=draw(st.sampled_from([2.0, 15.0, 40.0, 500.0])),
                         min_points=draw(st.sampled_from([3, 5, 20])),
                         max_radius_cm=draw(st.sampled_from([10.0, 60.0, 1e4])),
                         max_fit_rms_cm=draw(st.sampled_from([0.5, 3.0, 1e9])))


@given(scans(), configs())
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_kernel_finds_the_python_forms_detections(scan, config):
    assert _key(detect(scan, config)) == _key(detect_python(scan, config))


@pytest.mark.parametrize("seed", range(20))
def test_a_scan_where_every_beam_returns_is_one_closed_cluster_in_both(seed):
    rng = np.random.default_rng(seed)
    scan = _scan(50.0, 50.0, float(rng.uniform(0, 360)), 360, np.zeros((0, 4)),
                 np.array([[50.0 + rng.uniform(-5, 5), 50.0 + rng.uniform(-5, 5), 80.0]]), 0.0, rng)
    # the robot inside a circle reads 0 everywhere (every beam returns); gap large: all linked
    config = TrackerConfig(cluster_gap_cm=1e3, max_radius_cm=1e4, max_fit_rms_cm=1e9)
    assert scan.returned.all()
    assert _key(detect(scan, config)) == _key(detect_python(scan, config))


def test_sums_that_cancel_are_fsums_bits():
    """Points placed so that the fit's sums cancel to the last bits (where a plain sum would differ from
    math.fsum): the kernel's correctly rounded sums agree with Python's."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(3, 40))
        a = rng.uniform(0, 2 * np.pi, n)
        r = 10.0 ** rng.uniform(-3, 3)
        cx, cy = rng.uniform(-1e5, 1e5, 2)
        xy = np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)])
        xy[rng.integers(0, n)] += rng.normal(0, 1e-9, 2)
        ranges = np.full(n, 100.0)
        beams = np.empty(n, np.int64)
        got = tracking._tracking.discs(xy, ranges, np.ones(n, bool), 1e12, 3, 1e12, 1e12, 1e12, beams)
        assert got is not None and got[0] == n
        for i, j, fx, fy, fr, _ in got[1]:
            assert (repr(fx), repr(fy), repr(fr)) == tuple(repr(v) for v in tracking.fit_disc(xy[beams[i:j]])[:3])


def test_non_finite_points_go_to_the_python_form():
    xy = np.array([[0.0, 0.0], [1.0, math.nan], [2.0, 0.0], [3.0, 1.0]])
    beams = np.empty(4, np.int64)
    assert tracking._tracking.discs(xy, np.ones(4), np.ones(4, bool), 15.0, 3, 120.0, 60.0, 3.0, beams) is None


@pytest.mark.parametrize("which", range(4))
def test_bad_buffers_are_refused(which):
    args = [np.zeros((8, 2)), np.zeros(8), np.zeros(8, bool), np.zeros(8, np.int64)]
    args[which] = [np.zeros((8, 3)), np.zeros(8, np.float32), np.zeros(8, np.int8), np.zeros(8)][which]
    with pytest.raises((ValueError, BufferError, TypeError)):
        tracking._tracking.discs(args[0], args[1], args[2], 15.0, 3, 120.0, 60.0, 3.0, args[3])


def test_views_and_other_dtypes_are_taken_as_the_python_form_takes_them():
    """A scan whose arrays are views (every other beam of a finer scan) or float32: the same detections."""
    rng = np.random.default_rng(3)
    fine = _scan(200.0, 200.0, 10.0, 720, np.zeros((0, 4)), np.array([[260.0, 200.0, 20.0], [140.0, 230.0, 15.0]]),
                 0.0, rng)
    for ranges, directions in ((fine.ranges[::2], fine.directions[::2]),
                               (fine.ranges[::2].astype(np.float32), fine.directions[::2])):
        scan = LaserScan(ranges=ranges, directions=directions, labels=fine.labels[::2], origin=fine.origin,
                         range_cm=fine.range_cm)
        found = detect(scan, TrackerConfig())
        assert found and _key(found) == _key(detect_python(scan, TrackerConfig()))
