"""The referee's judgement of a refusal: whether a grasp the hand can make exists on the truth."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Box
from pickdemo.robot import robot_named
from pickdemo.runtime.grasp_truth import grasp_exists, true_box

CUBE = Box((0.05, 0.05, 0.05))
AT = Pose(np.array([0.5, 0.0, 0.025]), np.eye(3))


def _wall(dx: float, dy: float, height: float) -> object:
    """A box 6 cm deep, 20 cm long and ``height`` tall, flush against the cube's side (dx, dy)."""
    size = (0.06, 0.2, height) if dx else (0.2, 0.06, height)
    centre = np.array([0.5 + dx * 0.0555, dy * 0.0555, height / 2.0])
    return true_box(Pose(centre, np.eye(3)), Box(size))


def test_a_lone_cube_has_a_grasp() -> None:
    assert grasp_exists(AT, CUBE, [], robot_named("panda").gripper) is True


def test_a_cube_flush_against_a_taller_box_has_one_with_the_palm_above_it() -> None:
    assert grasp_exists(AT, CUBE, [_wall(1, 0, 0.07)], robot_named("panda").gripper) is True


def test_a_cube_walled_in_on_all_four_sides_by_tall_boxes_has_none() -> None:
    walls = [_wall(1, 0, 0.3), _wall(-1, 0, 0.3), _wall(0, 1, 0.3), _wall(0, -1, 0.3)]
    assert grasp_exists(AT, CUBE, walls, robot_named("panda").gripper) is False


def test_a_box_wider_than_the_hand_every_way_has_none() -> None:
    assert grasp_exists(AT, Box((0.12, 0.12, 0.05)), [], robot_named("panda").gripper) is False
