"""The pick skill's vocabulary: its states, its parameters, what it records, the cameras it knows
and the frames it asks them for, and its retry policy as data."""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass

import numpy as np

from pickdemo.core.camera import Intrinsics
from pickdemo.core.geometry import Pose
from pickdemo.grasping.top_down import GraspParams
from pickdemo.motion.ik_goals import GoalParams
from pickdemo.motion.online import CartesianLimits
from pickdemo.skills.actions import GripParams, PayloadParams
from pickdemo.tracking.belief import GateParams
from pickdemo.tracking.tracker import TrackerParams

#: A state may hand over to the next within one tick (an exit test met at once): at most this many times.
MAX_TRANSITIONS_PER_TICK = 4
#: On a belt, the least speed of a moving target (m/s): a slow belt's 1 cm/s is well clear of it
BELT_MOVING_SPEED_M_S = 0.004


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
#: The states with the target in the hand: a failure there drops it under the hand.
HELD_STATES = frozenset({State.LIFT, State.TRANSPORT, State.LOWER})
#: States whose motion, failed (IK, a trajectory), the next attempt may plan again: the hand empty, or
#: the target just lifted (let go there, it falls back where it was)
REPLANNABLE = frozenset({State.APPROACH, State.DESCEND, State.LIFT})
#: States in which the hand is over the target: a partial view of it is not acted on.
HAND_OVER_TARGET = frozenset({State.DESCEND, State.CLOSE})

Transition = tuple[State, str] | None  # the next state and what it says, or stay


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
    look_min_estimates: int = 2  # accepted estimates before the first plan (1 when open loop)
    look_max_frames: int = 10  # frames in LOOK without an accepted estimate: the episode fails
    #: ... after this many, the arm moves aside if it hides the table from the fixed camera (at most
    #: ``look_asides`` times a look, each to show what all the postures before it hid)
    look_aside_frames: int = 3
    #: looking again (after a miss, a drop, a place judged off), the first ``look_aside_frames`` frames
    #: are of the region about where the target was last known, this much wider (m): the object found
    #: there is the target, not a look-alike elsewhere; then the whole view
    relook_margin_m: float = 0.06
    look_asides: int = 2
    #: ... then, with a camera on the hand, this many looks from above where no view has seen the table
    look_searches: int = 3
    max_relooks: int = 2  # the target lost while approaching: look again from home, at most this often
    #: a target that stood still when the pick was planned and now moves out of the arm's reach (it
    #: tipped over, it rolls): the arm looks again from home, waiting this long (s) for it to stop
    stop_wait_s: float = 3.0
    #: no hand angle's descent can be followed from the pregrasp's full height (a small arm near its
    #: base: its hand points down only low there): the descent starts lower, where the arm follows it,
    #: down to this share of the robot's pregrasp height (the hand still comes down from above the object)
    min_descent_share: float = 0.5
    moved_tolerance_m: float = 0.008  # during the descent, a target this far from the plan: back off
    moved_tolerance_rad: float = float(np.radians(8.0))
    moved_views: int = 2  # ... or this many whole views in a row refused that far from the track: back off
    #: backed off so this often for a move the approach then found the target back from (the hand over
    #: it hid part of it: its view shifted, the target did not), the descent goes on to the plan it set
    #: out with, whatever views say on the way down
    shadow_back_offs: int = 2
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
    #: the last look: frames until two in a row see the target within this of each other (m), as
    #: settled (a target still rolling or toppling is judged where it comes to rest) ...
    verify_settled_m: float = 0.002
    #: ... or this many frames, judged on the last, saying it was still moving
    verify_max_frames: int = 10
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
    #: a grasp from the side's straight lines near the object (descent, lift, way out, retreat), run as
    #: joint transfers: at this share of the joints' limits
    side_line_scale: float = 0.2
    #: a motion whose straight way meets something is planned around it (issue 59); off: straight, as before
    plan_around: bool = True
    plan_max_checks: int = 20000  # states a plan checks before it gives up (:mod:`pickdemo.motion.planner`)
    #: a joint transfer's path is checked again each time a view changes the world model, and planned
    #: again from rest where it meets something now (:mod:`pickdemo.skills.pick.replan`); at most so often
    #: an attempt (a world model that keeps changing is not chased for ever)
    replan_on_change: bool = True
    max_replans: int = 3
    #: after the place, home, look at the place (a target seen put down off it is picked up again);
    #: off: done once home (a clear round looks at the whole table next)
    verify_place: bool = True
    #: let go from the carry's height over the place (at least ``place_z_m`` up), then straight home: a
    #: drop into a tray (no lowering onto the place, no retreat from it)
    drop_place: bool = False
    #: after the place, home (off: done where it let go, at rest; a sequencer goes on from there)
    home_after_place: bool = True
    #: before the first approach (and each attempt's), the fixed camera's whole view of the place:
    #: something standing there fails the episode in ``place`` before the target is picked up
    check_place: bool = True
    #: ... something: at least this much of its surface seen (m^2: half a square centimetre, about 20
    #: pixels of a camera a metre away; the world model's points each stand for their share of it)
    place_taken_area_m2: float = 5e-5
    #: ... within this of the target's footprint about the place (m)
    place_clearance_m: float = 0.005
    #: ... then the nearest spot where it is free, up to this share of the task's place tolerance away
    place_shift_share: float = 0.5
    #: ... or where the fingers, opening only this far past the target (m, each), let go of it clear of it
    release_margin_m: float = 0.01
    #: at the end, the target seen this far (m) above where it should rest (on something), or below it
    #: (fallen over): not placed
    verify_height_tolerance_m: float = 0.015
    #: ... or this many of the estimate's own standard deviations in height, when that is more: a camera
    #: known only to its calibration's accuracy (5 mm and 1 deg: 11 mm at a metre) sees a height that far
    #: off, and an estimate's covariance carries it
    verify_height_sigmas: float = 3.0
    #: lowering a described target, the wrist's vertical load this far (N) below what the hand and its
    #: load weigh at rest: what it holds stands on something (the motors' share keeps the reading above
    #: it on the way down, measured: 15.7 N moving, 8.4 at rest, -7.5 one frame after a cube met a carton)
    touch_down_n: float = 3.0
    #: ... met this far (m) or more above the planned height, a described target is on something at the
    #: place (the lowering stops, the hand rises holding it, and the episode fails in ``place``); nearer,
    #: it is put down there (an object nobody described is lowered to the planned height)
    touch_early_m: float = 0.01
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


