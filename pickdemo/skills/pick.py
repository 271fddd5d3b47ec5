"""The pick behaviour: a state machine called once per control tick.

Pure: no simulator. Each tick :meth:`PickMachine.update` gets the robot's observation (joints,
finger opening, finger contacts) and returns a :class:`~pickdemo.core.interfaces.Command`; perception's
estimates reach it through :meth:`PickMachine.on_estimate` when they arrive (late, by the modelled
latency), and it says through :meth:`PickMachine.frame_request` when it wants a camera frame and of
which region. Modelled on Drake's ``PickAndPlaceStateMachine::Update``: every state has an entry
action (run once, when it is entered: plan, send a target) and an exit test (run every tick); a
failure is a transition to ``FAILED`` with a typed stage and a reason.

States, in the order of a pick::

    LOOK -> APPROACH -> DESCEND -> CLOSE -> LIFT -> TRANSPORT -> LOWER -> RELEASE -> RETREAT -> HOME
         -> VERIFY -> DONE
    DESCEND --(the target moved)--> BACK_OFF -> APPROACH
    CLOSE --(nothing held)--> BACK_OFF -> LOOK          (a retry, up to ``max_attempts``)
    LIFT / TRANSPORT --(dropped)--> BACK_OFF -> LOOK    (a retry with more grip force, a slower lift)
    VERIFY --(seen put down off the place)--> LOOK      (picked up again, within ``max_attempts``)

While it approaches, descends and closes it keeps looking (closed loop): the tracker fuses every
estimate, and the motion is re-targeted to where the tracker says the target is. With
``open_loop`` it looks only in ``LOOK`` and plays the plan from that one look, for comparison.

A target the tracker sees moving (a belt) is met where it will be: each re-target solves for the
soonest time the hand can be at the plan's pose carried along at the target's velocity
(:meth:`~pickdemo.motion.online.OnlineMotion.intercept`), and sends Ruckig there with the target's
velocity as its target velocity and that time as its minimum duration; the hand then moves with
it, goes down with it, closes on it and lifts it off the belt. A target that will have left the
arm's reach by the time it is held, or that runs faster than the hand, fails the episode in ``ik``
by name.

The skill is states and transitions only, dispatched from a table (:data:`STATES`: each state's
entry action and exit test). What it does, it does through its parts: the hand's :class:`~pickdemo.skills.actions.Move`
and the fingers' :class:`~pickdemo.skills.actions.Grip` (started, then finished or failed), the target's
:class:`~pickdemo.tracking.belief.TargetBelief` (the tracker and the gate in front of it), a
:class:`~pickdemo.grasping.selection.GraspSelector` (ranked grasps from the belief). Which of a grasp's
equivalent hand angles the arm takes, and which IK solution a transfer goes to, is chosen by IK
(:mod:`pickdemo.motion.ik_goals`): joint-limit margin, then joint travel; no rule of a particular joint.
"""

from __future__ import annotations

import dataclasses
import enum
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pickdemo.core.camera import Intrinsics, project, roi_around
from pickdemo.core.geometry import Pose, wrap_angle
from pickdemo.core.interfaces import Command, Observation
from pickdemo.core.result import AttemptRecord, Failure, Stage
from pickdemo.grasping.selection import GraspRequest, GraspSelector, selector_for
from pickdemo.grasping.top_down import GraspParams, GraspPlan, GraspPlanningError, top_down
from pickdemo.motion.ik_goals import (
    GoalParams,
    along_line,
    choose_goal,
    goal_candidates,
    line_speed_scale,
    line_trackable,
    path_dip,
    path_low_z,
    straight_carry_ok,
)
from pickdemo.motion.online import (
    CartesianLimits,
    JointMotion,
    MotionError,
    MotionSample,
    OnlineMotion,
    pose_to_x4,
)
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel
from pickdemo.robot import panda as rm
from pickdemo.robot.kinematics import IKParams, PandaKinematics
from pickdemo.robot.rate_limit import RateLimiter
from pickdemo.skills.actions import Grip, GripParams, Move, PayloadParams, Scale
from pickdemo.tracking.belief import Counters, GateParams, Offered, TargetBelief, Verdict
from pickdemo.tracking.tracker import TargetTracker, TrackerParams

UNIT_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
#: Eight unit directions around the vertical: a footprint's circle, sampled (the hand camera's view of it)
FOOTPRINT_RING = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False)])
#: A state may hand over to the next within one tick (an exit test met at once): at most this many times.
MAX_TRANSITIONS_PER_TICK = 4


def _wrap(yaw_rad: float, period_rad: float) -> float:
    """The yaw in [-period/2, period/2): how a symmetric shape's yaw is said (a cube's modulo 90 deg)."""
    return float((yaw_rad + period_rad / 2.0) % period_rad - period_rad / 2.0)


class State(str, enum.Enum):
    LOOK = "look"
    APPROACH = "approach"
    DESCEND = "descend"
    CLOSE = "close"
    LIFT = "lift"
    TRANSPORT = "transport"
    LOWER = "lower"
    RELEASE = "release"
    RETREAT = "retreat"
    HOME = "home"
    VERIFY = "verify"
    BACK_OFF = "back_off"
    DONE = "done"
    FAILED = "failed"


#: States in which the closed loop keeps looking at the target (a region of interest around it).
TRACKING_STATES = frozenset({State.APPROACH, State.DESCEND, State.CLOSE, State.BACK_OFF})
#: States in which the hand is over the target: a partial view of it is not acted on.
HAND_OVER_TARGET = frozenset({State.DESCEND, State.CLOSE})


@dataclass(frozen=True)
class MachineParams:
    """Behaviour of the pick; SI units."""

    grasp: GraspParams = GraspParams()
    free: CartesianLimits = CartesianLimits(  # away from the object
        velocity=0.30, acceleration=1.5, jerk=15.0, yaw_velocity=1.5, yaw_acceleration=6.0, yaw_jerk=60.0
    )
    near: CartesianLimits = CartesianLimits(velocity=0.10, acceleration=0.5, jerk=5.0)  # near it: descend, lift
    grip: GripParams = GripParams()  # the fingers: forces, when they have stopped, held, dropped
    gate: GateParams = GateParams()  # when an estimate is no use, whatever the tracker says
    grip_force_n: float = 20.0  # per finger; measured: holds a 5 cm cube with ~1 mm slip
    payload: PayloadParams = PayloadParams()  # weighed at the wrist while lifting: a heavier hold grips harder
    max_grip_force_n: float = 70.0  # the Franka Hand's continuous grip force
    look_min_estimates: int = 2  # accepted estimates before the first plan (1 when open loop)
    look_max_frames: int = 10  # frames in LOOK without an accepted estimate: the episode fails
    max_relooks: int = 2  # the target lost while approaching: look again from home, at most this often
    moved_tolerance_m: float = 0.008  # during the descent, a target this far from the plan: back off
    moved_tolerance_rad: float = float(np.radians(8.0))
    moved_views: int = 2  # ... or this many whole views in a row refused that far from the track: back off
    touch_back_offs: int = 2  # a finger touching something during the descent: back off and look again, this often
    #: held, the hand's camera sees the target's centre this far (m, across the table) from where the
    #: grasp should hold it: let go and grasp it again (it would be put down that far off)
    off_centre_tolerance_m: float = 0.008
    hold_look_s: float = 0.3  # held, with a camera on the hand: wait this long for its view of the hold
    #: the hand goes down only when this many standard deviations of where the target is (its cameras'
    #: calibration included) fit in the grasp's clearance (how far the open fingers reach past it)
    clearance_sigmas: float = 2.0
    hover_max_s: float = 2.0  # above a target not yet sure enough: wait this long for the hand's camera
    close_timeout_s: float = 2.0
    verify_wait_s: float = 0.3  # let the placed object come to rest before the last look
    roi_margin_m: float = 0.03  # around the target's box, for the region of interest
    verify_roi_extra_m: float = 0.03  # the last look's region: this much wider (the object may lie off the place)
    roi_floor_z_m: float = -0.005  # a region of interest reaches this far below the table top
    roi_pad_px: int = 4
    back_off_grasp_z_m: float = 0.02  # backing off with no plan yet: as if the grasp were this high
    moving_speed_m_s: float = 0.01  # a target tracked faster than this (and than 3 sigma) is met where it will be
    chase_fraction: float = 0.9  # a target faster than this share of the hand's speed (an axis) runs away from it
    grasp_time_s: float = 2.0  # from above a moving target to holding it (descent and close): it travels on meanwhile
    meet_horizon_s: float = 15.0  # a moving target that cannot be met within this is out of reach
    lift_lead_s: float = 0.3  # lifting a moving target, the hand carries on along its way this long
    arrive_tolerance_m: float = 0.002  # at a moving target's pose: this close, moving with it within
    arrive_tolerance_rad: float = float(np.radians(1.0))
    arrive_speed_tolerance_m_s: float = 0.005
    tracker: TrackerParams = TrackerParams()
    #: transfers (home to above the target, above the target to above the place, back home) in joint
    #: space to IK goals chosen well; else straight Cartesian lines (as before)
    joint_transfers: bool = True
    #: the carry to above the place in joint space too (with joint_transfers); off: a straight top-down
    #: line: carried in joint space, a held box the hand turned and tilted can jam the fingers at the
    #: release (evidence: docs/decisions.md#motion-and-ik)
    carry_in_joint_space: bool = False
    goals: GoalParams = GoalParams()  # how a transfer's IK goal is chosen
    transfer_scale: float = 0.5  # transfers in joint space, the hand empty: this share of the datasheet's limits
    carry_scale: float = 0.25  # ... carrying the target (a retry after a drop slows it further)
    #: after the place, home, look at the place (a target seen put down off it is picked up again);
    #: off: done once home (a clear round looks at the whole table next)
    verify_place: bool = True
    #: let go from the carry's height over the place (at least ``place_z_m`` up), then straight home: a
    #: drop into a tray (no lowering onto the place, no retreat from it)
    drop_place: bool = False
    #: after the place, home (off: done where it let go, at rest; a sequencer goes on from there)
    home_after_place: bool = True
    #: the machine ends with the arm at rest: a last failed attempt backs off first (straight up, the
    #: fingers open), any other failure brakes the motion under way (a sequencer goes on from there)
    end_at_rest: bool = False

    def on_a_belt(self) -> MachineParams:
        """For a cell with a conveyor: a target may move at any speed the belt runs (up to 0.5 m/s),
        and its belt may change speed; the first plan waits for one more estimate (a velocity)."""
        tracker = dataclasses.replace(self.tracker, initial_speed_sigma_m_s=0.3, accel_sigma_m_s2=0.03)
        return dataclasses.replace(
            self,
            look_min_estimates=max(self.look_min_estimates, 3),
            tracker=tracker,
            # a slow belt is a belt: a target steadily faster than this (and the fit's noise) is moving
            moving_speed_m_s=min(self.moving_speed_m_s, BELT_MOVING_SPEED_M_S),
        )


