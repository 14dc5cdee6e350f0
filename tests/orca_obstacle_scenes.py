"""Scenes of ``orca`` pedestrians among static polygons (issue #37 item 9) and their figures: the deepest a
pedestrian goes into a polygon, how far pedestrians overlap each other, how far one walking straight at a wall
slides along it. Used by tests/test_orca_obstacles.py; ``python -m tests.orca_obstacle_scenes`` prints the
figures of our model and, when pyrvo (RVO2's Python binding, not a dependency of fuzzynav) is installed, of
RVO2 on the same scenes, and how far one step of each differs (:func:`rvo2_step_differences`). Units: cm, s,
cm/s.

The scenes: a long wall (a 20 cm thick rectangle, 5800 cm long) approached at an angle or head-on by one
pedestrian of radius 20 cm at a constant preferred velocity; eight pedestrians (radius 20 cm) on a circle of
radius 400 cm around a 200 cm square, each walking to the opposite point of the circle. Time step 0.25 s (one
substep, RVO2's time step), the model's default parameters otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from fuzzynav.kinematics import RobotState
from fuzzynav.pedestrians.crowd import Crowd
from fuzzynav.scenarios.scenario import Scenario, scenario_from_dict
from fuzzynav.scenarios.world import World

FAR_ROBOT = RobotState(-1e6, -1e6, 0.0, 0.0)  # a robot no pedestrian can see (beyond neighbor_dist_cm)
STEP_S = 0.25
RADIUS_CM = 20.0
WALL = ((100.0, 600.0), (5900.0, 600.0), (5900.0, 620.0), (100.0, 620.0))
WALL_BOUNDS = (0.0, 0.0, 6000.0, 1000.0)
SQUARE = ((500.0, 500.0), (700.0, 500.0), (700.0, 700.0), (500.0, 700.0))
SQUARE_BOUNDS = (0.0, 0.0, 1200.0, 1200.0)
RING_CM = 400.0


def _scenario(bounds: Sequence[float], polygon: Sequence[tuple[float, float]], pedestrians: list[dict],
              robot_start: tuple[float, float]) -> Scenario:
    return scenario_from_dict({
        "name": "orca_obstacles", "bounds": list(bounds), "max_steps": 1000,
        "robot": {"start": list(robot_start), "heading": 0, "goal": [robot_start[0] + 100, robot_start[1]],
                  "radius": 20},
        "static_obstacles": [{"polygon": [list(p) for p in polygon]}],
        "dynamic_obstacles": pedestrians})


def wall_scene(speed: float, angle_deg: float) -> Scenario:
    """One pedestrian 180 cm from the wall (gap from its rim), preferring ``speed`` cm/s at ``angle_deg`` from
    the wall's direction (90: straight at it)."""
    a = math.radians(angle_deg)
    velocity = [speed * math.cos(a), speed * math.sin(a)]
    start = [300.0 if angle_deg < 90 else 3000.0, 400.0]
    return _scenario(WALL_BOUNDS, WALL, [{"id": "p", "radius": RADIUS_CM, "start": start, "velocity": velocity,
                                          "model": "orca"}], (100.0, 100.0))


def ring_positions() -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """(start, goal) cm of the eight pedestrians around the square (goal: the opposite point of the ring)."""
    out = []
    for k in range(8):
        # 10 degrees off the axes and diagonals: aimed at the square's centre from a symmetric ring, the eight
        # block each other at its sides for good (in RVO2 as here)
        a = math.radians(10.0 + 45.0 * k)
        c, s = RING_CM * math.cos(a), RING_CM * math.sin(a)
        out.append(((600.0 + c, 600.0 + s), (600.0 - c, 600.0 - s)))
    return out


def square_scene(speed: float) -> Scenario:
    """Eight pedestrians on the ring around the square, each walking at ``speed`` cm/s to the opposite point."""
    peds = [{"id": f"p{k}", "radius": RADIUS_CM, "waypoints": [list(a), list(b)], "speed": speed, "model": "orca"}
            for k, (a, b) in enumerate(ring_positions())]
    return _scenario(SQUARE_BOUNDS, SQUARE, peds, (60.0, 60.0))


def run(s: Scenario, seconds: float) -> np.ndarray:
    """The pedestrians' positions (steps + 1, n, 2) cm every ``STEP_S`` over ``seconds``."""
    crowd = Crowd(s.dynamic_obstacles, World(s.bounds, s.static_obstacles), s.robot.radius)
    pos, _ = crowd.reset(0)
    out = [pos.copy()]
    for _ in range(round(seconds / STEP_S)):
        pos, _ = crowd.step(FAR_ROBOT, STEP_S)
        out.append(pos.copy())
    return np.array(out)


