"""Grasps of a described target beside something else: the open hand keeps out of its points."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Box
from pickdemo.grasping.selection import GraspRequest, TopDownFaceGrasps
from pickdemo.grasping.top_down import GraspPlanningError
from pickdemo.perception import TargetModel
from pickdemo.robot import robot_named

GRIPPER = robot_named().gripper
CUBE = TargetModel(Box((0.05, 0.05, 0.05)), (1.0, 0.0, 0.0))


def _wall(x0: float, height: float, width_y: float = 0.12, depth_x: float = 0.06) -> np.ndarray:
    """Points of a carton's top and near face, standing from x0 on (its face at x = x0)."""
    ys = np.linspace(-width_y / 2, width_y / 2, 25)
    top = [[x, y, height] for x in np.linspace(x0, x0 + depth_x, 13) for y in ys]
    face = [[x0, y, z] for z in np.linspace(0.01, height, 10) for y in ys]
    return np.array(top + face)


def _request(model: TargetModel, obstacles: np.ndarray | None, yaw_deg: float = 0.0) -> GraspRequest:
    pose = Pose.from_xyz_rpy([0.0, 0.0, model.height_m / 2], yaw=np.radians(yaw_deg))
    return GraspRequest(pose, model, (0.4, 0.3), obstacles=obstacles, gripper=GRIPPER)


def _closing_axis(psi: float) -> np.ndarray:
    return np.array([np.sin(psi), -np.cos(psi)])


@pytest.mark.parametrize("yaw_deg", [0.0, 30.0, -40.0])
def test_a_flush_neighbour_leaves_only_the_faces_beside_it(yaw_deg: float) -> None:
    """A carton flush against the cube's +x face (in the world): the fingers never close along x
    (one would come down on the carton), and nothing is lost without it."""
    c = np.cos(np.radians(yaw_deg))
    s = np.sin(np.radians(yaw_deg))
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    wall = _wall(0.025, 0.045) @ rot.T  # turned with the cube: flush against its face
    selector = TopDownFaceGrasps()
    free = selector.hand_yaws(_request(CUBE, None, yaw_deg))
    beside = selector.hand_yaws(_request(CUBE, wall, yaw_deg))
    assert len(free) == 4 and len(beside) == 2
    toward = rot[:2, 0]  # from the cube to the carton
    for psi in beside:
        assert abs(_closing_axis(psi) @ toward) < 1e-6
        plan = next(selector.candidates(_request(CUBE, wall, yaw_deg)))
        assert abs(_closing_axis(plan.hand_yaw_rad) @ toward) < 1e-6


def test_a_neighbour_taller_than_the_palm_raises_the_grasp_or_leaves_none() -> None:
    selector = TopDownFaceGrasps()
    low = next(selector.candidates(_request(CUBE, None)))
    raised = next(selector.candidates(_request(CUBE, _wall(0.025, 0.065))))
    assert raised.grasp.position[2] > low.grasp.position[2] + 0.005  # the palm clears its top
    assert raised.grasp.position[2] <= 0.05 - 0.009  # ... with the pads still wholly on the cube
    with pytest.raises(GraspPlanningError, match="beside the target"):
        next(selector.candidates(_request(CUBE, _wall(0.025, 0.12))))


def test_a_box_blocked_on_its_narrow_sides_is_taken_by_its_wide_ones() -> None:
    box = TargetModel(Box((0.03, 0.06, 0.05)), (1.0, 0.0, 0.0))  # narrow along x: closed along x
    selector = TopDownFaceGrasps()
    plan = next(selector.candidates(_request(box, _wall(0.015, 0.045))))
    assert abs(_closing_axis(plan.hand_yaw_rad) @ [0.0, 1.0]) > 1 - 1e-6  # closed along y instead
    assert plan.object_width_m == pytest.approx(0.06)


def test_a_grasp_rises_past_a_taller_neighbour_with_half_the_pads_on_the_target() -> None:
    """A 5 cm cube with a box 2.3 cm taller flush against its +x face (its top seen at 72.5 mm): the
    palm must pass over the box, which a grasp with the whole pads on the cube cannot (issue 58)."""
    import dataclasses as _dc

    import numpy as _np

    from pickdemo.core.geometry import Pose as _Pose
    from pickdemo.core.shapes import Box as _Box
    from pickdemo.grasping.selection import GraspRequest, TopDownFaceGrasps
    from pickdemo.grasping.top_down import GraspParams, GraspPlanningError
    from pickdemo.perception import TargetModel as _Model
    from pickdemo.robot import robot_named as _robot

    cube = _Model(_Box((0.05, 0.05, 0.05)), (0.85, 0.1, 0.1))
    xs, ys = _np.meshgrid(_np.linspace(0.5255, 0.585, 20), _np.linspace(-0.05, 0.05, 30))
    box_top = _np.column_stack([xs.ravel(), ys.ravel(), _np.full(xs.size, 0.0725)])
    request = GraspRequest(_Pose.from_xyz_rpy([0.5, 0.0, 0.025]), cube, (0.45, 0.3), obstacles=box_top,
                           gripper=_robot("panda").gripper)  # fmt: skip
    (plan,) = list(TopDownFaceGrasps().candidates(request))
    palm = plan.grasp.position[2] + _robot("panda").gripper.palm_above_tcp_m
    assert palm > 0.0725 and plan.grasp.position[2] <= 0.05 + 1e-9  # over the box, pads still on the cube
    whole = TopDownFaceGrasps(_dc.replace(GraspParams(), min_pad_on_target=1.0))
    with pytest.raises(GraspPlanningError):
        list(whole.candidates(request))
