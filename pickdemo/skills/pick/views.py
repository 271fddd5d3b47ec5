"""Where to look: which of the robot's cameras should take a frame now, and of which region. The
fixed camera looks for the target from home, keeps looking at it while the hand approaches,
descends and closes, and looks at the place at the end; a camera on the hand looks whenever the
target as tracked lies wholly in its view, and then the fixed camera, which sees the hand over the
target, does not. A part of the pick skill: it returns frame requests, never writes the machine's state."""

from __future__ import annotations

import numpy as np

from pickdemo.core.camera import project, roi_around
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.perception import TargetModel
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.pick.params import (
    HAND_OVER_TARGET,
    TRACKING_STATES,
    CameraModel,
    FrameRequest,
    MachineParams,
    State,
)
from pickdemo.skills.pick.watch import MoveWatch
from pickdemo.tracking.belief import TargetBelief

UNIT_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
#: Eight unit directions around the vertical: a footprint's circle, sampled (the hand camera's view of it)
FOOTPRINT_RING = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)])


def unsure(
    belief: TargetBelief,
    plan: GraspPlan,
    now_s: float,
    params: MachineParams,
    finger_max_m: float,
    *,
    calibration_only: bool = False,
) -> str:
    """Why the hand may not go down on the plan yet ("" when it may): where the target is, its
    cameras' calibration included (``calibration_only``: that alone), is less sure than the grasp's
    clearance allows (how far the fingers, open ``finger_max_m`` each, reach past the object)."""
    tp = belief.predict(now_s)
    sigma = tp.calibration_sigma_m if calibration_only else tp.grasp_sigma_m
    clearance = finger_max_m - plan.object_width_m / 2.0  # from the fingers open to the object
    if params.clearance_sigmas * sigma <= clearance:
        return ""
    return (
        f"the target is known to {params.clearance_sigmas:g} x {sigma * 1e3:.1f} mm"
        + (" (its camera's calibration)" if calibration_only else "")
        + ", more than the grasp's "
        f"clearance of {clearance * 1e3:.1f} mm"
    )


