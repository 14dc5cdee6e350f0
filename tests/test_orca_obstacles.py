"""The ORCA pedestrians' static obstacles (issue #37 item 9): RVO2's obstacle lines for walls and polygon edges
(fuzzynav.numerics.orca_lp.edge_lines; van den Berg et al. 2011, Sec. 5) — the vertex chains, the lines by hand
in each case (cut-off segment, legs, overlap, a pedestrian exactly at an edge's end or a radius from it, parallel
motion, concave corners), the edges a pedestrian faces, and the issue's scenes with their figures
(tests/orca_obstacle_scenes.py). The C kernel's sameness is tests/test_orca_kernel.py's. Units: cm, s, cm/s."""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from fuzzynav.numerics import orca_lp
from fuzzynav.numerics.orca_lp import Line, choose_velocity, edge_lines, obstacle_vertices, world_chains
from fuzzynav.pedestrians.orca import PedestrianOrcaConfig, PedestrianOrcaModel, _Obstacles
from tests import orca_obstacle_scenes as scenes

R, TAU = 10.0, 5.0
# a 200 x 200 box above the origin, counter-clockwise: its bottom edge (vertex 0 to 1) runs along y = 50
BOX = [(-100.0, 50.0), (100.0, 50.0), (100.0, 250.0), (-100.0, 250.0)]
FAR = (-1e5, -1e5, 1e5, 1e5)  # walls out of every reach


def box_vertices() -> orca_lp.ObstacleVertices:
    return obstacle_vertices([BOX])


def lines_at(position, velocity, edges=(0,), vertices=None):
    return edge_lines(vertices or box_vertices(), list(edges), position, velocity, R, TAU)


def approx_line(line: Line, point, direction, abs_tol=1e-12):
    assert line.point == pytest.approx(point, abs=abs_tol)
    assert line.direction == pytest.approx(direction, abs=abs_tol)


# -- the vertex chains ----------------------------------------------------------------------------------------


def test_walls_are_a_clockwise_chain_of_concave_corners_and_polygons_counter_clockwise():
    l_shape = [(0, 0), (0, 300), (100, 300), (100, 100), (300, 100), (300, 0)]  # clockwise, reflex at (100, 100)
    chains = world_chains((0, 0, 1000, 800), [BOX, l_shape])
    assert chains[0] == [(0.0, 0.0), (0.0, 800.0), (1000.0, 800.0), (1000.0, 0.0)]
    assert chains[1] == BOX
    assert chains[2] == [(float(x), float(y)) for x, y in reversed(l_shape)]
    v = obstacle_vertices(chains)
    assert v.convex[:4] == (False,) * 4  # a room's corners, seen from inside
    assert v.convex[4:8] == (True,) * 4
    convex_l = dict(zip(v.points[8:], v.convex[8:], strict=True))
    assert [p for p, c in convex_l.items() if not c] == [(100.0, 100.0)]
    assert v.next[:4] == (1, 2, 3, 0) and v.previous[:4] == (3, 0, 1, 2)
    assert v.directions[0] == (0.0, 1.0)  # the left wall upwards: the outside (x < 0) on its left


def test_repeated_vertices_are_dropped_and_a_segment_has_two_sides():
    v = obstacle_vertices([[(0, 0), (10, 0), (10, 0), (10, 10), (0, 0)], [(5, 5), (5, 5)], [(0, 20), (30, 20)]])
    assert v.points == ((0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 20.0), (30.0, 20.0))
    assert v.next == (1, 2, 0, 4, 3) and v.convex[3:] == (True, True)
    assert v.directions[3] == (1.0, 0.0) and v.directions[4] == (-1.0, 0.0)


# -- the lines by hand -----------------------------------------------------------------------------------------


def test_an_edge_ahead_gives_its_cut_off_segment():
    # 40 cm between the rim and the edge: within tau = 5 s no faster than 8 cm/s towards it
    (line,) = lines_at((0.0, 0.0), (0.0, 0.0))
    approx_line(line, (-20.0, 8.0), (-1.0, 0.0))
    assert orca_lp.violation(line, (0.0, 8.0)) == pytest.approx(0.0, abs=1e-12)
    assert orca_lp.violation(line, (25.0, 7.9)) < 0.0 < orca_lp.violation(line, (0.0, 8.1))


def test_an_edge_overlapped_or_touched_forbids_moving_towards_it():
    for gap in (0.0, -5.0):  # exactly a radius from the edge (touching), and overlapping it
        (line,) = lines_at((0.0, 50.0 - R - gap), (0.0, 30.0))
        assert line == Line((0.0, 0.0), (-1.0, -0.0))
        assert orca_lp.violation(line, (30.0, 0.0)) == 0.0 and orca_lp.violation(line, (0.0, 1e-9)) > 0.0


