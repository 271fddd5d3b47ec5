"""Online motion: Ruckig's online form in the TCP's Cartesian space, and one IK solve per tick.

Pure: no simulator. The hand always points down (every pose of a top-down pick and place), so the
TCP has four degrees of freedom: ``x, y, z`` (m) and the hand's yaw about world z (rad). One
``Ruckig(4, dt)`` instance lives for the whole episode, as in Ruckig's ``01_position`` example:
each tick ``update`` then ``pass_to_input``; re-targeting writes ``target_position`` (and
``target_velocity``) into the input and Ruckig recomputes from where the motion is, so the commanded
motion stays within the limits it was given, jerk included, across every re-target.

Phase synchronisation makes rest-to-rest moves straight lines in Cartesian space (the fingers move
straight near the object: joint-space moves were measured to stray 10-28 mm from the vertical).
Each tick's setpoint becomes joint angles by a few damped least-squares steps warm-started from the
last command (:meth:`pickdemo.kinematics.PandaKinematics.track`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, OutputParameter, Result, Ruckig, RuckigError, Synchronization

from pickdemo import robot_model as rm
from pickdemo.geometry import Pose
from pickdemo.kinematics import PandaKinematics

#: A target closer than this to the current one is not written (Ruckig would recompute for nothing).
RETARGET_EPS = np.array([2e-4, 2e-4, 2e-4, np.radians(0.1)])


class MotionError(RuntimeError):
    """Ruckig rejected the input, or IK lost the Cartesian setpoint."""


@dataclass(frozen=True)
class CartesianLimits:
    """Limits of the TCP per axis: m/s, m/s^2, m/s^3 for x, y, z; rad/s, rad/s^2, rad/s^3 for yaw."""

    velocity: float = 0.10
    acceleration: float = 0.5
    jerk: float = 5.0
    yaw_velocity: float = 0.8
    yaw_acceleration: float = 4.0
    yaw_jerk: float = 40.0

    def __post_init__(self) -> None:
        values = (self.velocity, self.acceleration, self.jerk, self.yaw_velocity, self.yaw_acceleration, self.yaw_jerk)
        if min(values) <= 0.0 or not all(np.isfinite(values)):
            raise ValueError("Cartesian limits must be positive and finite")

    def scaled(self, factor: float) -> CartesianLimits:
        """Slower limits (velocity x f, acceleration x f^2, jerk x f^3)."""
        return CartesianLimits(
            self.velocity * factor,
            self.acceleration * factor**2,
            self.jerk * factor**3,
            self.yaw_velocity * factor,
            self.yaw_acceleration * factor**2,
            self.yaw_jerk * factor**3,
        )

    def scaled_by(self, velocity: float, acceleration: float, jerk: float) -> CartesianLimits:
        """Each kind of limit scaled by its own factor (a scenario's ``[motion]``)."""
        return CartesianLimits(
            self.velocity * velocity,
            self.acceleration * acceleration,
            self.jerk * jerk,
            self.yaw_velocity * velocity,
            self.yaw_acceleration * acceleration,
            self.yaw_jerk * jerk,
        )

    def arrays(self) -> tuple[list[float], list[float], list[float]]:
        return (
            [self.velocity] * 3 + [self.yaw_velocity],
            [self.acceleration] * 3 + [self.yaw_acceleration],
            [self.jerk] * 3 + [self.yaw_jerk],
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


def top_down_pose(x4: np.ndarray) -> Pose:
    """The TCP pose pointing straight down at ``(x, y, z)`` with the hand turned by ``yaw`` about z."""
    return Pose.from_xyz_rpy(np.asarray(x4[:3], dtype=float), roll=np.pi, yaw=float(x4[3]))


def pose_to_x4(pose: Pose) -> np.ndarray:
    """``(x, y, z, yaw)`` of a top-down TCP pose (``R = Rz(yaw) Rx(pi)``)."""
    r = pose.rotation
    return np.array([*pose.position, float(np.arctan2(r[0, 1], r[0, 0]))])


class OnlineMotion:
    """The arm's motion, re-targetable every tick. Call :meth:`step` once per control tick."""

    def __init__(self, kin: PandaKinematics, q0: np.ndarray, dt_s: float, limits: CartesianLimits) -> None:
        self.kin = kin
        self.dt_s = dt_s
        self.q = np.asarray(q0, dtype=float).copy()
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
        self.retargets = 0  # re-targets written while a motion was under way

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
        self, x4: np.ndarray, *, velocity: np.ndarray | None = None, limits: CartesianLimits | None = None
    ) -> bool:
        """Move towards ``x4 = (x, y, z, yaw)``, arriving with ``velocity`` (default at rest).

        Returns whether the input changed. Limits should change only at rest: lowering them
        mid-motion makes Ruckig brake back inside them, which may overshoot.
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
            changed = True
        if changed:
            self._finished = False
        return changed

    @property
    def finished(self) -> bool:
        return self._finished

    # ------------------------------------------------------------------------------------- tick
    def step(self) -> MotionSample:
        """Advance the motion by one tick and solve the joints for the new setpoint."""
        if self._finished:
            out_pos = np.array(self._inp.current_position)
            zero = np.zeros(4)
            q, dq = self._joints(out_pos)
            return MotionSample(q, dq, out_pos, zero, zero, zero, True, False)
        try:
            result = self._otg.update(self._inp, self._out)
        except RuckigError as exc:  # raised (not returned) for some invalid inputs
            raise MotionError(
                f"Ruckig rejected target {np.round(self.target, 4).tolist()}: {exc or 'invalid input'}"
            ) from None
        if result not in (Result.Working, Result.Finished):
            raise MotionError(f"Ruckig returned {result.name} for target {np.round(self.target, 4).tolist()}")
        out = self._out
        new_calc = bool(out.new_calculation)
        out.pass_to_input(self._inp)
        self._finished = result == Result.Finished
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
        res = self.kin.track(top_down_pose(x4), self.q)
        if not res.success and (res.position_error_m > 1e-3 or res.rotation_error_rad > np.radians(0.5)):
            raise MotionError(f"IK lost the Cartesian setpoint {np.round(x4, 4).tolist()}: {res.reason}")
        dq = (res.q - self.q) / self.dt_s
        if np.any(np.abs(dq) > rm.MAX_VELOCITY_RAD_S):
            j = int(np.argmax(np.abs(dq) / rm.MAX_VELOCITY_RAD_S))
            raise MotionError(f"joint {j + 1} would move at {abs(dq[j]):.2f} rad/s, beyond its limit (a singularity?)")
        self.q = res.q
        return res.q.copy(), dq