class ViewPlanner:
    """Frame requests over the robot's cameras: the first fixed one, and every one on the hand."""

    def __init__(
        self,
        kin: Kinematics,
        params: MachineParams,
        model: TargetModel,
        belief: TargetBelief,
        watch: MoveWatch,
        cameras: list[CameraModel],
        place_xy: tuple[float, float],
        *,
        look_at: np.ndarray | None,
        open_loop: bool,
    ) -> None:
        self.kin, self.p, self.model, self.belief, self.watch = kin, params, model, belief, watch
        fixed = [c for c in cameras if not c.on_hand]
        if not fixed:
            raise ValueError("the pick skill needs a fixed camera to look for its target")
        self.fixed = fixed[0]
        self.on_hand = [c for c in cameras if c.on_hand]
        self.place_xy, self.look_at, self.open_loop = place_xy, look_at, open_loop

    def requests(
        self,
        now_s: float,
        state: State,
        *,
        ready: bool,
        since_s: float,
        verify_asked: bool,
        plan: GraspPlan | None,
        arm_q: np.ndarray,
        near: np.ndarray | None = None,
        searching: str | None = None,
    ) -> list[FrameRequest]:
        """The frames to take now (the loop applies the frame rate): ``ready``, the state's motion has
        finished since it was entered; ``arm_q``: the joint states last observed (where the hand is);
        ``near``: looking again, where the target was last known (its track); ``searching``: the camera on
        the hand that looks for the target from above (its whole frames, once the arm is there)."""
        fixed = self._fixed(now_s, state, ready=ready, since_s=since_s, verify_asked=verify_asked, near=near)
        hand = [r for c in self.on_hand if (r := self._from_the_hand(c, now_s, state, plan, arm_q)) is not None]
        if state is State.LOOK and searching is not None and ready:
            hand.append(FrameRequest(None, camera=searching))
        if hand and state in HAND_OVER_TARGET:
            fixed = None  # the hand's camera sees the target whole; the fixed one, the hand over it
        return [r for r in (fixed, *hand) if r is not None]

    def _fixed(
        self, now_s: float, state: State, *, ready: bool, since_s: float, verify_asked: bool, near: np.ndarray | None
    ) -> FrameRequest | None:
        name = self.fixed.name
        if state is State.LOOK:  # the whole image, then around the first estimate
            if not ready:
                return None
            if self.belief.initialised:
                return FrameRequest(self._roi(now_s), camera=name)
            if self.look_at is not None:  # where a survey saw it: the region about it
                return FrameRequest(self._roi_at(self.look_at, self.p.roi_margin_m), camera=name)
            if near is not None:  # looking again: about where it was (a look-alike elsewhere is not it)
                return FrameRequest(self._roi_at(near, self.p.roi_margin_m + self.p.relook_margin_m), camera=name)
            return FrameRequest(None, camera=name)
        if state is State.VERIFY:  # around where it was put down
            wait_over = now_s - since_s >= self.p.verify_wait_s
            if not wait_over or verify_asked:
                return None
            z = self.model.height_m / 2.0
            margin = self.p.roi_margin_m + self.p.verify_roi_extra_m
            return FrameRequest(self._roi_at(np.array([*self.place_xy, z]), margin), camera=name)
        if self.open_loop or state not in TRACKING_STATES or not self.belief.initialised:
            return None
        return FrameRequest(self._roi(now_s), camera=name)

    def _from_the_hand(
        self, cam: CameraModel, now_s: float, state: State, plan: GraspPlan | None, arm_q: np.ndarray
    ) -> FrameRequest | None:
        """While the hand descends, closes and backs off (and while it approaches a target not yet sure
        enough for the grasp), when the target as tracked lies wholly in the camera's view and depth range."""
        if self.open_loop or state not in TRACKING_STATES or not self.belief.initialised:
            return None
        finger = self.kin.robot.gripper.finger_max_m
        seen_fixed = self.belief.tracker.share_of(self.fixed.name) > 0.0  # (else the hand's camera found it)
        sure = plan is None or not unsure(self.belief, plan, now_s, self.p, finger)
        if state is State.APPROACH and seen_fixed and sure:
            return None  # on its way, the fixed camera sees it whole: the hand's looks when that is not sure enough
        T_world_cam = self.kin.forward(arm_q) @ cam.pose
        tp = self.belief.predict(now_s)
        radius, half_h = self._seen_size(tp.position)  # its footprint's circle, top and bottom, all in view
        ring = FOOTPRINT_RING
        corners = np.vstack([tp.position + radius * ring + [0.0, 0.0, dz * half_h] for dz in (-1, 1)])
        p_cam = T_world_cam.inverse().transform_points(corners)
        if np.any(p_cam[:, 2] <= cam.near_m) or np.any(p_cam[:, 2] >= cam.far_m):
            return None
        uv = project(p_cam, cam.intrinsics)
        K = cam.intrinsics
        if np.any(uv < 0.0) or np.any(uv[:, 0] > K.width - 1) or np.any(uv[:, 1] > K.height - 1):
            return None
        margin = self.p.roi_margin_m + 3.0 * tp.grasp_sigma_m  # (close by: never above its top, near the lens)
        wide = np.vstack([(radius + margin) * ring + [0.0, 0.0, dz] for dz in (-half_h, half_h)])
        far = self.watch.far_seen(cam.name)  # and where it last saw it, far from there
        corners = np.vstack([tp.position + wide] + ([] if far is None else [far + wide]))
        corners[:, 2] = np.maximum(corners[:, 2], self.p.roi_floor_z_m)
        roi = roi_around(corners, K, T_world_cam, pad_px=self.p.roi_pad_px)
        return None if roi is None else FrameRequest(roi, camera=cam.name)

    def _seen_size(self, position: np.ndarray) -> tuple[float, float]:
        """The target's footprint radius and half height (m): its model's, or for an object nobody
        described what was seen of it (its top face's extents, its centre's height above the table)."""
        g = self.model.geometry
        extents = self.belief.top_extents_m
        if not self.belief.unknown or extents is None:
            return g.footprint_radius_m, g.height_m / 2.0
        return float(np.hypot(*extents)) / 2.0, max(float(position[2]), 0.005)

    def _roi(self, now_s: float) -> tuple[int, int, int, int] | None:
        """Around the tracked target, widened by its uncertainty (None: the whole image)."""
        tp = self.belief.predict(now_s)
        return self._roi_at(tp.position, self.p.roi_margin_m + 3.0 * tp.position_sigma_m)

    def _roi_at(self, centre: np.ndarray, margin_m: float) -> tuple[int, int, int, int] | None:
        r = self.model.geometry.bounding_radius_m + margin_m
        corners = centre + r * UNIT_CUBE
        corners[:, 2] = np.maximum(corners[:, 2], self.p.roi_floor_z_m)
        cam = self.fixed
        return roi_around(corners, cam.intrinsics, cam.pose, pad_px=self.p.roi_pad_px)
