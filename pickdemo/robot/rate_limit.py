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

from pickdemo.robot.description import JointLimits

#: The limiter's share of the datasheet limits (the reflex sits at the datasheet itself).
LIMITER_SHARE = 0.98


@dataclass(frozen=True)
class JointRates:
    """Per joint: velocity (rad/s), acceleration (rad/s^2), jerk (rad/s^3)."""

    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray

    @classmethod
    def datasheet(cls, limits: JointLimits, share: float = 1.0) -> JointRates:
        """A robot's datasheet rates (:class:`~pickdemo.robot.description.JointLimits`), times ``share``."""
        return cls(
            limits.max_velocity_rad_s * share, limits.max_acceleration_rad_s2 * share, limits.max_jerk_rad_s3 * share
        )


class RateLimiter:
    """``franka::limitRate`` for joint positions, one control tick of ``dt_s`` at a time."""

    def __init__(self, q0: np.ndarray, dt_s: float, limits: JointLimits, rates: JointRates | None = None) -> None:
        """``limits``: the robot's datasheet; ``rates``: the limiter's own (default: ``LIMITER_SHARE`` of it)."""
        self.dt = float(dt_s)
        self.lim = rates or JointRates.datasheet(limits, LIMITER_SHARE)
        self.q = np.asarray(q0, dtype=float).copy()
        self.dq = np.zeros(len(self.q))
        self.ddq = np.zeros(len(self.q))
        self.limited_ticks = 0  # ticks on which any joint's command was changed
        self._ratio = self.lim.jerk / self.lim.acceleration
        # A short path for the usual tick: a joint whose last velocity is at least one tick of full
        # acceleration inside its limit may accelerate at the full limit (when a tick is long enough
        # for the jerk limit to reach it: dt >= A / J), so within |a| <= A and |j| <= J nothing clamps.
        inner = self.lim.velocity - self.lim.acceleration * self.dt
        self._short = bool(np.all(self.lim.jerk * self.dt >= self.lim.acceleration) and np.all(inner > 0))
        self._bounds = np.concatenate([inner, self.lim.acceleration, self.lim.jerk])
        self._n = n = len(self.q)
        self._buf = np.empty(3 * n)

    def __call__(self, q_cmd: np.ndarray) -> tuple[np.ndarray, bool]:
        """The position to send for the commanded ``q_cmd``; True when it had to be changed."""
        dt, lim = self.dt, self.lim
        q_cmd = np.asarray(q_cmd, dtype=float)
        v_cmd = (q_cmd - self.q) / dt
        acc_cmd = (v_cmd - self.dq) / dt
        jerk_cmd = (acc_cmd - self.ddq) / dt
        if self._short:
            buf = self._buf
            n = self._n
            buf[:n], buf[n : 2 * n], buf[2 * n :] = self.dq, acc_cmd, jerk_cmd
            if np.all(np.abs(buf) <= self._bounds):
                self.q, self.dq, self.ddq = q_cmd.copy(), v_cmd, acc_cmd  # within every limit: as commanded
                return q_cmd.copy(), False
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

    def __init__(
        self, q0: np.ndarray, dt_s: float, limits: JointLimits, rates: JointRates | None = None, rel_tol: float = 1e-6
    ) -> None:
        """``limits``: the robot's datasheet (its rates too, unless ``rates`` says otherwise)."""
        self.dt = float(dt_s)
        self.lim = rates or JointRates.datasheet(limits)
        self.lo, self.hi = limits.min_position_rad, limits.max_position_rad
        self.tol = 1.0 + rel_tol
        self.q = np.asarray(q0, dtype=float).copy()
        self.n = n = len(self.q)
        self.dq = np.zeros(n)
        self.ddq = np.zeros(n)
        # the position's distance from mid-range, the velocity, acceleration and jerk side by side,
        # each against its bound: one test a tick
        self._mid = 0.5 * (self.lo + self.hi)
        half = 0.5 * (self.hi - self.lo) + 1e-9
        self._limits = np.concatenate([self.lim.velocity, self.lim.acceleration, self.lim.jerk]) * self.tol
        self._bounds = np.concatenate([half, self._limits])
        self._buf = np.empty(4 * n)

    def check(self, q_cmd: np.ndarray, time_s: float) -> None:
        """Raise :class:`ReflexError` naming the joint, the quantity and the limit."""
        q_cmd = np.asarray(q_cmd, dtype=float)
        buf, n = self._buf, self.n
        buf[:n] = q_cmd - self._mid
        dq = buf[n : 2 * n] = (q_cmd - self.q) / self.dt
        ddq = buf[2 * n : 3 * n] = (dq - self.dq) / self.dt
        buf[3 * n :] = (ddq - self.ddq) / self.dt
        if not np.all(np.abs(buf) <= self._bounds):
            raise ReflexError(f"{self._what(q_cmd, buf[n:])} at {time_s:.3f} s: the robot stops")
        self.q, self.dq, self.ddq = q_cmd.copy(), dq.copy(), ddq.copy()

    def _what(self, q_cmd: np.ndarray, rates: np.ndarray) -> str:
        """The first joint and quantity beyond its limit, said."""
        out = np.flatnonzero((q_cmd < self.lo - 1e-9) | (q_cmd > self.hi + 1e-9))
        n = self.n
        if out.size:
            j = int(out[0])
            lo, hi = self.lo[j], self.hi[j]
            return f"joint {j + 1} commanded to {q_cmd[j]:.4f} rad, outside [{lo:.4f}, {hi:.4f}]"
        limits = (self.lim.velocity, self.lim.acceleration, self.lim.jerk)
        for k, unit in enumerate(("rad/s", "rad/s^2", "rad/s^3")):
            over = np.flatnonzero(np.abs(rates[n * k : n * k + n]) > self._limits[n * k : n * k + n])
            if over.size:
                j = int(over[0])
                value = abs(rates[n * k + j])
                return f"joint {j + 1} commanded at {value:.4g} {unit}, beyond its limit {limits[k][j]:.4g}"
        return "a command beyond the limits"  # (not reached)