@dataclass(frozen=True)
class Retry:
    """What a failed attempt changes in the next: the grip force and the lift's speed share
    (multiplied), whether a square box is taken by its other pair of faces first, and whether a grasp
    from any side comes before the top-down ones (the grasp held nothing, or let the object slip)."""

    force_factor: float = 1.0
    lift_factor: float = 1.0
    other_faces: bool = False
    any_side_first: bool = False


#: The retry policy, by the failed attempt's outcome: a miss looks again (a square box by its other
#: faces), a hold off centre grasps it again where it lies, a slip holds harder and lifts more gently.
RETRIES: dict[str, Retry] = {
    "missed": Retry(other_faces=True, any_side_first=True),
    "held off centre": Retry(),
    "motion failed": Retry(),
}
SLIPPED = Retry(force_factor=2.0, lift_factor=0.5, any_side_first=True)  # any other outcome: it slipped out


@dataclass(frozen=True)
class Event:
    """A state entered, at a simulated time, with what it says."""

    state: State
    time_s: float
    message: str
    note: bool = False  # something seen within a state, not a transition


@dataclass(frozen=True)
class CameraModel:
    """What the robot knows of one of its cameras: the intrinsics of its whole image and where it is:
    fixed in the world (``pose`` is ``T_world_cam``) or on the hand (``on_hand``: ``pose`` is
    ``T_tcp_cam``, from its hand-eye calibration, and it measures depths from ``near_m`` to ``far_m``).
    Frames and estimates carry its ``name``."""

    intrinsics: Intrinsics
    pose: Pose
    name: str = "camera"
    on_hand: bool = False
    near_m: float = 0.0
    far_m: float = float("inf")


@dataclass(frozen=True)
class FrameRequest:
    """A frame perception wants now from the camera ``camera``: the whole image (``roi`` None) or a
    region of it."""

    roi: tuple[int, int, int, int] | None
    survey: bool = False  # every object on the table (a clear round's look), not the target's pose
    camera: str = "camera"