@dataclass(frozen=True)
class Figures:
    """A run's figures (cm): the least signed gap between a pedestrian's rim and the polygon (negative: inside),
    the least gap between two pedestrians' rims (negative: overlap), the largest sideways drift from the start
    (along x), and the final position of the first pedestrian."""

    polygon_gap: float
    pair_gap: float
    drift_x: float
    final: tuple[float, float]


def figures(traj: np.ndarray, polygon: Sequence[tuple[float, float]], radius: float = RADIUS_CM) -> Figures:
    shape = shapely.Polygon(polygon)
    pts = shapely.points(traj.reshape(-1, 2))
    signed = np.where(shapely.contains(shape, pts), -1.0, 1.0) * shapely.distance(shape.exterior, pts)
    n = traj.shape[1]
    pair = math.inf
    if n > 1:
        d = np.hypot(*(traj[:, :, None, :] - traj[:, None, :, :]).transpose(3, 0, 1, 2))
        d[:, np.arange(n), np.arange(n)] = np.inf
        pair = float(d.min()) - 2 * radius
    return Figures(float(signed.min()) - radius, pair, float(np.abs(traj[:, :, 0] - traj[0, :, 0]).max()),
                   (float(traj[-1, 0, 0]), float(traj[-1, 0, 1])))


# -- RVO2 (pyrvo) on the same scenes ---------------------------------------------------------------------


def rvo2_run(s: Scenario, seconds: float) -> np.ndarray:
    """:func:`run` with RVO2 (pyrvo, float32): the same pedestrians, preferred velocities (constant, or
    ``speed`` towards the next waypoint and 0 within 30 cm of the last), the world's walls (a clockwise
    polygon: the pedestrians are inside) and its polygon, the model's default parameters."""
    import pyrvo

    sim = pyrvo.RVOSimulator()
    sim.set_time_step(STEP_S)
    xmin, ymin, xmax, ymax = s.bounds
    sim.add_obstacle([(xmin, ymin), (xmin, ymax), (xmax, ymax), (xmax, ymin)])
    for obstacle in s.static_obstacles:
        poly = list(obstacle.polygon)
        if shapely.Polygon(poly).exterior.is_ccw is False:
            poly.reverse()
        sim.add_obstacle([tuple(p) for p in poly])
    sim.process_obstacles()
    goals: list[tuple[float, float] | None] = []
    for o in s.dynamic_obstacles:
        start = o.start if o.waypoints is None else o.waypoints[0]
        if o.waypoints is None:
            velocity, speed, goals_i = o.velocity, math.hypot(*o.velocity), None
        else:
            d = np.subtract(o.waypoints[1], start)
            velocity, speed, goals_i = tuple(d / np.hypot(*d) * o.speed), o.speed, o.waypoints[-1]
        sim.add_agent(tuple(start), 1000.0, 10, 5.0, 5.0, o.radius, speed, tuple(velocity))
        goals.append(goals_i)
    arrived = [False] * len(goals)
    out = []
    for k in range(round(seconds / STEP_S) + 1):
        pos = np.array([sim.get_agent_position(i).to_tuple() for i in range(len(goals))])
        out.append(pos)
        if k == round(seconds / STEP_S):
            break
        for i, (o, goal) in enumerate(zip(s.dynamic_obstacles, goals, strict=True)):
            if goal is None:
                sim.set_agent_pref_velocity(i, tuple(o.velocity))
                continue
            d = np.subtract(goal, pos[i])
            arrived[i] = arrived[i] or np.hypot(*d) <= 30.0
            pref = (0.0, 0.0) if arrived[i] else tuple(d / np.hypot(*d) * o.speed)
            sim.set_agent_pref_velocity(i, pref)
        sim.do_step()
    return np.array(out)


#: three polygons in a 1000 x 800 cm room for :func:`rvo2_step_differences`: a box, an L (one concave corner) and a
#: triangle; their sides' lines cross the walls and each other, so RVO2's obstacle tree splits edges
ROOM_POLYGONS = (((200.0, 200.0), (400.0, 200.0), (400.0, 300.0), (200.0, 300.0)),
                 ((600.0, 400.0), (800.0, 400.0), (800.0, 600.0), (700.0, 600.0), (700.0, 500.0), (600.0, 500.0)),
                 ((300.0, 500.0), (450.0, 650.0), (250.0, 700.0)))


