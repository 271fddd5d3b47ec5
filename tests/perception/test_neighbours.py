"""What stands around the target: everything near it but itself, from a frame that shows it all."""

from __future__ import annotations

import dataclasses

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Box
from pickdemo.perception import PerceptionParams, PoseEstimate, TargetModel, neighbour_points, with_neighbours
from tests.raycast import Block, render

CUBE = TargetModel(Box((0.05, 0.05, 0.05)), (0.85, 0.1, 0.1))


def _estimate(xy: tuple[float, float]) -> PoseEstimate:
    return PoseEstimate(
        Pose.from_xyz_rpy([*xy, 0.025]), np.eye(3) * 1e-8, np.eye(3) * 1e-6, np.pi / 2, (0.05, 0.05), 0, 0
    )


def test_a_carton_flush_against_the_cube_is_its_neighbour_and_the_cube_is_not() -> None:
    cube = Block((0.5, 0.0), (0.05, 0.05, 0.05), rgb=(217, 25, 25))
    carton = Block((0.5, 0.055), (0.06, 0.06, 0.07), rgb=(60, 90, 200))  # touching the cube's +y face
    frame = render([cube, carton], noise=0.0015)
    pts = neighbour_points(frame, _estimate((0.5, 0.0)), CUBE, PerceptionParams())
    assert pts is not None and len(pts) > 100
    assert np.all(pts[:, 1] > 0.025)  # the carton's side of the cube's face, never the cube
    assert np.max(pts[:, 2]) > 0.06  # its top, above the cube's
    alone = neighbour_points(render([cube], noise=0.0015), _estimate((0.5, 0.0)), CUBE, PerceptionParams())
    assert alone is not None and len(alone) == 0  # nothing but the cube and the table


def test_a_frame_of_the_target_alone_says_nothing_of_its_neighbours() -> None:
    frame = render([Block((0.5, 0.0), (0.05, 0.05, 0.05), rgb=(217, 25, 25))])
    x0, y0, x1, y1 = 140, 100, 180, 140  # a region of interest about the target only
    K = frame.intrinsics
    crop = dataclasses.replace(
        frame,
        rgb=frame.rgb[y0:y1, x0:x1],
        depth_m=frame.depth_m[y0:y1, x0:x1],
        intrinsics=dataclasses.replace(K, width=x1 - x0, height=y1 - y0, cx=K.cx - x0, cy=K.cy - y0),
    )
    est = _estimate((0.5, 0.0))
    assert neighbour_points(crop, est, CUBE, PerceptionParams()) is None
    assert with_neighbours(crop, est, CUBE).neighbours is None
    assert with_neighbours(frame, est, CUBE).neighbours is not None
