"""The pick behaviour: a state machine called once per control tick.

Pure: no simulator. Each tick :meth:`PickMachine.update` gets the robot's observation (joints,
finger opening, finger contacts) and returns a :class:`~pickdemo.interfaces.Command`; perception's
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

While it approaches, descends and closes it keeps looking (closed loop): the tracker fuses every
estimate, and the motion is re-targeted to where the tracker says the target is. With
``open_loop`` it looks only in ``LOOK`` and plays the plan from that one look, for comparison.

A target the tracker sees moving (a belt) is met where it will be: each re-target solves for the
soonest time the hand can be at the plan's pose carried along at the target's velocity
(:meth:`~pickdemo.motion.OnlineMotion.intercept`), and sends Ruckig there with the target's
velocity as its target velocity and that time as its minimum duration; the hand then moves with
it, goes down with it, closes on it and lifts it off the belt. A target that will have left the
arm's reach by the time it is held, or that runs faster than the hand, fails the episode in ``ik``
by name.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pickdemo import robot_model as rm
from pickdemo.camera import Intrinsics, roi_around
from pickdemo.geometry import Pose, wrap_angle
from pickdemo.grasp import GraspParams, GraspPlan, GraspPlanningError, joint7_centre_yaw, plan_grasp
from pickdemo.interfaces import Command, Observation
from pickdemo.kinematics import IKParams, PandaKinematics
from pickdemo.motion import CartesianLimits, MotionError, MotionSample, OnlineMotion, pose_to_x4
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel
from pickdemo.result import AttemptRecord, Failure, Stage
from pickdemo.tracker import TargetTracker, TrackerParams


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


#: A turned hand (a retry's other grasp yaw) is taken only if joint 7 stays within this (its limit: 2.90 rad).
WRIST_TURN_LIMIT_RAD = 2.4
UNIT_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)

#: States in which the closed loop keeps looking at the target (a region of interest around it).
TRACKING_STATES = frozenset({State.APPROACH, State.DESCEND, State.CLOSE, State.BACK_OFF})


@dataclass(frozen=True)
class MachineParams:
    """Behaviour of the pick; SI units."""

    grasp: GraspParams = GraspParams()
    free: CartesianLimits = CartesianLimits(  # away from the object
        velocity=0.30, acceleration=1.5, jerk=15.0, yaw_velocity=1.5, yaw_acceleration=6.0, yaw_jerk=60.0
    )
    near: CartesianLimits = CartesianLimits(velocity=0.10, acceleration=0.5, jerk=5.0)  # near it: descend, lift
    grip_force_n: float = 20.0  # per finger; measured: holds a 5 cm cube with ~1 mm slip
    max_grip_force_n: float = 70.0  # the Franka Hand's continuous grip force
    open_force_n: float = 20.0
    look_min_estimates: int = 2  # accepted estimates before the first plan (1 when open loop)
    look_max_frames: int = 10  # frames in LOOK without an accepted estimate: the episode fails
    max_relooks: int = 2  # the target lost while approaching: look again from home, at most this often
    moved_tolerance_m: float = 0.008  # during the descent, a target this far from the plan: back off
    moved_tolerance_rad: float = float(np.radians(8.0))
    hold_margin_m: float = 0.008  # fingers closed this far past the object's width: nothing held
    drop_ticks: int = 3  # ticks in a row without a hold before a drop is called
    stall_ticks: int = 8  # ticks in a row of fingers not moving: they have closed or opened
    close_timeout_s: float = 2.0
    verify_wait_s: float = 0.3  # let the placed object come to rest before the last look
    roi_margin_m: float = 0.03  # around the target's box, for the region of interest
    face_size_tolerance: float = 0.2  # a top face measured this far off the model's size: a partial view
    max_estimate_sigma_m: float = 0.005  # an estimate less sure than this is no use to a grasp
    table_gap_m: float = 0.008  # a target resting on the table has its centre at half its height, give or take
    moving_speed_m_s: float = 0.01  # a target tracked faster than this (and than 3 sigma) is met where it will be
    grasp_time_s: float = 2.0  # from above a moving target to holding it (descent and close): it travels on meanwhile
    meet_horizon_s: float = 15.0  # a moving target that cannot be met within this is out of reach
    lift_lead_s: float = 0.3  # lifting a moving target, the hand carries on along its way this long
    arrive_tolerance_m: float = 0.002  # at a moving target's pose: this close, moving with it within
    arrive_tolerance_rad: float = float(np.radians(1.0))
    arrive_speed_tolerance_m_s: float = 0.005
    tracker: TrackerParams = TrackerParams()

    def on_a_belt(self) -> MachineParams:
        """For a cell with a conveyor: a target may move at any speed the belt runs (up to 0.5 m/s),
        and its belt may change speed; the first plan waits for one more estimate (a velocity)."""
        tracker = dataclasses.replace(self.tracker, initial_speed_sigma_m_s=0.3, accel_sigma_m_s2=0.03)
        return dataclasses.replace(self, look_min_estimates=max(self.look_min_estimates, 3), tracker=tracker)


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
class FrameRequest:
    """A frame perception wants now: the whole image (``roi`` None) or a region of it."""

    roi: tuple[int, int, int, int] | None


@dataclass
class _Counters:
    estimates: int = 0
    rejected: int = 0
    perception_errors: int = 0
    jumps: int = 0
    retargets: int = 0
    last_error: str = ""


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
        open_loop: bool = False,
        params: MachineParams | None = None,
        surface_z: Callable[[float, float], float] | None = None,
    ) -> None:
        """``surface_z(x, y)``: the height of what a target at (x, y) rests on, as the cell's layout
        says (a belt's top, or the table at 0)."""
        self.p = params or MachineParams()
        self.surface_z = surface_z or (lambda x, y: 0.0)
        self.kin = kin
        self.model = model
        self.symmetry = symmetry_rad
        self.place_xy = place_xy
        self.camera = camera
        self.rng = rng
        self.max_attempts = max_attempts
        self.open_loop = open_loop
        self.dt_s = dt_s
        self.motion = OnlineMotion(kin, q0, dt_s, self.p.free)
        self.home_x4 = pose_to_x4(kin.forward(rm.HOME_Q))
        self.tracker = TargetTracker(symmetry_rad, self.p.tracker)
        self.state = State.LOOK
        self.failure: Failure | None = None
        self.events: list[Event] = []
        self.attempts: list[AttemptRecord] = []
        self.counters = _Counters()
        self.plan: GraspPlan | None = None
        self.grasp_width_m: float | None = None  # finger opening on the object at the last grasp
        self.verify_estimate: PoseEstimate | None = None
        self.last_sample: MotionSample | None = None
        # Per attempt: what a retry may change.
        self.attempt = 1
        self.grip_force_n = self.p.grip_force_n
        self.lift_scale = 1.0
        self._turn_hand = False  # after a miss: try a square box by its other pair of faces
        self._attempt_start_s = 0.0
        # Per state.
        self._entered = False
        self._since_s = 0.0
        self._now_s = 0.0
        self._finger_target = rm.FINGER_MAX_M
        self._finger_force = self.p.open_force_n
        self._fresh_estimate = False
        self._look_frames = 0
        self._stall = 0
        self._no_hold = 0
        self._prev_opening: float | None = None
        self._after_back_off = State.LOOK
        self._descent_plan: GraspPlan | None = None
        self._planned_at_s = 0.0  # the plan is for the target where it was then
        self._velocity_cache: tuple[tuple, np.ndarray | None] | None = None
        self._descent_ref: tuple[np.ndarray, np.ndarray, float] | None = None  # (grasp xy, velocity, time)
        self._verify_asked = False
        self._relooks = 0

    # ================================================================================ interface
    @property
    def finished(self) -> bool:
        return self.state in (State.DONE, State.FAILED)

    def frame_request(self, now_s: float) -> FrameRequest | None:
        """Whether perception should look now, and at what (the loop applies the frame rate)."""
        if self.state is State.LOOK:  # the whole image, then around the first estimate
            if not (self._entered and self.motion.finished):
                return None
            return FrameRequest(self._roi(now_s) if self.tracker.initialised else None)
        if self.state is State.VERIFY:  # around where it was put down
            wait_over = now_s - self._since_s >= self.p.verify_wait_s
            if not wait_over or self._verify_asked:
                return None
            z = self.model.height_m / 2.0
            return FrameRequest(self._roi_at(np.array([*self.place_xy, z]), self.p.roi_margin_m + 0.03))
        if self.open_loop or self.state not in TRACKING_STATES or not self.tracker.initialised:
            return None
        return FrameRequest(self._roi(now_s))

    def on_estimate(self, result: PoseEstimate | PerceptionError, frame_time_s: float) -> str:
        """An estimate (or perception's word that it found none) from a frame taken at ``frame_time_s``.

        Returns what became of it: ``accepted`` (fused into the belief), ``rejected`` (implausible,
        or beyond the tracker's gate), ``no estimate``, or ``unused`` (not looking now).
        """
        if self.state is State.VERIFY:
            self._verify_asked = True
            if isinstance(result, PoseEstimate):
                self.verify_estimate = result
            return "unused"
        looking = self.state is State.LOOK or (self.state in TRACKING_STATES and not self.open_loop)
        if not looking:
            return "unused"
        if self.state is State.LOOK:
            self._look_frames += 1
        status = "no estimate"
        if isinstance(result, PoseEstimate):
            implausible = self._implausible(result)
            if not implausible and self.state in (State.DESCEND, State.CLOSE) and not self._complete_view(result):
                # The hand is over the target: a face it partly hides can mislead the fit consistently,
                # so such a view is not acted on; the tracker predicts through.
                implausible = "a partial view: its top face measures off the model's size"
            if implausible:
                result = PerceptionError(implausible)
                status = "rejected"
        if isinstance(result, PerceptionError):
            self.counters.perception_errors += 1
            self.counters.last_error = str(result)
            return status
        self.counters.estimates += 1
        up = self.tracker.update(result, frame_time_s, partial=not self._complete_view(result))
        if not up.accepted:
            self.counters.rejected += 1
        if up.jumped:
            self.counters.jumps += 1
            tp = self.tracker.predict(frame_time_s)
            moved = ""
            if self.plan is not None:
                d = float(np.linalg.norm(tp.position[:2] - self.plan.grasp.position[:2]))
                moved = f" {d * 1e3:.0f} mm from the plan"
            self.events.append(
                Event(
                    self.state,
                    self._now_s,
                    f"the target moved{moved} (seen in the frame of t = {frame_time_s:.2f} s): tracking it again",
                    note=True,
                )
            )
        if up.accepted:
            self._fresh_estimate = True
        return "accepted" if up.accepted else "rejected"

    def update(self, obs: Observation) -> Command:
        """One control tick: the state's entry action (once), its exit test, then the motion's tick."""
        self._now_s = obs.time_s
        for _ in range(4):  # a state may hand over to the next within the tick
            if not self._entered:
                self._entered = True
                self._since_s = obs.time_s
                getattr(self, f"_enter_{self.state.value}")(obs)
            if self.finished:
                break
            nxt = getattr(self, f"_tick_{self.state.value}")(obs)
            if nxt is None:
                break
            self._go(*nxt)
        if self.finished:
            return self._command_hold()
        try:
            sample = self.motion.step()
        except MotionError as exc:
            self._fail(Stage.TRAJECTORY, str(exc))
            return self._command_hold()
        self.last_sample = sample
        self.counters.retargets = self.motion.retargets
        return Command(sample.q, sample.dq, self._finger_target, self._finger_force)

    # ============================================================================== transitions
    def _go(self, state: State, message: str) -> None:
        self.state = state
        self._entered = False
        self.events.append(Event(state, self._now_s, message))

    def abort(self, stage: Stage, reason: str) -> None:
        """End the episode from outside (the step budget is spent)."""
        self._fail(stage, reason)

    def _fail(self, stage: Stage, reason: str) -> None:
        if self.plan is not None and (not self.attempts or self.attempts[-1].number != self.attempt):
            self._end_attempt("failed", f"{stage.value}: {reason}")
        self.failure = Failure(stage, reason)
        self.state = State.FAILED
        self._entered = True
        self.events.append(Event(State.FAILED, self._now_s, f"{stage.value}: {reason}"))

    def _command_hold(self) -> Command:
        q = self.motion.q
        return Command(q.copy(), np.zeros(7), self._finger_target, self._finger_force)

    def _end_attempt(self, outcome: str, reason: str) -> None:
        self.attempts.append(
            AttemptRecord(
                number=self.attempt,
                outcome=outcome,
                reason=reason,
                start_s=self._attempt_start_s,
                end_s=self._now_s,
                grip_force_n=self.grip_force_n,
                hand_yaw_deg=None if self.plan is None else float(np.degrees(self.plan.hand_yaw_rad)),
                lift_speed_scale=self.lift_scale,
            )
        )

    def _retry(self, stage: Stage, outcome: str, reason: str) -> tuple[State, str] | None:
        """End this attempt; start the next (changed by what failed) or fail the episode."""
        self._end_attempt(outcome, reason)
        if self.attempt >= self.max_attempts:
            self._fail(stage, f"{reason} (attempt {self.attempt} of {self.max_attempts})")
            return None
        self.attempt += 1
        if outcome == "missed":
            # Look again; a square box may be taken by its other pair of faces.
            self._turn_hand = self.model.shape == "box" and self.symmetry < np.pi - 1e-9
        else:
            # It slipped out: hold harder, lift more gently.
            self.grip_force_n = min(self.grip_force_n * 2.0, self.p.max_grip_force_n)
            self.lift_scale *= 0.5
        self._after_back_off = State.LOOK
        return State.BACK_OFF, f"{outcome}: {reason}; attempt {self.attempt} of {self.max_attempts} follows"

    # ==================================================================================== helpers
    def _open(self) -> None:
        self._finger_target, self._finger_force = rm.FINGER_MAX_M, self.p.open_force_n

    def _fingers_stalled(self, obs: Observation) -> bool:
        opening = obs.opening_m
        moved = self._prev_opening is None or abs(opening - self._prev_opening) > 2e-6 * 240.0 * self.dt_s
        self._prev_opening = opening
        self._stall = 0 if moved else self._stall + 1
        return self._stall >= self.p.stall_ticks

    def _holding(self, obs: Observation) -> bool:
        assert self.plan is not None
        left, right = obs.finger_contacts
        return left > 0 and right > 0 and obs.opening_m > self.plan.object_width_m - self.p.hold_margin_m

    def _dropped(self, obs: Observation) -> bool:
        self._no_hold = 0 if self._holding(obs) else self._no_hold + 1
        return self._no_hold >= self.p.drop_ticks

    def _tracked_pose(self) -> Pose:
        tp = self.tracker.predict(self._now_s)
        return Pose.from_xyz_rpy(tp.position, yaw=tp.yaw_rad)

    def _replan(self, *, first: bool) -> GraspPlan | None:
        """A grasp plan from the tracker's belief now; None after failing the episode.

        A re-plan keeps the hand's angle. The first plan of an attempt checks that the whole pick and
        place is in reach; after a miss it first tries the hand turned a quarter (a square box's other
        pair of faces), and the usual angle if that is out of reach.
        """
        pose = self._tracked_pose()
        self._planned_at_s = self._now_s
        if not first:
            near = None if self.plan is None else self.plan.hand_yaw_rad
            try:
                plan = plan_grasp(pose, self.model, self.place_xy, self.p.grasp, hand_yaw_near_rad=near)
                centre = joint7_centre_yaw(tuple(pose.position[:2]), tuple(self.place_xy))
                # Joint 7 where the plan would take it (it turns against the hand's yaw) and, as a
                # second opinion, the estimate from the arm's bearing alone.
                q7_then = float(self.motion.q[6]) - (float(self._x4(plan.pregrasp)[3]) - float(self.motion.setpoint[3]))
                if max(abs(plan.hand_yaw_rad - centre), abs(q7_then)) > WRIST_TURN_LIMIT_RAD:
                    # Keeping the hand's angle, re-plan after re-plan, can walk the wrist into its
                    # limit when the estimated yaw drifts (a noisy estimator's, measured: IK lost the
                    # setpoint at joint 7's stop); take the equivalent angle nearest mid-range.
                    plan = plan_grasp(pose, self.model, self.place_xy, self.p.grasp)
            except GraspPlanningError as exc:
                self._fail(Stage.GRASP_PLANNING, str(exc))
                return None
            if self.state is State.APPROACH and self._target_velocity() is not None:  # still in reach?
                reason = self._out_of_reach(plan)
                if reason:
                    self._fail(Stage.IK, reason)
                    return None
            return plan
        candidates: list[float | None] = [None]
        v = self._target_velocity()
        if v is not None:
            # A moving target: the least turn of the hand first (turning the wrist a quarter while
            # chasing it across the table drifts the arm's redundancy towards a singularity,
            # measured), then joint 7 mid-range where it will be held rather than where it is.
            held = pose.position[:2] + v * self.p.grasp_time_s
            candidates = [float(self.motion.setpoint[3]), joint7_centre_yaw(tuple(held), tuple(self.place_xy)), None]
        if self._turn_hand and self.plan is not None:
            # The other pair of faces: a quarter turn from the usual angle, towards the middle of
            # joint 7's range (q7 ~ centre - psi), so the wrist keeps room.
            centre = joint7_centre_yaw(tuple(pose.position[:2]), tuple(self.place_xy))
            try:
                usual = plan_grasp(pose, self.model, self.place_xy, self.p.grasp).hand_yaw_rad
            except GraspPlanningError as exc:
                self._fail(Stage.GRASP_PLANNING, str(exc))
                return None
            candidates.insert(0, usual + (np.pi / 2.0 if usual < centre else -np.pi / 2.0))
        self._turn_hand = False
        reason = ""
        for near in candidates:
            try:
                plan = plan_grasp(pose, self.model, self.place_xy, self.p.grasp, hand_yaw_near_rad=near)
            except GraspPlanningError as exc:
                self._fail(Stage.GRASP_PLANNING, str(exc))
                return None
            reason = ""
            reach = self._reach_targets(plan)
            if isinstance(reach, str):
                self._fail(Stage.IK, reach)
                return None
            for name, target in (*reach, ("place", plan.place)):
                res = self.kin.solve(target, self.motion.q, self.rng, IKParams())
                if not res.success:
                    reason = f"{name} pose out of reach: {res.reason}"
                    if name not in ("grasp", "place"):  # a moving target's
                        reason = f"the target leaves the arm's reach before the arm can meet it: {name} is out of reach"
                    break
                if near is not None and abs(res.q[6]) > WRIST_TURN_LIMIT_RAD:  # a turned hand: keep wrist room
                    reason = f"{name} pose turns joint 7 to {res.q[6]:.2f} rad"
                    break
            if not reason:
                return plan
        self._fail(Stage.IK, reason)
        return None

    # ------------------------------------------------------------------------- moving targets
    def _target_velocity(self) -> np.ndarray | None:
        """The target's horizontal velocity (m/s) while the tracker sees it move; None when it is at
        rest (or not surely moving), and always in open loop (it plans to where the target was)."""
        if self.open_loop or not self.tracker.initialised:
            return None
        key = (self._now_s, id(self.tracker), self.tracker.accepted)  # the belief changes only on an accept
        if self._velocity_cache is not None and self._velocity_cache[0] == key:
            v = self._velocity_cache[1]
            return None if v is None else v.copy()
        v = self._moving_velocity()
        self._velocity_cache = (key, v)
        return None if v is None else v.copy()

    def _moving_velocity(self) -> np.ndarray | None:
        tp = self.tracker.predict(self._now_s)
        v = tp.velocity[:2]
        sigma = float(np.sqrt(max(np.max(np.linalg.eigvalsh(tp.covariance[4:6, 4:6])), 0.0)))
        if float(np.linalg.norm(v)) <= max(self.p.moving_speed_m_s, 3.0 * sigma):
            return None
        return v.copy()

    def _meet(self, x4: np.ndarray, v: np.ndarray, limits: CartesianLimits | None) -> float | None:
        """Seconds from now until the hand can be at ``x4`` carried along at ``v`` (a plan's pose for
        the target where it is now) moving with it; None: not within the horizon."""
        vel4 = np.array([v[0], v[1], 0.0, 0.0])
        reach = np.array((limits or self.motion.limits).arrays()[0][:2])
        if np.any(np.abs(v) > 0.9 * reach):  # it would run away from the hand
            return None
        return self.motion.intercept(lambda t: x4 + vel4 * t, vel4, limits=limits, latest_s=self.p.meet_horizon_s)

    def _go_to(self, pose: Pose | np.ndarray, limits: CartesianLimits | None = None) -> None:
        """Send the hand to a pose of the plan (or an x4). For a moving target: to where they meet, arriving
        then with its velocity (Ruckig's target velocity and minimum duration), and following it."""
        x4 = self._x4(pose)
        v = self._target_velocity()
        if v is None:
            self.motion.set_target(x4, limits=limits)
            return
        t = self._meet(x4, v, limits or self.motion.limits)
        if t is None:
            self._fail(Stage.IK, self._too_fast(v))
            return
        vel4 = np.array([v[0], v[1], 0.0, 0.0])
        self.motion.set_target(x4 + vel4 * t, velocity=vel4, limits=limits, arrive_in_s=t)

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
        want = self._x4(pose) + vel4 * (self._now_s - self._planned_at_s)
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
        t = self._meet(self._x4(plan.pregrasp), v, self.p.free)
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

    def _x4(self, pose: Pose | np.ndarray) -> np.ndarray:
        """(x, y, z, yaw) of a pose (or of an x4), its yaw the turn of the hand that keeps joint 7 in
        range: the equivalent nearest the current setpoint's, unless that one would take joint 7
        beyond half a turn from mid-range, where the other way round does not (a turn near half a
        revolution: the nearest way can run into joint 7's stop)."""
        x4 = pose_to_x4(pose) if isinstance(pose, Pose) else np.array(pose, dtype=float)
        sp = self.motion.setpoint
        x4[3] = sp[3] + wrap_angle(x4[3] - sp[3])
        # Joint 7 turns against the hand's yaw and with the arm's bearing (q7 ~ pi/4 + q1 - yaw).
        q7 = float(self.motion.q[6]) + float(np.arctan2(x4[1], x4[0]) - np.arctan2(sp[1], sp[0])) - (x4[3] - sp[3])
        if abs(q7) > np.pi:
            x4[3] += 2.0 * np.pi * np.sign(q7)
        return x4

    def _implausible(self, est: PoseEstimate) -> str:
        """Why an estimate cannot be the target resting on the table or the belt ("" if it can): not
        finite, an uncertainty beyond anything the grasp tolerates, or floating above / sunk into what
        it rests on."""
        p = est.pose.position
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(est.position_cov))):
            return "estimate not finite"
        sigma = float(np.sqrt(max(np.max(np.linalg.eigvalsh(est.position_cov)), 0.0)))
        if sigma > self.p.max_estimate_sigma_m:
            return f"estimate too uncertain ({sigma * 1e3:.1f} mm)"
        surface = self.surface_z(float(p[0]), float(p[1]))
        gap = float(p[2]) - surface - self.model.height_m / 2.0
        if abs(gap) > self.p.table_gap_m:
            where = "above" if gap > 0 else "into"
            what = "the table" if surface == 0.0 else "the belt"
            return f"estimate {'floats' if gap > 0 else 'sinks'} {abs(gap) * 1e3:.0f} mm {where} {what}"
        return ""

    def _complete_view(self, estimate: PoseEstimate) -> bool:
        """Whether the estimate saw the whole top face: its measured extents within
        ``face_size_tolerance`` of the model's. A partly hidden face (the hand over it while it
        descends) can mislead the fit consistently, so only a complete view may restart the track."""
        if self.model.shape == "box":
            expected = sorted(self.model.size[:2], reverse=True)
        else:
            expected = [self.model.size[0]] * 2
        measured = sorted(estimate.top_face_size_m, reverse=True)
        tol = self.p.face_size_tolerance
        return all(abs(m - e) <= tol * e for m, e in zip(measured, expected, strict=True))

    def _roi(self, now_s: float) -> tuple[int, int, int, int] | None:
        """Around the tracked target, widened by its uncertainty (None: the whole image)."""
        tp = self.tracker.predict(now_s)
        return self._roi_at(tp.position, self.p.roi_margin_m + 3.0 * tp.position_sigma_m)

    def _roi_at(self, centre: np.ndarray, margin_m: float) -> tuple[int, int, int, int] | None:
        r = 0.5 * float(np.linalg.norm(self.model.size)) + margin_m
        corners = centre + r * UNIT_CUBE
        corners[:, 2] = np.maximum(corners[:, 2], -0.005)
        return roi_around(corners, self.camera.intrinsics, self.camera.T_world_cam, pad_px=4)

    # ===================================================================================== states
    # ---- LOOK: from the home pose, full frames until the tracker holds the target.
    def _enter_look(self, obs: Observation) -> None:
        if not self.events:
            self.events.append(Event(State.LOOK, obs.time_s, "looking for the target", note=True))
        self._open()
        self._attempt_start_s = obs.time_s
        self.tracker = TargetTracker(self.symmetry, self.p.tracker)
        self._look_frames = 0
        self._fresh_estimate = False
        self.motion.set_target(self._x4(self.home_x4), limits=self.p.free)

    def _tick_look(self, obs: Observation) -> tuple[State, str] | None:
        needed = 1 if self.open_loop else self.p.look_min_estimates
        if self.tracker.accepted >= needed:
            plan = self._replan(first=True)
            if plan is None:
                return None
            self.plan = plan
            tp = self.tracker.predict(obs.time_s)
            return State.APPROACH, (
                f"target at ({tp.position[0]:.4f}, {tp.position[1]:.4f}, {tp.position[2]:.4f}) m"
                + (
                    f", yaw {np.degrees(_wrap(tp.yaw_rad, self.symmetry)):+.2f} deg"
                    f" (modulo {np.degrees(self.symmetry):.0f})"
                    if self.symmetry > 0
                    else ""
                )
                + f" from {self.tracker.accepted} estimate(s); "
                f"grasp yaw {np.degrees(plan.hand_yaw_rad):+.1f} deg"
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
        self._go_to(self.plan.pregrasp, limits=self.p.free)

    def _track_plan(self) -> GraspPlan | None:
        """A fresh plan when a new estimate has come in (closed loop), else None."""
        if self.open_loop or not self._fresh_estimate:
            return None
        self._fresh_estimate = False
        return self._replan(first=False)

    def _tick_approach(self, obs: Observation) -> tuple[State, str] | None:
        if not self.open_loop and self.tracker.lost(obs.time_s):
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
            self._go_to(plan.pregrasp)
        if (self.motion.finished or self._with_target(self.plan.pregrasp)) and not self.finished:
            return State.DESCEND, "above the target" + (
                ", moving with it" if self._target_velocity() is not None else ""
            )
        return None

    # ---- DESCEND: straight down onto the grasp; backs off if the target moves away.
    def _near_limits(self) -> CartesianLimits:
        """Near the object: gentle, but keeping up across the table with a target that moves."""
        return self.p.near if self._target_velocity() is None else self.p.near.with_xy_of(self.p.free)

    def _enter_descend(self, obs: Observation) -> None:
        assert self.plan is not None
        self._descent_plan = self.plan
        v = self._target_velocity()
        self._descent_ref = (self.plan.grasp.position[:2].copy(), np.zeros(2) if v is None else v, self._planned_at_s)
        self._go_to(self.plan.grasp, limits=self._near_limits())

    def _tick_descend(self, obs: Observation) -> tuple[State, str] | None:
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
        if (self.motion.finished or self._with_target(self.plan.grasp)) and not self.finished:
            return State.CLOSE, "at the grasp pose"
        return None

    # ---- CLOSE: fingers close with this attempt's force; held or missed.
    def _enter_close(self, obs: Observation) -> None:
        self._finger_target, self._finger_force = 0.0, self.grip_force_n
        self._stall = 0
        self._prev_opening = None

    def _tick_close(self, obs: Observation) -> tuple[State, str] | None:
        assert self.plan is not None
        stalled = self._fingers_stalled(obs)
        if not stalled and obs.time_s - self._since_s < self.p.close_timeout_s:
            return None
        if self._holding(obs):
            self.grasp_width_m = obs.opening_m
            return State.LIFT, (
                f"holding: fingers at {obs.opening_m * 1e3:.1f} mm, contact on both, {self.grip_force_n:.0f} N"
            )
        reason = (
            f"fingers closed to {obs.opening_m * 1e3:.1f} mm "
            f"(expected {self.plan.object_width_m * 1e3:.0f} mm): nothing held"
        )
        return self._retry(Stage.GRASP, "missed", reason)

    # ---- LIFT, TRANSPORT, LOWER: carry it, watching the hold.
    def _enter_lift(self, obs: Observation) -> None:
        assert self.plan is not None
        self._no_hold = 0
        lift = self._x4(self.plan.lift)
        v = self.motion.velocity[:2]
        if np.any(v != 0.0):  # held on the move: carry on along its way a little while rising
            lift[:2] = self.motion.setpoint[:2] + v * self.p.lift_lead_s
        self.motion.set_target(lift, limits=self._near_limits().scaled(self.lift_scale))

    def _tick_lift(self, obs: Observation) -> tuple[State, str] | None:
        if self._dropped(obs):
            return self._retry(Stage.LIFT, "dropped while lifting", f"fingers at {obs.opening_m * 1e3:.1f} mm")
        if self.motion.finished:
            return State.TRANSPORT, f"lifted, fingers at {obs.opening_m * 1e3:.1f} mm"
        return None

    def _enter_transport(self, obs: Observation) -> None:
        assert self.plan is not None
        self.motion.set_target(self._x4(self.plan.place_above), limits=self.p.free.scaled(self.lift_scale))

    def _tick_transport(self, obs: Observation) -> tuple[State, str] | None:
        if self._dropped(obs):
            return self._retry(Stage.TRANSPORT, "dropped in transit", f"fingers at {obs.opening_m * 1e3:.1f} mm")
        if self.motion.finished:
            return State.LOWER, "above the place position"
        return None

    def _enter_lower(self, obs: Observation) -> None:
        assert self.plan is not None
        self.motion.set_target(self._x4(self.plan.place), limits=self.p.near)

    def _tick_lower(self, obs: Observation) -> tuple[State, str] | None:
        if self._dropped(obs):
            return self._retry(Stage.TRANSPORT, "dropped in transit", f"fingers at {obs.opening_m * 1e3:.1f} mm")
        if self.motion.finished:
            return State.RELEASE, "lowered onto the table"
        return None

    # ---- RELEASE, RETREAT, HOME, VERIFY.
    def _enter_release(self, obs: Observation) -> None:
        self._open()
        self._stall = 0
        self._prev_opening = None

    def _tick_release(self, obs: Observation) -> tuple[State, str] | None:
        opened = obs.opening_m > 2.0 * rm.FINGER_MAX_M - 0.004
        if opened or self._fingers_stalled(obs) or obs.time_s - self._since_s > self.p.close_timeout_s:
            assert self.plan is not None
            self._end_attempt("placed", "")
            p = self.plan.place.position
            return State.RETREAT, f"released at ({p[0]:.3f}, {p[1]:.3f})"
        return None

    def _enter_retreat(self, obs: Observation) -> None:
        assert self.plan is not None
        self.motion.set_target(self._x4(self.plan.retreat), limits=self.p.near)

    def _tick_retreat(self, obs: Observation) -> tuple[State, str] | None:
        return (State.HOME, "clear of the object") if self.motion.finished else None

    def _enter_home(self, obs: Observation) -> None:
        self.motion.set_target(self._x4(self.home_x4), limits=self.p.free)

    def _tick_home(self, obs: Observation) -> tuple[State, str] | None:
        return (State.VERIFY, "arm home") if self.motion.finished else None

    def _enter_verify(self, obs: Observation) -> None:
        self._verify_asked = False
        self.verify_estimate = None

    def _tick_verify(self, obs: Observation) -> tuple[State, str] | None:
        if not self._verify_asked:
            return None
        if self.verify_estimate is None:
            return State.DONE, "the camera does not find the target at the end"
        seen = self.verify_estimate.pose.position
        err = float(np.hypot(seen[0] - self.place_xy[0], seen[1] - self.place_xy[1]))
        return State.DONE, f"the camera sees the target {err * 1e3:.1f} mm from the place position"

    def _enter_done(self, obs: Observation) -> None:
        pass

    def _tick_done(self, obs: Observation) -> tuple[State, str] | None:
        return None

    # ---- BACK_OFF: open, straight up to a safe height, then look or approach again.
    def _enter_back_off(self, obs: Observation) -> None:
        if self._after_back_off is State.LOOK:
            self._open()
        safe_z = self.p.grasp.pregrasp_height_m + (self.plan.grasp.position[2] if self.plan is not None else 0.02)
        x4 = self.motion.setpoint.copy()
        x4[2] = max(x4[2], safe_z)
        # Limits change only at rest: lowered mid-motion, Ruckig may overshoot while braking.
        limits = self._near_limits() if self.motion.finished else None
        if self._after_back_off is State.APPROACH and self._target_velocity() is not None:
            self._go_to(x4, limits=limits)  # up, and along with it
            return
        self.motion.set_target(x4, limits=limits)

    def _tick_back_off(self, obs: Observation) -> tuple[State, str] | None:
        if self._after_back_off is State.APPROACH:
            plan = self._track_plan()  # keep following the target while rising
            if plan is not None:
                self.plan = plan
        if self.motion.finished:
            nxt = self._after_back_off
            return nxt, "clear above the table: " + ("look again" if nxt is State.LOOK else "approach again")
        return None
