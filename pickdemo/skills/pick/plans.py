"""Grasp plans turned, moved and raised: the same plan with the hand turned half a turn (a parallel
gripper's equivalent), put down elsewhere, and a selector whose plans let go higher (over a tray's rim)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose, about_vertical
from pickdemo.grasping.selection import GraspRequest, GraspSelector
from pickdemo.grasping.top_down import GraspPlan, top_down
from pickdemo.motion.online import hand_frame

#: A hand turned half a turn about its own approach axis (z): a parallel gripper's equivalent.
ABOUT_APPROACH = np.diag([-1.0, -1.0, 1.0])


def half_turn(pose: Pose, shift: np.ndarray | None = None) -> Pose:
    """A TCP pose turned half a turn about its approach axis, a parallel gripper's equivalent (moved by
    ``shift``, m): for a top-down pose, about the vertical."""
    at = pose.position if shift is None else pose.position + shift
    if hand_frame(pose.rotation) is not None:  # a grasp from the side
        return Pose(at, pose.rotation @ ABOUT_APPROACH)
    return top_down(at, float(pose.rpy[2]) + np.pi)


#: A half turn about the vertical.
ABOUT_VERTICAL = np.diag([-1.0, -1.0, 1.0])


def turned_about_vertical(pose: Pose, centre_xy: np.ndarray, angle_rad: float | None = None) -> Pose:
    """A TCP pose turned half a turn (or ``angle_rad``) about the vertical through ``centre_xy`` (m): a
    tilted hand holding an object there, turned so, holds it upright still (turned about its approach, it
    would turn the object over)."""
    c = np.array([centre_xy[0], centre_xy[1], 0.0])
    rz = ABOUT_VERTICAL if angle_rad is None else about_vertical(angle_rad)
    return Pose(c + rz @ (pose.position - c), rz @ pose.rotation)


def turned_place(plan: GraspPlan, angle_rad: float) -> GraspPlan:
    """The plan with the held object put down turned ``angle_rad`` about its own vertical (the hand
    turned with it about the object's centre over the place, which stays where it was)."""
    ox, oy = plan.place_offset_xy
    centre = plan.place.position[:2] - np.array([ox, oy])
    off = about_vertical(angle_rad)[:2, :2] @ np.array([ox, oy])
    return dataclasses.replace(
        plan,
        place_above=turned_about_vertical(plan.place_above, centre, angle_rad),
        place=turned_about_vertical(plan.place, centre, angle_rad),
        retreat=turned_about_vertical(plan.retreat, centre, angle_rad),
        place_offset_xy=(float(off[0]), float(off[1])),
    )


def moved_place(plan: GraspPlan, dxy: tuple[float, float]) -> GraspPlan:
    """The plan put down ``dxy`` (m, across the table) from where it was to be put down."""
    d = np.array([dxy[0], dxy[1], 0.0])
    return dataclasses.replace(
        plan,
        place_above=Pose(plan.place_above.position + d, plan.place_above.rotation),
        place=Pose(plan.place.position + d, plan.place.rotation),
        retreat=Pose(plan.retreat.position + d, plan.retreat.rotation),
    )


def turned_plan(plan: GraspPlan, *, pick: bool, place: bool) -> GraspPlan:
    """The plan with the hand turned half a turn for the pick's poses, the place's, or both. The place
    turned and not the pick turns the held object with the hand: its centre, not the TCP, stays over
    the place (the TCP moves to the other side of it)."""
    turn: dict[str, object] = {}
    if pick:
        turn.update(pregrasp=half_turn(plan.pregrasp), grasp=half_turn(plan.grasp), lift=half_turn(plan.lift))
        if plan.withdraw is not None:
            turn["withdraw"] = half_turn(plan.withdraw)
    if place and hand_frame(plan.place.rotation) is not None and not pick:  # tilted: about the object's vertical
        ox, oy = plan.place_offset_xy
        centre = plan.place.position[:2] - np.array([ox, oy])
        turn.update(
            place_above=turned_about_vertical(plan.place_above, centre),
            place=turned_about_vertical(plan.place, centre),
            retreat=turned_about_vertical(plan.retreat, centre),
            place_offset_xy=(-ox, -oy),
        )
    elif place:
        ox, oy = plan.place_offset_xy
        shift = np.array([-2.0 * ox, -2.0 * oy, 0.0]) if not pick else np.zeros(3)
        turn.update(
            place_above=half_turn(plan.place_above, shift),
            place=half_turn(plan.place, shift),
            retreat=half_turn(plan.retreat, shift),
        )
        if not pick:
            turn["place_offset_xy"] = (-ox, -oy)
    hand = plan.hand_yaw_rad + np.pi if pick else plan.hand_yaw_rad
    return dataclasses.replace(plan, hand_yaw_rad=float(hand), **turn)


@dataclass
class PlacedHigher:
    """A :class:`~pickdemo.grasping.selection.GraspSelector` whose plans let go of the target ``dz_m``
    higher (its bottom that far above the table: over a tray's rim, to drop in); ``from_carry``: at
    least as high as it is carried (no lowering)."""

    inner: GraspSelector
    dz_m: float
    from_carry: bool = False

    def hand_yaws(self, request: GraspRequest) -> list[float]:
        return self.inner.hand_yaws(request)

    def candidates(self, request: GraspRequest):  # noqa: ANN201 - an iterator of GraspPlan
        up = np.array([0.0, 0.0, self.dz_m])
        for plan in self.inner.candidates(request):
            place = Pose(plan.place.position + up, plan.place.rotation)
            if self.from_carry:
                z = max(float(plan.lift.position[2]), float(place.position[2]))
                place = Pose(np.array([*place.position[:2], z]), place.rotation)
                z_above = z
            else:
                z_above = max(float(plan.place_above.position[2]), float(place.position[2]) + 0.05)
            above = Pose(np.array([*place.position[:2], z_above]), plan.place_above.rotation)
            retreat = Pose(plan.retreat.position + up, plan.retreat.rotation)
            yield dataclasses.replace(plan, place=place, place_above=above, retreat=retreat)
