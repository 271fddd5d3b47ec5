"""Online motion: Ruckig's online form in the TCP's Cartesian space, and one IK solve per tick.

Pure: no simulator. Near the object the hand keeps its orientation but for a turn about the
vertical, so the TCP has four degrees of freedom: ``x, y, z`` (m) and the hand's yaw about world z
(rad). Its orientation at yaw 0 is the motion's ``frame``: pointing straight down (None: every pose
of a top-down pick and place), or a tilted grasp's (:func:`hand_frame`: its approach axis turned
into the x-z plane), taken on when the motion is re-seated for a target tilted so. One
``Ruckig(4, dt)`` instance lives for the whole episode, as in Ruckig's ``01_position`` example:
each tick ``update`` then ``pass_to_input``; re-targeting writes ``target_position`` (and
``target_velocity``) into the input and Ruckig recomputes from where the motion is, so the commanded
motion stays within the limits it was given, jerk included, across every re-target.

Phase synchronisation makes rest-to-rest moves straight lines in Cartesian space (the fingers move
straight near the object, where joint-space moves stray from the vertical; evidence:
docs/decisions.md#motion-and-ik).
Each tick's setpoint becomes joint angles by a few damped least-squares steps warm-started from the
last command (:meth:`pickdemo.robot.kinematics.Kinematics.track`), with a posture task in the hand's
null space: the arm's free swing is held to the posture the motion was seated in (home, or the IK goal
a joint transfer went to) and kept off its joint limits.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from ruckig import (
    ControlInterface,
    InputParameter,
    OutputParameter,
    Result,
    Ruckig,
    RuckigError,
    Synchronization,
    Trajectory,
)

from pickdemo.core.geometry import Pose, about_vertical
from pickdemo.robot.kinematics import IKResult, Kinematics

#: A target closer than this to the current one is not written (Ruckig would recompute for nothing).
RETARGET_EPS = np.array([2e-4, 2e-4, 2e-4, np.radians(0.1)])


class MotionError(RuntimeError):
    """Ruckig rejected the input, or IK lost the Cartesian setpoint."""


@dataclass(frozen=True)
class CartesianLimits:
    """Limits of the TCP per axis: m/s, m/s^2, m/s^3 for x, y, z; rad/s, rad/s^2, rad/s^3 for yaw.

    ``xy_*``, when given, replace the limits of x and y (z keeps its own): following a moving target,
    the hand must keep up with it across the table while it goes down gently.
    """

    velocity: float = 0.10
    acceleration: float = 0.5
    jerk: float = 5.0
    yaw_velocity: float = 0.8
    yaw_acceleration: float = 4.0
    yaw_jerk: float = 40.0
    xy_velocity: float | None = None
    xy_acceleration: float | None = None
    xy_jerk: float | None = None

    def __post_init__(self) -> None:
        values = (self.velocity, self.acceleration, self.jerk, self.yaw_velocity, self.yaw_acceleration, self.yaw_jerk)
        xy = tuple(v for v in (self.xy_velocity, self.xy_acceleration, self.xy_jerk) if v is not None)
        if min(values + xy) <= 0.0 or not all(np.isfinite(values + xy)):
            raise ValueError("Cartesian limits must be positive and finite")
        if 0 < len(xy) < 3:
            raise ValueError("give all of xy_velocity, xy_acceleration, xy_jerk, or none")

    def scaled_by(self, velocity: float, acceleration: float, jerk: float) -> CartesianLimits:
        """Each kind of limit scaled by its own factor (a scenario's ``[motion]``)."""
        xy = self.xy_velocity is not None
        return CartesianLimits(
            self.velocity * velocity,
            self.acceleration * acceleration,
            self.jerk * jerk,
            self.yaw_velocity * velocity,
            self.yaw_acceleration * acceleration,
            self.yaw_jerk * jerk,
            self.xy_velocity * velocity if xy else None,  # type: ignore[operator]
            self.xy_acceleration * acceleration if xy else None,  # type: ignore[operator]
            self.xy_jerk * jerk if xy else None,  # type: ignore[operator]
        )

    def scaled(self, factor: float) -> CartesianLimits:
        """Slower limits (velocity x f, acceleration x f^2, jerk x f^3)."""
        return self.scaled_by(factor, factor**2, factor**3)

    def with_xy_of(self, other: CartesianLimits) -> CartesianLimits:
        """These limits for z and yaw, ``other``'s (its xy, or its x, y, z) for x and y."""
        return dataclasses.replace(
            self,
            xy_velocity=other.xy_velocity or other.velocity,
            xy_acceleration=other.xy_acceleration or other.acceleration,
            xy_jerk=other.xy_jerk or other.jerk,
        )

    def arrays(self) -> tuple[list[float], list[float], list[float]]:
        def axes(xyz: float, xy: float | None, yaw: float) -> list[float]:
            return [xy if xy is not None else xyz] * 2 + [xyz, yaw]

        return (
            axes(self.velocity, self.xy_velocity, self.yaw_velocity),
            axes(self.acceleration, self.xy_acceleration, self.yaw_acceleration),
            axes(self.jerk, self.xy_jerk, self.yaw_jerk),
        )


@dataclass(frozen=True)
class MotionSample:
    """One tick of commanded motion."""

    q: np.ndarray  # (7,) rad, joint command
    dq: np.ndarray  # (7,) rad/s, its velocity feed-forward
    setpoint: np.ndarray  # (4,) x, y, z (m), yaw (rad)
    velocity: np.ndarray  # (4,)
    acceleration: np.ndarray  # (4,)
    jerk: np.ndarray  # (4,)
    finished: bool  # at the target (with the target velocity)
    new_calculation: bool  # Ruckig recomputed this tick (a re-target, or new limits)


#: A hand whose approach axis is within this of straight down points down (rad): a top-down pose.
TILT_EPS_RAD = 1e-3


def top_down_pose(x4: np.ndarray) -> Pose:
    """The TCP pose pointing straight down at ``(x, y, z)`` with the hand turned by ``yaw`` about z."""
    return Pose.from_se3(top_down_se3(x4))


def top_down_se3(x4: np.ndarray) -> pin.SE3:
    """:func:`top_down_pose` as a ``pin.SE3``, without a :class:`Pose` (the IK's target every tick)."""
    return pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0.0, float(x4[3])), np.array(x4[:3], dtype=float))


