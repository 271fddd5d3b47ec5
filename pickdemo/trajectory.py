"""Jerk-limited, time-optimal trajectories from Ruckig, sampled at the control rate.

Pure: no simulator. Offline form: one ``calculate`` per segment (rest to rest), then sampling, as in
Ruckig's ``02_position_offline`` example. Segments are planned one at a time because Ruckig's
intermediate waypoints need its cloud API.

Two kinds of segment:

* joint space (:func:`plan_joint_motion`): Ruckig on the seven joints; time-optimal, for moves in
  free space, whose Cartesian path curves.
* Cartesian line (:func:`plan_cartesian_line`): the TCP moves on the straight line (and the
  geodesic rotation, Pinocchio's SE(3) log/exp) between two poses. Ruckig time-parameterises the
  path parameter s in [0, 1] with limits derived from the Cartesian ones; IK at every sample,
  warm-started from the previous, gives the joints. For approaching, lifting and placing near the
  table, where a curved path would sweep the fingers into the object.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from pickdemo import robot_model as rm
from pickdemo.geometry import Pose
from pickdemo.kinematics import IKParams, PandaKinematics


class TrajectoryError(RuntimeError):
    """Ruckig rejected the input or found no trajectory."""


@dataclass(frozen=True)
class Limits:
    """Per-joint kinematic limits (rad/s, rad/s^2, rad/s^3)."""

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    @staticmethod
    def panda(velocity_scale: float, acceleration_scale: float, jerk_scale: float) -> Limits:
        """The Panda's datasheet limits, each scaled by a factor in (0, 1]."""
        for s in (velocity_scale, acceleration_scale, jerk_scale):
            if not 0.0 < s <= 1.0:
                raise ValueError("limit scales must be in (0, 1]")
        return Limits(
            velocity=rm.MAX_VELOCITY_RAD_S * velocity_scale,
            acceleration=rm.MAX_ACCELERATION_RAD_S2 * acceleration_scale,
            jerk=rm.MAX_JERK_RAD_S3 * jerk_scale,
        )

    def scaled(self, factor: float) -> Limits:
        """Slower limits for careful segments (velocity x f, acceleration x f^2, jerk x f^3)."""
        return Limits(self.velocity * factor, self.acceleration * factor**2, self.jerk * factor**3)


@dataclass(frozen=True)
class JointTrajectory:
    """Samples of a trajectory at a fixed period, from t = 0 to its duration inclusive."""

    dt_s: float
    positions: np.ndarray  # (N, dof) rad
    velocities: np.ndarray  # (N, dof) rad/s
    accelerations: np.ndarray  # (N, dof) rad/s^2

    @property
    def duration_s(self) -> float:
        return (len(self.positions) - 1) * self.dt_s


@dataclass(frozen=True)
class CartesianLimits:
    """Limits of the TCP along a straight line: m/s, m/s^2, m/s^3 and rad/s for the rotation."""

    velocity: float = 0.10
    acceleration: float = 0.5
    jerk: float = 5.0
    angular_velocity: float = 0.5

    def __post_init__(self) -> None:
        if min(self.velocity, self.acceleration, self.jerk, self.angular_velocity) <= 0:
            raise ValueError("Cartesian limits must be positive")


