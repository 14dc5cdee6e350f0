"""The compiled ``orca`` pedestrian kernel (fuzzynav.pedestrians._orca) against the Python path it replaces
(:meth:`fuzzynav.pedestrians.orca.PedestrianOrcaModel._velocity`): the same bits for random pedestrian groups and
worlds (coincident pedestrians, overlapping discs, zero velocities, pedestrians on walls, on polygon vertices and
edges and at a radius from them, convex and concave corners, lone segments, parallel constraint lines,
infeasible programs, tiny and large speed discs), and identical obstacle trajectories over whole crowd episodes
with and without the kernel. Units: cm, s, cm/s."""

from __future__ import annotations

import inspect
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzynav.numerics import orca_lp as orca
from fuzzynav.numerics.geometry import away_from_static
from fuzzynav.pedestrians import orca as pedestrian_orca
from fuzzynav.pedestrians.orca import PedestrianOrcaConfig, PedestrianOrcaModel, _Obstacles
from tests.conftest import require_compiled

require_compiled(pedestrian_orca._kernel, "_orca")

CONF = Path(__file__).resolve().parents[1] / "conf"


def bits(a: np.ndarray) -> bytes:
    """The array's bytes: equal bytes are equal bits (``==`` would equate -0.0 and 0.0)."""
    return np.ascontiguousarray(a, dtype=np.float64).tobytes()


def model_with(config: PedestrianOrcaConfig) -> PedestrianOrcaModel:
    """A model whose only state the velocity computation reads is its config (and its radii, set by the caller)."""
    model = PedestrianOrcaModel.__new__(PedestrianOrcaModel)
    model.config = config
    model._obstacles = None
    return model


def substep_inputs(rng: np.random.Generator, n: int, others: int, config: PedestrianOrcaConfig,
                   grid: float, speed_scale: float, n_seg: int, n_circ: int, sees_robot: bool) -> dict[str, Any]:
    """One substep's inputs of both paths, built as PedestrianOrcaModel.step builds them: positions on a coarse
    grid of ``grid`` cm (so pedestrians coincide, overlap, stand exactly on walls, polygon vertices and edges or
    a radius from them), velocities of a few values including 0 (axis-parallel ones move along the axis-parallel
    edges), speed discs from tiny to large; ``n_seg`` polygons of 2 to 6 grid points (lone segments, convex and
    concave corners, collinear and repeated vertices, either orientation, self-crossing ones)."""
    def pts(k: int) -> np.ndarray:
        return rng.integers(0, 6, size=(k, 2)).astype(float) * grid

    x = pts(n)
    o_pos = pts(others)
    choices = np.array([0.0, 0.0, -0.0, 1e-300, 3.0, -7.5, 30.0, 120.0]) * speed_scale
    v = rng.choice(choices, size=(n, 2))
    o_vel = rng.choice(choices, size=(others, 2))
    pref = rng.choice(choices, size=(n, 2))
    radii = rng.choice([0.0, 10.0, 25.0, 0.5 * grid], size=n)
    o_rad = rng.choice([0.0, 15.0, 25.0, grid], size=others)
    max_speed = rng.choice([0.0, 1e-9, 1e-3, 20.0, 130.0, 1e4], size=n)
    # polygons through grid points (pedestrians stand on their vertices and edges), degenerate ones included
    polygons = tuple(pts(int(rng.integers(2, 7))) for _ in range(n_seg))
    lo, hi = rng.choice([-grid, 0.0, grid]), rng.choice([3 * grid, 5 * grid])
    bounds = (float(lo), float(lo), float(hi), float(hi))  # the pedestrians on, inside or outside the walls
    circles = np.concatenate([pts(n_circ), rng.choice([0.0, 5.0, grid], size=(n_circ, 1))], axis=1)
    h = float(rng.choice([0.25, 0.1, 1.0]))
    sees_robot = sees_robot and others > 0  # the robot is the last of the others
    o_share = [1.0] * (others - sees_robot) + [config.robot_responsibility] * sees_robot
    pos_all = np.vstack([x, o_pos])
    vel_all = np.vstack([v, o_vel])
    rad_all = np.concatenate([radii, o_rad])
    share = [0.5] * n + o_share
    gaps, away = away_from_static(x, np.zeros((0, 4)), circles)
    model = model_with(config)
    model.radii = radii
    near = model._neighbours(x, pos_all)
    obstacles = _Obstacles(bounds, polygons)
    edges = model._edges_within_reach(obstacles, x, max_speed)
    reach = config.time_horizon_obst_s * max_speed + radii
    close = (gaps - radii[:, None]) < reach[:, None]
    if rng.random() < 0.3:  # any subset of statics, also ones beyond reach, in any order
        close = rng.random(close.shape) < 0.7
        edges = [rng.permutation(len(obstacles.points))[:int(rng.integers(0, len(obstacles.points) + 1))].tolist()
                 for _ in range(n)]
    rel = pos_all[None, :, :] - x[:, None, :]
    world = SimpleNamespace(bounds=bounds, polygons=polygons, circles=circles)
    return {"model": model,
            "args": (obstacles, x, v, pref, max_speed, rel, vel_all, rad_all, share, edges, gaps, away, close, near, h),
            "substep": (x, pos_all, vel_all, rad_all, share, v, pref, max_speed, world, h)}


