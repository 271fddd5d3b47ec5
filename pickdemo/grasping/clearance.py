"""The open hand against the cell's fixtures: the volume the fingers and the hand sweep on their way
in along a grasp's approach, as boxes, tested against a fixture's boxes (a shelf's boards, a bin's
walls) by the separating axis test.

Pure: no simulator. A fixture is known from the task as boxes (:mod:`pickdemo.scenario.fixtures`), so
the test is exact for it; what the camera sees beside the target is tested as points by each grasp
family. The hand frame is the TCP's (``z`` the approach, ``y`` the closing axis); the boxes are the
same the point checks use (:mod:`pickdemo.grasping.antipodal`): the fingers open ``opening_m`` each
with everything between them, and the hand's body behind the palm, each swept ``back_m`` back along
the approach (from the pregrasp).
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, boxes_meet
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.robot.description import Gripper

#: The hand's body behind the palm, along the approach (m): what lies farther back is the wrist's.
HAND_DEPTH_M = 0.12
#: The wrist behind the hand's body, along the approach (m), twice as wide each way as the palm is
#: thick: the arm's last links (a flange, a motor), which follow the hand into a shelf
WRIST_DEPTH_M = 0.15
#: The open hand keeps this far from a fixture (m): the estimate's error and the tracking's.
FIXTURE_CLEARANCE_M = 0.005


def hand_boxes(
    pose: Pose, gripper: Gripper, opening_m: float, back_m: float
) -> tuple[OrientedBox, OrientedBox, OrientedBox]:
    """The open hand at the TCP ``pose`` and everything it passes through coming in ``back_m`` along
    the approach: its fingers (open ``opening_m`` each, and what lies between them), its body, and the
    wrist behind it."""
    c = FIXTURE_CLEARANCE_M
    hw = max(gripper.pad_half_width_m, gripper.finger_thickness_m / 2.0) + c
    outer = opening_m + gripper.finger_thickness_m + c
    palm = gripper.palm_above_tcp_m
    fingers = OrientedBox(
        pose, np.array([-hw, -outer, -palm - back_m]), np.array([hw, outer, gripper.pad_half_height_m + c])
    )
    body = OrientedBox(
        pose,
        np.array([-gripper.palm_half_width_m - c, -gripper.palm_half_length_m - c, -palm - HAND_DEPTH_M - back_m]),
        np.array([gripper.palm_half_width_m + c, gripper.palm_half_length_m + c, -palm]),
    )
    w = 2.0 * gripper.palm_half_width_m + c
    behind = -palm - HAND_DEPTH_M
    wrist = OrientedBox(pose, np.array([-w, -w, behind - back_m - WRIST_DEPTH_M]), np.array([w, w, behind]))
    return fingers, body, wrist


def hand_meets(
    pose: Pose, gripper: Gripper, opening_m: float, back_m: float, fixtures: tuple[OrientedBox, ...]
) -> bool:
    """Whether the open hand coming in to ``pose`` (:func:`hand_boxes`) meets a fixture's box."""
    return bool(fixtures) and boxes_meet(hand_boxes(pose, gripper, opening_m, back_m), fixtures)


def plan_meets(plan: GraspPlan, gripper: Gripper, fixtures: tuple[OrientedBox, ...]) -> bool:
    """Whether the hand of this plan, open as it goes in, meets a fixture from its pregrasp to its grasp."""
    if not fixtures:
        return False
    back = float(np.linalg.norm(plan.pregrasp.position - plan.grasp.position))
    opening = gripper.finger_max_m if plan.open_m is None else plan.open_m
    return hand_meets(plan.grasp, gripper, opening, back, fixtures)


def near(fixtures: tuple[OrientedBox, ...], at: np.ndarray, radius_m: float) -> tuple[OrientedBox, ...]:
    """The fixtures' boxes that come within ``radius_m`` of the point ``at`` (a target's centre)."""
    out = []
    for box in fixtures:
        local = (np.asarray(at, dtype=float) - box.pose.position) @ box.pose.rotation
        if np.linalg.norm(local - np.clip(local, box.lo, box.hi)) <= radius_m:
            out.append(box)
    return tuple(out)