def _ruckig_samples(
    start: np.ndarray, goal: np.ndarray, v: np.ndarray, a: np.ndarray, j: np.ndarray, dt_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    dof = len(start)
    inp = InputParameter(dof)
    inp.current_position = start.tolist()
    inp.current_velocity = [0.0] * dof
    inp.current_acceleration = [0.0] * dof
    inp.target_position = goal.tolist()
    inp.target_velocity = [0.0] * dof
    inp.target_acceleration = [0.0] * dof
    inp.max_velocity = v.tolist()
    inp.max_acceleration = a.tolist()
    inp.max_jerk = j.tolist()
    traj = Trajectory(dof)
    try:
        result = Ruckig(dof).calculate(inp, traj)
    except (RuntimeError, RuckigError) as exc:  # ruckig raises on invalid input
        raise TrajectoryError(str(exc)) from None
    if result not in (Result.Working, Result.Finished):
        raise TrajectoryError(f"Ruckig returned {result}")
    n = int(np.ceil(traj.duration / dt_s)) + 1
    pos = np.empty((n, dof))
    vel = np.empty((n, dof))
    acc = np.empty((n, dof))
    for i in range(n):
        pos[i], vel[i], acc[i] = traj.at_time(min(i * dt_s, traj.duration))
    return pos, vel, acc


def _frozen_trajectory(dt_s: float, pos: np.ndarray, vel: np.ndarray, acc: np.ndarray) -> JointTrajectory:
    for arr in (pos, vel, acc):
        arr.setflags(write=False)
    return JointTrajectory(dt_s=dt_s, positions=pos, velocities=vel, accelerations=acc)


def plan_joint_motion(q_start: np.ndarray, q_goal: np.ndarray, limits: Limits, dt_s: float) -> JointTrajectory:
    """Time-optimal rest-to-rest motion from ``q_start`` to ``q_goal``, sampled every ``dt_s``."""
    pos, vel, acc = _ruckig_samples(
        np.asarray(q_start, dtype=float),
        np.asarray(q_goal, dtype=float),
        limits.velocity,
        limits.acceleration,
        limits.jerk,
        dt_s,
    )
    return _frozen_trajectory(dt_s, pos, vel, acc)


def plan_cartesian_line(
    kin: PandaKinematics,
    q_start: np.ndarray,
    goal: Pose,
    limits: CartesianLimits,
    joint_limits: Limits,
    dt_s: float,
    rng: np.random.Generator,
) -> JointTrajectory:
    """Rest-to-rest motion of the TCP on the straight line from where ``q_start`` puts it to ``goal``.

    Raises :class:`TrajectoryError` when IK loses the path or a joint would exceed its velocity or
    acceleration limit.
    """
    q_start = np.asarray(q_start, dtype=float)
    start = kin.forward(q_start).to_se3()
    delta = pin.log6(start.actInv(goal.to_se3()))  # twist from start to goal, in the start frame
    length = float(np.linalg.norm(goal.position - start.translation))
    angle = float(np.linalg.norm(delta.angular))
    # Limits on s in [0, 1]: the tighter of translation and rotation.
    scale = max(length / limits.velocity, angle / limits.angular_velocity, 1e-9)
    v_s = 1.0 / scale
    a_s = v_s * limits.acceleration / limits.velocity
    j_s = v_s * limits.jerk / limits.velocity
    s, _, _ = _ruckig_samples(np.zeros(1), np.ones(1), np.array([v_s]), np.array([a_s]), np.array([j_s]), dt_s)
    s = np.clip(s[:, 0], 0.0, 1.0)
    params = IKParams(restarts=0, max_iterations=50)
    q = np.empty((len(s), len(q_start)))
    q_prev = q_start
    for i, si in enumerate(s):
        target = Pose.from_se3(start * pin.exp6(delta * si))
        res = kin.solve(target, q_prev, rng, params)
        if not res.success:
            raise TrajectoryError(f"IK lost the straight line at s = {si:.3f}: {res.reason}")
        q[i] = q_prev = res.q
    q[0] = q_start
    vel = np.gradient(q, dt_s, axis=0)
    acc = np.gradient(vel, dt_s, axis=0)
    vel[[0, -1]] = 0.0
    over = np.abs(vel).max(axis=0) / joint_limits.velocity
    if np.any(over > 1.0):
        j = int(np.argmax(over))
        raise TrajectoryError(
            f"straight line needs joint {j + 1} at {over[j]:.1f}x its velocity limit (near a singularity?)"
        )
    return _frozen_trajectory(dt_s, q, vel, acc)