#: The name of the camera on the hand (an :class:`~pickdemo.core.camera.RGBDFrame`'s ``camera``)
WRIST_CAMERA = "wrist_camera"
#: On a belt, the least speed of a moving target (m/s): a slow belt's 1 cm/s is well clear of it
BELT_MOVING_SPEED_M_S = 0.004


@dataclass(frozen=True)
class Event:
    """A state entered, at a simulated time, with what it says."""

    state: State
    time_s: float
    message: str
    note: bool = False  # something seen within a state, not a transition


@dataclass(frozen=True)
class CameraModel:
    """What the robot knows of its camera: intrinsics of the whole image and its pose."""

    intrinsics: Intrinsics
    T_world_cam: Pose


@dataclass(frozen=True)
class WristCameraModel:
    """What the robot knows of the camera on its hand: intrinsics of the whole image, its pose on the
    hand (``T_tcp_cam``, from its hand-eye calibration) and the depths it measures."""

    intrinsics: Intrinsics
    T_tcp_cam: Pose
    near_m: float
    far_m: float


@dataclass(frozen=True)
class FrameRequest:
    """A frame perception wants now: the whole image (``roi`` None) or a region of it."""

    roi: tuple[int, int, int, int] | None
    survey: bool = False  # every object on the table (a clear round's look), not the target's pose
    wrist: bool = False  # of the camera on the hand (else the fixed camera's)


Transition = tuple[State, str] | None  # the next state and what it says, or stay


