"""Grasp selection behind one protocol: what the robot believes of the target in, ranked grasp
candidates out.

Pure: no simulator. The pick skill asks a :class:`GraspSelector` for candidates and takes the first
one the arm can reach; :class:`TopDownFaceGrasps` (a top-down parallel-jaw grasp across the
narrower pair of faces of a known box or cylinder) is the first implementation. A selector that
grasps from the point cloud gets the newest frame in the request.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

from pickdemo.camera import RGBDFrame
from pickdemo.geometry import Pose
from pickdemo.grasp import GraspParams, GraspPlan, plan_grasp
from pickdemo.perception import TargetModel


@dataclass(frozen=True)
class GraspRequest:
    """What a selector is given: the target as the belief has it now, and what the skill prefers."""

    pose: Pose  # the target's pose in the world frame, as the tracker believes it now
    model: TargetModel
    place_xy: tuple[float, float]
    #: hand angles (rad) the skill would like, best first; None: the selector's own choice
    hand_yaws: tuple[float | None, ...] = (None,)
    frame: RGBDFrame | None = None  # the newest frame, for selectors that look at the points themselves


class GraspSelector(Protocol):
    def candidates(self, request: GraspRequest) -> Iterator[GraspPlan]:
        """Grasp plans, best first (lazily: the skill stops at the first it can reach). Raises
        :class:`~pickdemo.grasp.GraspPlanningError` when the target has no feasible grasp."""
        ...


@dataclass(frozen=True)
class TopDownFaceGrasps:
    """A top-down grasp closing across the target's narrower side, one candidate per hand angle asked
    for (of the equivalent angles, the one nearest it)."""

    params: GraspParams = GraspParams()

    def candidates(self, request: GraspRequest) -> Iterator[GraspPlan]:
        for near in request.hand_yaws:
            yield plan_grasp(request.pose, request.model, request.place_xy, self.params, hand_yaw_near_rad=near)