def rvo2_step_differences(polygons: Sequence[Sequence[tuple[float, float]]], cases: int,
                          seed: int = 7) -> np.ndarray:
    """|our velocity − RVO2's| (cm/s) after one step of one pedestrian (radius 20 cm, top speed 60 cm/s, the
    model's default horizons) in a 1000 x 800 cm room with ``polygons``, for ``cases`` random positions clear of
    the walls and polygons by more than 25 cm, velocities and preferred velocities (within the speed disc: the
    model limits the preferred velocity to it, RVO2 does not). Ours: the model's edges within reach,
    :func:`~fuzzynav.numerics.orca_lp.edge_lines` and the linear program; RVO2's: pyrvo."""
    import pyrvo

    from fuzzynav.numerics.orca_lp import choose_velocity, edge_lines, world_chains
    from fuzzynav.pedestrians.orca import PedestrianOrcaConfig, PedestrianOrcaModel, _Obstacles

    bounds, radius, top = (0.0, 0.0, 1000.0, 800.0), 20.0, 60.0
    chains = world_chains(bounds, polygons)
    obstacles = _Obstacles(bounds, [np.array(p) for p in polygons])
    model = PedestrianOrcaModel.__new__(PedestrianOrcaModel)
    model.config, model.radii = PedestrianOrcaConfig(), np.array([radius])
    c = model.config
    solid = shapely.union_all([shapely.Polygon(p) for p in polygons]) if polygons else shapely.Polygon()
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < cases:
        p = rng.uniform(bounds[:2], bounds[2:])
        if min(p[0], p[1], bounds[2] - p[0], bounds[3] - p[1]) <= 25.0 or (
                polygons and (solid.contains(shapely.Point(p)) or solid.distance(shapely.Point(p)) <= 25.0)):
            continue
        vel, pref = rng.uniform(-top, top, 2), rng.uniform(-top, top, 2)
        pref = pref * min(1.0, top / float(np.hypot(*pref)))
        sim = pyrvo.RVOSimulator(STEP_S, c.neighbor_dist_cm, c.max_neighbors, c.time_horizon_s,
                                 c.time_horizon_obst_s, radius, top)
        for chain in chains:
            sim.add_obstacle([tuple(q) for q in chain])
        sim.process_obstacles()
        sim.add_agent(tuple(p))
        sim.set_agent_velocity(0, tuple(vel))
        sim.set_agent_pref_velocity(0, tuple(pref))
        sim.do_step()
        theirs = np.array(sim.get_agent_velocity(0).to_tuple())
        edges = model._edges_within_reach(obstacles, p[None, :], np.array([top]))[0]
        lines = edge_lines(obstacles.vertices, edges, (float(p[0]), float(p[1])), (float(vel[0]), float(vel[1])),
                           radius, c.time_horizon_obst_s)
        ours = np.array(choose_velocity(lines, len(lines), top, (float(pref[0]), float(pref[1]))).velocity)
        out.append(float(np.hypot(*(ours - theirs))))
    return np.array(out)


SPEEDS = (30.0, 40.0, 130.0)
ANGLES = (10.0, 20.0, 30.0, 45.0, 60.0, 75.0)
SECONDS = 30.0


def table(runner=run) -> list[str]:
    """The figures of every scene as lines of text."""
    lines = []
    for speed in SPEEDS:
        gaps = {a: figures(runner(wall_scene(speed, a), SECONDS), WALL).polygon_gap for a in ANGLES}
        worst = min(gaps, key=gaps.get)
        lines.append(f"wall at an angle, {speed:g} cm/s: least gap {gaps[worst]:+.2f} cm (at {worst:g} deg; "
                     + ", ".join(f"{a:g}: {g:+.2f}" for a, g in gaps.items()) + ")")
    for speed in SPEEDS:
        f = figures(runner(wall_scene(speed, 90.0), SECONDS), WALL)
        lines.append(f"wall head-on, {speed:g} cm/s: sideways drift {f.drift_x:.2f} cm, least gap "
                     f"{f.polygon_gap:+.2f} cm, final {f.final[0]:.2f}, {f.final[1]:.2f}")
    for speed in SPEEDS:
        traj = runner(square_scene(speed), 60.0)
        f = figures(traj, SQUARE)
        goals = np.array([b for _, b in ring_positions()])
        arrived = int((np.hypot(*(traj[-1] - goals).T) <= 30.0).sum())
        lines.append(f"eight around a square, {speed:g} cm/s: least gap to the square {f.polygon_gap:+.2f} cm, "
                     f"between pedestrians {f.pair_gap:+.2f} cm, {arrived} of 8 at their goals after 60 s")
    return lines


if __name__ == "__main__":
    print("fuzzynav orca:")
    print("\n".join(table()))
    try:
        import pyrvo  # noqa: F401
    except ImportError:
        print("pyrvo not installed: no RVO2 figures")
    else:
        print("RVO2 (pyrvo):")
        print("\n".join(table(rvo2_run)))
        for what, polygons in (("walls alone", ()), ("three polygons", ROOM_POLYGONS)):
            d = rvo2_step_differences(polygons, 3000)
            print(f"one step against RVO2, {what}, 3000 cases: |ours - RVO2| max {d.max():.1e} cm/s, median "
                  f"{np.median(d):.1e}, {(d > 1e-3).sum()} above 1e-3 cm/s")
