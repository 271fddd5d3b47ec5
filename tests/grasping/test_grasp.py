"""Grasp planning: across the narrower side, the equivalent hand angles, the gripper's width."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Box
from pickdemo.grasping.top_down import GraspPlanningError, hand_yaw_for, plan_grasp
from pickdemo.perception import TargetModel
from pickdemo.robot import robot_named

ROBOT = robot_named()


def _estimate(yaw_deg: float, z: float = 0.025) -> Pose:
    return Pose.from_xyz_rpy([0.5, 0.0, z], yaw=np.radians(yaw_deg))


def _finger_axis(psi: float) -> np.ndarray:
    return np.array([np.sin(psi), -np.cos(psi)])  # the hand's y axis for Rz(psi) Rx(pi)


@pytest.mark.parametrize("yaw_deg", [-80.0, -30.0, 0.0, 25.0, 60.0, 89.0])
def test_closes_across_the_narrow_side(yaw_deg: float) -> None:
    model = TargetModel(Box((0.06, 0.03, 0.04)), (1.0, 0.0, 0.0))  # narrow along the object's y
    psi, width = hand_yaw_for(_estimate(yaw_deg), model)
    obj_y = np.array([-np.sin(np.radians(yaw_deg)), np.cos(np.radians(yaw_deg))])
    assert abs(abs(_finger_axis(psi) @ obj_y) - 1.0) < 1e-9
    assert width == 0.03
    assert abs(psi) <= np.pi / 2 + 1e-9  # centred on 0 when no centre is given


def test_square_box_uses_quarter_turn_symmetry() -> None:
    model = TargetModel(Box((0.05, 0.05, 0.05)), (1.0, 0.0, 0.0))
    psi, _ = hand_yaw_for(_estimate(80.0), model)
    assert abs(psi) <= np.pi / 4 + 1e-9


def test_a_box_has_two_hand_angles_a_square_top_four_a_cylinder_any() -> None:
    from pickdemo.core.shapes import Cylinder
    from pickdemo.grasping.top_down import equivalent_hand_yaws

    pose = _estimate(20.0)
    box = equivalent_hand_yaws(pose, TargetModel(Box((0.06, 0.03, 0.04)), (1.0, 0.0, 0.0)))
    square = equivalent_hand_yaws(pose, TargetModel(Box((0.05, 0.05, 0.05)), (1.0, 0.0, 0.0)))
    round_ = equivalent_hand_yaws(pose, TargetModel(Cylinder(0.02, 0.06), (1.0, 0.0, 0.0)))
    assert len(box) == 2 and len(square) == 4 and len(round_) == 8
    assert abs(np.cos(box[1] - box[0]) + 1.0) < 1e-9  # half a turn apart
    assert np.allclose(np.diff(sorted(square)), np.pi / 2.0)


def test_plan_heights() -> None:
    model = TargetModel(Box((0.05, 0.05, 0.05)), (1.0, 0.0, 0.0))
    plan = plan_grasp(_estimate(10.0), model, (0.45, 0.3), gripper=ROBOT.gripper)
    assert plan.grasp.position[2] == pytest.approx(0.025)  # 25 mm below the top of a 50 mm cube
    assert plan.pregrasp.position[2] == pytest.approx(0.125)
    assert plan.place.position[:2] == pytest.approx([0.45, 0.3])
    assert plan.place.position[2] == pytest.approx(0.025 + 0.004)
    assert plan.grasp.rotation[2, 2] == pytest.approx(-1.0)


def test_too_wide_for_the_gripper() -> None:
    model = TargetModel(Box((0.09, 0.09, 0.05)), (1.0, 0.0, 0.0))
    with pytest.raises(GraspPlanningError, match="clearance"):
        plan_grasp(_estimate(0.0), model, (0.45, 0.3), gripper=ROBOT.gripper)


def test_hand_yaw_near_keeps_the_hand_angle() -> None:
    model = TargetModel(Box((0.05, 0.05, 0.05)), (1.0, 0.0, 0.0))
    first = plan_grasp(_estimate(44.0), model, (0.45, 0.3), gripper=ROBOT.gripper)
    # The estimate crosses the quarter-turn boundary; the re-plan keeps the hand where it was.
    again = plan_grasp(_estimate(46.0), model, (0.45, 0.3), gripper=ROBOT.gripper, hand_yaw_near_rad=first.hand_yaw_rad)
    assert abs(again.hand_yaw_rad - first.hand_yaw_rad) == pytest.approx(np.radians(2.0))


def test_a_grip_wider_than_a_known_object_is_no_hold_of_it_alone() -> None:
    from pickdemo.core.interfaces import Observation
    from pickdemo.skills.actions import Grip, GripParams

    box = TargetModel(Box((0.05, 0.05, 0.05)), color=(1.0, 0.0, 0.0))
    plan = plan_grasp(_estimate(0.0), box, (0.3, 0.3), gripper=ROBOT.gripper)
    assert plan.width_known and plan.object_width_m == pytest.approx(0.05)
    grip = Grip(GripParams(), 1.0 / 120.0, ROBOT.gripper)

    def at(opening_m: float) -> Observation:
        return Observation(0.0, np.zeros(7), np.zeros(7), np.full(2, opening_m / 2.0), (3, 3))

    assert grip.holding(at(0.050), plan.object_width_m) and not grip.too_wide(at(0.050), plan.object_width_m)
    assert grip.too_wide(at(0.060), plan.object_width_m)  # the 60 mm grip of a 50 mm cube
    assert not grip.too_wide(at(0.057), plan.object_width_m)  # turned a few degrees in the pads: held


def test_a_jaw_lowers_its_fixed_face_beside_the_object_and_puts_the_centre_on_the_place() -> None:
    """One jaw against a fixed one (the SO-101's): the TCP, on the fixed jaw's face, comes down
    ``jaw_clearance_m`` beside the object along the closing axis; the jaw then presses the object to
    it, and the object's centre, not the TCP, goes to the place."""
    jaw = robot_named("so101").gripper
    model = TargetModel(Box((0.025, 0.025, 0.025)), (1.0, 0.0, 0.0))
    pose = Pose.from_xyz_rpy([0.18, 0.02, 0.0125], yaw=np.radians(20.0))
    plan = plan_grasp(pose, model, (0.16, 0.14), gripper=jaw)
    shift = plan.grasp.position[:2] - pose.position[:2]
    y_axis = plan.grasp.rotation[:2, 1]  # the hand's closing axis: from the fixed jaw to the moving one
    assert np.linalg.norm(shift) == pytest.approx(0.0125 + jaw.jaw_clearance_m)
    assert shift @ y_axis == pytest.approx(-(0.0125 + jaw.jaw_clearance_m))
    assert plan.place_offset_xy == pytest.approx(tuple(shift * 0.0125 / np.linalg.norm(shift)))  # (pressed)
    assert plan.place.position[:2] - np.asarray(plan.place_offset_xy) == pytest.approx([0.16, 0.14])
    parallel = plan_grasp(pose, model, (0.16, 0.14), gripper=ROBOT.gripper)
    assert parallel.grasp.position[:2] == pytest.approx(pose.position[:2]) and parallel.place_offset_xy == (0.0, 0.0)
