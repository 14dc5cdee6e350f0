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


@pytest.mark.parametrize("sees, speed, seen", [("stationary", 0.0, True), ("stationary", 4.9, True),
                                               ("stationary", 5.0, False), ("stationary", 30.0, False),
                                               ("all", 30.0, True), ("all", 0.0, True),
                                               ("static_map", 0.0, False)])
def test_sonar_sees_people_by_its_mode(sees, speed, seen):
    """``stationary`` (the paper's "sonar detects the stationary obstacles"): a person slower than
    ``stationary_below_cm_s`` (5 cm/s) is one; ``all``: every person; ``static_map``: the map only."""
    w = world_with([])
    person = np.array([[600.0, 500.0, 20.0]])  # 100 cm ahead of the robot's centre
    _, front, _ = Sonar(SonarConfig(sees=sees), 20.0).read(500, 500, 0.0, w.solid, person, np.array([speed]))
    assert front == (pytest.approx(60.0, abs=0.01) if seen else 130.0)


def test_sonar_stationary_needs_the_speeds():
    w = world_with([])
    with pytest.raises(ValueError, match="needs the moving obstacles' speeds"):
        Sonar(SonarConfig(), 20.0).read(500, 500, 0.0, w.solid, np.array([[600.0, 500.0, 20.0]]))


def test_sonar_rejects_an_unknown_mode():
    with pytest.raises(ValueError, match=r"sensors\.sonar\.sees: unknown value 'people'"):
        SonarConfig(sees="people")


@pytest.mark.parametrize("speed", [70.0, 140.0])
def test_tracker_follows_a_mover_faster_than_its_gate(speed):
    """A track seen once has no velocity: its next detection is up to ``max_speed_cm_s`` x dt away, beyond the
    60 cm gate around a predicted position, and is still the same obstacle (at 70 and 140 cm/s, 1 s frames)."""
    w = world_with([])
    state, tracks = TrackerState(), []
    for t in range(3):
        disc = np.array([[400.0 + speed * t, 380.0, 20.0]])
        scan = laser_mod.scan(LaserConfig(noise_std_cm=0.0), 500, 500, 0.0, w.segments, w.circles, disc)
        state, tracks, _ = tracking.update(state, scan, float(t), TrackerConfig())
    assert len(tracks) == 1 and tracks[0].vx == pytest.approx(speed, abs=0.5)
    state = TrackerState()
    for t in range(3):  # with the gate bound to gate_cm (max_speed_cm_s at most gate / dt) it never becomes a track
        disc = np.array([[400.0 + speed * t, 380.0, 20.0]])
        scan = laser_mod.scan(LaserConfig(noise_std_cm=0.0), 500, 500, 0.0, w.segments, w.circles, disc)
        state, slow_tracks, _ = tracking.update(state, scan, float(t), TrackerConfig(max_speed_cm_s=60.0))
        assert slow_tracks == []


def test_tracker_gate_for_a_first_association_scales_with_the_frame_interval():
    """At 0.5 s frames the default gate of a new track is 75 cm (150 cm/s x 0.5 s): a disc 100 cm from its
    first detection is another obstacle, one 70 cm away the same."""
    w = world_with([])
    for jump, same in [(70.0, True), (100.0, False)]:
        state = TrackerState()
        for t in range(2):
            disc = np.array([[560.0 + jump * t, 380.0, 20.0]])
            scan = laser_mod.scan(LaserConfig(noise_std_cm=0.0), 500, 500, 0.0, w.segments, w.circles, disc)
            state, tracks, _ = tracking.update(state, scan, 0.5 * t, TrackerConfig())
        assert (len(tracks) == 1) is same
