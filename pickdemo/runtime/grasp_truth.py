"""Whether a grasp the hand can make exists, judged on the truth (the referee's, to score a refusal;
never the robot's): the target's true pose and shape, every other object's true box, the cell's
fixtures, and the hand's boxes (:func:`~pickdemo.grasping.clearance.hand_boxes`: the open fingers,
the hand's body and the wrist, swept back along the approach to the pregrasp).

A grasp is a TCP pose about the target's centre: the hand's angle about the vertical every 5 deg,
its approach tilted 0, 15, 30 or 45 deg away from the vertical (about the closing axis, either way),
and the TCP from where the pads close through the middle up to where half the pads' height is still
on the target's side. It exists when the target's width across the closing axis fits the open hand
with the grasp's margin, the fingers' tips stay above the table, and none of the hand's boxes meets
another object or a fixture. A box or an upright cylinder is judged so; any other shape (a mesh, a
lying can) by its narrowest width alone (``None``: not judged).
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, boxes_meet
from pickdemo.core.shapes import Box, Cylinder
from pickdemo.grasping.clearance import hand_boxes
from pickdemo.grasping.top_down import GraspParams, top_down
from pickdemo.robot.description import Gripper

HAND_YAWS_DEG = np.arange(0.0, 180.0, 5.0)
TILTS_DEG = (0.0, 15.0, -15.0, 30.0, -30.0, 45.0, -45.0)
HEIGHT_STEPS = 8


def true_box(pose: Pose, shape) -> OrientedBox:  # noqa: ANN001 - a Shape
    """An object's box as it stands (a cylinder's circumscribed box; a mesh's bounding box)."""
    if isinstance(shape, Box):
        half = np.asarray(shape.size, dtype=float) / 2.0
    elif isinstance(shape, Cylinder):
        r = shape.size[0] / 2.0
        half = np.array([r, r, shape.size[1] / 2.0])
    else:
        half = np.full(3, shape.bounding_radius_m)
    return OrientedBox(pose, -half, half)


def grasp_exists(
    pose: Pose,
    shape,
    others: list[OrientedBox],
    gripper: Gripper,
    params: GraspParams | None = None,  # noqa: ANN001
) -> bool | None:
    """Whether a grasp of the target (true ``pose`` and ``shape``) the hand can make exists among
    ``others`` (the other objects' and the fixtures' boxes); None: the shape is not judged here."""
    p = params or GraspParams()
    upright = abs(float(pose.rotation[2, 2])) > 0.999
    if not upright or not isinstance(shape, (Box, Cylinder)):
        return None
    R = pose.rotation
    centre = pose.position
    top = float(centre[2]) + shape.height_m / 2.0
    widest = gripper.max_opening_m - p.width_margin_m
    half = np.asarray(shape.size, dtype=float) / 2.0 if isinstance(shape, Box) else None
    z_mid = max(top - min(shape.height_m / 2.0, gripper.palm_above_tcp_m - p.palm_clearance_m), p.min_tcp_height_m)
    z_high = top - (2.0 * p.min_pad_on_target - 1.0) * gripper.pad_half_height_m
    heights = np.linspace(z_mid, max(z_mid, z_high), HEIGHT_STEPS)
    near = [b for b in others if np.linalg.norm(b.pose.position[:2] - centre[:2]) < 0.5]
    for yaw in np.radians(HAND_YAWS_DEG):
        closing = np.array([np.sin(yaw), -np.cos(yaw), 0.0])  # the hand's y at this angle, top-down
        if half is None:
            width = shape.size[0]
        else:
            width = 2.0 * float(np.abs(R[:, :2].T @ closing) @ half[:2])
        if width > widest:
            continue
        opening = min(width / 2.0 + p.width_margin_m, gripper.finger_max_m)
        for tilt in np.radians(TILTS_DEG):
            base = top_down(np.zeros(3), float(yaw)).rotation
            c, s = np.cos(tilt), np.sin(tilt)
            about_y = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])  # about the closing axis
            rot = base @ about_y
            for z in heights:
                grasp = Pose(np.array([centre[0], centre[1], z]), rot)
                tips = grasp.position[2] - gripper.pad_half_height_m * abs(c)
                if tips < p.min_tcp_height_m - gripper.pad_half_height_m:
                    continue
                if not boxes_meet(hand_boxes(grasp, gripper, opening, p.pregrasp_height_m), near):
                    return True
    return False
