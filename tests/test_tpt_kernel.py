"""The compiled Trajectory Prediction Table (fuzzynav/planning/_tpt.c) against its numpy form (tpt._tables_numpy).

Both are asked through build_tpt, once as it runs and once with FUZZYNAV_KERNEL=python: every array of the table
must be the same bits (a NaN's sign bit aside: nothing observes it), on the simulation's numbers and on hostile
ones (NaN, infinities, subnormals, goal on the robot, zero speed, no obstacles, obstacles on the robot).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fuzzynav.planning import tpt
from fuzzynav.sensing.tracking import Track

pytestmark = pytest.mark.skipif(tpt._kernel is None,
                                reason="the compiled kernel was not built (no C compiler at install)")

COORD = st.floats(-2000, 2000, allow_nan=False) | st.sampled_from([0.0, -0.0, 100.0, 250.0])
HOSTILE = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 1e308])
SPEED = st.floats(0, 60) | st.sampled_from([0.0, 10.0, 40.0, 5e-324, 1e308, float("inf"), float("nan")])


def _bits(a: np.ndarray) -> bytes:
    a = np.asarray(a)
    if a.dtype.kind == "f":
        a = np.where(np.isnan(a), np.nan, a)
    return a.dtype.str.encode() + repr(a.shape).encode() + a.tobytes()


def _table(monkeypatch, python: bool, *args, **kwargs) -> tuple[bytes, ...]:
    with monkeypatch.context() as m:
        if python:
            m.setenv("FUZZYNAV_KERNEL", "python")
        with np.errstate(all="ignore"):  # the numpy form warns of overflow and 0 * inf; the kernel does not
            table = tpt.build_tpt(*args, **kwargs)
    return tuple(_bits(a) for a in (table.robot, table.obstacles, table.collide, table.obstacle_radii,
                                    table.obstacle_velocities))


@st.composite
def _scenes(draw, numbers):
    n = draw(st.integers(0, 7))
    tracks = [Track(i + 1, *draw(st.tuples(numbers, numbers, numbers, numbers)), draw(numbers | st.floats(0, 60)))
              for i in range(n)]
    position = draw(st.tuples(numbers, numbers))
    goal = position if draw(st.booleans()) else draw(st.tuples(numbers, numbers))
    if n and draw(st.booleans()):  # an obstacle on the robot
        t = tracks[0]
        tracks[0] = Track(t.id, position[0], position[1], t.vx, t.vy, t.radius)
    return position, goal, tracks


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data(), st.booleans(), st.integers(1, 12), st.booleans(), st.sampled_from([1.0, 0.5, 2.0, 0.1, 0.0]))
def test_the_kernel_builds_the_numpy_forms_table(monkeypatch, data, hostile, n_traj, swept, dt):
    position, goal, tracks = data.draw(_scenes(HOSTILE if hostile else COORD))
    speed = data.draw(SPEED)
    radius = data.draw(st.sampled_from([20.0, 0.0, 25.5]) | (HOSTILE if hostile else st.floats(0, 100)))
    margin = data.draw(st.sampled_from([10.0, 0.0, 3.25]) | (HOSTILE if hostile else st.floats(0, 50)))
    args = (position, goal, speed, tracks, radius)
    kwargs = {"n_traj": n_traj, "dt": dt, "safety_margin": margin, "swept": swept}
    assert _table(monkeypatch, False, *args, **kwargs) == _table(monkeypatch, True, *args, **kwargs)


def test_a_pass_between_samples_marks_the_later_row_in_both_forms(monkeypatch):
    # an obstacle crossing the robot's path between steps 2 and 3: neither sample is within the limit, the pass is
    tracks = [Track(1, 500.0, -130.0, 0.0, 60.0, 20.0)]
    args = ((0.0, 0.0), (1000.0, 0.0), 200.0, tracks, 20.0)
    for python in (False, True):
        with monkeypatch.context() as m:
            if python:
                m.setenv("FUZZYNAV_KERNEL", "python")
            sampled = tpt.build_tpt(*args, n_traj=5, swept=False)
            swept = tpt.build_tpt(*args, n_traj=5)
        assert not sampled.collide.any()
        assert swept.collide[:, 0].tolist() == [False, False, False, True, False, False]
    assert _table(monkeypatch, False, *args) == _table(monkeypatch, True, *args)


def test_a_robot_inside_the_margin_now_has_step_one_marked_in_both_forms(monkeypatch):
    tracks = [Track(1, 30.0, 0.0, 0.0, 0.0, 20.0)]  # 30 cm away, limit 20 + 20 + 10: row 0 and every row marked
    args = ((0.0, 0.0), (0.0, 0.0), 0.0, tracks, 20.0)
    on, off = _table(monkeypatch, False, *args), _table(monkeypatch, True, *args)
    assert on == off
    table = tpt.build_tpt(*args)
    assert table.first_collision() == (1, 0)


def test_the_kernel_refuses_arrays_of_the_wrong_shape_or_type():
    robot, obstacles, collide = np.empty((3, 2)), np.empty((3, 1, 2)), np.empty((3, 1), dtype=bool)
    good = (np.zeros((1, 2)), np.zeros((1, 2)), np.ones(1))
    tpt._kernel.tables(0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, True, *good, robot, obstacles, collide)
    with pytest.raises(ValueError, match="collide must be a C-contiguous bool array"):
        tpt._kernel.tables(0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, True, *good, robot, obstacles,
                           np.empty((3, 1)))
    with pytest.raises(ValueError, match=r"obstacles \(n\+1, J, 2\)"):
        tpt._kernel.tables(0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, True, *good, robot, np.empty((2, 1, 2)),
                           collide)
    with pytest.raises(ValueError, match="radii must be a C-contiguous float64 array"):
        tpt._kernel.tables(0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, True, *good[:2], np.ones(1, dtype=np.float32),
                           robot, obstacles, collide)
    with pytest.raises(ValueError, match="robot \\(n\\+1 >= 2, 2\\)"):
        tpt._kernel.tables(0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, True, *good, np.empty((1, 2)),
                           np.empty((1, 1, 2)), np.empty((1, 1), dtype=bool))
