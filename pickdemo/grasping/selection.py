"""Grasp selection behind one protocol: what the robot believes of the target in, ranked grasp
candidates out.

Pure: no simulator. The pick skill asks a :class:`GraspSelector` for candidates and takes the first
one the arm can reach; :class:`TopDownFaceGrasps` (a top-down parallel-jaw grasp across the
narrower pair of faces of a known box or cylinder) is one implementation,
:class:`~pickdemo.grasping.cloud.CloudGrasps` (grasps sampled on the point cloud of an object nobody
described) another, and :class:`TopDownFirst` those or, where none fits, grasps from any side
(:class:`~pickdemo.grasping.antipodal.AnySideGrasps`); a suction cup's seals are
:class:`~pickdemo.grasping.suction.SuctionGrasps`; :func:`selector_for` gives each target its own.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import OrientedBox, Pose, wrap_angle
from pickdemo.core.shapes import Unknown
from pickdemo.grasping.antipodal import AnySideGrasps
from pickdemo.grasping.clearance import plan_meets
from pickdemo.grasping.cloud import CloudGrasps, hand_hits
from pickdemo.grasping.suction import SuctionGrasps
from pickdemo.grasping.top_down import (
    GraspParams,
    GraspPlan,
    GraspPlanningError,
    equivalent_hand_yaws,
    plan_grasp,
)
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
    #: the points of everything else near the target (other objects, fixtures): the hand keeps out of
    #: them (None: not seen)
    obstacles: np.ndarray | None = None
    gripper: Gripper = field(kw_only=True)  # the robot's hand the grasps are for
    #: this target's grasps that held nothing or let it slip so far
    misses: int = field(default=0, kw_only=True)
    #: the target stands still (a moving one is met from above: a tilted hand is re-seated at rest)
    still: bool = field(default=True, kw_only=True)
    #: the boxes of the cell's fixtures near the target (a shelf's boards, a bin's walls), known from the
    #: task: the open hand keeps out of them from the pregrasp in (:mod:`pickdemo.grasping.clearance`)
    fixtures: tuple[OrientedBox, ...] = field(default=(), kw_only=True)


class GraspSelector(Protocol):
    def hand_yaws(self, request: GraspRequest) -> list[float]:
        """The hand angles (rad) of the target's best grasp that are the same grasp (the skill ranks
        them by IK). Raises :class:`~pickdemo.grasping.top_down.GraspPlanningError` when there is no grasp."""
        ...

    def candidates(self, request: GraspRequest) -> Iterator[GraspPlan]:
        """Grasp plans, best first (lazily: the skill stops at the first it can reach). Raises
        :class:`~pickdemo.grasping.top_down.GraspPlanningError` when the target has no feasible grasp."""
        ...


#: Hand angles tried about a round target when something stands beside it (every 10 deg).
FREE_STEPS_NEAR_NEIGHBOURS = 36
#: A grasp the hand can make beside what stands around the target: its hand angle, across the wider
#: side or not, and how much higher than where the pads would close.
Clear = tuple[float, bool, float]


@dataclass(frozen=True)
class TopDownFaceGrasps:
    """A top-down grasp closing across the target's narrower side, one candidate per hand angle asked
    for (of the equivalent angles, the one nearest it). With something beside the target (the
    request's ``obstacles``), only grasps whose open fingers and palm keep out of its points: at the
    hand angles that do, each as low as it can be; none across the narrower side, then across the
    wider one if the hand opens wide enough; none at all, no grasp (a
    :class:`~pickdemo.grasping.top_down.GraspPlanningError` naming it)."""

    params: GraspParams = GraspParams()

    def hand_yaws(self, request: GraspRequest) -> list[float]:
        clear = self._clear(request)
        return equivalent_hand_yaws(request.pose, request.model) if clear is None else [c[0] for c in clear]

    def candidates(self, request: GraspRequest) -> Iterator[GraspPlan]:
        clear = self._clear(request)
        for near in request.hand_yaws:
            yaw, wide, raise_m = near, False, 0.0
            if clear is not None:  # of the clear grasps, the one nearest the angle asked for
                pick = clear[0] if near is None else min(clear, key=lambda c: abs(float(wrap_angle(c[0] - near))))
                yaw, wide, raise_m = pick
            yield plan_grasp(
                request.pose,
                request.model,
                request.place_xy,
                self.params,
                gripper=request.gripper,
                hand_yaw_near_rad=yaw,
                wide=wide,
                raise_m=raise_m,
            )

    def _clear(self, request: GraspRequest) -> list[Clear] | None:
        """The grasps clear of the request's obstacles (None: there are none; every grasp is)."""
        obstacles = request.obstacles
        if obstacles is None or len(obstacles) == 0:
            return None
        # (a shape the same from every side is tried every 10 deg: near a flat neighbour only an angle
        # within a few degrees of its face keeps the fingers off it)
        yaws = equivalent_hand_yaws(request.pose, request.model, free_steps=FREE_STEPS_NEAR_NEIGHBOURS)
        clear = [c for yaw in yaws if (c := self._lowest_clear(request, yaw, wide=False)) is not None]
        shape = request.model.geometry
        widest = request.gripper.max_opening_m - self.params.width_margin_m
        if not clear and shape.yaw_symmetry_rad == np.pi and max(shape.top_extents_m) <= widest:
            clear = [c for yaw in yaws if (c := self._lowest_clear(request, yaw + np.pi / 2.0, wide=True)) is not None]
        if not clear:
            raise GraspPlanningError(
                f"every top-down grasp would put a finger or the palm into something beside the target "
                f"({len(obstacles)} points seen within reach of the hand)"
            )
        return clear

    def _lowest_clear(self, request: GraspRequest, yaw: float, *, wide: bool) -> Clear | None:
        """The grasp at hand angle ``yaw`` as low as it is clear of the obstacles (None: at no height
        with the pads wholly on the target)."""
        p = self.params
        plan = plan_grasp(request.pose, request.model, request.place_xy, p, gripper=request.gripper,
                          hand_yaw_near_rad=yaw, wide=wide)  # fmt: skip
        top = float(request.pose.position[2]) + request.model.height_m / 2.0
        tcp = plan.grasp.position.copy()
        tcp[:2] = request.pose.position[:2]  # (the grasp's centre: a jaw's TCP is beside it)
        gripper = request.gripper
        # up as far as the pads keep half their height on the target's side: raised past a lower
        # neighbour, half a pad holds what the whole pad would (the grip's force is scaled by the share)
        highest = max(top - p.min_pad_on_target * 2.0 * gripper.pad_half_height_m + gripper.pad_half_height_m
                      - float(tcp[2]), 0.0)  # fmt: skip
        steps = np.arange(0.0, highest, p.raise_step_m)
        for raise_m in (*steps, highest):  # up in steps, and the highest last
            at = tcp + [0.0, 0.0, raise_m]
            if not hand_hits(request.obstacles, at, plan.hand_yaw_rad, request.surface_z, gripper.palm_above_tcp_m,
                             p.neighbour_clearance_m, gripper, p.neighbour_min_points):  # fmt: skip
                return plan.hand_yaw_rad, wide, float(raise_m)
        return None


@dataclass
class TopDownFirst:
    """A :class:`GraspSelector` of the top-down cloud grasps where any fits, and of grasps from any side
    where none does (an object leaning, one beside a wall) or once a grasp of the target held nothing or
    let it slip (the request's ``misses``): the top-down grasps first, where they hold (measured:
    docs/decisions.md#grasps-and-holds). Chosen once per plan (the request's ``plan_id``)."""

    top: CloudGrasps | TopDownFaceGrasps
    any_side: AnySideGrasps
    #: a miss puts the grasps from any side first (an object nobody described); False: only where no
    #: top-down grasp is clear (a described target: its top-down grasps are across its known faces)
    misses_first: bool = True
    _chosen: tuple[int, GraspSelector] | None = field(default=None, repr=False)

    def _pick(self, request: GraspRequest) -> GraspSelector:
        if self._chosen is None or self._chosen[0] != request.plan_id:
            first = request.misses and self.misses_first
            order = (self.any_side, self.top) if first else (self.top, self.any_side)
            if not request.still:
                order = (self.top, self.top)
            try:
                yaws = order[0].hand_yaws(request)
                over = _over(request)  # a shelf's board: from above, the hand meets it
                if order[0] is self.top and over:
                    plans = order[0].candidates(dataclasses.replace(request, hand_yaws=tuple(yaws)))
                    if all(plan_meets(plan, request.gripper, over) for plan in plans):
                        raise GraspPlanningError("every top-down grasp would meet a fixture over the target")
                chosen: GraspSelector = order[0]
            except GraspPlanningError:
                chosen = order[1]
            self._chosen = (request.plan_id, chosen)
        return self._chosen[1]

    def hand_yaws(self, request: GraspRequest) -> list[float]:
        return self._pick(request).hand_yaws(request)

    def candidates(self, request: GraspRequest) -> Iterator[GraspPlan]:
        return self._pick(request).candidates(request)


def _over(request: GraspRequest) -> tuple[OrientedBox, ...]:
    """The request's fixture boxes wholly above the target's centre (a shelf's board over it; a bin's
    walls, which the top-down grasps keep clear of as points, are not)."""
    z = float(request.pose.position[2])
    return tuple(b for b in request.fixtures if float(b.corners()[:, 2].min()) > z)


def selector_for(
    model: TargetModel,
    params: GraspParams,
    *,
    any_side: np.random.Generator | None = None,
    gripper: Gripper | None = None,
) -> GraspSelector:
    """A target's grasps: a suction cup's seals (:class:`~pickdemo.grasping.suction.SuctionGrasps`) for a
    suction gripper; else from its cloud when nobody described it, else across its known faces.
    ``any_side``: the draw of grasps from any side, where no top-down grasp fits (of the cloud, or
    clear of what stands beside a described target: on its known surface; None: top-down only: an arm
    that cannot tilt its hand every way, a jaw gripper)."""
    if gripper is not None and gripper.suction:
        return SuctionGrasps(params)
    if isinstance(model.geometry, Unknown):
        if any_side is not None:
            return TopDownFirst(CloudGrasps(params), AnySideGrasps(any_side, params))
        return CloudGrasps(params)
    if any_side is not None:  # (from any side on its known surface, where no top-down grasp is clear)
        return TopDownFirst(TopDownFaceGrasps(params), AnySideGrasps(any_side, params), misses_first=False)
    return TopDownFaceGrasps(params)
