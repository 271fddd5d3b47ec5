"""Grasps under a shelf's board (no simulator): the kiva shelf's boxes, read from its file; a box
standing in its middle bin is grasped level from the front with the open hand clear of every board,
lip and divider; lifted only as far as the board above allows, then taken back out the way the hand
came in, far enough for the hand and the object to rise freely."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, boxes_meet
from pickdemo.grasping.antipodal import AntipodalGrasp, by_tilt_in_turns, sample_antipodal
from pickdemo.grasping.clearance import hand_boxes, near
from pickdemo.grasping.side_plans import OUT_MARGIN_M, out_direction, way_out
from pickdemo.grasping.top_down import GraspParams
from pickdemo.robot import robot_named
from pickdemo.scenario.fixtures import ModelSpec

GRIPPER = robot_named().gripper
SHELF = ModelSpec(kind="model", name="shelf", file="pybullet_data:kiva_shelf/model.sdf", position=(0.0, 0.9, -0.75))
BOARD_TOP = SHELF.support_z(0.0, 0.57, 0.1)


def seen_box(centre: np.ndarray, size: tuple[float, float, float]) -> np.ndarray:
    """Points 2 mm apart on what a camera in front, to the right and above sees of an upright box: its
    front (-y), its right side (+x) and its top."""
    hx, hy, hz = (s / 2.0 for s in size)
    g = lambda a: np.arange(-a, a + 1e-9, 0.002)  # noqa: E731
    out = []
    for u in g(hx):  # front and top
        out += [[u, -hy, v] for v in g(hz)]
        out += [[u, v, hz] for v in g(hy)]
    for u in g(hy):  # right side
        out += [[hx, u, v] for v in g(hz)]
    return np.array(out) + centre


def test_the_shelf_is_read_as_its_collision_boxes() -> None:
    boxes = SHELF.boxes()
    assert len(boxes) == 21
    assert abs(BOARD_TOP - (0.814 - 0.75)) < 1e-3  # the middle row's board, the floor 0.75 m below the table
    # the board above the middle bin, 23 cm higher, is over what stands there
    assert abs(SHELF.support_z(0.0, 0.57, 1.0) - BOARD_TOP) > 0.2


def test_a_box_in_the_bin_is_grasped_level_from_the_front_clear_of_the_shelf() -> None:
    size = (0.05, 0.05, 0.11)
    centre = np.array([0.0, 0.58, BOARD_TOP + size[2] / 2.0])
    cloud = seen_box(centre, size)
    fixtures = near(SHELF.boxes(), centre, 0.5)
    params = GraspParams()
    grasps = sample_antipodal(cloud, BOARD_TOP, GRIPPER, np.random.default_rng(0), grasp=params, fixtures=fixtures)
    assert grasps, "no grasp of a 5 cm box in a 29 cm bin"
    for g in grasps[:5]:
        approach = g.rotation[:, 2]
        assert approach[1] > 0.8 and abs(approach[2]) < 0.6  # in from the front, level or nearly
        opening = GRIPPER.finger_max_m if g.open_m is None else g.open_m
        hand = hand_boxes(Pose(g.position, g.rotation), GRIPPER, opening, params.pregrasp_height_m)
        assert not boxes_meet(list(hand), fixtures)
        assert abs(g.width_m - 0.05) < 0.01
    # taken out: lifted under the board above, then back along the approach past the lip
    g = grasps[0]
    held = (cloud.min(axis=0), cloud.max(axis=0))
    out = way_out(g, held, GRIPPER, params, fixtures)
    assert out is not None
    lift, back = out
    assert 0.015 <= lift < params.transport_height_m and back >= params.pregrasp_height_m
    far_y = held[1][1] - g.rotation[1, 2] * back
    assert far_y < 0.9 - 0.439  # the object wholly in front of the shelf's face (its lip's front)


def test_nothing_over_the_object_no_level_grasp() -> None:
    """On an open table, the hand comes from above: rolled at most 60 deg from its most downward
    approach (more only where a corner's normal tilts the closing axis), never level."""
    size = (0.05, 0.05, 0.11)
    centre = np.array([0.5, 0.0, size[2] / 2.0])
    grasps = sample_antipodal(seen_box(centre, size), 0.0, GRIPPER, np.random.default_rng(0))
    assert grasps and max(np.degrees(g.tilt_rad) for g in grasps) < 75.0


def test_under_a_board_high_enough_to_lift_it_the_hand_still_backs_out_before_it_rises() -> None:
    """A board 30 cm over the table: lifted its full 12 cm, the hand would still be under it, where the
    arm would have to find its own way out between the boards: it backs out first."""
    size = (0.05, 0.05, 0.11)
    centre = np.array([0.0, 0.6, size[2] / 2.0])
    board = OrientedBox(
        Pose(np.array([0.0, 0.7, 0.31]), np.eye(3)), np.array([-0.4, -0.2, -0.01]), np.array([0.4, 0.2, 0.01])
    )
    cloud = seen_box(centre, size)
    params = GraspParams()
    grasps = sample_antipodal(cloud, 0.0, GRIPPER, np.random.default_rng(0), grasp=params, fixtures=(board,))
    level = [g for g in grasps if g.rotation[1, 2] > 0.8]
    assert level, "no grasp from the front"
    held = (cloud.min(axis=0), cloud.max(axis=0))
    out = way_out(level[0], held, GRIPPER, params, (board,))
    assert out is not None
    lift, back = out
    assert back > 0.0
    assert held[1][1] - out_direction(level[0].rotation)[1] * back < 0.5 - OUT_MARGIN_M  # (before the board's edge)


def test_among_fixtures_the_grasps_come_the_best_of_each_tilt_in_turn() -> None:
    def grasp(tilt_deg: float, cost: float) -> AntipodalGrasp:
        t = np.radians(tilt_deg)
        z = np.array([np.sin(t), 0.0, -np.cos(t)])
        y = np.array([0.0, 1.0, 0.0])
        return AntipodalGrasp(np.zeros(3), np.column_stack([np.cross(y, z), y, z]), 0.05, cost)

    ranked = [(grasp(75.0, 1.0 + 0.01 * k), (0.1, 0.0)) for k in range(30)] + [(grasp(90.0, 2.0), (0.1, 0.0))]
    turns = by_tilt_in_turns(ranked)
    assert sorted(id(g) for g, _ in turns) == sorted(id(g) for g, _ in ranked)  # (the same, reordered)
    assert [round(np.degrees(g.tilt_rad)) for g, _ in turns[:3]] == [75, 90, 75]  # (the level one within 24)
