"""The per-step /scene message written from byte templates is exactly orjson's encoding of its dict form."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import orjson
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fuzzynav.numerics.portable_math import atan2_deg
from runners.logs.foxglove_scene import (
    BLUE,
    CYAN,
    HIT,
    ORANGE,
    PURPLE,
    RED,
    StepScenes,
    disc,
    entity,
    line,
    line_m,
    metres,
    point,
    point_lists,
    pose,
    stamp,
    template,
)


def _scene_as_dicts(when, x, y, heading, radius, ids, radii, headings, positions, velocities, tpt, plan_lines):
    """The step's scene built as nested dicts, one entity after the other (what the templates must reproduce)."""
    robot_arrow = {"pose": pose(x, y, heading, 0.2), "shaft_length": metres(radius), "shaft_diameter": 0.03,
                   "head_length": metres(radius * 0.6), "head_diameter": 0.08, "color": BLUE}
    entities = [entity(when, "robot", cylinders=[disc(x, y, radius, 0.2, BLUE)], arrows=[robot_arrow])]
    for oid, r, shows, (px, py), (vx, vy) in zip(ids, radii, headings, positions.tolist(), velocities.tolist(),
                                                 strict=True):
        arrows = [] if not shows or (vx == 0.0 and vy == 0.0) else [
            {"pose": pose(px, py, atan2_deg(vy, vx), 0.3), "shaft_length": metres(r), "shaft_diameter": 0.03,
             "head_length": metres(r * 0.6), "head_diameter": 0.08, "color": RED}]
        d = metres(2 * r)
        body = {"pose": pose(px, py, 0.0, 0.15), "size": {"x": d, "y": d, "z": 0.3}, "bottom_scale": 1.0,
                "top_scale": 1.0, "color": RED}
        entities.append(entity(when, f"obstacle/{oid}", cylinders=[body], arrows=arrows))
    lines, hits = [], []
    if tpt is not None:
        lines.append(line(tpt.robot, CYAN, z_m=0.02))
        for j in range(len(tpt.obstacle_ids)):
            lines.append(line(tpt.obstacles[:, j], ORANGE, z_m=0.02))
        for row in range(1, len(tpt.robot)):
            if tpt.collide[row].any():
                hits.append(disc(*tpt.robot[row].tolist(), tpt.robot_radius, 0.05, HIT))
    entities.append(entity(when, "tpt", lines=lines, cylinders=hits))
    entities.append(entity(when, "plan", lines=plan_lines))
    return {"deletions": [], "entities": entities}


_cm = st.floats(-1e5, 1e5, allow_nan=False) | st.sampled_from([0.0, -0.0, 0.004999, 0.00005, 12345.678901, -1e-9])
_speed = st.floats(-500, 500, allow_nan=False) | st.just(0.0) | st.just(-0.0)
_name = st.text(st.sampled_from("ab%-._Z9\"\\é"), min_size=1, max_size=8) | st.just("-1.000987654321e300")


@st.composite
def _episodes(draw):
    n = draw(st.integers(0, 5))
    ids = draw(st.lists(_name, min_size=n, max_size=n))
    radii = draw(st.lists(st.floats(1, 200) | st.sampled_from([15.0, 25, 0.5]), min_size=n, max_size=n))
    headings = draw(st.lists(st.booleans(), min_size=n, max_size=n))
    radius = draw(st.floats(1, 100) | st.sampled_from([20, 25.0]))
    steps = []
    for _ in range(draw(st.integers(1, 4))):
        xy = np.array(draw(st.lists(_cm, min_size=2 * n, max_size=2 * n)), dtype=float).reshape(n, 2)
        v = np.array(draw(st.lists(_speed, min_size=2 * n, max_size=2 * n)), dtype=float).reshape(n, 2)
        tpt = None
        if draw(st.booleans()):
            t_rows, j = draw(st.integers(0, 5)), draw(st.integers(0, n))
            tpt = SimpleNamespace(
                robot=np.array(draw(st.lists(_cm, min_size=2 * t_rows, max_size=2 * t_rows)), float).reshape(-1, 2),
                obstacles=np.array(draw(st.lists(_cm, min_size=2 * t_rows * j, max_size=2 * t_rows * j)),
                                   float).reshape(t_rows, j, 2),
                obstacle_ids=tuple(f"o{k}" for k in range(j)),
                collide=np.array(draw(st.lists(st.booleans(), min_size=t_rows * j, max_size=t_rows * j)),
                                 bool).reshape(t_rows, j),
                robot_radius=draw(st.floats(1, 100)))
        plan = draw(st.sampled_from(["none", "new", "kept"]))
        path = np.array(draw(st.lists(_cm, min_size=2, max_size=8).filter(lambda p: len(p) % 2 == 0))).reshape(-1, 2)
        steps.append((draw(st.floats(0, 1e5)), draw(_cm), draw(_cm), draw(_cm | st.floats(-720, 720)), xy, v, tpt,
                      plan, path))
    return radius, ids, radii, headings, steps


