"""Grasp selection behind one protocol: what the robot believes of the target in, ranked grasp
candidates out.

Pure: no simulator. The pick skill asks a :class:`GraspSelector` for candidates and takes the first
one the arm can reach; :class:`TopDownFaceGrasps` (a top-down parallel-jaw grasp across the
narrower pair of faces of a known box or cylinder) is one implementation,
:class:`~pickdemo.grasping.cloud.CloudGrasps` (grasps sampled on the point cloud of an object nobody
described) the other; :func:`selector_for` gives each target its own.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Unknown
from pickdemo.grasping.cloud import CloudGrasps
from pickdemo.grasping.top_down import GraspParams, GraspPlan, equivalent_hand_yaws, plan_grasp
from pickdemo.perception import ObjectCloud, TargetModel
from pickdemo.robot.description import Gripper


@dataclass(frozen=True)
class GraspRequest:
    """What a selector is given: the target as the belief has it now, and what the skill prefers."""

    pose: Pose  # the target's pose in the world frame, as the tracker believes it now
    model: TargetModel
    place_xy: tuple[float, float]
    #: hand angles (rad) the skill would like, best first; None: the selector's own choice
    hand_yaws: tuple[float | None, ...] = (None,)
    frame: RGBDFrame | None = None  # the newest frame, for selectors that look at the points themselves
    #: an object nobody described: the newest cloud seen of it
    cloud: ObjectCloud | None = None
    surface_z: float = 0.0  # the height of what the target rests on
    plan_id: int = 0  # the skill's plan this request belongs to (a new one: plan afresh)
    gripper: Gripper = field(kw_only=True)  # the robot's hand the grasps are for


class GraspSelector(Protocol):
    def hand_yaws(self, request: GraspRequest) -> list[float]:
        """The hand angles (rad) of the target's best grasp that are the same grasp (the skill ranks
        them by IK). Raises :class:`~pickdemo.grasping.top_down.GraspPlanningError` when there is no grasp."""
        ...

    def candidates(self, request: GraspRequest) -> Iterator[GraspPlan]:
        """Grasp plans, best first (lazily: the skill stops at the first it can reach). Raises
        :class:`~pickdemo.grasping.top_down.GraspPlanningError` when the target has no feasible grasp."""
        ...


@dataclass(frozen=True)
class TopDownFaceGrasps:
    """A top-down grasp closing across the target's narrower side, one candidate per hand angle asked
    for (of the equivalent angles, the one nearest it)."""

    params: GraspParams = GraspParams()

    def hand_yaws(self, request: GraspRequest) -> list[float]:
        return equivalent_hand_yaws(request.pose, request.model)

    def candidates(self, request: GraspRequest) -> Iterator[GraspPlan]:
        for near in request.hand_yaws:
            yield plan_grasp(
                request.pose,
                request.model,
                request.place_xy,
                self.params,
                gripper=request.gripper,
                hand_yaw_near_rad=near,
            )


def selector_for(model: TargetModel, params: GraspParams) -> GraspSelector:
    """A target's grasps: from its cloud when nobody described it, else across its known faces."""
    if isinstance(model.geometry, Unknown):
        return CloudGrasps(params)
    return TopDownFaceGrasps(params)
