"""Scenario validation: each violation is one ScenarioError naming the field."""

from __future__ import annotations

import copy

import pytest

from fuzzynav.pedestrians.motion import ObstacleMotion
from fuzzynav.scenarios.scenario import ScenarioError, scenario_from_dict

BASE = {
    "name": "t", "bounds": [0, 0, 1000, 600],
    "robot": {"start": [100, 300], "heading": 0, "goal": [900, 300], "radius": 20},
    "static_obstacles": [{"polygon": [[400, 0], [450, 0], [450, 150], [400, 150]]},
                         {"circle": {"center": [600, 450], "radius": 40}}],
    "dynamic_obstacles": [{"id": "a", "radius": 20, "start": [800, 300], "velocity": [-20, 0]},
                          {"id": "b", "radius": 20, "waypoints": [[200, 100], [800, 100]], "speed": 30,
                           "loop": True}],
    "max_steps": 100,
}


def test_valid_scenario_round_trips():
    s = scenario_from_dict(BASE)
    assert s.tolerance == 20 and len(s.static_obstacles) == 2 and s.dynamic_obstacles[1].loop


def _set(path: str, value):
    def mutate(d):
        keys = path.split(".")
        node = d
        for k in keys[:-1]:
            node = node[int(k)] if k.isdigit() else node[k]
        last = keys[-1]
        if value is KeyError:
            del node[last]
        elif last.isdigit():
            node[int(last)] = value
        else:
            node[last] = value
    return mutate


CASES = [
    (_set("robot.start", KeyError), "robot.start: missing"),
    (_set("robot.start", [float("nan"), 3]), "robot.start[0]: must be finite"),
    (_set("robot.goal", [float("inf"), 3]), "robot.goal[0]: must be finite"),
    (_set("robot.goal", [1e308, 3]), "robot.goal[0]"),
    (_set("robot.goal", [2000, 300]), "robot.goal: [2000.0, 300.0] is outside bounds"),
    (_set("robot.start", [-5, 300]), "robot.start"),
    (_set("robot.goal", [425, 50]), "robot.goal: inside static_obstacles[0]"),
    (_set("robot.start", [420, 160]), "static_obstacles[0]: overlaps the robot"),
    (_set("robot.goal", [100, 300]), "robot.goal: equal to robot.start"),
    (_set("robot.radius", 0), "robot.radius: must be > 0"),
    (_set("robot.colour", "red"), "robot.colour: unknown key"),
    (_set("static_obstacles.0.polygon", [[0, 0], [100, 100], [100, 0], [0, 100]]),
     "static_obstacles[0].polygon: self-intersecting"),
    (_set("static_obstacles.0.polygon", [[0, 0], [100, 100]]), "static_obstacles[0].polygon: needs at least 3"),
    (_set("static_obstacles.1.circle.radius", -4), "static_obstacles[1].circle.radius: must be > 0"),
    (_set("dynamic_obstacles.1.id", "a"), "dynamic_obstacles[1].id: duplicate id"),
    (_set("dynamic_obstacles.1.waypoints", []), "dynamic_obstacles[1].waypoints: needs at least 1"),
    (_set("dynamic_obstacles.1.speed", 0), "dynamic_obstacles[1].speed: must be > 0"),
    (_set("dynamic_obstacles.0.velocity", KeyError), "dynamic_obstacles[0].velocity: missing"),
    (_set("dynamic_obstacles.0.start", [110, 300]), "dynamic_obstacles[0]: overlaps the robot"),
    (_set("bounds", [0, 0, -5, 600]), "bounds: need xmin < xmax"),
    (_set("max_steps", "lots"), "max_steps: expected a positive integer"),
    (_set("bounds", "wide"), "bounds: expected [xmin, ymin, xmax, ymax]"),
    # issue 14: a static obstacle wholly outside the bounds, circle or polygon alike; ids are names (strings)
    (_set("static_obstacles.1.circle.center", [5000, 5000]),
     "static_obstacles[1].circle: wholly outside bounds [0.0, 0.0, 1000.0, 600.0]"),
    (_set("static_obstacles.0.polygon", [[5000, 0], [5100, 0], [5100, 100]]),
     "static_obstacles[0].polygon: wholly outside bounds"),
    (_set("dynamic_obstacles.0.id", 123), "dynamic_obstacles[0].id: expected a name (string), got 123"),
    (_set("dynamic_obstacles.0.id", 0x1F), "dynamic_obstacles[0].id: expected a name (string), got 31"),
]


def test_obstacles_reaching_into_the_bounds_are_kept():
    """Only obstacles that could never be met are refused: one that crosses or touches a wall is a wall's part."""
    data = copy.deepcopy(BASE)
    data["static_obstacles"] = [{"circle": {"center": [-30, 300], "radius": 40}},
                                {"circle": {"center": [500, 640], "radius": 40}},
                                {"polygon": [[1000, 0], [1100, 0], [1100, 100], [1000, 100]]}]
    assert len(scenario_from_dict(data).static_obstacles) == 3


@pytest.mark.parametrize("mutate, message", CASES, ids=[c[1].split(":")[0] + str(i) for i, c in enumerate(CASES)])
def test_invalid_scenarios_name_the_field(mutate, message):
    data = copy.deepcopy(BASE)
    mutate(data)
    with pytest.raises(ScenarioError) as err:
        scenario_from_dict(data)
    assert str(err.value).startswith(message), str(err.value)


def test_obstacle_motion_constant_velocity_and_waypoints():
    s = scenario_from_dict({**BASE, "dynamic_obstacles": [
        {"id": "cv", "radius": 10, "start": [800, 300], "velocity": [-20, 5]},
        {"id": "loop", "radius": 10, "waypoints": [[200, 100], [800, 100]], "speed": 30, "loop": True},
        {"id": "stop", "radius": 10, "waypoints": [[200, 500], [260, 500]], "speed": 30}]})
    m = ObstacleMotion(s.dynamic_obstacles)
    pos, vel = m.at(10.0)
    assert pos[0].tolist() == [600.0, 350.0] and vel[0].tolist() == [-20.0, 5.0]
    assert pos[1].tolist() == [500.0, 100.0] and vel[1].tolist() == [30.0, 0.0]
    assert pos[2].tolist() == [260.0, 500.0] and vel[2].tolist() == [0.0, 0.0]
    pos, vel = m.at(30.0)  # 900 cm along a 1200 cm loop: on the way back
    assert pos[1].tolist() == [500.0, 100.0] and vel[1].tolist() == [-30.0, 0.0]


@pytest.mark.parametrize("path, point", [("robot.start", [300, 0]), ("robot.goal", [1000, 300]),
                                         ("robot.start", [0, 600])])
def test_a_point_on_the_boundary_is_inside(path, point):
    """The bounds are closed (as the docs' ranges say): a robot placed on a wall is refused because it does not
    fit there, not as outside."""
    d = copy.deepcopy(BASE)
    _set(path, point)(d)
    with pytest.raises(ScenarioError, match=rf"{path.replace('.', '[.]')}: the robot \(radius 20.0 cm\) does not fit"):
        scenario_from_dict(d)


def test_a_waypoint_on_the_boundary_is_accepted():
    d = copy.deepcopy(BASE)
    d["dynamic_obstacles"][1]["waypoints"] = [[200, 100], [1000, 100]]
    assert scenario_from_dict(d).dynamic_obstacles[1].waypoints[1] == (1000.0, 100.0)
