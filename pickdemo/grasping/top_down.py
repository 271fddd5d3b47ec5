"""Grasp planning: a top-down parallel-jaw grasp from the pose estimate, with the poses around it.

Pure: no simulator. The hand's fingers close along its y axis; a top-down TCP orientation is
``Rz(psi) Rx(pi)``, whose y axis points along ``(sin psi, -cos psi, 0)``. The grasp closes across
the object's narrower side. The hand is symmetric under a half turn and a square box under a quarter
turn, so a grasp has several equivalent hand angles (:func:`equivalent_hand_yaws`; a cylinder's is
free). Which of them the arm takes is the skill's choice, by IK (:mod:`pickdemo.skills.pick`): this module
knows nothing of the robot's joints.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose, wrap_angle
from pickdemo.core.shapes import Box
from pickdemo.perception import TargetModel
from pickdemo.robot.description import Gripper


class GraspPlanningError(RuntimeError):
    """No feasible grasp for this estimate (for example an object wider than the open gripper)."""


@dataclass(frozen=True)
class GraspParams:
    """Distances in m."""

    pregrasp_height_m: float = 0.10  # above the grasp, for a straight vertical approach
    transport_height_m: float = 0.12  # lift above the grasp height before moving sideways
    palm_clearance_m: float = 0.005  # the palm stays this far above the top face
    min_tcp_height_m: float = 0.012  # keeps the finger tips off the table
    place_clearance_m: float = 0.004  # release this far above the table
    retreat_height_m: float = 0.10
    #: the open gripper must exceed the object by this much: 2.5 mm a side, for the estimate's error
    #: (sub-millimetre when the whole top face is seen) and the arm's tracking (under a millimetre)
    width_margin_m: float = 0.005
    #: the open hand keeps this far from the points of anything beside the target (m) ...
    neighbour_clearance_m: float = 0.004
    #: ... so many of them at least (a speck of depth noise, or a pixel of the arm's edge, is not a neighbour)
    neighbour_min_points: int = 5
    #: a grasp whose hand would meet something beside the target is tried this much higher, step by
    #: step (m)
    raise_step_m: float = 0.003
    #: ... up to where this share of the pads' height stays on the target's side
    min_pad_on_target: float = 0.5

    def __post_init__(self) -> None:
        if min(self.pregrasp_height_m, self.transport_height_m, self.retreat_height_m) <= 0:
            raise ValueError("heights must be positive")


@dataclass(frozen=True)
class GraspPlan:
    """TCP poses of a pick and place, all top-down, in the world frame."""

    pregrasp: Pose
    grasp: Pose
    lift: Pose
    place_above: Pose
    place: Pose
    retreat: Pose
    object_width_m: float  # expected width between the fingers when closed on the object
    hand_yaw_rad: float
    #: the TCP from the object's centre when it is put down (m, world x and y): the centre, not the
    #: hand, goes to the place (zero when the grasp is through the centre)
    place_offset_xy: tuple[float, float] = (0.0, 0.0)
    #: the object's width between the fingers is known (a described shape): a close that stops wider
    #: than ``object_width_m`` by the grip's ``wide_margin_m`` held it askew, or held something else too
    width_known: bool = False
    #: the share of a pad's area on the object's face (a box face smaller than the pad): the fingers
    #: squeeze it with that share of the grip force, as hard per area as a whole pad would (measured:
    #: a 15 mm, 10 g cube squeezed at the full 20 N turned between the pads in 25 of 50 first grasps)
    pad_share: float = 1.0
    #: each finger's opening from the middle on the way in (m; None: wide open): a grasp whose wide-open
    #: fingers would meet a wall or a neighbour opens only as far as it needs
    open_m: float | None = None
    #: lifted (to ``lift``) under something (a shelf's board), the hand takes the target back out along its
    #: approach to here before it carries it (None: from the lift straight on)
    withdraw: Pose | None = None


def top_down(position: np.ndarray, yaw_rad: float) -> Pose:
    """A TCP pose pointing straight down, rotated ``yaw_rad`` about world z."""
    return Pose.from_xyz_rpy(position, roll=np.pi, yaw=yaw_rad)


def hand_yaw_for(pose: Pose, model: TargetModel, centre_rad: float = 0.0) -> tuple[float, float]:
    """Hand angle (rad) that closes across the narrower side, nearest ``centre_rad``; the width (m)."""
    shape = model.geometry
    period = shape.yaw_symmetry_rad
    if period == 0.0:  # the same from every side (a cylinder): the hand angle is free
        return float(centre_rad), shape.grasp_width_m
    obj_yaw = float(pose.rpy[2])
    sx, sy = shape.size[0], shape.size[1]
    # Finger axis along the object's x axis when x is the narrower side, else along its y axis.
    psi = obj_yaw + np.pi / 2.0 if sx <= sy else obj_yaw
    return float(centre_rad + wrap_angle(psi - centre_rad, period)), shape.grasp_width_m


def equivalent_hand_yaws(pose: Pose, model: TargetModel, free_steps: int = 8) -> list[float]:
    """Every hand angle (rad, wrapped to [-pi, pi)) that closes across the target's narrower side:
    its symmetry with the hand's own half turn (2 for a box, 4 for a square top); for a shape with no
    yaw (a cylinder) ``free_steps`` angles evenly round."""
    period = model.geometry.yaw_symmetry_rad
    if period == 0.0:
        return [float(wrap_angle(-np.pi + 2.0 * np.pi * k / free_steps)) for k in range(free_steps)]
    psi0, _ = hand_yaw_for(pose, model, 0.0)
    step = min(period, np.pi)
    n = int(round(2.0 * np.pi / step))
    return [float(wrap_angle(psi0 + k * step)) for k in range(n)]


def plan_grasp(
    pose: Pose,
    model: TargetModel,
    place_xy: tuple[float, float],
    params: GraspParams | None = None,
    *,
    gripper: Gripper,
    hand_yaw_near_rad: float | None = None,
    wide: bool = False,
    raise_m: float = 0.0,
) -> GraspPlan:
    """All TCP poses of the pick and place from the estimated pose of the target, for this ``gripper``.

    ``hand_yaw_near_rad``: of the equivalent hand angles, take the one nearest this (the skill chooses
    it; a re-plan keeps the hand's angle); by default the one nearest 0. ``wide``: a box closed across
    its wider side (its narrower one is blocked); ``raise_m``: the grasp this much above where the
    pads would close (something beside the target stands higher than the palm would be).
    """
    params = params or GraspParams()
    centre = 0.0 if hand_yaw_near_rad is None else hand_yaw_near_rad
    if wide:  # the wider side's angle: a quarter turn from the narrower one's
        psi, _ = hand_yaw_for(pose, model, centre - np.pi / 2.0)
        psi, width = psi + np.pi / 2.0, max(model.geometry.top_extents_m)
    else:
        psi, width = hand_yaw_for(pose, model, centre)
    opening = gripper.max_opening_m
    if width > opening - params.width_margin_m:
        raise GraspPlanningError(
            f"object is {width * 1e3:.0f} mm across its narrower side; the gripper opens to "
            f"{opening * 1e3:.0f} mm and needs {params.width_margin_m * 1e3:.0f} mm of clearance, "
            f"so at most {(opening - params.width_margin_m) * 1e3:.0f} mm"
        )
    center = pose.position
    top_z = center[2] + model.height_m / 2.0
    # The pads close through the centre of mass (a held payload has no lever to turn on about the
    # finger axis), or as deep as the palm allows on a taller object.
    depth = min(model.height_m / 2.0, gripper.palm_above_tcp_m - params.palm_clearance_m)
    grasp_z = max(top_z - depth, params.min_tcp_height_m) + raise_m
    bottom_z = center[2] - model.height_m / 2.0
    grasp_above_bottom = grasp_z - bottom_z

    grasp_p = np.array([center[0], center[1], grasp_z])
    shift = tcp_shift(gripper, float(width), psi)
    if shift is None:
        plan = poses_of_pick(grasp_p, psi, grasp_above_bottom, float(width), place_xy, params)
    else:  # a jaw: the TCP (the fixed jaw's face) beside the object; the object's centre goes to the place
        grasp_p = grasp_p + shift
        held = tcp_shift(gripper, float(width), psi, held=True)
        plan = poses_of_pick(grasp_p, psi, grasp_above_bottom, float(width), place_xy, params, (held[0], held[1]))
    share = 1.0
    if isinstance(model.geometry, Box):  # flat faces: the pads' area on them
        along = sum(model.geometry.top_extents_m) - width  # the face's length along the pads
        half_h, half_w = gripper.pad_half_height_m, gripper.pad_half_width_m
        low, high = grasp_z - half_h, grasp_z + half_h
        tall = max(0.0, min(high, top_z) - max(low, bottom_z))
        share = min(1.0, along / (2.0 * half_w)) * min(1.0, tall / (2.0 * half_h))
        share = 1.0 if share > 1.0 - 1e-6 else share  # (a whole pad, whatever the rounding)
    return dataclasses.replace(plan, width_known=True, pad_share=share)


def tcp_shift(gripper: Gripper, width_m: float, psi: float, *, held: bool = False) -> np.ndarray | None:
    """Where the TCP goes from the grasp's centre (world, m) with the hand at angle ``psi``: None for
    fingers closing about the middle; a jaw's fixed face beside the object (:meth:`Gripper.tcp_offset_m`),
    or, ``held``, against it once closed (:meth:`Gripper.held_offset_m`)."""
    off = gripper.held_offset_m(width_m) if held else gripper.tcp_offset_m(width_m)
    if off == 0.0:
        return None
    return top_down(np.zeros(3), psi).rotation[:, 1] * off


def poses_of_pick(
    grasp_p: np.ndarray,
    psi: float,
    grasp_above_bottom: float,
    width: float,
    place_xy: tuple[float, float],
    params: GraspParams,
    place_offset_xy: tuple[float, float] = (0.0, 0.0),
) -> GraspPlan:
    """Every TCP pose of a top-down pick and place from its grasp: the TCP at ``grasp_p`` with the hand
    angle ``psi``, ``grasp_above_bottom`` above what the object rests on; put down with the object's
    centre over ``place_xy`` (the TCP ``place_offset_xy`` from it) at that height over the table."""
    grasp_z = float(grasp_p[2])
    up = np.array([0.0, 0.0, 1.0])
    place_p = np.array(
        [
            place_xy[0] + place_offset_xy[0],
            place_xy[1] + place_offset_xy[1],
            grasp_above_bottom + params.place_clearance_m,
        ]
    )
    carry_z = grasp_z + params.transport_height_m
    return GraspPlan(
        pregrasp=top_down(grasp_p + params.pregrasp_height_m * up, psi),
        grasp=top_down(grasp_p, psi),
        lift=top_down(np.array([grasp_p[0], grasp_p[1], carry_z]), psi),
        place_above=top_down(np.array([place_p[0], place_p[1], max(carry_z, place_p[2] + 0.05)]), psi),
        place=top_down(place_p, psi),
        retreat=top_down(place_p + params.retreat_height_m * up, psi),
        object_width_m=float(width),
        hand_yaw_rad=psi,
        place_offset_xy=(float(place_offset_xy[0]), float(place_offset_xy[1])),
    )
