"""The joint command's rate limiter and the robot's reflex, as the Franka's controller has them.

Pure: numpy only. A real Panda checks every command it is sent: a joint position, velocity,
acceleration or jerk beyond the datasheet (the finite differences of the commanded positions, tick
to tick) stops the arm with a reflex. libfranka therefore passes every command through
``franka::limitRate`` before sending it; :class:`RateLimiter` is that filter, written after it
(``libfranka/src/rate_limiting.cpp``): the commanded velocity's jerk is clamped, the acceleration it
integrates to is clamped to what can still brake before the velocity limit, and the velocity it
integrates to gives the position sent (and, our ticks being longer than its 1 ms, no tick steps past
the velocity limit). A command within the limits passes unchanged, bit for bit.

:class:`Reflex` is the robot side's check of what it is sent (the same differences against the
datasheet itself); the controller's limiter keeps a margin below it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo import robot_model as rm

#: The limiter's share of the datasheet limits (the reflex sits at the datasheet itself).
LIMITER_SHARE = 0.98


@dataclass(frozen=True)
class JointRates:
    """Per joint: velocity (rad/s), acceleration (rad/s^2), jerk (rad/s^3)."""

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    @classmethod
    def datasheet(cls, share: float = 1.0) -> JointRates:
        return cls(rm.MAX_VELOCITY_RAD_S * share, rm.MAX_ACCELERATION_RAD_S2 * share, rm.MAX_JERK_RAD_S3 * share)


class RateLimiter:
    """``franka::limitRate`` for joint positions, one control tick of ``dt_s`` at a time."""

    def __init__(self, q0: np.ndarray, dt_s: float, limits: JointRates | None = None) -> None:
        self.dt = float(dt_s)
        self.lim = limits or JointRates.datasheet(LIMITER_SHARE)
        self.q = np.asarray(q0, dtype=float).copy()
        self.dq = np.zeros(7)
        self.ddq = np.zeros(7)
        self.limited_ticks = 0  # ticks on which any joint's command was changed
        self._ratio = self.lim.jerk / self.lim.acceleration

    def __call__(self, q_cmd: np.ndarray) -> tuple[np.ndarray, bool]:
        """The position to send for the commanded ``q_cmd``; True when it had to be changed."""
        dt, lim = self.dt, self.lim
        q_cmd = np.asarray(q_cmd, dtype=float)
        v_cmd = (q_cmd - self.q) / dt
        acc_cmd = (v_cmd - self.dq) / dt
        jerk_cmd = (acc_cmd - self.ddq) / dt
        # the acceleration that can still be braked (at the jerk limit) before the velocity limit,
        # and, ticks being longer than the Franka's 1 ms, no tick's step past the velocity limit
        room_up, room_down = lim.velocity - self.dq, -lim.velocity - self.dq
        acc_max = np.minimum(np.minimum(self._ratio * room_up, lim.acceleration), room_up / dt)
        acc_min = np.maximum(np.maximum(self._ratio * room_down, -lim.acceleration), room_down / dt)
        if np.all(np.abs(jerk_cmd) <= lim.jerk) and np.all(acc_cmd <= acc_max) and np.all(acc_cmd >= acc_min):
            self.q, self.dq, self.ddq = q_cmd.copy(), v_cmd, acc_cmd  # within every limit: as commanded
            return q_cmd.copy(), False
        jerk = np.clip(jerk_cmd, -lim.jerk, lim.jerk)
        acc = np.clip(self.ddq + jerk * dt, acc_min, acc_max)
        v = self.dq + acc * dt
        q = self.q + v * dt
        # joints whose command was within every limit keep it exactly
        free = np.abs(v - v_cmd) <= 1e-12 * np.maximum(1.0, np.abs(v_cmd))
        q = np.where(free, q_cmd, q)
        v_sent = (q - self.q) / dt
        self.ddq = (v_sent - self.dq) / dt
        self.dq = v_sent
        self.q = q
        limited = not bool(free.all())
        self.limited_ticks += limited
        return q.copy(), limited


class ReflexError(RuntimeError):
    """A command beyond the Franka's limits: the robot stops (the episode fails in ``reflex``)."""


class Reflex:
    """The robot's check of each joint position command it is sent, tick to tick."""

    def __init__(self, q0: np.ndarray, dt_s: float, limits: JointRates | None = None, rel_tol: float = 1e-6) -> None:
        self.dt = float(dt_s)
        self.lim = limits or JointRates.datasheet()
        self.tol = 1.0 + rel_tol
        self.q = np.asarray(q0, dtype=float).copy()
        self.dq = np.zeros(7)
        self.ddq = np.zeros(7)

    def check(self, q_cmd: np.ndarray, time_s: float) -> None:
        """Raise :class:`ReflexError` naming the joint, the quantity and the limit."""
        q_cmd = np.asarray(q_cmd, dtype=float)
        dq = (q_cmd - self.q) / self.dt
        ddq = (dq - self.dq) / self.dt
        jerk = (ddq - self.ddq) / self.dt
        checks = (
            ("position", "rad", np.maximum(rm.MIN_POSITION_RAD - q_cmd, q_cmd - rm.MAX_POSITION_RAD), 0.0, q_cmd),
            ("velocity", "rad/s", np.abs(dq), self.lim.velocity, dq),
            ("acceleration", "rad/s^2", np.abs(ddq), self.lim.acceleration, ddq),
            ("jerk", "rad/s^3", np.abs(jerk), self.lim.jerk, jerk),
        )
        for quantity, unit, value, limit, signed in checks:
            over = value > limit * self.tol if quantity != "position" else value > 1e-9
            if np.any(over):
                j = int(np.flatnonzero(over)[0])
                if quantity == "position":
                    lo, hi = rm.MIN_POSITION_RAD[j], rm.MAX_POSITION_RAD[j]
                    said = f"joint {j + 1} commanded to {signed[j]:.4f} rad, outside [{lo:.4f}, {hi:.4f}]"
                else:
                    said = f"joint {j + 1} commanded at {abs(signed[j]):.4g} {unit}, beyond its limit {limit[j]:.4g}"
                raise ReflexError(f"{said} at {time_s:.3f} s: the robot stops")
        self.q, self.dq, self.ddq = q_cmd.copy(), dq, ddq
