"""Where to put the target down: the task's place, or the nearest spot to it that the task's place
tolerance allows, where the target's footprint and the hand letting go of it clear everything the
world model knows standing there (once a view showed all of the place). A part of the pick skill: it
returns a spot or the reason there is none, never writes the machine's state.

The footprint is the target's as it will stand there: a top-down carry keeps its yaw (the hand turns
half a turn at most, and the footprint is the same then), so a box's rectangle, a cylinder's circle,
an object nobody described its extents as seen, turned as it is now. The hand is the plan's at the
place: its fingers opening to let go, and its palm. The task chooses how far the spot
may move: up to ``place_shift_share`` of its place tolerance (the rest is left for the hand's own
error); a task with no tolerance takes the place or nothing.
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.shapes import Box, Cylinder
from pickdemo.grasping.cloud import hand_hits
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.perception import TargetModel
from pickdemo.perception.neighbours import NEIGHBOURHOOD_ABOVE_M, OWN_MARGIN_M
from pickdemo.robot.description import Gripper
from pickdemo.skills.pick.params import MachineParams
from pickdemo.tracking.belief import TargetBelief
from pickdemo.worldmodel import PlaceView, SceneView, WorldModel

#: An object nobody described: the place is looked at this far about (m; its size is known only once seen)
UNKNOWN_PLACE_RADIUS_M = 0.1
#: Where to put it down, and how far each finger opens to let go there (None: wide).
Spot = tuple[tuple[float, float], float | None]
#: Spots tried about the place, this far apart (m).
SPOT_STEP_M = 0.002


def outside(points_xy: np.ndarray, centre: np.ndarray, yaw_rad: float, half: np.ndarray | float) -> np.ndarray:
    """How far (m) each point lies outside a footprint about ``centre``: a rectangle of half extents
    ``half`` (2,) turned ``yaw_rad``, or a circle of radius ``half`` (0 inside)."""
    d = points_xy - centre
    if np.ndim(half) == 0:
        return np.maximum(np.hypot(d[:, 0], d[:, 1]) - float(half), 0.0)
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    local = d @ np.array([[c, -s], [s, c]])  # into its own frame
    gap = np.maximum(np.abs(local) - np.asarray(half), 0.0)
    return np.hypot(gap[:, 0], gap[:, 1])


class PlaceFinder:
    """The spot to put the target down at, from what the camera saw at the task's place."""

    def __init__(
        self,
        params: MachineParams,
        model: TargetModel,
        belief: TargetBelief,
        place_xy: tuple[float, float],
        tolerance_m: float | None,
        gripper: Gripper,
        surface_z: float = 0.0,
    ) -> None:
        self.p, self.model, self.belief, self.gripper, self.surface_z = params, model, belief, gripper, surface_z
        self.place_xy = (float(place_xy[0]), float(place_xy[1]))
        self.shift_m = 0.0 if tolerance_m is None else params.place_shift_share * tolerance_m
        g = model.geometry
        r = UNKNOWN_PLACE_RADIUS_M if belief.unknown else g.footprint_radius_m
        #: what the camera is asked to look at: the task's place and this far about it (None: not asked)
        self.look: tuple[tuple[float, float], float] | None = None
        if params.check_place and not params.drop_place:  # (the open fingers reach past the footprint)
            reach = max(r, gripper.finger_max_m + gripper.finger_thickness_m)
            self.look = (self.place_xy, reach + params.place_clearance_m + self.shift_m)

    def _footprint(self) -> np.ndarray | float:
        """The target's footprint as half extents (2,) of a rectangle, or a circle's radius."""
        g = self.model.geometry
        if isinstance(g, Box):
            return np.asarray(g.size_m[:2]) / 2.0
        if isinstance(g, Cylinder):
            return g.diameter_m / 2.0
        extents = self.belief.top_extents_m  # (seen: its principal axes')
        return np.asarray(extents) / 2.0 if extents is not None else g.footprint_radius_m

    def seen(self, world: WorldModel, view: SceneView) -> PlaceView | None:
        """What stands at the place as the world model knows it, once ``view`` has shown all of the place
        (None: no look at it asked, or this view does not show it whole: the last one stands)."""
        if self.look is None or not view.shows(self.look[0], self.look[1], NEIGHBOURHOOD_ABOVE_M):
            return None
        xy, r = self.look
        points, areas = world.standing_near(xy, r)
        return PlaceView(xy, r, points, view.time_s, areas)

    def spot(self, view: PlaceView | None, now_s: float, plan: GraspPlan) -> Spot | str:
        """The nearest spot to the task's place (it first) where less than ``place_taken_area_m2`` of
        what stands there comes within ``place_clearance_m`` of the target's footprint, and none where
        ``plan``'s hand lets go of it there: opening wide, or else only ``release_margin_m`` past the
        target (then the spot says how far: each finger from the middle); the reason when none within
        the shift the task allows will do. No view of it (none asked, or it did not come): the place."""
        if view is None or self.look is None:
            return self.place_xy, None
        tp = self.belief.predict(now_s)
        half = self._footprint()
        pts = view.points[:, :2]
        # (the target itself may stand about the place now: its own points are no obstacle)
        own = outside(pts, tp.position[:2], tp.yaw_rad, half) <= OWN_MARGIN_M
        pts = pts[~own]
        place = np.asarray(self.place_xy)
        n = int(np.floor(self.shift_m / SPOT_STEP_M))
        steps = np.arange(-n, n + 1) * SPOT_STEP_M
        offsets = np.array([(dx, dy) for dx in steps for dy in steps if np.hypot(dx, dy) <= self.shift_m + 1e-12])
        offsets = offsets[np.argsort(np.hypot(offsets[:, 0], offsets[:, 1]), kind="stable")]
        others = view.points[~own]
        tcp = plan.place.position - np.array([*self.place_xy, 0.0])  # the TCP from the place, as planned
        g = self.gripper
        narrow = min(plan.object_width_m / 2.0 + self.p.release_margin_m, g.finger_max_m)
        areas = view.areas_m2[~own]
        free = [o for o in offsets if float(areas[outside(pts, place + o, tp.yaw_rad, half) < self.p.place_clearance_m]
                                            .sum()) < self.p.place_taken_area_m2]  # fmt: skip
        for fingers in (g.finger_max_m, narrow):  # let go wide where it can; else only just
            for off in free:
                at = np.array([place[0] + off[0], place[1] + off[1], 0.0]) + tcp
                if not hand_hits(others, at, plan.hand_yaw_rad, self.surface_z, g.palm_above_tcp_m,
                                 self.p.place_clearance_m, g, self.p.grasp.neighbour_min_points, fingers):  # fmt: skip
                    xy = (float(place[0] + off[0]), float(place[1] + off[1]))
                    return xy, (None if fingers == g.finger_max_m else fingers)
        tall = float(others[:, 2].max()) if len(others) else 0.0
        within = f" or within {self.shift_m * 1e3:.0f} mm of it (half the task's tolerance)" if self.shift_m else ""
        return (
            f"the place ({place[0]:.3f}, {place[1]:.3f}) is taken: something up to {tall * 1e3:.0f} mm tall stands "
            f"where the target or the hand letting go of it would{within} "
            f"(seen in the frame of t = {view.time_s:.2f} s)"
        )