def hand_frame(rotation: np.ndarray) -> np.ndarray | None:
    """The orientation of a TCP ``rotation`` at yaw 0: None if it points straight down (within
    :data:`TILT_EPS_RAD`), else the rotation turned about the vertical until its approach axis (z)
    lies in the x-z plane, pointing along +x (a tilted grasp's frame; its yaw is the approach's heading)."""
    z = rotation[:, 2]
    if -z[2] >= np.cos(TILT_EPS_RAD):
        return None
    return about_vertical(-float(np.arctan2(z[1], z[0]))) @ rotation


def hand_se3(x4: np.ndarray, frame: np.ndarray | None = None) -> pin.SE3:
    """The TCP pose at ``x4 = (x, y, z, yaw)``: the ``frame`` turned by ``yaw`` about the vertical
    (None: pointing straight down, :func:`top_down_se3`)."""
    if frame is None:
        return top_down_se3(x4)
    return pin.SE3(about_vertical(float(x4[3])) @ frame, np.array(x4[:3], dtype=float))


def pose_to_x4(pose: Pose | pin.SE3, frame: np.ndarray | None = None) -> np.ndarray:
    """``(x, y, z, yaw)`` of a TCP pose: pointing down (``R = Rz(yaw) Rx(pi)``, ``frame`` None), or the
    ``frame`` turned by ``yaw`` about the vertical (the yaw is the approach axis's heading)."""
    if isinstance(pose, pin.SE3):
        r, t = pose.rotation, pose.translation
    else:
        r, t = pose.rotation, pose.position
    if frame is None:
        return np.array([*t, float(np.arctan2(r[0, 1], r[0, 0]))])
    return np.array([*t, float(np.arctan2(r[1, 2], r[0, 2]))])


