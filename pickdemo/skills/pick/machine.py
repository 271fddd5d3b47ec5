"""The pick skill's machine: its state, its transitions, its failures and what it records.

Pure: no simulator. Each tick :meth:`PickMachine.update` gets the robot's observation (joints,
finger opening, finger contacts, the wrist's force) and returns a :class:`~pickdemo.core.interfaces.Command`;
perception's estimates reach it through :meth:`PickMachine.on_estimate` when they arrive (late, by
the modelled latency), and it says through :meth:`PickMachine.views` which of its cameras should
take a frame now, and of which region. Modelled on Drake's ``PickAndPlaceStateMachine::Update``:
every state has an entry action and an exit test, dispatched from the table
:data:`~pickdemo.skills.pick.states.STATES`; a failure is a transition to ``FAILED`` with a typed
stage and a reason.

The machine only decides. What it does, it does through its parts, each of which returns values
(a plan or a failure, a reason, a note) and never writes the machine's state: where to look
(:class:`~pickdemo.skills.pick.views.ViewPlanner`), what moved
(:class:`~pickdemo.skills.pick.watch.MoveWatch`), which grasp
(:class:`~pickdemo.skills.pick.chooser.GraspChooser`), meeting a moving target
(:class:`~pickdemo.skills.pick.intercept.Interceptor`), how the arm gets there
(:class:`~pickdemo.skills.pick.arm.ArmDriver`), and the actions' fingers and scale
(:class:`~pickdemo.skills.actions.Grip`, :class:`~pickdemo.skills.actions.Scale`).
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, box_surface_points
from pickdemo.core.interfaces import Command, Observation
from pickdemo.core.result import AttemptRecord, Failure, Stage
from pickdemo.grasping.selection import GraspSelector, selector_for
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel
from pickdemo.robot.collision import Obstacle
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.actions import Scale, grip_for
from pickdemo.skills.pick.arm import ArmDriver
from pickdemo.skills.pick.carry import verify_frame
from pickdemo.skills.pick.chooser import GraspChooser
from pickdemo.skills.pick.intercept import LEAVES_REACH, Interceptor
from pickdemo.skills.pick.params import (
    HAND_OVER_TARGET,
    HELD_STATES,
    MAX_TRANSITIONS_PER_TICK,
    REPLANNABLE,
    RETRIES,
    SLIPPED,
    TRACKING_STATES,
    CameraModel,
    Event,
    FrameRequest,
    MachineParams,
    State,
    Transition,
)
from pickdemo.skills.pick.place import PlaceFinder
from pickdemo.skills.pick.plans import PlacedHigher
from pickdemo.skills.pick.readout import MachineReadout
from pickdemo.skills.pick.replan import PathWatch
from pickdemo.skills.pick.routes import Router
from pickdemo.skills.pick.search import Searcher
from pickdemo.skills.pick.sightline import Sightline
from pickdemo.skills.pick.states import STATES
from pickdemo.skills.pick.views import ViewPlanner
from pickdemo.skills.pick.watch import MoveWatch
from pickdemo.tracking.belief import Counters, TargetBelief, Verdict
from pickdemo.worldmodel import PlaceView, SceneView, WorldModel


class PickMachine(MachineReadout):
    """Pick and place as a state machine; see the module docstring and :mod:`pickdemo.skills.pick`."""

    def __init__(
        self,
        *,
        kin: Kinematics,
        model: TargetModel,
        symmetry_rad: float,
        place_xy: tuple[float, float],
        cameras: list[CameraModel],
        q0: np.ndarray,
        dt_s: float,
        rng: np.random.Generator,
        max_attempts: int = 3,
        place_tolerance_m: float | None = None,
        open_loop: bool = False,
        params: MachineParams | None = None,
        surface_z=None,  # noqa: ANN001 - Callable[..., float] | None
        selector: GraspSelector | None = None,
        place_z_m: float = 0.0,
        look_at: np.ndarray | None = None,
        look_from_here: bool = False,
        fixtures: tuple[OrientedBox, ...] = (),
        solids: tuple[OrientedBox, ...] = (),
        grasp_rng: np.random.Generator | None = None,
        world: WorldModel | None = None,
        cell: tuple[Obstacle, ...] = (),
        plan_rng: np.random.Generator | None = None,
    ) -> None:
        """``cameras``: the robot's cameras (a fixed one at least; one on the hand looks too whenever
        the target is wholly in its view). ``surface_z(x, y, z)``: the height of what a target at (x, y),
        its centre at ``z``, rests on, as the cell's layout says (a belt's top, a bin's floor, a shelf's
        board, or the table at 0). ``selector``: where
        grasps come from (default: a top-down grasp across the target's narrower side).
        ``place_tolerance_m``: the task's; a target the camera sees put down farther than this from
        the place position is picked up again (within ``max_attempts``). ``place_z_m``: the height
        above the table the target's bottom is let go at (a tray's rim: it drops in). ``look_at``:
        where the target was seen last (a survey of the table chose it among others): the first look
        is at a region around it; ``look_from_here``: from where the arm is (it hides nothing of the
        table from the camera), not from home. ``fixtures``: the cell's fixtures seen as the points of
        their faces (a bin's walls), known from the task: the grasps keep the hand out of them;
        ``solids``: every fixture's boxes (a shelf's too): the open hand and the arm keep out of them.
        ``grasp_rng``: the draw of grasps from any side, for an object nobody described that no top-down
        grasp fits, where the robot's hand can take them (None: top-down only). ``cell``: the table and
        the fixtures, named, as the task knows them: the arm's motions are planned around them and
        around the world model's objects; ``plan_rng``: the planner's seeds."""
        self.p = p = params or MachineParams()
        self.kin, self.model, self.symmetry, self.place_xy, self.rng = kin, model, symmetry_rad, place_xy, rng
        self.max_attempts, self.place_tolerance_m, self.open_loop = max_attempts, place_tolerance_m, open_loop
        self.look_at = None if look_at is None else np.asarray(look_at, dtype=float)
        self.look_here = look_from_here
        self.hand_cameras = frozenset(c.name for c in cameras if c.on_hand)
        self.arm_q = np.asarray(q0, dtype=float)  # the joint states last observed (where a hand camera is)
        any_side = grasp_rng if kin.robot.grasps_any_side and p.joint_transfers else None
        selector = selector or selector_for(model, p.grasp, any_side=any_side, gripper=kin.robot.gripper)
        if place_z_m != 0.0 or p.drop_place:
            selector = PlacedHigher(selector, place_z_m, from_carry=p.drop_place)
        self.selector = selector
        # The parts.
        self.arm = ArmDriver(kin, q0, dt_s, p, rng)
        self.router = Router(kin, cell, plan_rng or np.random.default_rng(0), max_checks=p.plan_max_checks)
        self.held: OrientedBox | None = None  # the held object's box in the TCP's frame (from the close)
        self.held_at: tuple[np.ndarray, float] | None = None  # ... and the arm's joints and fingers then
        self.grip = grip_for(p.grip, dt_s, kin.robot.gripper)
        self.scale = Scale(p.payload)
        # The wrist's sensor reads in its joint's frame; where that is turned from the TCP's (the SO-101's
        # roll joint: its z is the TCP's -z), the reading is turned with it (None: the TCP's frame).
        sensor = kin.tcp_to_frame(kin.robot.wrist_joint).rotation
        self.sensor_in_tcp = None if np.allclose(sensor, np.eye(3), atol=1e-9) else sensor
        self.counters = Counters()
        self.belief = TargetBelief(
            model, symmetry_rad, p.tracker, p.gate, surface_z=surface_z or _on_the_table, counters=self.counters
        )
        self.world = world if world is not None else WorldModel()  # every object seen, with its id
        self.intercept = Interceptor(kin, rng, p, self.belief, self.arm, open_loop=open_loop)
        self.chooser = GraspChooser(
            kin, rng, p, model, place_xy, selector, self.belief, self.arm, self.intercept,
            fixture_points=box_surface_points(fixtures) if fixtures else None, solids=solids, world=self.world,
        )  # fmt: skip
        self.watch = MoveWatch(kin, p, model, self.belief, self.hand_cameras, open_loop=open_loop)
        self.place_finder = PlaceFinder(
            p, model, self.belief, place_xy, place_tolerance_m, kin.robot.gripper, place_z_m
        )
        self.view_planner = ViewPlanner(
            kin, p, model, self.belief, self.watch, cameras, place_xy, look_at=self.look_at, open_loop=open_loop,
        )  # fmt: skip
        self.sight = Sightline(kin, self.view_planner.fixed)
        self.searcher = Searcher(kin, cameras, p)
        # What happened.
        self.state = State.LOOK
        self.failure: Failure | None = None
        self.events: list[Event] = []
        self.attempts: list[AttemptRecord] = []
        self.plan: GraspPlan | None = None
        self.grasp_width_m: float | None = None  # finger opening on the object at the last grasp
        self.verify_estimate: PoseEstimate | None = None
        self.place_view: PlaceView | None = None  # what the camera last saw standing at the place
        self.place_z_m = place_z_m
        self.release_m: float | None = None  # letting go, each finger opens this far (None: wide)
        self.rest_height_m: float | None = None  # its centre above what it stood on, when grasped
        self.keep_hold = False  # backing off to fail with the target in the hand (met something lowering it)
        #: where the target was last known, for the next look (its track: under the hand that dropped it)
        self.last_at: np.ndarray | None = None
        self.released_at_s: float | None = None  # when it last began to let go of the target
        # Per attempt: what a retry may change.
        self.attempt = 1
        self.grip_force_n = p.grip_force_n
        self.lift_scale = 1.0
        self.turn_hand = False  # after a miss: try a square box by its other pair of faces
        #: hand angles to take the target by other faces than, if it has them: a finger touched
        #: something beside it going down, or the arm's motion failed
        self.avoid_yaws: list[float] = []
        self.recovering: tuple[State, str] | None = None  # brought to rest, then to this state (saying so)
        self.paths = PathWatch()
        self.weighed_force_n = 0.0  # the grip force the payload asked for, once weighed
        self.forced_open = False  # releasing: the fingers were told to open with full force
        self.lifted_off = False  # lifting: past the pause just off the table where it is weighed
        self.withdrawing = False  # lifted under a shelf's board: going back out along the approach
        self.attempt_start_s = 0.0
        # Per state.
        self.entered = False
        self.since_s = 0.0
        self.now_s = 0.0
        self.fresh_estimate = False
        self.look_frames = 0
        self.after_back_off = State.LOOK
        self.descent_plan: GraspPlan | None = None
        self.planned_at_s = 0.0  # the plan is for the target where it was then
        self.descent_ref: tuple[np.ndarray, np.ndarray, float] | None = None  # (grasp xy, velocity, time)
        self.moved_from: np.ndarray | None = None  # where the last descent backed off from for a move (grasp xy)
        self.shadow_moves = 0  # this attempt's moves the approach then found the target back from
        self.searched_on = False  # a cup at its grasp touching nothing went on along its approach
        self.hover_since: float | None = None  # above the target, waiting to be sure enough of it
        self.verify_asked = False  # the last look is over (settled, or out of frames)
        self.verify_frames = 0
        self.verify_settled = True
        self.relooks = 0
        self.rested = False  # a pick was planned for the target at rest
        #: (why, since when) a target that stood still moves out of reach: waiting for it to stop
        self.moving_off: tuple[str, float] | None = None
        #: this look's postures looked from without finding the target (the arm hid the table from the
        #: fixed camera); no other posture would show more of it
        self.looked_from: list[np.ndarray] = []
        self.searched: list[np.ndarray] = []  # where the hand's camera looked for the target from above
        self.search_camera: str | None = None  # ... and which: its whole frames while it looks
        self.no_aside = False
        self.failing: Failure | None = None  # the last attempt failed: backing off before failing so

    # ================================================================================ interface
    def views(self, now_s: float) -> list[FrameRequest]:
        """The frames its cameras should take now (the loop applies the frame rate)."""
        ready = self.entered and self.arm.finished
        return self.view_planner.requests(
            now_s, self.state, ready=ready, since_s=self.since_s, verify_asked=self.verify_asked, plan=self.plan,
            arm_q=self.arm_q, near=self.last_at if self.look_frames < self.p.look_aside_frames else None,
            searching=self.search_camera,
        )  # fmt: skip

    def on_estimate(
        self, result: PoseEstimate | PerceptionError | SceneView, frame_time_s: float,
        camera: str = "camera",
    ) -> Verdict:  # fmt: skip
        """An estimate (or perception's word that it found none) from a frame taken at ``frame_time_s``
        by ``camera``, or what it saw at the place, or the frame's instances (into the world model); what
        became of it (:class:`~pickdemo.tracking.belief.Verdict`)."""
        if isinstance(result, SceneView):
            self.world.update(result)
            self.place_view = self.place_finder.seen(self.world, result) or self.place_view
            self._mark_target(frame_time_s)
            return Verdict.UNUSED
        if self.state is State.VERIFY:
            verify_frame(self, result if isinstance(result, PoseEstimate) else None)
            return Verdict.UNUSED
        looking = self.state is State.LOOK or (self.state in TRACKING_STATES and not self.open_loop)
        if not looking:
            return Verdict.UNUSED
        if self.state is State.LOOK:
            self.look_frames += 1
        over = self.state in HAND_OVER_TARGET
        offered = self.belief.offer(result, frame_time_s, hand_over_target=over, camera=camera)
        if offered.jumped:
            tp = self.belief.predict(frame_time_s)
            moved = ""
            if self.plan is not None:
                d = float(np.linalg.norm(tp.position[:2] - self.plan.grasp.position[:2]))
                moved = f" {d * 1e3:.0f} mm from the plan"
            self.note(f"the target moved{moved} (seen in the frame of t = {frame_time_s:.2f} s): tracking it again")
        if offered.verdict is Verdict.ACCEPTED:
            self.fresh_estimate = True
            self._mark_target(frame_time_s, follow=True)
        seen = result.pose.position if isinstance(result, PoseEstimate) else None
        whole = offered.verdict is Verdict.ACCEPTED or (offered.off_m is not None and not offered.partial)
        if self.state is State.CLOSE and camera in self.hand_cameras and seen is not None and whole:
            self.watch.hold_view(frame_time_s, seen)  # (a plausible whole view, accepted or not)
        self.watch.offered(offered, camera, frame_time_s, seen, hand_over_target=over)
        return offered.verdict

    def _mark_target(self, time_s: float, *, follow: bool = False) -> None:
        """Tell the world model where the target is tracked (which of its objects is the target; ``follow``:
        a fresh estimate, which the target's object follows)."""
        if self.belief.initialised:
            where = self.belief.predict(time_s).position
            self.world.mark_target(where, self.model.geometry.footprint_radius_m, follow=follow)

    def update(self, obs: Observation) -> Command:
        """One control tick: the state's entry action (once), its exit test, then the motion's tick."""
        self.now_s = obs.time_s
        self.arm_q = obs.arm_q
        for _ in range(MAX_TRANSITIONS_PER_TICK):
            if not self.entered:
                self.entered = True
                self.since_s = obs.time_s
                STATES[self.state].enter(self, obs)
            if self.finished:
                break
            nxt = STATES[self.state].tick(self, obs)
            if nxt is None:
                break
            self.go(*nxt)
        if not self.finished and self.arm.legs and self.arm.leg_finished:  # the next leg (over the top)
            self.arm.legs.popleft()()
        if self.finished:
            return self._stopped()
        if self.recovering is None:
            self.recovering = self.paths.blocked(self, obs)
        if self.recovering is not None:
            return self._recover()
        out = self.arm.step(self.grip)
        if isinstance(out, Failure):
            if self.state in REPLANNABLE and self.attempt < self.max_attempts and self.plan is not None:
                # Another attempt may take another IK goal or hand angle: at rest first, then home.
                self.avoid_yaws.append(self.plan.hand_yaw_rad)
                nxt = self.retry(out.stage, "motion failed", out.reason)
                assert nxt is not None  # (an attempt is left)
                self.note(nxt[1].replace("; attempt", ": braking to look again; attempt"))
                self.recovering = (State.LOOK, "at rest after the failed motion: looking again")
                return self._recover()
            self.fail(out.stage, out.reason)
            return self._stopped()
        self.counters.retargets = self.arm.retargets
        return out

    def _recover(self) -> Command:
        """A tick of bringing the arm to rest (within the joints' limits); at rest, on to the state
        :attr:`recovering` names."""
        cmd = self.arm.brake(self.grip)
        if self.arm.braked and self.recovering is not None:
            self.arm.rested()
            (state, message), self.recovering = self.recovering, None
            self.go(state, message)
        return cmd

    def _stopped(self) -> Command:
        """The command once finished: held where it is (with ``end_at_rest``, after a failure, braked first)."""
        if self.state is State.FAILED and self.p.end_at_rest and not self.arm.braked:
            return self.arm.brake(self.grip)
        return self.arm.hold(self.grip)

    def abort(self, stage: Stage, reason: str) -> None:
        """End the episode from outside (the step budget is spent)."""
        self.fail(stage, reason)

    # ============================================================================== transitions
    def go(self, state: State, message: str) -> None:
        # the world model's target is the hand's from the close (the fingers about it hide it), goes
        # with the hand once lifted, and stands where it was let go (or where it stood: not lifted)
        before, self.state = self.state, state
        if (before in IN_HAND) != (state in IN_HAND):
            if state in IN_HAND:
                self.world.hold()
            elif before is State.CLOSE:
                self.world.release(None)
            else:
                off = (0.0, 0.0) if self.plan is None else self.plan.place_offset_xy
                self.world.release(self.kin.forward(self.arm_q).position[:2] - np.asarray(off))
        self.entered = False
        self.arm.legs.clear()  # each state starts its own motion
        self.events.append(Event(state, self.now_s, message))

    def fail(self, stage: Stage, reason: str) -> None:
        if self.plan is not None and (not self.attempts or self.attempts[-1].number != self.attempt):
            self.end_attempt("failed", f"{stage.value}: {reason}")
        self.failure = Failure(stage, reason)
        self.state = State.FAILED
        self.entered = True
        self.events.append(Event(State.FAILED, self.now_s, f"{stage.value}: {reason}"))

    def note(self, message: str | None) -> None:
        """Something seen within the state, not a transition (nothing if None)."""
        if message is not None:
            self.events.append(Event(self.state, self.now_s, message, note=True))

    @property
    def close_force_n(self) -> float:
        """This attempt's grip force on the plan's faces: its share of the pads' area (a face smaller
        than a pad is squeezed as hard per area as a whole pad would be)."""
        share = 1.0 if self.plan is None else self.plan.pad_share
        return self.grip_force_n * share

    def end_attempt(self, outcome: str, reason: str) -> None:
        self.attempts.append(
            AttemptRecord(
                number=self.attempt,
                outcome=outcome,
                reason=reason,
                start_s=self.attempt_start_s,
                end_s=self.now_s,
                grip_force_n=max(self.close_force_n, self.weighed_force_n),
                hand_yaw_deg=None if self.plan is None else float(np.degrees(self.plan.hand_yaw_rad)),
                lift_speed_scale=self.lift_scale,
                payload_kg=self.scale.payload_kg,
            )
        )

    def retry(self, stage: Stage, outcome: str, reason: str) -> Transition:
        """End this attempt; start the next (changed by what failed, :data:`RETRIES`) or fail the episode."""
        self.end_attempt(outcome, reason)
        if self.attempt >= self.max_attempts:
            if self.p.end_at_rest:  # up and open first: the machine ends with the hand clear of the table
                self.failing = Failure(stage, f"{reason} (attempt {self.attempt} of {self.max_attempts})")
                self.after_back_off = State.FAILED
                return State.BACK_OFF, f"{outcome}: {reason}; no attempt left: backing off"
            self.fail(stage, f"{reason} (attempt {self.attempt} of {self.max_attempts})")
            return None
        self.attempt += 1
        if self.state in HELD_STATES and self.belief.initialised:  # it fell from the hand
            z = self.belief.predict(self.now_s).position[2]
            self.last_at = np.array([*self.kin.forward(self.arm_q).position[:2], z])
        change = RETRIES.get(outcome, SLIPPED)
        if change.other_faces:  # a square box may be taken by its other pair of faces
            self.turn_hand = 0.0 < self.symmetry < np.pi - 1e-9  # a square top (a cube)
        if change.any_side_first:  # (where the robot's grasps come from any side too)
            self.chooser.misses += 1
        if change.force_factor != 1.0:
            self.grip_force_n = min(self.grip_force_n * change.force_factor, self.grip.max_force_n)
        self.lift_scale *= change.lift_factor
        self.after_back_off = State.LOOK
        return State.BACK_OFF, f"{outcome}: {reason}; attempt {self.attempt} of {self.max_attempts} follows"

    # ================================================================================ planning
    def replan(self, *, first: bool, avoid: tuple[float, ...] = ()) -> GraspPlan | None:
        """A grasp plan from the tracker's belief now (:class:`~pickdemo.skills.pick.chooser.GraspChooser`);
        None after failing the episode. ``avoid``: a first plan by other faces than these hand angles', if it can."""
        tp = self.belief.predict(self.now_s)
        pose = Pose.from_xyz_rpy(tp.position, yaw=tp.yaw_rad)
        self.planned_at_s = self.now_s
        v = self.intercept.velocity(self.now_s)
        if first:
            missed = (self.plan.hand_yaw_rad,) if (self.turn_hand and self.plan is not None) else ()
            self.turn_hand = False
            out = self.chooser.first_plan(pose, v, missed + tuple(self.avoid_yaws) + avoid, self.now_s)
        else:
            over, approaching = self.state in HAND_OVER_TARGET, self.state is State.APPROACH
            out = self.chooser.replan(
                pose, v, self.plan, hand_over_target=over, approaching=approaching, now_s=self.now_s
            )
        if isinstance(out, Failure):
            if out.stage is Stage.IK and out.reason.startswith(LEAVES_REACH) and self.rested:
                # it stood still: tipped over or rolling, it stops on the table (waited for, a while)
                since = self.now_s if self.moving_off is None else self.moving_off[1]
                if self.now_s - since < self.p.stop_wait_s:
                    self.moving_off = (out.reason, since)
                    return None
            self.fail(out.stage, out.reason)
            return None
        self.moving_off = None
        self.rested = self.rested or (first and v is None)
        return out

    def put_down_at(self, xy: tuple[float, float]) -> None:
        """Put the target down at ``xy``, not where the task's place is (it is taken there)."""
        self.place_xy = xy
        self.chooser.place_xy = self.view_planner.place_xy = xy

    def track_plan(self) -> GraspPlan | None:
        """A fresh plan when a new estimate has come in (closed loop), else None."""
        if self.open_loop or not self.fresh_estimate:
            return None
        self.fresh_estimate = False
        return self.replan(first=False)

    def go_to(self, pose, limits=None) -> None:  # noqa: ANN001 - Pose | x4, CartesianLimits | None
        """Send the hand to a pose of the plan; a moving target that cannot be met fails the episode in ``ik``."""
        reason = self.intercept.go_to(pose, self.now_s, limits)
        if reason:
            self.fail(Stage.IK, reason)


#: The states in which the world model's target is the hand's (:meth:`PickMachine.go`).
IN_HAND = frozenset({State.CLOSE, *HELD_STATES})


def _on_the_table(x: float, y: float, z: float | None = None) -> float:
    """What a target rests on where the cell says nothing: the table."""
    return 0.0
