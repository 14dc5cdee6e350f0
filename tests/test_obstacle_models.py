"""Obstacle models (fuzzynav.pedestrians.base and the built-ins): the seam, the math of each model against hand
computations, behaviour in small scenes, determinism, and the scenario keys ``model`` / ``model_params``."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzynav.episode import Episode, EpisodeConfig
from fuzzynav.kinematics import RobotState
from fuzzynav.pedestrians import social_force as sf
from fuzzynav.pedestrians.base import MODELS, model_factory, register_obstacle_model
from fuzzynav.pedestrians.crowd import Crowd
from fuzzynav.pedestrians.motion import ObstacleMotion
from fuzzynav.pedestrians.social_force import SocialForceConfig, agent_repulsion, wall_repulsion
from fuzzynav.scenarios.scenario import ScenarioError, scenario_from_dict
from fuzzynav.scenarios.world import World
from runners.run import scenario_yaml
from tests.conftest import load_scenario

FAR_ROBOT = RobotState(-1e6, -1e6, 0.0, 0.0)  # a robot far away: it does not matter to anyone


def scene(obstacles, bounds=(0, 0, 1200, 800), robot_start=(100, 400), goal=(1100, 400), **extra):
    return scenario_from_dict({"name": "t", "bounds": list(bounds),
                               "robot": {"start": list(robot_start), "heading": 0, "goal": list(goal),
                                         "radius": 20},
                               "dynamic_obstacles": obstacles, "max_steps": 300, **extra})


def trajectory(s, steps, robot=FAR_ROBOT, seed=0, dt=1.0):
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds, s.static_obstacles), s.robot.radius)
    pos, _ = crowd.reset(seed)
    out = [pos.copy()]
    for _ in range(steps):
        pos, _ = crowd.step(robot, dt)
        out.append(pos.copy())
    return np.array(out), crowd


# -- the seam ---------------------------------------------------------------------------------------------


def test_builtin_models_are_registered():
    model_factory("scripted", "model")  # the registry loads the built-ins on first use
    assert {"scripted", "social_force", "orca", "random_walk"} <= set(MODELS)


def test_scripted_model_is_the_scripted_motion_at_k_dt_to_the_last_bit():
    s = load_scenario("multi_crossing")
    dt = 0.7
    traj, _ = trajectory(s, 30, dt=dt)
    motion = ObstacleMotion(s.dynamic_obstacles)
    for k in range(31):
        assert np.array_equal(traj[k], motion.at(k * dt)[0])


def test_a_scenario_without_models_logs_the_yaml_it_logged_before():
    s = load_scenario("crossing_right")
    text = scenario_yaml(s)
    assert "model" not in text


def test_a_model_registered_outside_fuzzynav_moves_its_obstacles():
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class StandStillConfig:
        pass

    @register_obstacle_model("test_stand_still")
    class StandStill:
        config_class = StandStillConfig

        def __init__(self, obstacles, config):
            self.start = np.array([o.start for o in obstacles], float)

        def reset(self, rng):
            return self.start.copy(), np.zeros_like(self.start)

        def step(self, view, indices, dt):
            return self.start.copy(), np.zeros_like(self.start)

    s = scene([{"id": "a", "radius": 20, "start": [600, 600], "velocity": [10, 0], "model": "test_stand_still"},
               {"id": "b", "radius": 20, "start": [600, 200], "velocity": [10, 0]}])
    traj, _ = trajectory(s, 5)
    assert np.array_equal(traj[5, 0], [600, 600])
    assert np.array_equal(traj[5, 1], [650, 200])


@pytest.mark.parametrize("returned, says", [
    (lambda start: (start[0], np.zeros(2)), "returned positions of shape (2,), expected (2, 2)"),
    (lambda start: (start, np.zeros((3, 2))), "returned velocities of shape (3, 2), expected (2, 2)"),
    (lambda start: (start, [["a", "b"], [1, 2]]), "returned velocities that are not numbers"),
    (lambda start: start.ravel(), "returned ndarray, expected (positions, velocities)"),
    (lambda start: None, "returned NoneType, expected (positions, velocities)"),
])
def test_a_model_that_returns_the_wrong_shape_is_named(returned, says):
    """A plug-in model's arrays of the wrong shape: a ``ValueError`` naming the model (a (2,) array for a group of
    two was broadcast to both pedestrians without a word)."""
    name = f"test_bad_shape_{abs(hash(says)) % 10**8}"

    @dataclass(frozen=True)
    class BadConfig:
        pass

    @register_obstacle_model(name)
    class Bad:
        config_class = BadConfig

        def __init__(self, obstacles, config):
            self.start = np.array([o.start for o in obstacles], float)

        def reset(self, rng):
            return self.start.copy(), np.zeros_like(self.start)

        def step(self, view, indices, dt):
            return returned(self.start.copy())

    try:
        s = scene([{"id": k, "radius": 20, "start": [600, y], "velocity": [10, 0], "model": name}
                   for k, y in (("a", 600), ("b", 200))])
        with pytest.raises(ValueError, match=re.escape(f"pedestrian model {name!r}: step {says}")):
            trajectory(s, 1)
    finally:
        MODELS.pop(name, None)


# -- scenario keys ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("entry, message", [
    ({"model": "crowdy"}, "dynamic_obstacles[0].model: unknown obstacle model 'crowdy'"),
    ({"model": 3}, "dynamic_obstacles[0].model: unknown obstacle model 3"),
    ({"model_params": {"sees_robot": False}}, "dynamic_obstacles[0].model_params: given without a model"),
    ({"model": "social_force", "model_params": {"relaxation_s": 0}},
     "dynamic_obstacles[0].model_params.relaxation_s: must be in [0.01, 60] s, got 0.0"),
    ({"model": "social_force", "model_params": {"relaxation_s": float("nan")}},
     "dynamic_obstacles[0].model_params.relaxation_s: must be finite"),
    ({"model": "social_force", "model_params": {"sees_robot": "yes"}},
     "dynamic_obstacles[0].model_params.sees_robot: expected true or false"),
    ({"model": "social_force", "model_params": {"step_ahead": 1}},
     "dynamic_obstacles[0].model_params.step_ahead: expected a string, got 1"),
    ({"model": "social_force", "model_params": {"step_ahead": "heading"}},
     "dynamic_obstacles[0].model_params.step_ahead: unknown value 'heading' (known: velocity, desired_direction)"),
    ({"model": "social_force", "model_params": {"speed": 3}},
     "dynamic_obstacles[0].model_params.speed: unknown parameter of model 'social_force'"),
    ({"model": "orca", "model_params": {"max_neighbors": 2.5}},
     "dynamic_obstacles[0].model_params.max_neighbors: expected an integer"),
    ({"model": "random_walk", "model_params": {"speed_min_cm_s": 50, "speed_max_cm_s": 40}},
     "dynamic_obstacles[0].model_params.speed_max_cm_s: must be in [50, 1000] cm/s"),
    ({"model": "random_walk", "model_params": [1, 2]}, "dynamic_obstacles[0].model_params: expected a mapping"),
])
def test_bad_models_are_one_line_errors_naming_the_field(entry, message):
    with pytest.raises(ScenarioError) as err:
        scene([{"id": "a", "radius": 20, "start": [600, 600], "velocity": [10, 0], **entry}])
    assert str(err.value).startswith(message), str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("model", ["scripted", "social_force", "orca", "random_walk"])
def test_the_logged_scenario_yaml_parses_back_to_the_same_scenario(model):
    s = scene([{"id": "a", "radius": 20, "waypoints": [[300, 600], [900, 600]], "speed": 30, "loop": True,
                "model": model}])
    again = scenario_from_dict(yaml.safe_load(scenario_yaml(s)))
    assert again == s


# -- social force: the paper's equations ----------------------------------------------------------------


def potential(rel, other_vel, strength=21_000.0, sigma=30.0, step_time=2.0):
    """V(b(r)) of Eqs. 3-4, computed directly."""
    s = math.hypot(*other_vel) * step_time
    ahead = (rel[0] - other_vel[0] * step_time, rel[1] - other_vel[1] * step_time)
    b = 0.5 * math.sqrt((math.hypot(*rel) + math.hypot(*ahead)) ** 2 - s * s)
    return strength * math.exp(-b / sigma)


@given(st.floats(-300, 300), st.floats(-300, 300), st.floats(-60, 60), st.floats(-60, 60))
@settings(max_examples=200, deadline=None)
def test_the_closed_form_repulsion_is_minus_the_gradient_of_the_potential(x, y, vx, vy):
    ahead = (x - 2 * vx, y - 2 * vy)
    s = 2 * math.hypot(vx, vy)
    b = 0.5 * math.sqrt(max((math.hypot(x, y) + math.hypot(*ahead)) ** 2 - s * s, 0.0))
    if b < 5:
        return  # near the segment between the ellipse's foci the gradient is unbounded (floored in the model)
    h = 1e-4
    numeric = [-(potential((x + h, y), (vx, vy)) - potential((x - h, y), (vx, vy))) / (2 * h),
               -(potential((x, y + h), (vx, vy)) - potential((x, y - h), (vx, vy))) / (2 * h)]
    closed = agent_repulsion(np.array([x, y]), np.array([vx, vy]), 21_000.0, 30.0, 2.0)
    assert np.allclose(closed, numeric, rtol=1e-5, atol=1e-7)


def test_repulsion_from_a_standing_pedestrian_is_the_circular_potential():
    # v_β = 0: b = |r|, so −∇V = V⁰/σ e^(−|r|/σ) r̂; at 60 cm: 700 e^-2 = 94.73 cm/s²
    f = agent_repulsion(np.array([60.0, 0.0]), np.zeros(2), 21_000.0, 30.0, 2.0)
    assert f[0] == pytest.approx(700 * math.exp(-2), rel=1e-12)
    assert f[1] == 0.0


def test_a_walker_repels_more_in_front_of_it_than_behind_it():
    v = np.array([30.0, 0.0])  # β walks along +x; α 90 cm in front of it or 90 cm behind it
    front = agent_repulsion(np.array([90.0, 0.0]), v, 21_000.0, 30.0, 2.0)
    behind = agent_repulsion(np.array([-90.0, 0.0]), v, 21_000.0, 30.0, 2.0)
    assert front[0] > 0 > behind[0] and abs(front[0]) > abs(behind[0])


def test_step_ahead_readings_by_hand():
    """Helbing & Molnár 1995: f = −∇V(b), V = V⁰ e^(−b/σ), 2b = √((‖r‖ + ‖r − v_β Δt e_β‖)² − (v_β Δt)²),
    so −∇V = V⁰/σ e^(−b/σ) ∇b with ∇b = (‖r‖ + ‖a‖)/(4b) · (r/‖r‖ + a/‖a‖), a = r − v_β Δt e_β.
    β at the origin walks east at v_β = 30 cm/s (velocity (30, 0)) but wants to go north (preferred velocity
    (0, 40)); α stands 80 cm north of it (r = (0, 80)); Δt = 2 s, so s = v_β Δt = 60 cm; V⁰/σ = 700 cm/s².
    - ``velocity``: e_β = (1, 0), a = (−60, 80), ‖a‖ = 100, b = ½√(180² − 60²) = 60√2,
      ∇b = 180/(240√2) · ((0, 1) + (−0.6, 0.8)) = (0.75/√2)·(−0.6, 1.8): f = 700 e^(−2√2) (0.75/√2)(−0.6, 1.8);
    - ``desired_direction``: e_β = (0, 1), a = (0, 20), b = ½√(100² − 60²) = 40, ∇b = 100/160 · (0, 2):
      f = (0, 875 e^(−4/3)) = (0, 230.6), 5.5 times the other reading's 41.6 cm/s², straight away from β's
      intended path.
    α stands with no preferred velocity (no driving force, nothing outside its view), so its force is β's
    repulsion alone. A β that is not of the group (another model's pedestrian, a scripted obstacle, the robot)
    steps along its velocity in both readings; so does a group member standing with no preferred velocity."""
    substep_force = sf._substep_force
    by_velocity = 700.0 * math.exp(-2.0 * math.sqrt(2.0)) * 0.75 / math.sqrt(2.0) * np.array([-0.6, 1.8])
    by_desire = np.array([0.0, 875.0 * math.exp(-4.0 / 3.0)])
    x, v, radii = np.array([[0.0, 80.0], [0.0, 0.0]]), np.array([[0.0, 0.0], [30.0, 0.0]]), np.full(2, 20.0)
    none2, none4, none3 = np.zeros((0, 2)), np.zeros((0, 4)), np.zeros((0, 3))
    for reading, want in [("velocity", by_velocity), ("desired_direction", by_desire)]:
        c = sf.SocialForceConfig(step_ahead=reading)
        cos_fov = math.cos(math.radians(c.fov_deg))
        group = substep_force(x, v, np.array([[0.0, 0.0], [0.0, 40.0]]), none2, none2, 0.0, radii, none4, none3,
                              c, cos_fov)
        assert group[0] == pytest.approx(want, rel=1e-13, abs=1e-13)
        # β standing with no preferred velocity, or not of this group: its velocity
        standing = substep_force(x, v, np.zeros((2, 2)), none2, none2, 0.0, radii, none4, none3, c, cos_fov)
        other = substep_force(x[:1], v[:1], np.zeros((1, 2)), x[1:], v[1:], 0.0, radii[:1], none4, none3, c,
                              cos_fov)
        assert standing[0] == pytest.approx(by_velocity, rel=1e-13)
        assert other[0] == pytest.approx(by_velocity, rel=1e-13)
    assert (by_desire[1], np.hypot(*by_velocity)) == pytest.approx((230.6, 41.6), abs=0.05)


def test_step_ahead_is_checked():
    assert SocialForceConfig().step_ahead == "velocity"  # the logs' reading
    with pytest.raises(ValueError, match=r"^step_ahead: unknown value 'desired' \(known: velocity, "
                                         r"desired_direction\)$"):
        SocialForceConfig(step_ahead="desired")


def test_wall_repulsion_by_hand():
    # a 20 cm disc with its centre 40 cm above the bottom wall only (the others 10 m away): gap 20 cm,
    # U⁰/R e^(−20/20) = 5000/e along +y
    f = wall_repulsion(np.array([[1000.0, 40.0]]), np.array([20.0]), np.array([[0.0, 0.0, 2000.0, 0.0]]),
                       np.zeros((0, 3)), 100_000.0, 20.0)
    assert f[0, 1] == pytest.approx(5000 / math.e, rel=1e-12)
    assert f[0, 0] == 0.0


def test_two_social_force_pedestrians_head_on_pass_each_other():
    s = scene([{"id": "a", "radius": 20, "waypoints": [[200, 400], [1000, 400]], "speed": 30, "model": "social_force"},
               {"id": "b", "radius": 20, "waypoints": [[1000, 405], [200, 405]], "speed": 30,
                "model": "social_force"}], robot_start=(100, 100))
    traj, _ = trajectory(s, 60)
    gap = np.hypot(*(traj[:, 0] - traj[:, 1]).T)
    assert gap.min() > 40.0  # never touching (radii 20 + 20)
    assert np.hypot(*(traj[-1, 0] - [1000, 400])) < 40 and np.hypot(*(traj[-1, 1] - [200, 405])) < 40


@pytest.mark.parametrize("sees_robot", [True, False])
def test_social_force_pedestrians_avoid_the_robot_only_when_they_see_it(sees_robot):
    s = scene([{"id": "a", "radius": 20, "waypoints": [[200, 600], [1000, 600]], "speed": 30,
                "model": "social_force", "model_params": {"sees_robot": sees_robot}}], robot_start=(100, 100))
    robot = RobotState(600.0, 600.0, 90.0, 0.0)  # standing on the pedestrian's line
    traj, _ = trajectory(s, 40, robot=robot)
    closest = np.hypot(*(traj[:, 0] - [600, 600]).T).min()
    if sees_robot:
        assert closest > 40.0
    else:
        assert closest < 20.0  # sampled once a second at 30 cm/s: within 15 cm of its straight line's point


def test_social_force_keeps_pedestrians_off_the_walls_and_under_their_speed_cap():
    obstacles = [{"id": f"p{i}", "radius": 20, "waypoints": [[200 + 40 * i, 60 + 70 * (i % 3)], [1000, 150]],
                  "speed": 40, "model": "social_force"} for i in range(8)]
    s = scene(obstacles, bounds=(0, 0, 1200, 300), robot_start=(100, 250), goal=(1100, 250))
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds, ()), 20)
    crowd.reset(0)
    for _ in range(60):
        pos, vel = crowd.step(FAR_ROBOT, 1.0)
        assert (pos[:, 1] > 0).all() and (pos[:, 1] < 300).all()
        assert (np.hypot(*vel.T) <= SocialForceConfig().max_speed_factor * 40 + 1e-9).all()


# -- ORCA pedestrians -------------------------------------------------------------------------------------


def test_orca_pedestrians_crossing_in_two_groups_never_overlap():
    obstacles = []
    for i in range(6):
        obstacles.append({"id": f"l{i}", "radius": 20, "waypoints": [[200, 250 + 60 * i], [1000, 250 + 60 * i]],
                          "speed": 30, "model": "orca"})
        obstacles.append({"id": f"r{i}", "radius": 20, "waypoints": [[1000, 280 + 60 * i], [200, 280 + 60 * i]],
                          "speed": 30, "model": "orca"})
    s = scene(obstacles, robot_start=(100, 100))
    traj, _ = trajectory(s, 50)
    for k in range(len(traj)):
        d = np.hypot(*(traj[k][:, None, :] - traj[k][None, :, :]).transpose(2, 0, 1))
        d[np.arange(12), np.arange(12)] = np.inf
        assert d.min() > 39.0, (k, d.min())  # radii 20 + 20, to the linear program's rounding
    assert np.hypot(*(traj[-1, 0] - [1000, 250])) < 60


def test_orca_pedestrian_steps_around_a_standing_robot():
    s = scene([{"id": "a", "radius": 20, "waypoints": [[200, 600], [1000, 600]], "speed": 30, "model": "orca"}],
              robot_start=(100, 100))
    traj, _ = trajectory(s, 40, robot=RobotState(600.0, 600.0, 90.0, 0.0))
    assert np.hypot(*(traj[:, 0] - [600, 600]).T).min() > 39.0


# -- random walk ----------------------------------------------------------------------------------------


def walkers(**params):
    return scene([{"id": f"w{i}", "radius": 20, "start": [300 + 100 * i, 300 + 50 * i], "velocity": [20, 10],
                   "model": "random_walk", **({"model_params": params} if params else {})} for i in range(5)])


def test_random_walk_without_noise_is_constant_velocity():
    traj, _ = trajectory(walkers(heading_sigma_deg=0, speed_sigma_cm_s=0), 5)
    assert np.allclose(traj[5, 0], [300 + 100, 300 + 50], atol=1e-9)


def test_random_walk_is_seeded():
    a, _ = trajectory(walkers(), 30, seed=4)
    b, _ = trajectory(walkers(), 30, seed=4)
    c, _ = trajectory(walkers(), 30, seed=5)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


@given(st.integers(0, 2**32 - 1), st.floats(0, 360), st.floats(0, 100))
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_random_walkers_stay_inside_the_world(seed, heading_sigma, speed_sigma):
    s = walkers(heading_sigma_deg=heading_sigma, speed_sigma_cm_s=speed_sigma, speed_max_cm_s=200)
    traj, _ = trajectory(s, 40, seed=seed)
    assert np.isfinite(traj).all()
    assert (traj[..., 0] >= 20 - 1e-9).all() and (traj[..., 0] <= 1180 + 1e-9).all()
    assert (traj[..., 1] >= 20 - 1e-9).all() and (traj[..., 1] <= 780 + 1e-9).all()


# -- episodes -----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["social_force", "orca", "random_walk"])
def test_episodes_with_reactive_pedestrians_are_deterministic(model, table1):
    s = scene([{"id": f"p{i}", "radius": 20, "waypoints": [[600 + 30 * i, 100 + 120 * i], [600, 700]], "speed": 25,
                "model": model} for i in range(4)])
    a = [r.obstacle_positions for r in Episode(s, table1, EpisodeConfig(), seed=3).run()]
    b = [r.obstacle_positions for r in Episode(s, table1, EpisodeConfig(), seed=3).run()]
    assert len(a) == len(b) and all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))


def test_the_robot_is_seen_where_it_was_when_it_sensed(table1):
    # the model steps after the robot decided: the view's robot is the record's state, not next_state
    seen = []

    class Spy:
        def __init__(self, crowd):
            self.crowd, self.step_orig = crowd, crowd.step

        def __call__(self, robot, dt):
            seen.append(robot)
            return self.step_orig(robot, dt)

    s = scene([{"id": "a", "radius": 20, "waypoints": [[600, 100], [600, 700]], "speed": 25, "model": "social_force"}])
    ep = Episode(s, table1, EpisodeConfig(), seed=0)
    ep.crowd.step = Spy(ep.crowd)
    records = [ep.step() for _ in range(5)]
    assert [r.state for r in records] == seen
