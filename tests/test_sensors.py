"""Sonar, laser and the laser tracker against geometry with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fuzzynav.scenarios.scenario import scenario_from_dict
from fuzzynav.scenarios.world import World
from fuzzynav.sensing import laser as laser_mod
from fuzzynav.sensing import tracking
from fuzzynav.sensing.laser import LaserConfig
from fuzzynav.sensing.sonar import Sonar, SonarConfig
from fuzzynav.sensing.tracking import TrackerConfig, TrackerState


def world_with(statics, bounds=(0, 0, 1000, 1000)):
    s = scenario_from_dict({"bounds": list(bounds), "static_obstacles": statics,
                            "robot": {"start": [500, 500], "goal": [550, 900], "radius": 20}})
    return World(s.bounds, s.static_obstacles)


def test_sonar_sees_box_in_front_only():
    w = world_with([{"polygon": [[600, 450], [650, 450], [650, 550], [600, 550]]}])
    left, front, right = Sonar(SonarConfig(), 20.0).read(500, 500, 0.0, w.solid)
    assert front == pytest.approx(100 - 20, abs=0.01)  # surface to surface
    assert left == 130 and right == 130


def test_sonar_left_right_follow_heading():
    w = world_with([{"circle": {"center": [500, 580], "radius": 20}}])
    sonar = Sonar(SonarConfig(), 20.0)
    left, front, right = sonar.read(500, 500, 0.0, w.solid)  # circle at +y = left of a robot heading +x
    assert left == pytest.approx(80 - 20 - 20, abs=0.5) and front == 130 and right == 130
    left, front, right = sonar.read(500, 500, 180.0, w.solid)  # now it is on the right
    assert right == pytest.approx(40, abs=0.5) and left == 130


def test_sonar_sees_walls_and_clips_to_range():
    w = world_with([], bounds=(0, 0, 600, 1000))
    _, front, _ = Sonar(SonarConfig(), 20.0).read(500, 500, 0.0, w.solid)
    assert front == pytest.approx(80, abs=0.01)
    _, front, _ = Sonar(SonarConfig(), 20.0).read(500, 500, 180.0, w.solid)
    assert front == 130


def test_laser_ranges_to_circle_and_wall():
    w = world_with([{"circle": {"center": [700, 500], "radius": 50}}])
    cfg = LaserConfig(beams=360)
    scan = laser_mod.scan(cfg, 500, 500, 0.0, w.segments, w.circles, np.zeros((0, 3)))
    assert scan.ranges[0] == pytest.approx(150.0)
    assert scan.labels[0] == 0
    assert scan.ranges[180] == 250.0 and scan.labels[180] == -1  # wall at 500 cm: out of range
    disc = np.array([[500.0, 600.0, 20.0]])
    scan = laser_mod.scan(cfg, 500, 500, 0.0, w.segments, w.circles, disc)
    assert scan.ranges[90] == pytest.approx(80.0) and scan.labels[90] == 1


def test_tracker_estimates_speed_and_heading_of_a_moving_disc():
    w = world_with([])
    cfg = LaserConfig()
    state = TrackerState()
    tracks = []
    for t in range(4):
        disc = np.array([[650.0 - 20.0 * t, 420.0 + 10.0 * t, 20.0]])
        scan = laser_mod.scan(cfg, 500, 500, 0.0, w.segments, w.circles, disc)
        state, tracks, mask = tracking.update(state, scan, float(t), TrackerConfig())
    assert len(tracks) == 1
    tr = tracks[0]
    assert tr.x == pytest.approx(650 - 60, abs=0.5) and tr.y == pytest.approx(450, abs=0.5)
    assert tr.vx == pytest.approx(-20, abs=0.5) and tr.vy == pytest.approx(10, abs=0.5)
    assert tr.moving_angle_deg == pytest.approx(math.degrees(math.atan2(10, -20)) % 360, abs=1.0)
    assert tr.radius == pytest.approx(20, abs=0.5) and mask.sum() > 3


def test_tracker_ignores_walls_and_static_discs():
    w = world_with([{"circle": {"center": [650, 500], "radius": 20}}], bounds=(0, 0, 700, 1000))
    state = TrackerState()
    for t in range(3):
        scan = laser_mod.scan(LaserConfig(), 500 + 10 * t, 500, 0.0, w.segments, w.circles, np.zeros((0, 3)))
        state, tracks, _ = tracking.update(state, scan, float(t), TrackerConfig())
        assert tracks == []