def both_paths(case: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The velocity part alone (given statics and neighbours): kernel and Python path."""
    model, args = case["model"], case["args"]
    return model._velocities_compiled(*args), model._velocities_python(*args)


def both_substeps(case: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """A whole substep (neighbours, statics, velocities): kernel and Python path."""
    model, args = case["model"], case["substep"]
    return model._substep_compiled(*args), model._substep_python(*args)


configs = st.builds(
    PedestrianOrcaConfig,
    neighbor_dist_cm=st.sampled_from([0.0, 60.0, 1_000.0]),
    max_neighbors=st.sampled_from([0, 1, 3, 10]),
    time_horizon_s=st.sampled_from([0.05, 1.0, 5.0, 600]),
    time_horizon_obst_s=st.sampled_from([0.05, 2.0, 5.0]),
    robot_responsibility=st.sampled_from([0.5, 0.75, 1]),
)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(config=configs, seed=st.integers(0, 2**32 - 1), n=st.integers(1, 7), others=st.integers(0, 5),
       grid=st.sampled_from([1.0, 10.0, 20.0, 50.0]), speed_scale=st.sampled_from([1e-6, 1.0, 100.0]),
       n_seg=st.integers(0, 3), n_circ=st.integers(0, 2), sees_robot=st.booleans())
def test_kernel_velocities_are_the_python_paths_bits(config, seed, n, others, grid, speed_scale, n_seg, n_circ,
                                                    sees_robot):
    case = substep_inputs(np.random.default_rng(seed), n, others, config, grid, speed_scale, n_seg, n_circ,
                          sees_robot)
    compiled_v, python_v = both_paths(case)
    assert bits(compiled_v) == bits(python_v), (compiled_v, python_v)


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(config=configs, seed=st.integers(0, 2**32 - 1), n=st.integers(1, 7), others=st.integers(0, 5),
       grid=st.sampled_from([1.0, 10.0, 20.0, 50.0]), speed_scale=st.sampled_from([1e-6, 1.0, 100.0]),
       n_seg=st.integers(0, 3), n_circ=st.integers(0, 2), sees_robot=st.booleans(), negative_zero=st.booleans())
def test_kernel_substeps_are_the_python_paths_bits(config, seed, n, others, grid, speed_scale, n_seg, n_circ,
                                                  sees_robot, negative_zero):
    """The whole substep in C — the neighbours (ties of equal distances on the grid, fewer slots than
    candidates), the edges within reach (ties, pedestrians on edges and vertices), the circles' gaps and directions
    (pedestrians at circle centres), the statics within reach and the velocities — against the Python path."""
    case = substep_inputs(np.random.default_rng(seed), n, others, config, grid, speed_scale, n_seg, n_circ,
                          sees_robot)
    if negative_zero:  # -0.0 coordinates: numpy keeps -0.0, and so must the kernel
        x, pos_all, *rest = case["substep"]
        world = rest[-2]
        for a in (x, pos_all, *world.polygons, world.circles):
            a[a == 0.0] = -0.0
        world.bounds = tuple(-0.0 if b == 0.0 else b for b in world.bounds)
    compiled_v, python_v = both_substeps(case)
    assert bits(compiled_v) == bits(python_v), (compiled_v, python_v)


def test_random_cases_reach_every_branch(monkeypatch):
    """Many random substeps, bitwise equal, and among them the 3-D fallback (infeasible programs), parallel
    constraint lines in the 1-D and 3-D programs, overlaps, pedestrians on walls and zero-length vectors, and
    every branch of the edges' lines (:data:`EDGE_BRANCHES`): the hypothesis test's generator does reach the
    branches a port could get wrong."""
    hits = {"lp3": 0, "parallel": 0, "overlap": 0, "on_wall": 0}
    real_lp3, real_det, real_static = orca.solve_lp3, orca._det, orca.static_point_line

    def lp3(*a, **k):
        hits["lp3"] += 1
        return real_lp3(*a, **k)

    def det(a, b):
        value = real_det(a, b)
        if value == 0.0 and a != b and a[0] ** 2 + a[1] ** 2 > 0.5:  # two unit directions: parallel lines
            hits["parallel"] += 1
        return value

    def static(rel, r, *a):
        if rel[0] * rel[0] + rel[1] * rel[1] <= r * r:
            hits["on_wall" if rel == (0.0, 0.0) or rel == (-0.0, -0.0) else "overlap"] += 1
        return real_static(rel, r, *a)

    monkeypatch.setattr(orca, "solve_lp3", lp3)
    monkeypatch.setattr(orca, "_det", det)
    monkeypatch.setattr(pedestrian_orca, "static_point_line", static)
    rng = np.random.default_rng(2026)
    with edge_branches_run() as ran:
        for _ in range(300):
            config = PedestrianOrcaConfig(neighbor_dist_cm=float(rng.choice([60.0, 1000.0])),
                                          max_neighbors=int(rng.choice([1, 3, 10])),
                                          time_horizon_s=float(rng.choice([1.0, 5.0])))
            case = substep_inputs(rng, int(rng.integers(1, 8)), int(rng.integers(0, 6)), config,
                                  float(rng.choice([1.0, 10.0, 20.0])), float(rng.choice([1e-6, 1.0, 100.0])),
                                  int(rng.integers(0, 4)), int(rng.integers(0, 3)), bool(rng.random() < 0.5))
            for compare in (both_paths, both_substeps):
                compiled_v, python_v = compare(case)
                assert bits(compiled_v) == bits(python_v)
    assert all(count > 0 for count in hits.values()), hits
    assert not set(EDGE_BRANCHES) - ran, set(EDGE_BRANCHES) - ran


#: orca_lp.edge_lines' branches, each by the line of code only it runs: a text on that line, or "after: " a text on
#: the line before it
EDGE_BRANCHES = {
    "already covered": "after: if _covered(",
    "overlapping a convex vertex 1": "_unit((-rel1[1], rel1[0]))",
    "overlapping vertex 2, kept": "_unit((-rel2[1], rel2[0]))",
    "overlapping the edge": "lines.append(Line((0.0, 0.0), (-dirs[k1][0], -dirs[k1][1])))",
    "oblique past vertex 1": "k2, rel2 = k1, rel1",
    "oblique past vertex 2": "k1, rel1 = k2, rel2",
    "oblique past a concave vertex 1": "after: if not convex[k1]:",
    "oblique past a concave vertex 2": "after: if not convex[k2]:",
    "left leg foreign": "left, left_foreign =",
    "right leg foreign": "right, right_foreign =",
    "left cut-off disc": "w = _unit(from_left)",
    "right cut-off disc": "w = _unit(from_right)",
    "cut-off segment": "lines.append(_through(left_cut, scale, (-dirs[k1][0]",
    "left leg": "lines.append(_through(left_cut, scale, left))",
    "right leg": "lines.append(_through(right_cut, scale, (-right[0]",
    "nearest a foreign left leg: no line": "after: if left_foreign:",
    "nearest a foreign right leg: no line": "after: if right_foreign:",
}


@contextmanager
def edge_branches_run() -> Iterator[set[str]]:
    """The names of :data:`EDGE_BRANCHES` that orca_lp.edge_lines ran while the context was open (a line tracer on
    that function alone)."""
    code = orca.edge_lines.__code__
    source, first = inspect.getsourcelines(orca.edge_lines)
    where = {}
    for name, marker in EDGE_BRANCHES.items():
        text = marker.removeprefix("after: ")
        found = [first + k + (text != marker) for k, line in enumerate(source) if text in line]
        assert len(found) == 1, (name, found)
        where[found[0]] = name
    ran: set[str] = set()

    def local(frame, event, arg):
        if event == "line" and frame.f_lineno in where:
            ran.add(where[frame.f_lineno])
        return local

    def tracer(frame, event, arg):
        return local if frame.f_code is code else None

    old = sys.gettrace()
    sys.settrace(tracer)
    try:
        yield ran
    finally:
        sys.settrace(old)


def test_a_python_error_takes_the_python_path(monkeypatch):
    """Where the Python path raises, the kernel flags the pedestrian and the Python path runs for it: the same
    error. Forced with a zero substep (1 / dt for an overlapping pair), which the model never passes."""
    config = PedestrianOrcaConfig()
    case = substep_inputs(np.random.default_rng(0), 2, 0, config, 1.0, 1.0, 0, 0, False)
    model, args = case["model"], list(case["args"])
    args[5] = np.zeros_like(args[5])  # everyone at the same place: overlapping discs
    args[7] = np.full_like(args[7], 10.0)
    args[13] = [[1], [0]]
    args[14] = 0.0
    with pytest.raises(ZeroDivisionError):
        model._velocities_python(*args)
    with pytest.raises(ZeroDivisionError):
        model._velocities_compiled(*args)
    x, pos_all, vel_all, rad_all, share, v, pref, max_speed, world, _ = case["substep"]
    substep = (x, np.zeros_like(pos_all), vel_all, np.full_like(rad_all, 10.0), share, v, pref, max_speed, world,
               0.0)
    with pytest.raises(ZeroDivisionError):
        model._substep_python(*substep)
    with pytest.raises(ZeroDivisionError):
        model._substep_compiled(*substep)


def test_kernel_rejects_mismatched_arrays():
    config = PedestrianOrcaConfig()
    case = substep_inputs(np.random.default_rng(1), 3, 2, config, 10.0, 1.0, 1, 1, True)
    model, args = case["model"], list(case["args"])
    args[6] = args[6][:-1]  # one velocity short
    with pytest.raises(ValueError, match="vel"):
        model._velocities_compiled(*args)
    args = list(case["args"])
    args[13] = [[99]] * 3  # a neighbour that does not exist
    with pytest.raises((ValueError, IndexError)):
        model._velocities_compiled(*args)
    args = list(case["args"])
    args[9] = [[999]] * 3  # an edge that does not exist
    with pytest.raises(ValueError, match="edge index"):
        model._velocities_compiled(*args)
    obstacles = _Obstacles((0.0, 0.0, 100.0, 100.0), ())
    obstacles.next = obstacles.next + 4  # a vertex whose next one does not exist
    args = list(case["args"])
    args[0], args[9] = obstacles, [[]] * 3
    with pytest.raises(ValueError, match="next or previous"):
        model._velocities_compiled(*args)


# -- whole episodes ---------------------------------------------------------------------------------------


def crowd_inputs(n: int, max_steps: int) -> dict[str, Any]:
    """runners.benchmarks.crowd's inputs: crowd_crossing with ``n`` orca pedestrians, laser perception."""
    scenario = yaml.safe_load((CONF / "scenario" / "crowd_crossing.yaml").read_text())
    scenario["params"].update(n=n, model="orca", max_steps=max_steps)
    return {"sensors": yaml.safe_load((CONF / "sensors" / "default.yaml").read_text()),
            "navigator": yaml.safe_load((CONF / "navigator" / "fuzzy_tpt.yaml").read_text()),
            "planner": yaml.safe_load((CONF / "planner" / "auto.yaml").read_text()),
            "scenario": scenario,
            "controller": yaml.safe_load((CONF / "controller" / "table1.yaml").read_text())}


def obstacle_trajectory(seed: int, n: int, max_steps: int) -> tuple[bytes, bytes, int]:
    from fuzzynav.episode import Episode
    from runners.run import episode_config, load_evaluator, load_scenario

    base = crowd_inputs(n, max_steps)
    scenario = load_scenario(base, seed)
    episode = Episode(scenario, load_evaluator(base), episode_config(base), seed=seed)
    records = list(episode.run())
    positions = np.array([r.obstacle_next_positions for r in records])
    velocities = np.array([r.obstacle_velocities for r in records])
    return bits(positions), bits(velocities), len(records)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_crowd_episodes_have_the_same_obstacle_trajectories(monkeypatch, seed):
    monkeypatch.delenv("FUZZYNAV_KERNEL", raising=False)  # CI's kernels-off pass sets it: this half is the kernel's
    with_kernel = obstacle_trajectory(seed, 20, 60)
    monkeypatch.setenv("FUZZYNAV_KERNEL", "python")
    without = obstacle_trajectory(seed, 20, 60)
    assert with_kernel[2] > 10
    assert with_kernel == without