def _tcp_x4(kin: Kinematics, q: np.ndarray, frame: np.ndarray | None = None) -> np.ndarray:
    """:func:`pose_to_x4` of the TCP at ``q`` (without a :class:`Pose`: this runs every tick)."""
    return pose_to_x4(kin.forward_se3(q), frame)


def _advance(otg: Ruckig, inp: InputParameter, out: OutputParameter, what: Callable[[], str]) -> tuple[bool, bool]:
    """One tick of an online Ruckig trajectory, its output passed back to its input: (finished, whether
    Ruckig recomputed). A rejected input is a :class:`MotionError` naming ``what()`` it was asked for
    (said only then: this runs every tick)."""
    try:
        result = otg.update(inp, out)
    except RuckigError as exc:  # raised (not returned) for some invalid inputs
        raise MotionError(f"Ruckig rejected {what()}: {exc or 'invalid input'}") from None
    if result not in (Result.Working, Result.Finished):
        raise MotionError(f"Ruckig returned {result.name} for {what()}")
    new_calc = bool(out.new_calculation)
    out.pass_to_input(inp)
    return result == Result.Finished, new_calc


class OnlineMotion:
    """The arm's motion, re-targetable every tick. Call :meth:`step` once per control tick."""

    def __init__(self, kin: Kinematics, q0: np.ndarray, dt_s: float, limits: CartesianLimits) -> None:
        self.kin = kin
        self.dt_s = dt_s
        self.q = np.asarray(q0, dtype=float).copy()
        #: the configuration the per-tick IK holds the arm's free swing to: where the motion was seated
        self.posture = self.q.copy()
        #: the hand's orientation at yaw 0 (:func:`hand_frame`; None: pointing down)
        self.frame: np.ndarray | None = None
        self._otg = Ruckig(4, dt_s)
        self._inp = InputParameter(4)
        self._out = OutputParameter(4)
        x0 = pose_to_x4(kin.forward(self.q))
        self._inp.current_position = x0.tolist()
        self._inp.current_velocity = [0.0] * 4
        self._inp.current_acceleration = [0.0] * 4
        self._inp.target_position = x0.tolist()
        self._inp.target_velocity = [0.0] * 4
        self._inp.synchronization = Synchronization.Phase
        self.limits = limits
        self._write_limits(limits)
        self._finished = True
        self._tilt: tuple[np.ndarray, Trajectory] | None = None  # (axis, angle over time) being turned out
        self._tilt_s = 0.0
        self.retargets = 0  # re-targets written while a motion was under way
        self.seated = 0  # times the motion was re-seated where a joint transfer left the arm
        self._calc = Ruckig(4)  # offline: how long a motion would take (an intercept's search)
        self._trajectory = Trajectory(4)

    # ------------------------------------------------------------------------------------ input
    def _write_limits(self, limits: CartesianLimits) -> None:
        v, a, j = limits.arrays()
        self._inp.max_velocity, self._inp.max_acceleration, self._inp.max_jerk = v, a, j
        self.limits = limits

    @property
    def setpoint(self) -> np.ndarray:
        """Where the commanded TCP is now: ``(x, y, z, yaw)``."""
        return np.array(self._inp.current_position)

    @property
    def target(self) -> np.ndarray:
        return np.array(self._inp.target_position)

    def set_target(
        self,
        x4: np.ndarray,
        *,
        velocity: np.ndarray | None = None,
        limits: CartesianLimits | None = None,
        arrive_in_s: float | None = None,
    ) -> bool:
        """Move towards ``x4 = (x, y, z, yaw)``, arriving with ``velocity`` (default at rest), at the
        earliest or in ``arrive_in_s`` (Ruckig's minimum duration: to meet a moving target there).

        Returns whether the input changed. Limits should change only at rest: lowering them
        mid-motion makes Ruckig brake back inside them, which may overshoot. After arriving with a
        velocity the setpoint carries on at that velocity (as Ruckig's trajectory does after its
        duration) until the next target.
        """
        x4 = np.asarray(x4, dtype=float)
        vel = np.zeros(4) if velocity is None else np.asarray(velocity, dtype=float)
        if not (np.all(np.isfinite(x4)) and np.all(np.isfinite(vel))):
            raise MotionError(f"target is not finite: {x4.tolist()}")
        changed = False
        if limits is not None and limits != self.limits:
            self._write_limits(limits)
            changed = True
        if np.any(np.abs(x4 - self.target) > RETARGET_EPS) or np.any(
            np.abs(vel - np.array(self._inp.target_velocity)) > 1e-4
        ):
            if not self._finished:
                self.retargets += 1
            self._inp.target_position = x4.tolist()
            self._inp.target_velocity = vel.tolist()
            self._inp.minimum_duration = arrive_in_s
            changed = True
        if changed:
            self._finished = False
        return changed

    @property
    def finished(self) -> bool:
        """At the target (a tilt being turned out goes on meanwhile: :attr:`turning`; what comes next
        as before, the turn under it, or a transfer from where it has got to)."""
        return self._finished

    @property
    def turning(self) -> bool:
        """A re-seat's tilt is still being turned out."""
        return self._tilt is not None

    @property
    def velocity(self) -> np.ndarray:
        """The commanded TCP's velocity now."""
        return np.array(self._inp.current_velocity)

    def time_to(self, x4: np.ndarray, velocity: np.ndarray, limits: CartesianLimits | None = None) -> float:
        """How long the time-optimal motion from the current state to ``x4`` at ``velocity`` takes (s)."""
        inp = InputParameter(4)
        inp.current_position = self._inp.current_position
        inp.current_velocity = self._inp.current_velocity
        inp.current_acceleration = self._inp.current_acceleration
        inp.target_position = np.asarray(x4, dtype=float).tolist()
        inp.target_velocity = np.asarray(velocity, dtype=float).tolist()
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = (limits or self.limits).arrays()
        inp.synchronization = Synchronization.Phase
        try:
            result = self._calc.calculate(inp, self._trajectory)
        except RuckigError as exc:
            raise MotionError(f"Ruckig rejected target {np.round(x4, 4).tolist()}: {exc or 'invalid input'}") from None
        if result not in (Result.Working, Result.Finished):
            raise MotionError(f"Ruckig returned {result.name} for target {np.round(x4, 4).tolist()}")
        return float(self._trajectory.duration)

    def intercept(
        self,
        point_at: Callable[[float], np.ndarray],
        velocity: np.ndarray,
        *,
        limits: CartesianLimits | None = None,
        earliest_s: float = 0.0,
        latest_s: float = 30.0,
    ) -> float | None:
        """The soonest time ``t`` from now (within ``[earliest_s, latest_s]``) at which the hand can be
        at ``point_at(t)`` moving at ``velocity``: a moving target's meeting point. None: not by then.

        The fixed point of ``t = time_to(point_at(t))``, approached from below (it converges while the
        target is slower than the hand), then bisected back to the soonest ``t`` that is feasible: a
        step may jump past it (reaching where a target is *now* can take longer than meeting it later
        on). Pass the result as ``arrive_in_s`` to arrive exactly then.
        """
        lo = t = max(earliest_s, 0.0)
        for _ in range(40):
            need = self.time_to(point_at(t), velocity, limits)
            if need <= t + 1e-3:
                break
            lo, t = t, need
            if t > latest_s:
                return None
        else:
            return None
        if t == lo:
            return t
        hi = t  # the step may have jumped past the soonest meeting: bisect back to it (to ~2 ms)
        while hi - lo > 2e-3:
            mid = 0.5 * (lo + hi)
            if self.time_to(point_at(mid), velocity, limits) <= mid + 1e-3:
                hi = mid
            else:
                lo = mid
        return hi

    def reset_at(self, q: np.ndarray, frame: np.ndarray | None = None) -> None:
        """Re-seat the motion at rest where a joint-space transfer left the arm (its TCP at ``q``), its
        hand's orientation at yaw 0 ``frame`` from now (None: pointing down)."""
        self.q = np.asarray(q, dtype=float).copy()
        self.seated += 1
        self.posture = self.q.copy()  # the posture the goal was chosen for
        self.frame = frame
        x0 = pose_to_x4(self.kin.forward(self.q), frame)
        self._inp.current_position = x0.tolist()
        self._inp.current_velocity = [0.0] * 4
        self._inp.current_acceleration = [0.0] * 4
        self._inp.target_position = x0.tolist()
        self._inp.target_velocity = [0.0] * 4
        self._inp.minimum_duration = None
        self._finished = True
        self._turn_out_tilt(x0)

    def _turn_out_tilt(self, x0: np.ndarray) -> None:
        """Where the arm, re-seated, is turned otherwise than its frame at any yaw (a plan's tilt changed
        while a transfer went to its last one; pointing down again after a tilted grasp), the difference
        is turned out over a jerk-limited profile of its own, at the yaw's limits, where the joints could
        not take it in one tick. Taken as the first setpoint, it asked the wrist for 2 to 25 degrees in
        one tick (`suction_clear_tote`: 17 picks stopped). Where they can, it is, as it always was."""
        self._tilt, self._tilt_s = None, 0.0
        rest = hand_se3(x0, self.frame)
        axis = pin.log3(self.kin.forward_se3(self.q).rotation @ rest.rotation.T)
        angle = float(np.linalg.norm(axis))
        if angle <= TILT_KEPT_RAD:
            return
        if self._unfollowed(self.kin.track(rest, self.q, posture=self.posture)) is None:
            return  # (the first tick's solve, as it would be, can be taken)
        v_max = self.kin.robot.limits.max_velocity_rad_s
        axis = axis / angle
        # As fast as the yaw may turn, slower where the joints turn fast for it (near a singular posture):
        # each joint within TURN_SPEED_SHARE of its limit, the rate taken from the IK along the turn.
        q, rate = self.q, 0.0
        for k in range(1, TURN_CHECKS + 1):
            left = angle * (1.0 - k / TURN_CHECKS)
            res = self.kin.track(pin.SE3(pin.exp3(axis * left) @ rest.rotation, rest.translation), q, max_iterations=20)
            rate = max(rate, float(np.max(np.abs(res.q - q) / v_max)) * TURN_CHECKS / angle)
            q = res.q
        v, a, j = self.limits.arrays()
        f = min(1.0, TURN_SPEED_SHARE / (rate * v[3])) if rate > 0.0 else 1.0
        inp = InputParameter(1)
        inp.current_position, inp.target_position = [angle], [0.0]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [v[3] * f], [a[3] * f**2], [j[3] * f**3]
        profile = Trajectory(1)
        Ruckig(1).calculate(inp, profile)
        self._tilt = (axis, profile)

    # ------------------------------------------------------------------------------------- tick
    def step(self) -> MotionSample:
        """Advance the motion by one tick and solve the joints for the new setpoint."""
        if self._tilt is not None:
            self._tilt_s += self.dt_s
        sample = self._step()
        if self._tilt is not None and self._tilt_s >= self._tilt[1].duration:
            self._tilt = None
        return sample

    def _step(self) -> MotionSample:
        if self._finished:
            zero = np.zeros(4)
            vel = np.array(self._inp.target_velocity)
            out_pos = np.array(self._inp.current_position) + vel * self.dt_s  # carries on at the target's velocity
            if np.any(vel != 0.0):
                self._inp.current_position = out_pos.tolist()
                self._inp.target_position = (np.array(self._inp.target_position) + vel * self.dt_s).tolist()
            q, dq = self._joints(out_pos)
            return MotionSample(q, dq, out_pos, vel, zero, zero, True, False)
        self._finished, new_calc = _advance(
            self._otg, self._inp, self._out, lambda: f"target {np.round(self.target, 4).tolist()}"
        )
        out = self._out
        pos = np.array(out.new_position)
        q, dq = self._joints(pos)
        return MotionSample(
            q,
            dq,
            pos,
            np.array(out.new_velocity),
            np.array(out.new_acceleration),
            np.array(out.new_jerk),
            self._finished,
            new_calc,
        )

    def _joints(self, x4: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        goal = hand_se3(x4, self.frame)
        if self._tilt is not None:  # (what is left of a tilt being turned out)
            axis, profile = self._tilt
            angle = profile.at_time(min(self._tilt_s, profile.duration))[0][0]
            goal = pin.SE3(pin.exp3(axis * angle) @ goal.rotation, goal.translation)
        res = self.kin.track(goal, self.q, posture=self.posture)
        failed = self._unfollowed(res)
        if failed is not None:
            raise MotionError(failed.replace("the setpoint", f"the Cartesian setpoint {np.round(x4, 4).tolist()}"))
        dq = (res.q - self.q) / self.dt_s
        # A joint heading for its stop keeps the room to brake before it (the brake after a failed motion
        # ran joint 5 past its stop, and the robot's reflex stopped the arm: pick_shelf seed 10).
        room = np.where(dq > 0.0, self.kin.upper - res.q, res.q - self.kin.lower)
        a = BRAKE_SHARE * self.kin.robot.limits.max_acceleration_rad_s2
        jerk = BRAKE_SHARE * self.kin.robot.limits.max_jerk_rad_s3
        need = np.abs(dq) * (np.abs(dq) / (2.0 * a) + a / jerk)
        if np.any(room < need):
            j = int(np.argmax(need - room))
            raise MotionError(
                f"joint {j + 1} would reach its stop at {abs(dq[j]):.2f} rad/s, too fast to brake before it"
            )
        self.q = res.q
        return res.q.copy(), dq

    def _unfollowed(self, res: IKResult) -> str | None:
        """Why the arm cannot take a tick's solve ``res`` from where it is: the IK lost the setpoint, or a
        joint would move beyond its speed limit (None: it can)."""
        if not res.success and (res.position_error_m > LOST_M or res.rotation_error_rad > LOST_RAD):
            return f"IK lost the setpoint: {res.reason}"
        dq = np.abs(res.q - self.q) / self.dt_s
        v_max = self.kin.robot.limits.max_velocity_rad_s
        if np.any(dq > v_max):
            j = int(np.argmax(dq / v_max))
            return f"joint {j + 1} would move at {dq[j]:.2f} rad/s, beyond its limit (a singularity?)"
        return None


#: A re-seated arm turned otherwise than its frame by at most this takes it in its first tick (rad): the
#: per-tick IK's tolerance (:data:`LOST_RAD`); a turn of 0.4 deg out at a near-singular posture lost
#: the IK (`pick_shelf` seed 3), taken at once it does not
TILT_KEPT_RAD = float(np.radians(0.5))
#: ... beyond it, turned with each joint within this share of its speed limit, checked at this many points
TURN_SPEED_SHARE = 0.5
TURN_CHECKS = 8
#: The per-tick IK has lost a Cartesian setpoint once it ends this far from it (m, rad): short of its
#: tolerance, but within this, the arm is where the line wants it, to a millimetre.
LOST_M = 1e-3
LOST_RAD = float(np.radians(0.5))
#: A Cartesian motion keeps each joint this share of the datasheet's braking from its stop (the brake
#: after a failed motion uses more: :data:`JOINT_LIMIT_SHARE`)
BRAKE_SHARE = 0.5
#: A transfer plans within this share of the datasheet's joint velocity, acceleration and jerk: the
#: command sampled at the control rate and differenced (as ``peak_joint_limit_ratio`` measures it) then
#: stays within the datasheet.
JOINT_LIMIT_SHARE = 0.9


class JointMotion:
    """A transfer in joint space: Ruckig over the arm's joints and the robot's datasheet limits (a share of
    them, scaled down further for a held payload), time-optimal and jerk-limited, re-targetable every
    tick. It starts from rest where the Cartesian motion left the arm and ends at rest."""

    def __init__(self, kin: Kinematics, q0: np.ndarray, dt_s: float) -> None:
        self.kin = kin
        self.dt_s = dt_s
        self.q = np.asarray(q0, dtype=float).copy()
        self.limits = kin.robot.limits
        n = kin.robot.dof
        self._otg = Ruckig(n, dt_s)
        self._inp = InputParameter(n)
        self._out = OutputParameter(n)
        self._inp.synchronization = Synchronization.Phase
        self._finished = True
        self.scale = 1.0
        self.retargets = 0

    def start(self, q_now: np.ndarray, q_goal: np.ndarray, *, scale: float = 1.0) -> None:
        """From rest at ``q_now`` to rest at ``q_goal``; ``scale`` (0-1] slows velocity, acceleration
        and jerk alike (a held payload)."""
        if not (np.all(np.isfinite(q_goal)) and self.kin.within_limits(np.asarray(q_goal))):
            raise MotionError(f"joint goal out of the arm's range: {np.round(q_goal, 3).tolist()}")
        self.q = np.asarray(q_now, dtype=float).copy()
        self._inp.current_position = self.q.tolist()
        self._inp.current_velocity = [0.0] * len(self.q)
        self._inp.current_acceleration = [0.0] * len(self.q)
        self._inp.control_interface = ControlInterface.Position  # (after a brake: to a goal again)
        self._write(q_goal, scale)
        self._finished = False

    def brake(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> None:
        """From the arm's state (``q``, ``dq``, ``ddq``: the commands sent) to rest, as soon as the
        datasheet's share allows (Ruckig's velocity interface: wherever it comes to rest)."""
        self.q = np.asarray(q, dtype=float).copy()
        self._inp.current_position = self.q.tolist()
        self._inp.current_velocity = np.asarray(dq, dtype=float).tolist()
        self._inp.current_acceleration = np.asarray(ddq, dtype=float).tolist()
        self._write(self.q, 1.0)
        self._inp.control_interface = ControlInterface.Velocity
        self._inp.target_acceleration = [0.0] * len(self.q)
        self._finished = False

    def retarget(self, q_goal: np.ndarray) -> None:
        """A new goal while moving (the plan changed): Ruckig goes on from where the motion is."""
        if np.max(np.abs(np.asarray(q_goal) - np.array(self._inp.target_position))) < 1e-4:
            return
        if not self._finished:
            self.retargets += 1
        self._write(q_goal, self.scale)
        self._finished = False

    def _write(self, q_goal: np.ndarray, scale: float) -> None:
        self.scale = scale
        share = JOINT_LIMIT_SHARE * scale
        self._inp.target_position = np.asarray(q_goal, dtype=float).tolist()
        self._inp.target_velocity = [0.0] * len(self.q)
        self._inp.max_velocity = (self.limits.max_velocity_rad_s * share).tolist()
        self._inp.max_acceleration = (self.limits.max_acceleration_rad_s2 * share).tolist()
        self._inp.max_jerk = (self.limits.max_jerk_rad_s3 * share).tolist()

    @property
    def finished(self) -> bool:
        return self._finished

    @property
    def target(self) -> np.ndarray:
        return np.array(self._inp.target_position)

    def step(self) -> MotionSample:
        """Advance one tick: the joint command, and the TCP it puts there (as the setpoint)."""
        if self._finished:
            zero = np.zeros(4)
            return MotionSample(self.q.copy(), np.zeros(len(self.q)), _tcp_x4(self.kin, self.q), zero, zero, zero,
                                True, False)  # fmt: skip
        self._finished, new_calc = _advance(
            self._otg, self._inp, self._out, lambda: f"joint goal {np.round(self.target, 3).tolist()}"
        )
        out = self._out
        self.q = np.array(out.new_position)
        zero = np.zeros(4)
        x4 = _tcp_x4(self.kin, self.q)
        return MotionSample(self.q.copy(), np.array(out.new_velocity), x4, zero, zero, zero, self._finished, new_calc)