class PickMachine:
    """Pick and place as a state machine; see the module docstring."""

    def __init__(
        self,
        *,
        kin: PandaKinematics,
        model: TargetModel,
        symmetry_rad: float,
        place_xy: tuple[float, float],
        camera: CameraModel,
        q0: np.ndarray,
        dt_s: float,
        rng: np.random.Generator,
        max_attempts: int = 3,
        place_tolerance_m: float | None = None,
        open_loop: bool = False,
        params: MachineParams | None = None,
        surface_z: Callable[[float, float], float] | None = None,
        selector: GraspSelector | None = None,
        place_z_m: float = 0.0,
        look_at: np.ndarray | None = None,
        look_from_here: bool = False,
        wrist: WristCameraModel | None = None,
    ) -> None:
        """``surface_z(x, y)``: the height of what a target at (x, y) rests on, as the cell's layout
        says (a belt's top, or the table at 0). ``selector``: where grasps come from (default: a
        top-down grasp across the target's narrower side). ``place_tolerance_m``: the task's; a target
        the camera sees put down farther than this from the place position is picked up again (within
        ``max_attempts``). ``place_z_m``: the height above the table the target's bottom is let go at
        (a tray's rim: it drops in). ``look_at``: where the target was seen last (a survey of the table
        chose it among others): the first look is at a region around it; ``look_from_here``: from where
        the arm is (it hides nothing of the table from the camera), not from home. ``wrist``: the camera
        on the hand, if there is one (it looks too whenever the target is wholly in its view)."""
        self.p = params or MachineParams()
        self.look_at = None if look_at is None else np.asarray(look_at, dtype=float)
        self._look_here = look_from_here
        self.kin = kin
        self.model = model
        self.symmetry = symmetry_rad
        self.place_xy = place_xy
        self.camera = camera
        self.wrist = wrist
        self._arm_q = np.asarray(q0, dtype=float)  # the joint states last observed (where the wrist camera is)
        self.rng = rng  # the IK's restarts
        self.max_attempts = max_attempts
        self.place_tolerance_m = place_tolerance_m
        self.open_loop = open_loop
        self.dt_s = dt_s
        self.selector: GraspSelector = selector or selector_for(model, self.p.grasp)
        if place_z_m != 0.0 or self.p.drop_place:
            self.selector = PlacedHigher(self.selector, place_z_m, from_carry=self.p.drop_place)
        # The parts: the hand's motion, the fingers, the belief about the target.
        self.motion = OnlineMotion(kin, q0, dt_s, self.p.free)
        self.move = Move(self.motion, chase_fraction=self.p.chase_fraction, meet_horizon_s=self.p.meet_horizon_s)
        self.grip = Grip(self.p.grip, dt_s)
        self.scale = Scale(self.p.payload)
        self.joints = JointMotion(kin, q0, dt_s)  # transfers in joint space
        self.limiter = RateLimiter(q0, dt_s)  # every joint command within the datasheet, as libfranka's
        self._joint = False  # the joint-space transfer drives the arm (else the Cartesian motion)
        self._legs: deque[Callable[[], None]] = deque()  # the state's motion still to come, leg by leg
        self._sample: MotionSample | None = None
        self.counters = Counters()
        self.belief = TargetBelief(
            model,
            symmetry_rad,
            self.p.tracker,
            self.p.gate,
            surface_z=surface_z or (lambda x, y: 0.0),
            counters=self.counters,
        )
        self.home_x4 = pose_to_x4(kin.forward(rm.HOME_Q))
        # What happened.
        self.state = State.LOOK
        self.failure: Failure | None = None
        self.events: list[Event] = []
        self.attempts: list[AttemptRecord] = []
        self.plan: GraspPlan | None = None
        self.grasp_width_m: float | None = None  # finger opening on the object at the last grasp
        self.verify_estimate: PoseEstimate | None = None
        self.released_at_s: float | None = None  # when it last began to let go of the target
        # Per attempt: what a retry may change.
        self.attempt = 1
        self.grip_force_n = self.p.grip_force_n
        self.lift_scale = 1.0
        self._turn_hand = False  # after a miss: try a square box by its other pair of faces
        self._weighed_force_n = 0.0  # the grip force the payload asked for, once weighed
        self._line_checked_q: np.ndarray | None = None  # a transfer goal whose straight line was checked
        self._room_checked: tuple[np.ndarray, bool] | None = None  # a re-plan's last check of joint room
        self._forced_open = False  # releasing: the fingers were told to open with full force
        self._lifted_off = False  # lifting: past the pause just off the table where it is weighed
        self._attempt_start_s = 0.0
        # Per state.
        self._entered = False
        self._since_s = 0.0
        self._now_s = 0.0
        self._fresh_estimate = False
        self._look_frames = 0
        self._after_back_off = State.LOOK
        self._descent_plan: GraspPlan | None = None
        self._planned_at_s = 0.0  # the plan is for the target where it was then
        self._descent_ref: tuple[np.ndarray, np.ndarray, float] | None = None  # (grasp xy, velocity, time)
        #: per camera: views refused far from the track, in a row (how far, where seen)
        self._far_views: dict[str, list[tuple[float, np.ndarray | None, bool]]] = {}  # (+ partial or not)
        #: the target moved under the hand: how far, seen by which camera, in the frame of when
        self._moved_seen: tuple[float, str, float] | None = None
        self._hover_since: float | None = None  # above the target, waiting to be sure enough of it
        self._move_unconfirmed = False  # it backed off on a move the tracker has not confirmed (yet)
        self._touch_back_offs = 0  # backed off this often on a finger touching something in the descent
        self._touched_at: np.ndarray | None = None  # where the grasp was when a finger last touched (x, y)
        self._held_at: float | None = None  # closing: when the fingers were found holding it
        self._hold_views: list[tuple[float, np.ndarray]] = []  # closing: the hand camera's whole views (t, centre)
        self._verify_asked = False
        self._relooks = 0
        self._plan_id = 0  # counts first plans (the grasp selector's plan_id)
        self._failing: Failure | None = None  # the last attempt failed: backing off before failing so
        self._braked = False  # (end_at_rest) the motion under way at a failure has come to rest
        self._braking = False

    # ================================================================================ interface
    @property
    def finished(self) -> bool:
        return self.state in (State.DONE, State.FAILED)

    @property
    def at_rest(self) -> bool:
        """Finished, and the arm at rest (with ``end_at_rest`` a failure brakes it first)."""
        return self.state is State.DONE or (self.state is State.FAILED and (self._braked or not self.p.end_at_rest))

    @property
    def tracker(self) -> TargetTracker:
        """The belief's tracker (read by observers: the video, the trace, the scoring)."""
        return self.belief.tracker

    @property
    def last_sample(self) -> MotionSample | None:
        return self._sample

    def cartesian_limits(self) -> tuple[list[float], list[float], list[float]]:
        """The Cartesian limits the hand moves within now (infinite during a joint-space transfer,
        which keeps the joints' limits instead)."""
        if self._joint:
            inf = [float("inf")] * 4
            return inf, inf, inf
        return self.motion.limits.arrays()

    def frame_request(self, now_s: float) -> FrameRequest | None:
        """Whether perception should look now, and at what (the loop applies the frame rate)."""
        if self.state is State.LOOK:  # the whole image, then around the first estimate
            if not (self._entered and self._motion_finished):
                return None
            if self.belief.initialised:
                return FrameRequest(self._roi(now_s))
            if self.look_at is not None:  # where a survey saw it: the region about it
                return FrameRequest(self._roi_at(self.look_at, self.p.roi_margin_m))
            return FrameRequest(None)
        if self.state is State.VERIFY:  # around where it was put down
            wait_over = now_s - self._since_s >= self.p.verify_wait_s
            if not wait_over or self._verify_asked:
                return None
            z = self.model.height_m / 2.0
            return FrameRequest(
                self._roi_at(np.array([*self.place_xy, z]), self.p.roi_margin_m + self.p.verify_roi_extra_m)
            )
        if self.open_loop or self.state not in TRACKING_STATES or not self.belief.initialised:
            return None
        return FrameRequest(self._roi(now_s))

    def wrist_request(self, now_s: float) -> FrameRequest | None:
        """Whether the camera on the hand should look now, and at what region: while the hand descends,
        closes and backs off (and while it approaches a target not yet sure enough for the grasp), when
        the target as tracked lies wholly in its view and depth range."""
        if self.wrist is None or self.open_loop or self.state not in TRACKING_STATES or not self.belief.initialised:
            return None
        if self.state is State.APPROACH and (self.plan is None or not self._unsafe(now_s)):
            return None  # on its way, the fixed camera sees it whole: the hand's looks when that is not sure enough
        w = self.wrist
        T_world_cam = self.kin.forward(self._arm_q) @ w.T_tcp_cam
        tp = self.belief.predict(now_s)
        radius, half_h = self._seen_size(tp.position)  # its footprint's circle, top and bottom, all in view
        ring = FOOTPRINT_RING
        corners = np.vstack([tp.position + radius * ring + [0.0, 0.0, dz * half_h] for dz in (-1, 1)])
        p_cam = T_world_cam.inverse().transform_points(corners)
        if np.any(p_cam[:, 2] <= w.near_m) or np.any(p_cam[:, 2] >= w.far_m):
            return None
        uv = project(p_cam, w.intrinsics)
        K = w.intrinsics
        if np.any(uv < 0.0) or np.any(uv[:, 0] > K.width - 1) or np.any(uv[:, 1] > K.height - 1):
            return None
        margin = self.p.roi_margin_m + 3.0 * tp.grasp_sigma_m  # (close by: never above its top, near the lens)
        wide = np.vstack([(radius + margin) * ring + [0.0, 0.0, dz] for dz in (-half_h, half_h)])
        far = self._far_seen(WRIST_CAMERA)  # and where it last saw it, far from there
        corners = np.vstack([tp.position + wide] + ([] if far is None else [far + wide]))
        corners[:, 2] = np.maximum(corners[:, 2], self.p.roi_floor_z_m)
        roi = roi_around(corners, K, T_world_cam, pad_px=self.p.roi_pad_px)
        return None if roi is None else FrameRequest(roi, wrist=True)

    def _seen_size(self, position: np.ndarray) -> tuple[float, float]:
        """The target's footprint radius and half height (m): its model's, or for an object nobody
        described what was seen of it (its top face's extents, its centre's height above the table)."""
        g = self.model.geometry
        extents = self.belief.top_extents_m
        if not self.belief.unknown or extents is None:
            return g.footprint_radius_m, g.height_m / 2.0
        return float(np.hypot(*extents)) / 2.0, max(float(position[2]), 0.005)

    def on_estimate(
        self, result: PoseEstimate | PerceptionError, frame_time_s: float, camera: str = "camera"
    ) -> Verdict:
        """An estimate (or perception's word that it found none) from a frame taken at ``frame_time_s``
        by ``camera``; what became of it (:class:`~pickdemo.tracking.belief.Verdict`)."""
        if self.state is State.VERIFY:
            self._verify_asked = True
            if isinstance(result, PoseEstimate):
                self.verify_estimate = result
            return Verdict.UNUSED
        looking = self.state is State.LOOK or (self.state in TRACKING_STATES and not self.open_loop)
        if not looking:
            return Verdict.UNUSED
        if self.state is State.LOOK:
            self._look_frames += 1
        offered = self.belief.offer(
            result, frame_time_s, hand_over_target=self.state in HAND_OVER_TARGET, camera=camera
        )
        if offered.jumped:
            tp = self.belief.predict(frame_time_s)
            moved = ""
            if self.plan is not None:
                d = float(np.linalg.norm(tp.position[:2] - self.plan.grasp.position[:2]))
                moved = f" {d * 1e3:.0f} mm from the plan"
            message = f"the target moved{moved} (seen in the frame of t = {frame_time_s:.2f} s): tracking it again"
            self.events.append(Event(self.state, self._now_s, message, note=True))
        if offered.verdict is Verdict.ACCEPTED:
            self._fresh_estimate = True
        seen = result.pose.position if isinstance(result, PoseEstimate) else None
        whole = offered.verdict is Verdict.ACCEPTED or (offered.off_m is not None and not offered.partial)
        if self.state is State.CLOSE and camera == WRIST_CAMERA and seen is not None and whole:
            self._hold_views.append((frame_time_s, seen.copy()))  # (a plausible whole view, accepted or not)
        self._watch_moves(offered, camera, frame_time_s, seen)
        return offered.verdict

    def _watch_moves(self, offered: Offered, camera: str, frame_time_s: float, seen: np.ndarray | None) -> None:
        """With the hand over the target, views of it that are refused, ``moved_views`` of them in a row
        from one camera, each farther than ``moved_tolerance_m`` from where it is tracked (and than a view
        of it there could be off), one at least a whole view (after a far view, a frame in which the model
        fits nothing counts too): the target moved under the hand (the tracker confirms where to only
        once it is at rest again; until it does, no views send the hand back again). Meanwhile each
        camera also looks where it last saw it (:meth:`_far_seen`)."""
        if offered.jumped:
            self._move_unconfirmed = False
        if self.belief.unknown:  # told from its neighbours only by where it is: a view far off may be one
            return
        if self.wrist is None:  # the fixed camera alone sees the hand over it: its views there mislead (README)
            return
        if self._move_unconfirmed:
            return  # views said it moved before, and the tracker never found it moved: not again until it does
        # How far off a view may be and still be of the target where it is tracked: a partial view's
        # centre up to half its top face; a whole one's, from the fixed camera, up to the share of the
        # face a view may miss and still pass as whole (the fingers hide an edge of a large face; the
        # hand's camera sees past them).
        extents = self.belief.top_extents_m
        half = max(extents) / 2.0 if extents is not None else self.model.geometry.footprint_radius_m
        whole = 0.0 if camera == WRIST_CAMERA else self.p.gate.face_size_tolerance * half  # (its fingers, close by)
        far = self.p.moved_tolerance_m + (half if offered.partial else whole)
        if offered.verdict is Verdict.ACCEPTED:  # where it is tracked, as a camera sees it: no run goes on
            self._far_views.clear()
            return
        run = self._far_views.get(camera)
        if offered.verdict is Verdict.NO_ESTIMATE and run and self.state in HAND_OVER_TARGET:
            run.append(run[-1])  # after a far view, the model fits nothing where it was tracked: on the run goes
            self._judge_run(run, camera, frame_time_s)
            return
        if offered.off_m is None or offered.off_m <= far:
            if offered.off_m is not None and not offered.partial:
                self._far_views.pop(camera, None)  # a near whole view ends its camera's run (no view does not)
            return
        if self.state not in HAND_OVER_TARGET:
            return
        run = self._far_views.setdefault(camera, [])
        run.append((offered.off_m, seen, offered.partial))
        self._judge_run(run, camera, frame_time_s)

    def _judge_run(self, run: list, camera: str, frame_time_s: float) -> None:
        """``moved_views`` in a row, one of them at least a whole view (partial views alone can mislead
        consistently: the fixed camera's, of the face the hand leaves): it moved (evidence:
        docs/decisions.md#the-loop-and-the-tracker)."""
        if len(run) >= self.p.moved_views and any(not partial for *_, partial in run):
            self._moved_seen = (max(off for off, *_ in run), camera, frame_time_s)

    def _far_seen(self, camera: str) -> np.ndarray | None:
        """Where a camera last saw the target far from where it is tracked (a run under way), or None."""
        run = self._far_views.get(camera)
        return None if not run else run[-1][1]

    def update(self, obs: Observation) -> Command:
        """One control tick: the state's entry action (once), its exit test, then the motion's tick."""
        self._now_s = obs.time_s
        self._arm_q = obs.arm_q
        for _ in range(MAX_TRANSITIONS_PER_TICK):
            if not self._entered:
                self._entered = True
                self._since_s = obs.time_s
                STATES[self.state].enter(self, obs)
            if self.finished:
                break
            nxt = STATES[self.state].tick(self, obs)
            if nxt is None:
                break
            self._go(*nxt)
        if self.finished:
            return self._stopped()
        if self._legs and self._leg_finished:  # the next leg of the state's motion (over the top)
            self._legs.popleft()()
            if self.finished:
                return self._stopped()
        if self._joint:
            try:
                sample = self.joints.step()
            except MotionError as exc:
                self._fail(Stage.TRAJECTORY, str(exc))
                return self._stopped()
        else:
            sample = self.move.step()
            if sample is None:
                self._fail(Stage.TRAJECTORY, str(self.move.failure))
                return self._stopped()
        self._sample = sample
        self.counters.retargets = self.motion.retargets + self.joints.retargets
        q, limited = self.limiter(sample.q)
        return Command(q, self.limiter.dq.copy() if limited else sample.dq, self.grip.target_m, self.grip.force_n)

    def _stopped(self) -> Command:
        """The command once finished: held where it is (with ``end_at_rest``, after a failure, braked first)."""
        if self.state is State.FAILED and self.p.end_at_rest and not self._braked:
            return self._brake()
        return self._command_hold()

    def _brake(self) -> Command:
        """After a failure (``end_at_rest``): the joints brought to rest from the commands last sent
        (whatever motion was under way, even one that failed), within their limits; then held there."""
        if not self._braking:
            self._braking = True
            self._legs.clear()
            if not np.any(self.limiter.dq) and not np.any(self.limiter.ddq):  # at rest already
                self._braked = True
                return self._command_hold()
            self.joints.brake(self.limiter.q, self.limiter.dq, self.limiter.ddq)
            self._joint = True
        try:
            sample = self.joints.step()
        except MotionError:
            sample = None
        if sample is None or sample.finished:
            self._braked = True
        if sample is None:
            return self._command_hold()
        self._sample = sample
        q, limited = self.limiter(sample.q)
        return Command(q, self.limiter.dq.copy() if limited else sample.dq, self.grip.target_m, self.grip.force_n)

    def abort(self, stage: Stage, reason: str) -> None:
        """End the episode from outside (the step budget is spent)."""
        self._fail(stage, reason)

    # ============================================================================== transitions
    def _go(self, state: State, message: str) -> None:
        self.state = state
        self._entered = False
        self._legs.clear()  # each state starts its own motion
        self.events.append(Event(state, self._now_s, message))

    def _fail(self, stage: Stage, reason: str) -> None:
        if self.plan is not None and (not self.attempts or self.attempts[-1].number != self.attempt):
            self._end_attempt("failed", f"{stage.value}: {reason}")
        self.failure = Failure(stage, reason)
        self.state = State.FAILED
        self._entered = True
        self.events.append(Event(State.FAILED, self._now_s, f"{stage.value}: {reason}"))

    def _command_hold(self) -> Command:
        """Hold where the motion is, through the rate limiter (a motion that stopped short of the last
        command, or an IK that settled elsewhere, is not a jump)."""
        q = self.joints.q if self._joint else self.motion.q
        sent, limited = self.limiter(q)
        return Command(sent, self.limiter.dq.copy() if limited else np.zeros(7), self.grip.target_m, self.grip.force_n)

    @property
    def commanded_q(self) -> np.ndarray:
        """The joint command last sent (where the next controller takes over)."""
        return self.limiter.q.copy()

    def _end_attempt(self, outcome: str, reason: str) -> None:
        self.attempts.append(
            AttemptRecord(
                number=self.attempt,
                outcome=outcome,
                reason=reason,
                start_s=self._attempt_start_s,
                end_s=self._now_s,
                grip_force_n=max(self.grip_force_n, self._weighed_force_n),
                hand_yaw_deg=None if self.plan is None else float(np.degrees(self.plan.hand_yaw_rad)),
                lift_speed_scale=self.lift_scale,
                payload_kg=self.scale.payload_kg,
            )
        )

    def _retry(self, stage: Stage, outcome: str, reason: str) -> Transition:
        """End this attempt; start the next (changed by what failed) or fail the episode."""
        self._end_attempt(outcome, reason)
        if self.attempt >= self.max_attempts:
            if self.p.end_at_rest:  # up and open first: the machine ends with the hand clear of the table
                self._failing = Failure(stage, f"{reason} (attempt {self.attempt} of {self.max_attempts})")
                self._after_back_off = State.FAILED
                return State.BACK_OFF, f"{outcome}: {reason}; no attempt left: backing off"
            self._fail(stage, f"{reason} (attempt {self.attempt} of {self.max_attempts})")
            return None
        self.attempt += 1
        if outcome == "missed":
            # Look again; a square box may be taken by its other pair of faces.
            self._turn_hand = 0.0 < self.symmetry < np.pi - 1e-9  # a square top (a cube)
        elif outcome == "held off centre":
            pass  # look again, and grasp it where it lies now
        else:
            # It slipped out: hold harder, lift more gently.
            self.grip_force_n = min(self.grip_force_n * 2.0, self.p.max_grip_force_n)
            self.lift_scale *= 0.5
        self._after_back_off = State.LOOK
        return State.BACK_OFF, f"{outcome}: {reason}; attempt {self.attempt} of {self.max_attempts} follows"

    # ==================================================================================== helpers
    def _holding(self, obs: Observation) -> bool:
        assert self.plan is not None
        return self.grip.holding(obs, self.plan.object_width_m)

    def _dropped(self, obs: Observation) -> bool:
        assert self.plan is not None
        return self.grip.dropped(obs, self.plan.object_width_m)

    def _wrist_load(self, obs: Observation, hand: Pose | None = None) -> float:
        """The wrist's load along world z (N)."""
        hand = hand or self.kin.forward(obs.arm_q)
        return self.scale.vertical(obs, hand.rotation)

    def _weigh(self, obs: Observation) -> bool:
        """Lifted, at rest: weigh what hangs in the fingers (a few ticks), and grip as hard as it
        needs; True once weighed. (Readings on the move are no use: the simulated sensor, like the
        Franka's estimate, misses the motors' share then.)"""
        if self.scale.payload_kg is not None:
            return True
        payload = self.scale.read(self._wrist_load(obs), 0.0)
        if payload is None:
            return False
        force = min(max(self.grip_force_n, self.scale.grip_force_n(payload)), self.p.max_grip_force_n)
        self._weighed_force_n = force
        note = f"weighed {payload:.2f} kg at the wrist"
        if force > self.grip.force_n:
            self.grip.close(force)
            note += f": gripping with {force:.0f} N"
        self.events.append(Event(self.state, self._now_s, note, note=True))
        return True

    def _tracked_pose(self) -> Pose:
        tp = self.belief.predict(self._now_s)
        return Pose.from_xyz_rpy(tp.position, yaw=tp.yaw_rad)

    def _grasp(self, pose: Pose, near: float | None) -> GraspPlan:
        """The selector's best grasp for the target at ``pose`` with the hand angle nearest ``near``."""
        return next(iter(self.selector.candidates(self._request(pose, (near,)))))

    def _request(self, pose: Pose, hand_yaws: tuple[float | None, ...]) -> GraspRequest:
        """What the selector is asked: the target at ``pose`` (and, seen as a cloud, its newest view)."""
        surface = self.belief.surface_z(float(pose.position[0]), float(pose.position[1]))
        return GraspRequest(
            pose,
            self.model,
            self.place_xy,
            hand_yaws,
            cloud=self.belief.cloud,
            surface_z=surface,
            plan_id=self._plan_id,
        )

    def _best_ik(self, pose: Pose, seeds: list[np.ndarray]) -> np.ndarray | None:
        """Of the IK solutions of ``pose`` from each of ``seeds``, the one with the most joint-limit
        margin; None if none converged."""
        best = None
        for seed in seeds:
            res = self.kin.solve(pose, seed, self.rng, self.p.goals.ik)
            if res.success and (best is None or self.kin.limit_margin(res.q) > self.kin.limit_margin(best)):
                best = res.q
        return best

    def _room_kept(self, plan: GraspPlan) -> bool:
        """Whether the arm, on the branch it is on, still holds this plan's pregrasp with every joint
        ``min_margin_rad`` from its limits (a re-plan's check; re-used while the pose moves less than
        a millimetre and a half-degree: the tracker moves it that much a frame)."""
        x4 = pose_to_x4(plan.pregrasp)
        last = self._room_checked
        if last is not None and np.all(np.abs(x4 - last[0]) < np.array([1e-3, 1e-3, 1e-3, np.radians(0.5)])):
            return last[1]
        q = self._best_ik(plan.pregrasp, [self._q])  # on the branch the arm is on
        kept = q is not None and self.kin.limit_margin(q) >= self.p.goals.min_margin_rad
        self._room_checked = (x4, kept)
        return kept

    def _hand_angle_score(self, plan: GraspPlan, held: np.ndarray | None) -> tuple[bool, bool, float]:
        """How the arm would do this plan's pick and place with its hand angle, by IK: whether the
        grasp (where it will be held, for a moving target) has a solution; whether the hand can then
        go straight to the place with the joints following continuously (the carry: the angle's
        joint 7 turns with the arm's bearing, and past its stop the carry cannot follow) and every
        joint ``min_margin_rad`` clear of its limits at both ends; and the joint travel (s at the
        speed limits) from here to the grasp and on to the place."""
        grasp = plan.grasp if held is None else Pose(np.array([*held, plan.grasp.position[2]]), plan.grasp.rotation)
        best = self._best_ik(grasp, [self._q] if np.array_equal(self._q, rm.HOME_Q) else [self._q, rm.HOME_Q])
        if best is None:
            return False, False, 0.0
        g = dataclasses.replace(self.p.goals, line_steps=self.p.goals.line_steps // 2)
        q_end = best
        for q_k in along_line(self.kin, best, grasp, plan.place, g.line_steps):
            if q_k is None:
                q_end = None
                break
            q_end = q_k
        travel = float(np.max(np.abs(best - self._q) / rm.MAX_VELOCITY_RAD_S))
        if q_end is None:
            return True, False, travel
        travel += float(np.max(np.abs(q_end - best) / rm.MAX_VELOCITY_RAD_S))
        margin = min(self.kin.limit_margin(best), self.kin.limit_margin(q_end))
        return True, margin >= g.min_margin_rad, travel

    def _ranked_hand_yaws(self, pose: Pose, held: np.ndarray | None, other_faces_than: float | None) -> list[float]:
        """The target's equivalent hand angles (the selector's ``hand_yaws``), best
        first by IK (:meth:`_hand_angle_score`): those whose grasp has a solution; of them those from
        which the carry to the place can be followed with room at both ends; then the least joint
        travel, or for a moving target the least turn of the hand from where it is (turning the
        wrist while chasing a target across the table drifts the arm's redundancy towards a
        singularity, measured). ``other_faces_than``: a square box missed at this angle is taken by
        its other pair of faces first."""
        scored = []
        try:
            yaws = self.selector.hand_yaws(self._request(pose, (None,)))
        except GraspPlanningError:
            return []
        for yaw in yaws:
            try:
                plan = self._grasp(pose, yaw)
            except GraspPlanningError:
                return []
            feasible, carries, travel = self._hand_angle_score(plan, held)
            missed = other_faces_than
            same_faces = missed is not None and abs(float(wrap_angle(yaw - missed, np.pi))) < np.pi / 4
            turn = abs(float(wrap_angle(yaw - float(self.motion.setpoint[3]))))
            scored.append(((not feasible, same_faces, not carries, turn if held is not None else travel), yaw))
        return [yaw for _, yaw in sorted(scored, key=lambda kv: kv[0])]

    def _replan(self, *, first: bool) -> GraspPlan | None:
        """A grasp plan from the tracker's belief now; None after failing the episode.

        A re-plan keeps the hand's angle, unless IK says the arm would then be left without room at the
        grasp (and the hand is not yet going down). The first plan of an attempt takes the best of the
        equivalent hand angles by IK (:meth:`_ranked_hand_yaws`) that the whole pick and place can
        reach; after a miss, a square box's other pair of faces first.
        """
        pose = self._tracked_pose()
        self._planned_at_s = self._now_s
        v = self._target_velocity()
        held = None if v is None else pose.position[:2] + v * self.p.grasp_time_s
        if not first:
            near = None if self.plan is None else self.plan.hand_yaw_rad
            try:
                plan = self._grasp(pose, near)
                if not self._room_kept(plan):  # this hand angle is running out of room: choose again
                    ranked = self._ranked_hand_yaws(pose, held, None)
                    # ... but not with the hand going down over the target (the room was judged before
                    # it went down; another angle there reads as the target turning, and backed the
                    # hand off again and again)
                    other = ranked and abs(float(wrap_angle(ranked[0] - plan.hand_yaw_rad))) > 1e-6
                    if other and self.state not in HAND_OVER_TARGET:
                        plan = self._grasp(pose, ranked[0])
            except GraspPlanningError as exc:
                self._fail(Stage.GRASP_PLANNING, str(exc))
                return None
            if self.state is State.APPROACH and v is not None:  # still in reach?
                reason = self._out_of_reach(plan)
                if reason:
                    self._fail(Stage.IK, reason)
                    return None
            return plan
        missed = self.plan.hand_yaw_rad if (self._turn_hand and self.plan is not None) else None
        self._turn_hand = False
        self._plan_id += 1  # a first plan: the selector plans afresh
        try:
            hand_yaws = self._ranked_hand_yaws(pose, held, missed) or [None]
            candidates = iter(self.selector.candidates(self._request(pose, tuple(hand_yaws))))
        except GraspPlanningError as exc:
            self._fail(Stage.GRASP_PLANNING, str(exc))
            return None
        first_reason = ""  # the best-ranked hand angle's reason, if no angle will do
        for _ in hand_yaws:
            try:
                plan = next(candidates)
            except GraspPlanningError as exc:
                self._fail(Stage.GRASP_PLANNING, str(exc))
                return None
            reason = self._unreachable(plan)
            if isinstance(reason, tuple):
                self._fail(*reason)
                return None
            if not reason:
                return plan
            first_reason = first_reason or reason
        self._fail(Stage.IK, first_reason)
        return None

    def _unreachable(self, plan: GraspPlan) -> str | tuple[Stage, str]:
        """Why the arm cannot do this plan's pick and place ("" if it can; a (stage, reason) to fail
        the episode at once: a moving target that cannot be met at all)."""
        reach = self._reach_targets(plan)
        if isinstance(reach, str):
            return Stage.IK, reach
        for name, target in (*reach, ("place", plan.place)):
            res = self.kin.solve(target, self.motion.q, self.rng, IKParams())
            if not res.success:
                if name not in ("grasp", "place"):  # a moving target's
                    return f"the target leaves the arm's reach before the arm can meet it: {name} is out of reach"
                return f"{name} pose out of reach: {res.reason}"
        # Above the place, some IK solution from which the lowering can be followed: with joint
        # transfers the carry may go in joint space to any of them, the hand turned half a turn or not.
        lines = [(plan.place_above, plan.place)]
        if self.p.joint_transfers:
            turned = _turned_plan(plan, pick=False, place=True)
            lines.append((turned.place_above, turned.place))
            found = goal_candidates(self.kin, [a for a, _ in lines], self.motion.q, self.rng, self.p.goals)
            above = [(g.q, *lines[g.index]) for g in found]
        else:
            res = self.kin.solve(plan.place_above, self.motion.q, self.rng, IKParams())
            above = [(res.q, *lines[0])] if res.success else []
        if not above:
            return "the pose above the place is out of reach"
        floor = self.p.goals.min_line_speed_scale
        if all(line_speed_scale(self.kin, q, start, end, self.p.goals) < floor for q, start, end in above):
            return "the straight lowering onto the place passes too near a singular posture"
        return ""

    # ------------------------------------------------------------------------- moving targets
    def _target_velocity(self) -> np.ndarray | None:
        """The target's horizontal velocity (m/s) while the tracker sees it move; None when it is at
        rest (or not surely moving), and always in open loop (it plans to where the target was)."""
        if self.open_loop:
            return None
        return self.belief.moving_velocity(self._now_s, self.p.moving_speed_m_s)

    # ------------------------------------------------------------------- joint-space transfers
    @property
    def _leg_finished(self) -> bool:
        return self.joints.finished if self._joint else self.move.finished

    @property
    def _motion_finished(self) -> bool:
        """The state's motion has finished: the leg under way and every leg after it."""
        return self._leg_finished and not self._legs

    @property
    def _q(self) -> np.ndarray:
        """The arm's commanded configuration now."""
        return self.joints.q if self._joint else self.motion.q

    def _transfer_to(self, q_goal: np.ndarray, scale: float) -> None:
        """A transfer in joint space to ``q_goal`` (from rest where the Cartesian motion is, or a new
        goal for the transfer under way)."""
        if self._joint:
            self.joints.retarget(q_goal)
        else:
            self.joints.start(self.motion.q, q_goal, scale=scale)
            self._joint = True

    def _cartesian(self) -> None:
        """The Cartesian motion takes over, at rest where a transfer left the arm."""
        if self._joint:
            self.motion.reset_at(self.joints.q)
            self._joint = False

    # ------------------------------------------------------------------------- over the top
    def _raised(self, pose: Pose, h: float) -> Pose:
        return Pose(pose.position + np.array([0.0, 0.0, h]), pose.rotation)

    def _rise_from_here(self, h: float) -> tuple[Pose, np.ndarray] | None:
        """The pose ``h`` straight above the hand (at rest, in the Cartesian motion) and the joints the
        per-tick IK reaches it with; None if it cannot follow the line."""
        here = self.kin.forward(self.motion.q)
        up = self._raised(here, h)
        q = self.motion.q
        for q_k in along_line(self.kin, q, here, up, self.p.goals.line_steps):
            if q_k is None:
                return None
            q = q_k
        return up, q

    def _via_above(
        self, pose: Pose, h: float, q_from: np.ndarray, floor_z: float, q_goal: np.ndarray
    ) -> np.ndarray | None:
        """An IK goal ``h`` above ``pose`` (the hand's angle kept) that a transfer from ``q_from`` reaches
        without the hand going below ``floor_z``, and from which the straight line down to ``pose``
        can be followed; None if there is none. The one on the branch of ``q_goal`` (the goal chosen
        for ``pose``, from which what follows was checked) first: on another branch the line down
        arrives where the lowering after it crawls near a singular posture (evidence:
        docs/decisions.md#motion-and-ik)."""
        via = self._raised(pose, h)
        g = self.p.goals
        same = self.kin.solve(via, q_goal, self.rng, g.ik)
        if same.success and self.kin.limit_margin(same.q) > 0.0:
            if path_low_z(self.kin, q_from, same.q, g) >= floor_z and line_trackable(self.kin, same.q, via, pose, g):
                return same.q
        found = goal_candidates(self.kin, [via], q_from, self.rng, g, lines_to=[pose])
        ok = [c for c in found if c.line_ok and path_low_z(self.kin, q_from, c.q, g) >= floor_z]
        goal = choose_goal(ok, g)
        return None if goal is None else goal.q

    def _transfer_over_the_top(
        self,
        q_goal: np.ndarray,
        scale: float,
        limits: CartesianLimits,
        *,
        rise: bool,
        above: Pose | None = None,
        down: Callable[[], None] | None = None,
    ) -> bool:
        """A transfer to ``q_goal`` whose straight joint path would take the hand down below both of its
        ends goes over the top instead, each leg from rest to rest: straight up from here first
        (``rise``, from the Cartesian motion at rest), in joint space to ``q_goal`` or to a goal
        straight above ``above`` (the goal's pose) and then straight down onto it (``down``: that last
        leg, the caller's, so that it goes to where the plan is by then). The path must keep the hand
        above the lower of the two ends (less ``max_dip_m``). True if so planned (its first leg
        started); False if the direct path does not dip, or no way over the top was found (the direct
        transfer is then the caller's)."""
        g = self.p.goals
        dip = path_dip(self.kin, self._q, q_goal, g)
        if dip <= g.max_dip_m:
            return False
        z_goal = self.kin.forward(q_goal).position[2]
        floor = min(self.kin.forward(self._q).position[2], z_goal) - g.max_dip_m
        for h in g.via_heights_m:
            legs: list[Callable[[], None]] = []
            q_start = self._q
            if rise:
                found = None if self._joint else self._rise_from_here(h)
                if found is None:
                    continue
                up, q_start = found
                legs.append(lambda up=up: self.move.to(up, limits=limits))
            if above is not None:
                q_via = self._via_above(above, h, q_start, floor, q_goal)
                if q_via is None:
                    continue
                legs.append(lambda q=q_via: self._transfer_to(q, scale))
                legs.append(down or (lambda: (self._cartesian(), self.move.to(above, limits=limits))))
            else:
                if path_low_z(self.kin, q_start, q_goal, g) < floor:
                    continue
                legs.append(lambda: self._transfer_to(q_goal, scale))
            note = (
                f"over the top: the joint path would take the hand {dip * 1e3:.0f} mm below its ends, "
                f"so {'up ' if rise else ''}{h * 1e2:.0f} cm{' and down' if above is not None else ''}"
            )
            self.events.append(Event(self.state, self._now_s, note, note=True))
            self._legs.clear()
            self._legs.extend(legs[1:])
            legs[0]()
            return True
        return False

    def _goal(
        self,
        pose: Pose,
        line_to: Pose,
        *,
        seeded: np.ndarray | None = None,
        half_turned: tuple[Pose, Pose] | None = None,
    ):
        """The IK goal for a top-down TCP pose, or the same pose turned half a turn (a parallel gripper
        closes the same way) when the pose's own angle will not do: the best of several solutions
        (:mod:`pickdemo.motion.ik_goals`). ``seeded``: a re-plan keeps to the solution near the goal it had,
        if there is one."""
        if seeded is not None:
            res = self.kin.solve(pose, seeded, self.rng, self.p.goals.ik)
            if res.success and self._joint and not self.joints.finished:
                # Mid-transfer, the goal stays on its branch while it has a solution there: a goal on
                # another branch bends the transfer's path off its straight line in joint space, which
                # can swing the hand down onto the target (evidence: docs/decisions.md#motion-and-ik).
                return res.q, 0
            if res.success and self.kin.limit_margin(res.q) >= self.p.goals.min_margin_rad:
                # a re-plan a hair from a goal whose line was checked keeps that check (the tracker
                # moves the goal by a millimetre or so a frame)
                near = self._line_checked_q is not None and np.max(np.abs(res.q - self._line_checked_q)) < 0.01
                if near or line_trackable(self.kin, res.q, pose, line_to, self.p.goals):
                    if not near:
                        self._line_checked_q = res.q.copy()
                    return res.q, 0
        # The plan's own hand angle first (chosen by IK for the whole pick and place); the half
        # turn only when that angle has no goal whose line can be followed and whose path does not dip.
        g = self.p.goals
        found = goal_candidates(self.kin, [pose], self._q, self.rng, g, lines_to=[line_to])
        goal = choose_goal(found, g)
        if goal is None or not goal.line_ok or goal.dip_m > g.max_dip_m:
            half = half_turned if half_turned is not None else (_half_turn(pose), _half_turn(line_to))
            poses, ends = [pose, half[0]], [line_to, half[1]]
            turned = goal_candidates(self.kin, poses[1:], self._q, self.rng, g, lines_to=ends[1:])
            found += [dataclasses.replace(t, index=1) for t in turned]
            goal = choose_goal(found, g)
        if goal is None:
            return None, 0
        if goal.line_ok:
            self._line_checked_q = goal.q.copy()
        return goal.q, goal.index

    def _line_limits(self, end: Pose) -> CartesianLimits:
        """The near-object limits for a straight line from where the hand is to ``end``, slowed as the
        joints need near a singular posture (:func:`~pickdemo.motion.ik_goals.line_speed_scale`)."""
        here = self.kin.forward(self.motion.q)
        scale = line_speed_scale(self.kin, self.motion.q, here, end, self.p.goals)
        if scale >= 1.0:
            return self.p.near
        return self.p.near.scaled(max(scale, self.p.goals.min_line_speed_scale))

    def _go_to(self, pose: Pose | np.ndarray, limits: CartesianLimits | None = None) -> None:
        """Send the hand to a pose of the plan (or an x4). For a moving target: to where they meet,
        arriving then with its velocity, and following it."""
        v = self._target_velocity()
        if v is None:
            self.move.to(pose, limits=limits)
        elif not self.move.meet(pose, v, limits):
            self._fail(Stage.IK, self._too_fast(v))

    def _too_fast(self, v: np.ndarray) -> str:
        return (
            f"the target moves at {np.linalg.norm(v):.2f} m/s: too fast for the hand "
            f"({self.p.free.velocity:.2f} m/s an axis) to meet it within {self.p.meet_horizon_s:.0f} s"
        )

    def _with_target(self, pose: Pose) -> bool:
        """Whether the hand is at ``pose`` of the plan (for the target where it is now) and moving with
        the target: a moving target's arrival, which re-targets on every estimate never let finish."""
        v = self._target_velocity()
        if v is None:
            return False
        vel4 = np.array([v[0], v[1], 0.0, 0.0])
        want = self.move.x4(pose) + vel4 * (self._now_s - self._planned_at_s)
        off = np.abs(self.motion.setpoint - want)
        p = self.p
        return bool(
            np.linalg.norm(off[:3]) < p.arrive_tolerance_m
            and off[3] < p.arrive_tolerance_rad
            and np.linalg.norm(self.motion.velocity - vel4) < p.arrive_speed_tolerance_m_s
        )

    def _reach_targets(self, plan: GraspPlan) -> list[tuple[str, Pose]] | str:
        """The poses of the pick that must be in reach: the grasp; for a moving target, where the hand
        will meet it and where it will hold it (``grasp_time_s`` later). A string: it cannot be met."""
        v = self._target_velocity()
        if v is None:
            return [("grasp", plan.grasp)]
        t = self.move.meet_in(self.move.x4(plan.pregrasp), v, self.p.free)
        if t is None:
            return self._too_fast(v)
        out = []
        for name, dt in (("the meeting point", t), ("where it would be held", t + self.p.grasp_time_s)):
            d = np.array([v[0], v[1], 0.0]) * dt
            p = plan.grasp.position + d
            out.append((f"{name} ({p[0]:.2f}, {p[1]:.2f}) m in {dt:.1f} s", Pose(p, plan.grasp.rotation)))
        return out

    def _out_of_reach(self, plan: GraspPlan) -> str:
        """Why the moving target cannot be picked where it will be ("" if it can)."""
        reach = self._reach_targets(plan)
        if isinstance(reach, str):
            return reach
        for name, target in reach:
            if not self.kin.solve(target, self.motion.q, self.rng, IKParams()).success:
                return f"the target leaves the arm's reach before the arm can meet it: {name} is out of reach"
        return ""

    def _roi(self, now_s: float) -> tuple[int, int, int, int] | None:
        """Around the tracked target, widened by its uncertainty (None: the whole image)."""
        tp = self.belief.predict(now_s)
        return self._roi_at(tp.position, self.p.roi_margin_m + 3.0 * tp.position_sigma_m)

    def _roi_at(self, centre: np.ndarray, margin_m: float) -> tuple[int, int, int, int] | None:
        r = self.model.geometry.bounding_radius_m + margin_m
        corners = centre + r * UNIT_CUBE
        corners[:, 2] = np.maximum(corners[:, 2], self.p.roi_floor_z_m)
        return roi_around(corners, self.camera.intrinsics, self.camera.T_world_cam, pad_px=self.p.roi_pad_px)

    def _near_limits(self) -> CartesianLimits:
        """Near the object: gentle, but keeping up across the table with a target that moves."""
        return self.p.near if self._target_velocity() is None else self.p.near.with_xy_of(self.p.free)

    def _track_plan(self) -> GraspPlan | None:
        """A fresh plan when a new estimate has come in (closed loop), else None."""
        if self.open_loop or not self._fresh_estimate:
            return None
        self._fresh_estimate = False
        return self._replan(first=False)

    # ===================================================================================== states
    # ---- LOOK: from the home pose, full frames until the tracker holds the target.
    def _enter_look(self, obs: Observation) -> None:
        if not self.events:
            self.events.append(Event(State.LOOK, obs.time_s, "looking for the target", note=True))
        self.grip.open()
        self._attempt_start_s = obs.time_s
        self.belief.restart()
        self.scale.start()
        self._weighed_force_n = 0.0
        self._look_frames = 0
        self._fresh_estimate = False
        if self._look_here:  # the first look, from where the arm is (at rest)
            self._look_here = False
            return
        if self.p.joint_transfers:
            if not self._transfer_over_the_top(rm.HOME_Q, self.p.transfer_scale, self.p.free, rise=True):
                self._transfer_to(rm.HOME_Q, self.p.transfer_scale)
        else:
            self.move.to(self.home_x4, limits=self.p.free)

    def _tick_look(self, obs: Observation) -> Transition:
        if self._motion_finished:  # at rest with the hand empty: what the wrist reads is the hand
            self.scale.tare(self._wrist_load(obs))
        needed = 1 if self.open_loop else self.p.look_min_estimates
        if self.belief.accepted >= needed:
            plan = self._replan(first=True)
            if plan is None:
                return None
            self.plan = plan
            unsafe = self._unsafe(obs.time_s, calibration_only=True)  # (more frames cannot mend that)
            if unsafe and (self.wrist is None or self.open_loop):
                self._fail(Stage.PERCEPTION, f"{unsafe}, and no camera can see it closer: not tried")
                return None
            tp = self.belief.predict(obs.time_s)
            yaw = ""
            if self.symmetry > 0:
                said = np.degrees(_wrap(tp.yaw_rad, self.symmetry))
                yaw = f", yaw {said:+.2f} deg (modulo {np.degrees(self.symmetry):.0f})"
            return State.APPROACH, (
                f"target at ({tp.position[0]:.4f}, {tp.position[1]:.4f}, {tp.position[2]:.4f}) m{yaw} "
                f"from {self.belief.accepted} estimate(s); grasp yaw {np.degrees(plan.hand_yaw_rad):+.1f} deg"
                + (f" (attempt {self.attempt})" if self.attempt > 1 else "")
            )
        if self._look_frames >= self.p.look_max_frames:
            self._fail(
                Stage.PERCEPTION,
                f"no estimate of the target in {self._look_frames} frames: {self.counters.last_error or 'rejected'}",
            )
        return None

    # ---- APPROACH: to above the target, re-targeted as estimates arrive.
    def _enter_approach(self, obs: Observation) -> None:
        assert self.plan is not None
        self._hover_since = None
        if not self.p.joint_transfers or self._target_velocity() is not None:
            # Cartesian (a moving target is met so, moving with it)
            self._cartesian()
            self._go_to(self.plan.pregrasp, limits=self.p.free)
            return
        q, turned = self._goal(self.plan.pregrasp, self.plan.grasp)
        if q is None:
            self._fail(Stage.IK, "pregrasp pose out of reach: no IK solution for either hand angle")
            return
        if turned:
            self.plan = _turned_plan(self.plan, pick=True, place=True)
        down = lambda: (self._cartesian(), self._go_to(self.plan.pregrasp, limits=self.p.free))  # noqa: E731
        if not self._transfer_over_the_top(
            q, self.p.transfer_scale, self.p.free, rise=False, above=self.plan.pregrasp, down=down
        ):
            self._transfer_to(q, self.p.transfer_scale)

    def _tick_approach(self, obs: Observation) -> Transition:
        if not self.open_loop and self.belief.lost(obs.time_s):
            # Nothing it sees agrees with its belief any more: look again from home, a few times.
            self._relooks += 1
            if self._relooks > self.p.max_relooks:
                self._fail(Stage.PERCEPTION, f"target lost: no estimate accepted for {self.p.tracker.lost_after_s} s")
                return None
            self._after_back_off = State.LOOK
            return State.BACK_OFF, "target lost while approaching: looking again"
        plan = self._track_plan()
        if plan is not None:
            self.plan = plan
            if self._legs:  # going over the top: its last leg goes down to where the plan is by then
                pass
            elif self._joint:  # the transfer goes on to the new plan's goal, on the same branch
                q, turned = self._goal(plan.pregrasp, plan.grasp, seeded=self.joints.target)
                if q is None:
                    self._fail(Stage.IK, "pregrasp pose out of reach: no IK solution for either hand angle")
                    return None
                if turned:
                    self.plan = _turned_plan(plan, pick=True, place=True)
                self.joints.retarget(q)
            else:
                self._go_to(plan.pregrasp)
        if (self._motion_finished or self._with_target(self.plan.pregrasp)) and not self.finished:
            unsafe = "" if self.open_loop else self._unsafe(obs.time_s)  # (open loop: the plan of one look)
            if unsafe:  # wait above it for more frames, or the hand's camera, to make it surer (a bounded wait)
                self._hover_since = obs.time_s if self._hover_since is None else self._hover_since
                if obs.time_s - self._hover_since >= self.p.hover_max_s:
                    self._fail(Stage.PERCEPTION, f"{unsafe} after {obs.time_s - self._hover_since:.1f} s above it")
                return None
            return State.DESCEND, "above the target" + (
                ", moving with it" if self._target_velocity() is not None else ""
            )
        return None

    def _unsafe(self, now_s: float, *, calibration_only: bool = False) -> str:
        """Why the hand may not go down on the plan yet ("" when it may): where the target is, its
        cameras' calibration included (``calibration_only``: that alone), is less sure than the grasp's
        clearance allows."""
        assert self.plan is not None
        tp = self.belief.predict(now_s)
        sigma = tp.calibration_sigma_m if calibration_only else tp.grasp_sigma_m
        clearance = rm.FINGER_MAX_M - self.plan.object_width_m / 2.0  # from the fingers open to the object
        if self.p.clearance_sigmas * sigma <= clearance:
            return ""
        return (
            f"the target is known to {self.p.clearance_sigmas:g} x {sigma * 1e3:.1f} mm"
            + (" (its camera's calibration)" if calibration_only else "")
            + ", more than the grasp's "
            f"clearance of {clearance * 1e3:.1f} mm"
        )

    # ---- DESCEND: straight down onto the grasp; backs off if the target moves away.
    def _moved_under_hand(self) -> Transition:
        """Back off (and approach again) when views refused by the tracker say the target moved under the hand."""
        if self._moved_seen is None:
            return None
        off, camera, t = self._moved_seen
        self._moved_seen = None
        self._far_views.clear()
        self._move_unconfirmed = True  # (until the tracker finds where it went)
        self.grip.open()
        self._after_back_off = State.APPROACH
        by = "the hand's camera" if camera == WRIST_CAMERA else "the camera"
        return State.BACK_OFF, (
            f"{by} sees the target {off * 1e3:.0f} mm from where it was tracked (frame of t = {t:.2f} s) "
            f"during the {self.state.value}: backing off to approach again"
        )

    def _touched_early(self, obs: Observation) -> Transition:
        """Back off and look again when a finger touches something on the way down: the fingers go
        down beside the target, in free space, so a touch means the target (or something else) is not
        where it was seen; closing there would close on nothing or on it askew. The fixed camera, with
        the hand over the target, cannot say so; the fingers can. At most ``touch_back_offs`` times
        (then the descent goes on as before), and not again where it touched before if the look since
        found the target there (a neighbour brushed, not a move). Not for an object nobody described:
        its grasps, from its cloud, go down close to its surface, so a finger brushing it is no news
        (evidence: docs/decisions.md#the-loop-and-the-tracker)."""
        left, right = obs.finger_contacts
        if not (left or right) or self._touch_back_offs >= self.p.touch_back_offs:
            return None
        if self.belief.unknown:  # grasps from a cloud go down close to its surface: a finger brushing it is no news
            return None
        if self.open_loop:  # one look and the plan played (the comparison): no feedback
            return None
        assert self.plan is not None
        grasp_xy = self.plan.grasp.position[:2]
        if self._touched_at is not None and np.linalg.norm(grasp_xy - self._touched_at) < self.p.moved_tolerance_m:
            return None  # touched here before, and the look since found the target where it was: a neighbour
        self._touched_at = grasp_xy.copy()
        self._touch_back_offs += 1
        self.grip.open()
        self._after_back_off = State.LOOK
        above = (float(self.kin.forward(obs.arm_q).position[2]) - float(self.plan.grasp.position[2])) * 1e3
        which = "both fingers" if left and right else ("the left finger" if left else "the right finger")
        return State.BACK_OFF, (
            f"{which} touched something {above:.0f} mm above the grasp during the descent: backing off to look again"
        )

    def _enter_descend(self, obs: Observation) -> None:
        assert self.plan is not None
        self._moved_seen = None
        self._descent_plan = self.plan
        v = self._target_velocity()
        self._descent_ref = (self.plan.grasp.position[:2].copy(), np.zeros(2) if v is None else v, self._planned_at_s)
        self._cartesian()
        self._go_to(self.plan.grasp, limits=self._near_limits())

    def _tick_descend(self, obs: Observation) -> Transition:
        moved = self._moved_under_hand()
        if moved is None:
            moved = self._touched_early(obs)
        if moved is not None:
            return moved
        plan = self._track_plan()
        if plan is not None:
            assert self._descent_plan is not None and self._descent_ref is not None
            xy, v, t = self._descent_ref  # where the descent expected the target now
            moved = float(np.linalg.norm(plan.grasp.position[:2] - (xy + v * (obs.time_s - t))))
            turned = abs(plan.hand_yaw_rad - self._descent_plan.hand_yaw_rad)
            self.plan = plan
            if moved > self.p.moved_tolerance_m or turned > self.p.moved_tolerance_rad:
                self._after_back_off = State.APPROACH
                return State.BACK_OFF, (
                    f"the target moved {moved * 1e3:.0f} mm, {np.degrees(turned):.0f} deg during the descent: "
                    "backing off to approach again"
                )
            self._go_to(plan.grasp)
        if (self._motion_finished or self._with_target(self.plan.grasp)) and not self.finished:
            return State.CLOSE, "at the grasp pose"
        return None

    # ---- CLOSE: fingers close with this attempt's force; held or missed.
    def _enter_close(self, obs: Observation) -> None:
        self.grip.close(self.grip_force_n)
        self.grip.watch()
        self._held_at = None
        self._hold_views.clear()

    def _tick_close(self, obs: Observation) -> Transition:
        assert self.plan is not None
        stalled = self.grip.stopped(obs)
        if not stalled and not self._holding(obs):
            moved = self._moved_under_hand()
            if moved is not None:
                return moved
        if not stalled and obs.time_s - self._since_s < self.p.close_timeout_s:
            return None
        if self._holding(obs):
            if self.plan.width_known and self.grip.too_wide(obs, self.plan.object_width_m):
                reason = (
                    f"fingers stopped at {obs.opening_m * 1e3:.1f} mm "
                    f"(expected {self.plan.object_width_m * 1e3:.0f} mm): held askew, or not it alone"
                )
                return self._retry(Stage.GRASP, "missed", reason)
            off_centre = self._held_off_centre(obs)
            if off_centre is False:
                return None  # (waiting for the hand's camera to see the hold)
            if off_centre is not None:
                return self._retry(Stage.GRASP, "held off centre", off_centre)
            self.grasp_width_m = obs.opening_m
            return State.LIFT, (
                f"holding: fingers at {obs.opening_m * 1e3:.1f} mm, contact on both, {self.grip_force_n:.0f} N"
            )
        reason = (
            f"fingers closed to {obs.opening_m * 1e3:.1f} mm "
            f"(expected {self.plan.object_width_m * 1e3:.0f} mm): nothing held"
        )
        return self._retry(Stage.GRASP, "missed", reason)

    def _held_off_centre(self, obs: Observation) -> str | bool | None:
        """Held, the width right: whether the hand's camera sees it held off centre (a reason), cannot
        say yet (False: a view of the hold is on its way) or sees nothing wrong (None). The fingers
        centre it between them, not along them: pushed as they closed, it may be held near an end of
        a face and carried that far from where it should go. A whole view from a frame taken once the
        fingers held it, within ``hold_look_s``; no view (or no camera on the hand): as before, lifted.
        Not for an object nobody described (a grasp from its cloud holds it anywhere)."""
        if self.wrist is None or self.open_loop or self.belief.unknown:
            return None
        assert self.plan is not None
        if self._held_at is None:
            self._held_at = obs.time_s
        views = [c for t, c in self._hold_views if t >= self._held_at]
        if not views:
            return False if obs.time_s - self._held_at < self.p.hold_look_s else None
        tcp = self.kin.forward(obs.arm_q).position[:2]
        off = float(np.linalg.norm(tcp - views[-1][:2] - np.asarray(self.plan.place_offset_xy)))
        if off <= self.p.off_centre_tolerance_m:
            return None
        return f"the hand's camera sees it held {off * 1e3:.0f} mm off centre"

    # ---- LIFT, TRANSPORT, LOWER: carry it, watching the hold.
    def _enter_lift(self, obs: Observation) -> None:
        assert self.plan is not None
        self.grip.watch_hold()
        lift = self.move.x4(self.plan.lift)
        v = self.motion.velocity[:2]
        self._lifted_off = np.any(v != 0.0)  # (a target held on the move is weighed at the top)
        if self._lifted_off:  # held on the move: carry on along its way a little while rising
            lift[:2] = self.motion.setpoint[:2] + v * self.p.lift_lead_s
        else:  # first just off the table, to weigh it before it hangs long at the first grip force
            lift[2] = self.plan.grasp.position[2] + self.p.payload.lift_off_m
        self.motion.set_target(lift, limits=self._near_limits().scaled(self.lift_scale))
        self.scale.start()

    def _tick_lift(self, obs: Observation) -> Transition:
        if self._dropped(obs):
            return self._retry(Stage.LIFT, "dropped while lifting", f"fingers at {obs.opening_m * 1e3:.1f} mm")
        if not (self._motion_finished and self._weigh(obs)):
            return None
        if not self._lifted_off:  # weighed just off the table: on up to the carry height
            self._lifted_off = True
            self.motion.set_target(self.move.x4(self.plan.lift), limits=self._near_limits().scaled(self.lift_scale))
            return None
        return State.TRANSPORT, f"lifted, fingers at {obs.opening_m * 1e3:.1f} mm"

    def _enter_transport(self, obs: Observation) -> None:
        assert self.plan is not None
        straight = not (self.p.joint_transfers and self.p.carry_in_joint_space)
        if straight and (not self.p.joint_transfers or self._straight_carry_lowers()):
            self.move.to(self.plan.place_above, limits=self.p.free.scaled(self.lift_scale * self._payload_scale()))
            return
        # in joint space, to a goal from which the lowering can be tracked
        if straight:
            note = "carried in joint space: the straight line would pass too near a singular posture"
            self.events.append(Event(self.state, self._now_s, note, note=True))
        other = _turned_plan(self.plan, pick=False, place=True)
        q, turned = self._goal(self.plan.place_above, self.plan.place, half_turned=(other.place_above, other.place))
        if q is None:
            self._fail(Stage.IK, "place pose out of reach: no IK solution for either hand angle")
            return
        if turned:  # put down with the hand turned half a turn: the same for the place, not the grasp
            self.plan = other
        scale = self.p.carry_scale * self.lift_scale * self._payload_scale()
        limits = self.p.free.scaled(self.lift_scale * self._payload_scale())
        if not self._transfer_over_the_top(q, scale, limits, rise=True, above=self.plan.place_above):
            self._transfer_to(q, scale)

    def _payload_scale(self) -> float:
        """The carry's speed share for what the wrist weighed: a heavier hold is carried more gently
        (its accelerations as the square of this), so that it does not swing in the pads."""
        m = self.scale.payload_kg
        light = self.p.payload.gentle_above_kg
        return 1.0 if m is None or m <= light else float(np.sqrt(light / m))

    def _straight_carry_lowers(self) -> bool:
        """Whether the arm, carried along a straight line to above the place (the per-tick IK keeps
        to the branch it is on), stays clear of singular postures and joint limits on the way and
        arrives where it can follow the lowering onto the place
        (:func:`~pickdemo.motion.ik_goals.straight_carry_ok`)."""
        assert self.plan is not None
        return straight_carry_ok(
            self.kin,
            self.motion.q,
            self.motion.setpoint,
            self.move.x4(self.plan.place_above),
            self.plan.place,
            speed_m_s=self.p.free.scaled(self.lift_scale).velocity,
            posture=self.motion.posture,
            params=self.p.goals,
        )

    def _tick_transport(self, obs: Observation) -> Transition:
        if self._dropped(obs):
            return self._retry(Stage.TRANSPORT, "dropped in transit", f"fingers at {obs.opening_m * 1e3:.1f} mm")
        if self._motion_finished:
            return State.LOWER, "above the place position"
        return None

    def _enter_lower(self, obs: Observation) -> None:
        assert self.plan is not None
        self._cartesian()
        self.move.to(self.plan.place, limits=self._line_limits(self.plan.place))

    def _tick_lower(self, obs: Observation) -> Transition:
        if self._dropped(obs):
            return self._retry(Stage.TRANSPORT, "dropped in transit", f"fingers at {obs.opening_m * 1e3:.1f} mm")
        if self._motion_finished:
            return State.RELEASE, "lowered onto the table"
        return None

    # ---- RELEASE, RETREAT, HOME, VERIFY.
    def _enter_release(self, obs: Observation) -> None:
        self.released_at_s = obs.time_s
        self.grip.open()
        self.grip.watch()
        self._forced_open = False

    def _tick_release(self, obs: Observation) -> Transition:
        assert self.plan is not None
        opened = self.grip.opened(obs)
        stopped = not opened and self.grip.stopped(obs)
        if stopped and not self._forced_open and self.grip.holding(obs, self.plan.object_width_m):
            # The fingers stopped on the object instead of opening (a simulated Panda's fingers jammed
            # so after a held cube had turned half a turn in the carry, measured: the retreat then
            # lifted it away). Open with the hand's full force before letting go of it for good.
            self._forced_open = True
            self.grip.open(self.p.max_grip_force_n)
            self.grip.watch()
            force = self.p.max_grip_force_n
            note = (
                f"the fingers stopped at {obs.opening_m * 1e3:.1f} mm, still on the target: opening with {force:.0f} N"
            )
            self.events.append(Event(self.state, self._now_s, note, note=True))
            return None
        if opened or stopped or obs.time_s - self._since_s > self.p.close_timeout_s:
            self._end_attempt("placed", "")
            p = self.plan.place.position
            if self.p.drop_place:  # (let go from above: nothing to back away from)
                nxt = State.HOME if self.p.home_after_place else State.DONE
                return nxt, f"dropped at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})"
            return State.RETREAT, f"released at ({p[0]:.3f}, {p[1]:.3f})"
        return None

    def _enter_retreat(self, obs: Observation) -> None:
        assert self.plan is not None
        self.move.to(self.plan.retreat, limits=self._line_limits(self.plan.retreat))

    def _tick_retreat(self, obs: Observation) -> Transition:
        return (State.HOME, "clear of the object") if self._motion_finished else None

    def _enter_home(self, obs: Observation) -> None:
        if self.p.joint_transfers:
            if not self._transfer_over_the_top(rm.HOME_Q, self.p.transfer_scale, self.p.free, rise=True):
                self._transfer_to(rm.HOME_Q, self.p.transfer_scale)
        else:
            self.move.to(self.home_x4, limits=self.p.free)

    def _tick_home(self, obs: Observation) -> Transition:
        if not self._motion_finished:
            return None
        return (State.VERIFY, "arm home") if self.p.verify_place else (State.DONE, "arm home")

    def _enter_verify(self, obs: Observation) -> None:
        self._verify_asked = False
        self.verify_estimate = None

    def _tick_verify(self, obs: Observation) -> Transition:
        if not self._verify_asked:
            return None
        if self.verify_estimate is None:
            return State.DONE, "the camera does not find the target at the end"
        seen = self.verify_estimate.pose.position
        err = float(np.hypot(seen[0] - self.place_xy[0], seen[1] - self.place_xy[1]))
        said = f"the camera sees the target {err * 1e3:.1f} mm from the place position"
        if self.place_tolerance_m is None or err <= self.place_tolerance_m:
            return State.DONE, said
        said += f" (tolerance {self.place_tolerance_m * 1e3:.0f} mm)"
        if self.attempt >= self.max_attempts:
            return State.DONE, f"{said}; no attempt left to place it again"
        # Placed off: this attempt's record says so, and the next picks it up from where it lies.
        self.attempts[-1] = dataclasses.replace(self.attempts[-1], outcome="placed off", reason=said)
        self.attempt += 1
        return State.LOOK, f"{said}: picking it up again; attempt {self.attempt} of {self.max_attempts} follows"

    def _enter_done(self, obs: Observation) -> None:
        pass

    def _tick_done(self, obs: Observation) -> Transition:
        return None

    # ---- BACK_OFF: open, straight up to a safe height, then look or approach again.
    def _enter_back_off(self, obs: Observation) -> None:
        if self._after_back_off in (State.LOOK, State.FAILED):
            self.grip.open()
        if self._joint:  # in free space, mid-transfer: on to home from where it is
            self.joints.retarget(rm.HOME_Q)
            return
        grasp_z = self.plan.grasp.position[2] if self.plan is not None else self.p.back_off_grasp_z_m
        safe_z = self.p.grasp.pregrasp_height_m + grasp_z
        x4 = self.motion.setpoint.copy()
        x4[2] = max(x4[2], safe_z)
        # Limits change only at rest: lowered mid-motion, Ruckig may overshoot while braking.
        limits = self._near_limits() if self.motion.finished else None
        if self._after_back_off is State.APPROACH and self._target_velocity() is not None:
            self._go_to(x4, limits=limits)  # up, and along with it
            return
        self.motion.set_target(x4, limits=limits)

    def _tick_back_off(self, obs: Observation) -> Transition:
        if self._after_back_off is State.APPROACH:
            plan = self._track_plan()  # keep following the target while rising
            if plan is not None:
                self.plan = plan
        if self._motion_finished:
            nxt = self._after_back_off
            if nxt is State.FAILED and self._failing is not None:
                self._braked = True  # (at rest already)
                self._fail(self._failing.stage, self._failing.reason)
                return None
            return nxt, "clear above the table: " + ("look again" if nxt is State.LOOK else "approach again")
        return None


@dataclass(frozen=True)
class StateHandlers:
    """A state's entry action (run once, when it is entered) and exit test (run every tick)."""

    enter: Callable[[PickMachine, Observation], None]
    tick: Callable[[PickMachine, Observation], Transition]


#: The dispatch table: every state the machine runs (``FAILED`` is final and runs nothing).
STATES: dict[State, StateHandlers] = {
    State.LOOK: StateHandlers(PickMachine._enter_look, PickMachine._tick_look),
    State.APPROACH: StateHandlers(PickMachine._enter_approach, PickMachine._tick_approach),
    State.DESCEND: StateHandlers(PickMachine._enter_descend, PickMachine._tick_descend),
    State.CLOSE: StateHandlers(PickMachine._enter_close, PickMachine._tick_close),
    State.LIFT: StateHandlers(PickMachine._enter_lift, PickMachine._tick_lift),
    State.TRANSPORT: StateHandlers(PickMachine._enter_transport, PickMachine._tick_transport),
    State.LOWER: StateHandlers(PickMachine._enter_lower, PickMachine._tick_lower),
    State.RELEASE: StateHandlers(PickMachine._enter_release, PickMachine._tick_release),
    State.RETREAT: StateHandlers(PickMachine._enter_retreat, PickMachine._tick_retreat),
    State.HOME: StateHandlers(PickMachine._enter_home, PickMachine._tick_home),
    State.VERIFY: StateHandlers(PickMachine._enter_verify, PickMachine._tick_verify),
    State.BACK_OFF: StateHandlers(PickMachine._enter_back_off, PickMachine._tick_back_off),
    State.DONE: StateHandlers(PickMachine._enter_done, PickMachine._tick_done),
}


def _half_turn(pose: Pose, shift: np.ndarray | None = None) -> Pose:
    """A top-down TCP pose turned half a turn about the vertical: a parallel gripper's equivalent (moved
    by ``shift``, m)."""
    return top_down(pose.position if shift is None else pose.position + shift, float(pose.rpy[2]) + np.pi)


def _turned_plan(plan: GraspPlan, *, pick: bool, place: bool) -> GraspPlan:
    """The plan with the hand turned half a turn for the pick's poses, the place's, or both. The place
    turned and not the pick turns the held object with the hand: its centre, not the TCP, stays over
    the place (the TCP moves to the other side of it)."""
    turn: dict[str, object] = {}
    if pick:
        turn.update(pregrasp=_half_turn(plan.pregrasp), grasp=_half_turn(plan.grasp), lift=_half_turn(plan.lift))
    if place:
        ox, oy = plan.place_offset_xy
        shift = np.array([-2.0 * ox, -2.0 * oy, 0.0]) if not pick else np.zeros(3)
        turn.update(
            place_above=_half_turn(plan.place_above, shift),
            place=_half_turn(plan.place, shift),
            retreat=_half_turn(plan.retreat, shift),
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
