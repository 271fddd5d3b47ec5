"""Jerk-limited, time-optimal joint trajectories from Ruckig, sampled at the control rate.

Pure: no simulator. Offline form: one ``calculate`` per segment (rest to rest), then sampling, as in
Ruckig's ``02_position_offline`` example. Segments are planned one at a time because Ruckig's
intermediate waypoints need its cloud API.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

from pickdemo import robot_model as rm


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


def plan_joint_motion(q_start: np.ndarray, q_goal: np.ndarray, limits: Limits, dt_s: float) -> JointTrajectory:
    """Time-optimal rest-to-rest motion from ``q_start`` to ``q_goal``, sampled every ``dt_s``."""
    q_start = np.asarray(q_start, dtype=float)
    q_goal = np.asarray(q_goal, dtype=float)
    dof = len(q_start)
    inp = InputParameter(dof)
    inp.current_position = q_start.tolist()
    inp.current_velocity = [0.0] * dof
    inp.current_acceleration = [0.0] * dof
    inp.target_position = q_goal.tolist()
    inp.target_velocity = [0.0] * dof
    inp.target_acceleration = [0.0] * dof
    inp.max_velocity = limits.velocity.tolist()
    inp.max_acceleration = limits.acceleration.tolist()
    inp.max_jerk = limits.jerk.tolist()
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
        p, v, a = traj.at_time(min(i * dt_s, traj.duration))
        pos[i], vel[i], acc[i] = p, v, a
    for arr in (pos, vel, acc):
        arr.setflags(write=False)
    return JointTrajectory(dt_s=dt_s, positions=pos, velocities=vel, accelerations=acc)