def test_touching_a_convex_end_forbids_moving_towards_that_vertex():
    # exactly a radius (6, 8 cm) before vertex 0, below the edge's line (s < 0): the line through the origin
    # normal to the direction to the vertex
    (line,) = lines_at((-106.0, 42.0), (10.0, 0.0))
    approx_line(line, (0.0, 0.0), (-0.8, 0.6))
    assert orca_lp.violation(line, (6.0, 8.0)) > 0.0 > orca_lp.violation(line, (-6.0, -8.0))
    # exactly a radius beyond vertex 1 (s > 1): the bottom edge leaves it to the right edge, which starts there
    beyond = (106.0, 42.0)
    assert edge_lines(box_vertices(), [0], beyond, (-10.0, 0.0), R, TAU) == []
    (line,) = edge_lines(box_vertices(), [0, 1], beyond, (-10.0, 0.0), R, TAU)
    approx_line(line, (0.0, 0.0), (-0.8, -0.6))


def test_an_edge_seen_obliquely_is_its_end_disc():
    # far before vertex 0, 5 cm below the edge's line: vertex 0's disc alone is the velocity obstacle (its left
    # leg would enter the box's left edge: that edge's direction instead); moving at it is forbidden, standing
    # still is on the boundary (the legs pass through the origin), moving away is permitted
    (line,) = lines_at((-200.0, 45.0), (30.0, 0.0))
    assert orca_lp.violation(line, (30.0, 0.0)) > 0.0
    assert abs(orca_lp.violation(line, (0.0, 0.0))) < 1e-12
    assert orca_lp.violation(line, (0.0, -30.0)) < 0.0


def test_a_pedestrian_moving_along_an_edge_keeps_its_velocity():
    # 20 cm from the edge (10 from the rim), moving parallel to it: nothing to avoid
    (line,) = lines_at((0.0, 30.0), (30.0, 0.0))
    assert orca_lp.violation(line, (30.0, 0.0)) < 0.0
    assert choose_velocity([line], 1, 40.0, (30.0, 0.0)).velocity == (30.0, 0.0)


def test_a_concave_corner_keeps_both_walls_lines():
    # the room's lower left corner: the pedestrian 15 cm from both walls (5 from its rim), heading into it
    v = obstacle_vertices(world_chains((0, 0, 400, 400), []))
    model = model_for(v)
    edges = model._edges_within_reach(_Obstacles((0, 0, 400, 400), ()), np.array([[15.0, 15.0]]),
                                      np.array([40.0]))[0]
    assert sorted(edges) == [0, 3]  # the left wall (vertex 0) and the bottom wall (vertex 3), equally near
    lines = edge_lines(v, edges, (15.0, 15.0), (-20.0, -20.0), R, TAU)
    assert len(lines) == 2
    chosen = choose_velocity(lines, 2, 40.0, (-28.0, -28.0)).velocity
    # each wall 5 cm from the rim: no faster than 1 cm/s towards either
    assert chosen[0] >= -1.0 - 1e-9 and chosen[1] >= -1.0 - 1e-9


def model_for(vertices) -> PedestrianOrcaModel:
    model = PedestrianOrcaModel.__new__(PedestrianOrcaModel)
    model.config = PedestrianOrcaConfig()
    model.radii = np.array([R])
    model._obstacles = None
    return model


def test_a_pedestrian_faces_the_edges_on_its_side_within_reach_nearest_first():
    obstacles = _Obstacles(FAR, [BOX])
    model = model_for(obstacles.vertices)
    speed = np.array([40.0])  # reach 5 s x 40 cm/s + 10 cm = 210 cm
    # below the box: its bottom edge (vertex 4; the walls are vertices 0-3); the others face away
    assert model._edges_within_reach(obstacles, np.array([[0.0, 0.0]]), speed) == [[4]]
    # below and right of the box: the bottom and the right edge, equally near (their shared corner): vertex order
    assert model._edges_within_reach(obstacles, np.array([[150.0, 0.0]]), speed) == [[4, 5]]
    # on a vertex, or on an edge's line: not strictly outside either edge there
    assert model._edges_within_reach(obstacles, np.array([[100.0, 50.0]]), speed) == [[]]
    assert model._edges_within_reach(obstacles, np.array([[0.0, 50.0]]), speed) == [[]]
    # out of reach
    assert model._edges_within_reach(obstacles, np.array([[0.0, -170.0]]), speed) == [[]]


def test_an_edge_a_nearer_ones_line_covers_adds_no_line():
    # a straight wall in two collinear pieces: the second piece lies wholly beyond the first one's cut-off line
    v = obstacle_vertices([[(-100.0, 50.0), (0.0, 50.0), (100.0, 50.0), (100.0, 250.0), (-100.0, 250.0)]])
    assert len(edge_lines(v, [0, 1], (-10.0, 0.0), (0.0, 0.0), R, TAU)) == 1


