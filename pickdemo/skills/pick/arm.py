"""How the arm gets there: the hand's Cartesian motion and the arm's joint-space transfers, the
legs of a transfer over the top, the IK goals they go to, and the one command builder every joint
command passes (the rate limiter's). A part of the pick skill: it moves the arm as told and says
what it did (a note, a failure), never the machine's state."""

from __future__ import annotations

import dataclasses
from collections import deque
from collections.abc import Callable

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.interfaces import Command
from pickdemo.core.result import Failure, Stage
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.motion.ik_goals import (
    along_line,
    choose_goal,
    goal_candidates,
    line_reach,
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
    hand_frame,
    pose_to_x4,
)
from pickdemo.robot.kinematics import Kinematics
from pickdemo.robot.rate_limit import RateLimiter
from pickdemo.skills.actions import Grip, Move
from pickdemo.skills.pick.params import MachineParams
from pickdemo.skills.pick.plans import half_turn

#: The goal's starts are this many times more when none of the first keeps its line clear.
MORE_STARTS = 4


class ArmDriver:
    """The arm's motion, one leg at a time: the Cartesian motion (:class:`~pickdemo.skills.actions.Move`)
    or a joint-space transfer drives it, and each tick's sample goes out through the rate limiter."""

    def __init__(
        self, kin: Kinematics, q0: np.ndarray, dt_s: float, params: MachineParams, rng: np.random.Generator
    ) -> None:
        self.kin = kin
        self.p = params
        self.rng = rng  # the IK's restarts
        self.motion = OnlineMotion(kin, q0, dt_s, params.free)
        self.move = Move(self.motion, chase_fraction=params.chase_fraction, meet_horizon_s=params.meet_horizon_s)
        self.joints = JointMotion(kin, q0, dt_s)  # transfers in joint space
        self.limiter = RateLimiter(q0, dt_s, kin.robot.limits)  # every joint command within the datasheet
        self.home_q = kin.robot.home_q
        self.home_x4 = pose_to_x4(kin.forward(self.home_q))
        self.joint = False  # the joint-space transfer drives the arm (else the Cartesian motion)
        self.legs: deque[Callable[[], None]] = deque()  # the state's motion still to come, leg by leg
        self.route: list[np.ndarray] = []  # the waypoints of the last path followed (:meth:`follow`)
        self.sample: MotionSample | None = None
        self.braked = False  # (end_at_rest) the motion under way at a failure has come to rest
        self._braking = False
        self._line_checked_q: np.ndarray | None = None  # a transfer goal whose straight line was checked

    # ============================================================================ where it is
    @property
    def q(self) -> np.ndarray:
        """The arm's commanded configuration now."""
        return self.joints.q if self.joint else self.motion.q

    def ahead(self) -> list[np.ndarray]:
        """The joint transfer's goal under way and, on a planned path, the waypoints after it ([]: the
        hand's motion is Cartesian)."""
        if not self.joint:
            return []
        goal = self.joints.target
        for i, q in enumerate(self.route):
            if np.array_equal(q, goal):
                return [goal, *self.route[i + 1 :]]
        return [goal]

    @property
    def leg_finished(self) -> bool:
        return self.joints.finished if self.joint else self.move.finished

    @property
    def finished(self) -> bool:
        """The state's motion has finished: the leg under way and every leg after it."""
        return self.leg_finished and not self.legs

    @property
    def retargets(self) -> int:
        return self.motion.retargets + self.joints.retargets

    def cartesian_limits(self) -> tuple[list[float], list[float], list[float]]:
        """The Cartesian limits the hand moves within now (infinite during a joint-space transfer,
        which keeps the joints' limits instead)."""
        if self.joint:
            inf = [float("inf")] * 4
            return inf, inf, inf
        return self.motion.limits.arrays()

    # ========================================================================== the command
    def step(self, grip: Grip) -> Command | Failure:
        """One control tick of the motion under way: the command, or why the motion failed."""
        if self.joint:
            try:
                sample = self.joints.step()
            except MotionError as exc:
                return Failure(Stage.TRAJECTORY, str(exc))
        else:
            sample = self.move.step()
            if sample is None:
                return Failure(Stage.TRAJECTORY, str(self.move.failure))
        self.sample = sample
        return self._send(sample.q, sample.dq, grip)

    def _send(self, q: np.ndarray, dq: np.ndarray, grip: Grip) -> Command:
        """The one command builder: joints through the rate limiter (a motion that stopped short of the
        last command, or an IK that settled elsewhere, is not a jump), with the fingers' target."""
        sent, limited = self.limiter(q)
        return Command(sent, self.limiter.dq.copy() if limited else dq, grip.target_m, grip.force_n, grip.vacuum)

    def hold(self, grip: Grip) -> Command:
        """Hold where the motion is."""
        return self._send(self.q, np.zeros(len(self.q)), grip)

    def brake(self, grip: Grip) -> Command:
        """After a failure (``end_at_rest``): the joints brought to rest from the commands last sent
        (whatever motion was under way, even one that failed), within their limits; then held there."""
        if not self._braking:
            self._braking = True
            self.legs.clear()
            if not np.any(self.limiter.dq) and not np.any(self.limiter.ddq):  # at rest already
                self.braked = True
                return self.hold(grip)
            self.joints.brake(self.limiter.q, self.limiter.dq, self.limiter.ddq)
            self.joint = True
        try:
            sample = self.joints.step()
        except MotionError:
            sample = None
        if sample is None or sample.finished:
            self.braked = True
        if sample is None:
            return self.hold(grip)
        self.sample = sample
        return self._send(sample.q, sample.dq, grip)

    def rested(self) -> None:
        """Braked to rest (not at the episode's end): the next motion starts afresh from here."""
        self._braking = False
        self.braked = False
        self.cartesian()  # (at rest where the brake left the joints)

    # ====================================================================== joint transfers
    def transfer_to(self, q_goal: np.ndarray, scale: float) -> None:
        """A transfer in joint space to ``q_goal`` (from rest where the Cartesian motion is, or a new
        goal for the transfer under way)."""
        if self.joint:
            self.joints.retarget(q_goal)
        else:
            self.joints.start(self.motion.q, q_goal, scale=scale)
            self.joint = True

    def joint_line(self, waypoints: np.ndarray, scale: float) -> None:
        """A straight line of the hand's run as joint transfers from rest to rest through ``waypoints``
        (K, dof) (a grasp from the side's: see :func:`~pickdemo.motion.lines.line_in_joints`),
        at this share of the limits."""
        self.legs.clear()
        for q in waypoints[1:]:
            self.legs.append(lambda q=q: self.transfer_to(q, scale))
        self.joints.start(self.q, waypoints[0], scale=scale)
        self.joint = True

    def cartesian(self) -> None:
        """The Cartesian motion takes over, at rest where a transfer left the arm, in the hand's frame
        there (the next target's, if tilted otherwise, is turned to from it)."""
        if self.joint:
            self.motion.reset_at(self.joints.q, hand_frame(self.kin.forward(self.joints.q).rotation))
            self.joint = False

    def home(self, clear: Callable[[np.ndarray, np.ndarray], bool] | None = None) -> str | None:
        """Home: in joint space (over the top if the straight path dips, and its legs are ``clear``; its
        note), or a straight line."""
        if not self.p.joint_transfers:
            self.move.to(self.home_x4, limits=self.p.free)
            return None
        note = self.over_the_top(self.home_q, self.p.transfer_scale, self.p.free, rise=True, clear=clear)
        if note is None:
            self.transfer_to(self.home_q, self.p.transfer_scale)
        return note

    # ========================================================================== over the top
    @staticmethod
    def raised(pose: Pose, h: float) -> Pose:
        return Pose(pose.position + np.array([0.0, 0.0, h]), pose.rotation)

    def rise_from_here(self, h: float) -> tuple[Pose, np.ndarray] | None:
        """The pose ``h`` straight above the hand (at rest, in the Cartesian motion) and the joints the
        per-tick IK reaches it with; None if it cannot follow the line."""
        here = self.kin.forward(self.motion.q)
        up = self.raised(here, h)
        q = self.motion.q
        for q_k in along_line(self.kin, q, here, up, self.p.goals.line_steps):
            if q_k is None:
                return None
            q = q_k
        return up, q

    def via_above(
        self, pose: Pose, h: float, q_from: np.ndarray, floor_z: float, q_goal: np.ndarray
    ) -> np.ndarray | None:
        """An IK goal ``h`` above ``pose`` (the hand's angle kept) that a transfer from ``q_from`` reaches
        without the hand going below ``floor_z``, and from which the straight line down to ``pose``
        can be followed; None if there is none. The one on the branch of ``q_goal`` (the goal chosen
        for ``pose``, from which what follows was checked) first: on another branch the line down
        arrives where the lowering after it crawls near a singular posture (evidence:
        docs/decisions.md#motion-and-ik)."""
        via = self.raised(pose, h)
        g = self.p.goals
        same = self.kin.solve(via, q_goal, self.rng, g.ik)
        if same.success and self.kin.limit_margin(same.q) > 0.0:
            if path_low_z(self.kin, q_from, same.q, g) >= floor_z and line_trackable(self.kin, same.q, via, pose, g):
                return same.q
        found = goal_candidates(self.kin, [via], q_from, self.rng, g, lines_to=[pose])
        ok = [c for c in found if c.line_ok and path_low_z(self.kin, q_from, c.q, g) >= floor_z]
        goal = choose_goal(ok, g)
        return None if goal is None else goal.q

    def follow(self, waypoints: np.ndarray, scale: float, then: Callable[[], None] | None = None) -> None:
        """A planned joint path (:mod:`~pickdemo.skills.pick.routes`): a transfer to each waypoint in turn,
        each from rest to rest (a transfer from rest to rest keeps to the straight line in joint space the
        plan checked), then ``then`` (the caller's last leg), if any."""
        self.legs.clear()
        self.route = list(waypoints)
        for q in waypoints[1:]:
            self.legs.append(lambda q=q: self.transfer_to(q, scale))
        if then is not None:
            self.legs.append(then)
        self.transfer_to(waypoints[0], scale)

    def over_the_top(
        self,
        q_goal: np.ndarray,
        scale: float,
        limits: CartesianLimits,
        *,
        rise: bool,
        above: Pose | None = None,
        down: Callable[[], None] | None = None,
        clear: Callable[[np.ndarray, np.ndarray], bool] | None = None,
    ) -> str | None:
        """A transfer to ``q_goal`` whose straight joint path would take the hand down below both of its
        ends goes over the top instead, each leg from rest to rest: straight up from here first
        (``rise``, from the Cartesian motion at rest), in joint space to ``q_goal`` or to a goal
        straight above ``above`` (the goal's pose) and then straight down onto it (``down``: that last
        leg, the caller's, so that it goes to where the plan is by then). The path must keep the hand
        above the lower of the two ends (less ``max_dip_m``); ``clear(q_a, q_b)``: whether a leg's straight
        joint path keeps clear of what is in the way (each leg must). Its note if so planned (its first leg
        started); None if the direct path does not dip, or no way over the top was found (the direct
        transfer is then the caller's)."""
        g = self.p.goals
        dip = path_dip(self.kin, self.q, q_goal, g)
        if dip <= g.max_dip_m:
            return None
        z_goal = self.kin.forward(q_goal).position[2]
        floor = min(self.kin.forward(self.q).position[2], z_goal) - g.max_dip_m
        for h in g.via_heights_m:
            legs: list[Callable[[], None]] = []
            q_start = self.q
            if rise:
                found = None if self.joint else self.rise_from_here(h)
                if found is None or (clear is not None and not clear(self.q, found[1])):
                    continue
                up, q_start = found
                legs.append(lambda up=up: self.move.to(up, limits=limits))
            if above is not None:
                q_via = self.via_above(above, h, q_start, floor, q_goal)
                if q_via is None or (clear is not None and not (clear(q_start, q_via) and clear(q_via, q_goal))):
                    continue
                legs.append(lambda q=q_via: self.transfer_to(q, scale))
                legs.append(down or (lambda: (self.cartesian(), self.move.to(above, limits=limits))))
            else:
                if path_low_z(self.kin, q_start, q_goal, g) < floor or (
                    clear is not None and not clear(q_start, q_goal)
                ):
                    continue
                legs.append(lambda: self.transfer_to(q_goal, scale))
            note = (
                f"over the top: the joint path would take the hand {dip * 1e3:.0f} mm below its ends, "
                f"so {'up ' if rise else ''}{h * 1e2:.0f} cm{' and down' if above is not None else ''}"
            )
            self.legs.clear()
            self.legs.extend(legs[1:])
            legs[0]()
            return note
        return None

    def goal(
        self,
        pose: Pose,
        line_to: Pose,
        *,
        seeded: np.ndarray | None = None,
        half_turned: tuple[Pose, Pose] | None = None,
        accept: Callable[[np.ndarray, int], bool] | None = None,
        near: Callable[[np.ndarray, int], bool] | None = None,
        fixed: Callable[[np.ndarray, int], bool] | None = None,
    ) -> tuple[np.ndarray | None, int]:
        """The IK goal for a top-down TCP pose, or the same pose turned half a turn (a parallel gripper
        closes the same way) when the pose's own angle will not do: the best of several solutions
        (:mod:`pickdemo.motion.ik_goals`); and 1 if turned. ``seeded``: a re-plan keeps to the solution
        near the goal it had, if there is one. ``accept(q, index)``: whether the straight line that follows
        a goal (of the pose, or the turned one) keeps clear of what is in the way: those that do first; if
        none does, those ``near`` accepts (the same within tighter margins), then those ``fixed`` accepts
        (clear of the fixtures alone, the line followed as the arm will make it), then the best of all
        (the caller's route says what is in the way)."""
        if seeded is not None:
            res = self.kin.solve(pose, seeded, self.rng, self.p.goals.ik)
            if res.success and self.joint and not self.joints.finished:
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
        found = goal_candidates(self.kin, [pose], self.q, self.rng, g, lines_to=[line_to])
        clear = found if accept is None else [c for c in found if c.line_ok and accept(c.q, 0)]
        goal = choose_goal(clear, g)
        # (a jaw's hand turned half a turn about its TCP, the fixed jaw's face, would close away from
        # the object: its other angles are the grasp chooser's, each planned anew)
        equivalent = self.kin.robot.gripper.coupled or half_turned is not None
        if equivalent and (goal is None or not goal.line_ok or goal.dip_m > g.max_dip_m):
            half = half_turned if half_turned is not None else (half_turn(pose), half_turn(line_to))
            poses, ends = [pose, half[0]], [line_to, half[1]]
            turned = goal_candidates(self.kin, poses[1:], self.q, self.rng, g, lines_to=ends[1:])
            turned = [dataclasses.replace(t, index=1) for t in turned]
            found += turned
            clear += turned if accept is None else [c for c in turned if c.line_ok and accept(c.q, 1)]
            goal = choose_goal(clear, g)
        if goal is None and accept is not None and found:
            # none clear: the arm's other postures, from more starts (each turned pose's too)
            more = dataclasses.replace(g, starts=g.starts * MORE_STARTS)
            poses = [pose] if not equivalent else [pose, *(half_turned or (half_turn(pose), half_turn(line_to)))[:1]]
            ends = [line_to] if not equivalent else [line_to, (half_turned or (None, half_turn(line_to)))[1]]
            extras: list = []
            for i, (p, e) in enumerate(zip(poses, ends, strict=True)):
                extra = goal_candidates(self.kin, [p], self.q, self.rng, more, lines_to=[e])
                extra = [dataclasses.replace(c, index=i) for c in extra]
                clear += [c for c in extra if c.line_ok and accept(c.q, i)]
                extras += extra
            goal = choose_goal(clear, g)
            if goal is None and near is not None:
                # within the tight margins, a goal whose line can be followed (in a shelf's bin, the
                # hand's way in keeps within a centimetre of the boards), before one whose line cannot
                goal = choose_goal([c for c in found + extras if c.line_ok and near(c.q, c.index)], g)
            if goal is None and fixed is not None:
                # (those of the first starts before those of more, as the best of all is theirs)
                goal = choose_goal([c for c in found if fixed(c.q, c.index)], g) or choose_goal(
                    [c for c in extras if fixed(c.q, c.index)], g
                )
            goal = goal or choose_goal(found, g)
        if goal is None:
            return None, 0
        if goal.line_ok:
            self._line_checked_q = goal.q.copy()
        return goal.q, goal.index

    def lift_in_reach(self, plan: GraspPlan) -> GraspPlan:
        """The plan with its lift as high as the per-tick IK can follow the hand straight up from where
        it is, up to the plan's (a small arm's hand points down only low near its base; the grasp
        chooser made sure that the descent from the pregrasp can be followed, so a lift goes as high
        as that at least)."""
        here = self.kin.forward(self.motion.q).position
        start = Pose(np.array([*plan.lift.position[:2], here[2]]), plan.lift.rotation)
        share = line_reach(self.kin, self.motion.q, start, plan.lift, self.p.goals)
        if share >= 1.0:
            return plan
        z = here[2] + share * (plan.lift.position[2] - here[2])
        lower = dataclasses.replace(plan, lift=Pose(np.array([*plan.lift.position[:2], z]), plan.lift.rotation))
        if plan.withdraw is not None:  # taken out of a shelf as much lower
            dz = np.array([0.0, 0.0, z - float(plan.lift.position[2])])
            lower = dataclasses.replace(lower, withdraw=Pose(plan.withdraw.position + dz, plan.withdraw.rotation))
        return lower

    def straight_carry_ok(self, plan: GraspPlan, lift_scale: float) -> bool:
        """Whether the arm, carried along a straight line to above the place (the per-tick IK keeps
        to the branch it is on), stays clear of singular postures and joint limits on the way and
        arrives where it can follow the lowering onto the place
        (:func:`~pickdemo.motion.ik_goals.straight_carry_ok`)."""
        return straight_carry_ok(
            self.kin,
            self.motion.q,
            self.motion.setpoint,
            self.move.x4(plan.place_above),
            plan.place,
            speed_m_s=self.p.free.scaled(lift_scale).velocity,
            posture=self.motion.posture,
            params=self.p.goals,
            frame=self.motion.frame,
        )

    def line_limits(self, end: Pose) -> CartesianLimits:
        """The near-object limits for a straight line from where the hand is to ``end``, slowed as the
        joints need near a singular posture (:func:`~pickdemo.motion.ik_goals.line_speed_scale`)."""
        here = self.kin.forward(self.motion.q)
        scale = line_speed_scale(self.kin, self.motion.q, here, end, self.p.goals)
        if scale >= 1.0:
            return self.p.near
        return self.p.near.scaled(max(scale, self.p.goals.min_line_speed_scale))