@settings(max_examples=300, deadline=None)
@given(_episodes())
def test_the_step_scene_is_the_encoding_of_its_dict_form(episode):
    radius, ids, radii, headings, steps = episode
    scenes = StepScenes(radius, ids, radii, headings)
    plan_lines: list = []
    for t, x, y, heading, xy, v, tpt, plan, path in steps:
        if plan == "none":
            running, new, plan_lines = None, False, []
        else:
            running, new = SimpleNamespace(path=path), plan == "new" or not plan_lines
            if new:
                plan_lines = [line([[x, y], *path.tolist()], PURPLE, thickness_m=0.04, z_m=0.03)]
        when = stamp(t)
        got = scenes.message(when, x, y, heading, xy, v, tpt, running, new)
        want = orjson.dumps(_scene_as_dicts(when, x, y, heading, radius, ids, [float(r) for r in radii], headings,
                                            xy, v, tpt, plan_lines), option=orjson.OPT_SERIALIZE_NUMPY)
        assert got == want


def test_numpy_scalars_are_encoded_as_python_floats():
    scenes = StepScenes(20, ["a"], [15.0], [True])
    args = (stamp(3.0), np.float64(101.25), np.float64(-7.5), np.float64(33.0), np.array([[1.5, 2.5]]),
            np.array([[3.0, -4.0]]), None, None, False)
    plain = (stamp(3.0), 101.25, -7.5, 33.0, *args[4:])
    assert scenes.message(*args) == scenes.message(*plain)


@given(st.lists(st.lists(st.tuples(_cm, _cm).map(list), min_size=1, max_size=4), max_size=4),
       st.sampled_from([0.02, 0.0, -0.0, 1e-7, 123.5]))
def test_point_lists_are_the_encoding_of_point_dicts(columns, z):
    columns = [[[metres(x), metres(y)] for x, y in c] for c in columns]
    width = min((len(c) for c in columns), default=0)
    columns = [c[:width] for c in columns]  # one length, as the columns of a table
    assert point_lists(columns, z) == [orjson.dumps([point(x, y, z) for x, y in c]) for c in columns]


def test_a_template_fills_its_slots_in_order_and_keeps_percent_signs():
    fmt = template(lambda a, b: {"name": "100%", "a": a, "inner": {"b": b}}, 2)
    assert fmt % (b"1.5", b"[]") == orjson.dumps({"name": "100%", "a": 1.5, "inner": {"b": []}})


@pytest.mark.parametrize("build", [lambda a, b: [b, a], lambda a, b: [a, a, b], lambda a, b: [a]])
def test_a_template_refuses_slots_not_encoded_once_in_order(build):
    with pytest.raises(ValueError, match="not encoded once"):
        template(build, 2)


def test_line_m_of_point_lists_matches_the_dict_line():
    xy = [[[0.5, 1.25], [2.0, -3.0]]]
    points, = point_lists(xy, 0.02)
    fmt = template(lambda p: line_m(p, ORANGE), 1)
    assert fmt % (points,) == orjson.dumps(line_m([point(x, y, 0.02) for x, y in xy[0]], ORANGE))


def test_no_radius_can_take_a_templates_slot():
    # a slot is found by its sentinel's digits: no value baked into a template (m, 0.1 mm) can be one
    for radius in (-1.000987654321e302, -5.004938271605e301, 1e-300, 15.0):
        scenes = StepScenes(radius, ["a"], [radius], [True])
        tpt = SimpleNamespace(robot=np.zeros((2, 2)), obstacles=np.zeros((2, 1, 2)), obstacle_ids=("a",),
                              collide=np.ones((2, 1), bool), robot_radius=radius)
        when = stamp(1.0)
        got = scenes.message(when, 1.0, 2.0, 30.0, np.ones((1, 2)), np.ones((1, 2)), tpt, None, False)
        want = orjson.dumps(_scene_as_dicts(when, 1.0, 2.0, 30.0, radius, ["a"], [radius], [True], np.ones((1, 2)),
                                            np.ones((1, 2)), tpt, []), option=orjson.OPT_SERIALIZE_NUMPY)
        assert got == want