# -- the scenes ---------------------------------------------------------------------------------------
# Measured (min over every 0.25 s; python -m tests.orca_obstacle_scenes) before this change, with each edge's
# nearest point as a disc: -1.09, -1.70 and -13.40 cm into the wall at 30, 40 and 130 cm/s; head-on 31.56, 51.33
# and 40.00 cm sideways; around the square -0.80, -1.00 and -104.73 cm into it and +1.67, +2.07 and -5.04 cm
# between pedestrians. RVO2 (pyrvo 0.4.3, float32) on the same scenes: +0.39, +0.38, +0.38 cm; 0.00 cm
# sideways; +0.00 cm into the square and +1.03, +4.10, +0.28 cm between pedestrians.


@pytest.mark.parametrize("speed", scenes.SPEEDS)
def test_a_pedestrian_walking_into_a_long_wall_never_enters_it(speed):
    gaps = [scenes.figures(scenes.run(scenes.wall_scene(speed, a), scenes.SECONDS), scenes.WALL).polygon_gap
            for a in scenes.ANGLES]
    # measured: at least +0.38 cm at every speed and angle (RVO2 the same to 0.01 cm)
    assert min(gaps) >= 0.3, gaps


@pytest.mark.parametrize("speed", scenes.SPEEDS)
def test_a_pedestrian_walking_straight_at_a_wall_stops_in_front_of_it(speed):
    f = scenes.figures(scenes.run(scenes.wall_scene(speed, 90.0), scenes.SECONDS), scenes.WALL)
    assert f.drift_x == 0.0  # measured 0 (RVO2 too); with nearest points it slid 31.6-51.3 cm sideways
    assert f.polygon_gap >= 0.3 and f.final[1] == pytest.approx(580.0, abs=0.5)


@pytest.mark.parametrize("speed, pair_gap", [(30.0, 1.0), (40.0, 4.0), (130.0, -1.2)])
def test_eight_pedestrians_around_a_square_keep_out_of_it(speed, pair_gap):
    traj = scenes.run(scenes.square_scene(speed), 60.0)
    f = scenes.figures(traj, scenes.SQUARE)
    # measured +0.0009, +0.0041 and +0.0012 cm from the square (RVO2 +0.00); between pedestrians +1.03, +4.10 and
    # -1.07 cm (RVO2 +1.03, +4.10, +0.28: at 130 cm/s a pedestrian moves 32 cm per step, and RVO2's pedestrians
    # overlap by up to 10.9 cm with the ring turned by 5 degrees either way)
    assert f.polygon_gap >= 0.0
    assert f.pair_gap >= pair_gap
    goals = np.array([b for _, b in scenes.ring_positions()])
    assert (np.hypot(*(traj[-1] - goals).T) <= 30.0).sum() >= 7


def test_a_pedestrian_walking_into_a_concave_corner_stops_there():
    # an L-shaped block; the pedestrian walks diagonally into its inner (reflex) corner at (300, 300)
    l_shape = [(100.0, 100.0), (600.0, 100.0), (600.0, 300.0), (300.0, 300.0), (300.0, 600.0), (100.0, 600.0)]
    s = scenes._scenario((0, 0, 1000, 1000), l_shape,
                         [{"id": "p", "radius": 20, "start": [600, 600], "velocity": [-40, -40], "model": "orca"}],
                         (800.0, 100.0))
    traj = scenes.run(s, 30.0)
    f = scenes.figures(traj, l_shape)
    assert f.polygon_gap >= 0.0
    # it ends in the corner, 20 cm (its radius) from both of the corner's edges: measured 0.64 cm short of that
    # after 30 s (the cut-off lets it close 1/20 of the gap per 0.25 s step), straight on the diagonal
    assert traj[-1, 0] == pytest.approx([320.0, 320.0], abs=1.0)
    assert traj[-1, 0, 0] == traj[-1, 0, 1]
    assert shapely.Polygon(l_shape).distance(shapely.Point(traj[-1, 0])) < 21.0


# -- against RVO2 ------------------------------------------------------------------------------------------


def test_one_step_agrees_with_rvo2_where_its_kd_tree_splits_no_edge():
    """One pedestrian, one step, against RVO2 (pyrvo, when installed; not a dependency): a room's walls alone,
    where RVO2's obstacle tree splits no edge (a split adds a collinear vertex RVO2 calls convex, and its lines
    then differ from the edge's; so does its order of equally near edges). The velocities agree to float32."""
    pytest.importorskip("pyrvo")
    differences = scenes.rvo2_step_differences((), 300)
    assert differences.max() < 1e-3, differences.max()  # measured 1.1e-5 cm/s over 3000 such steps
