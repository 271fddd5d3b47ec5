"""The environments' control modes: an agent's action made into each control tick's command.

An action is held for the control ticks of one agent step. Between actions the robot moves the
joints from where they were last sent toward the action's joint goal, a straight line in joint
space over the step's ticks, and every tick's joint command passes the robot's own rate limiter
(:class:`~pickdemo.robot.rate_limit.RateLimiter`, ``franka::limitRate`` after libfranka), so no action
can ask the arm for more than its datasheet: a goal too far for one step is reached later. The
robot's reflex (:class:`~pickdemo.robot.rate_limit.Reflex`) still checks what is sent, as in the loop.

- ``joint_pos``: the arm's joint goals (rad, within the joint limits) and the gripper.
- ``ee_delta``: the hand's displacement (x, y, z, each in [-1, 1] of ``max_speed_m_s`` over one
  step) and its turn about the vertical (``max_yaw_rate_rad_s``), the hand pointing down, and the
  gripper. The goal pose is kept from step to step (from the hand's pose at the first step),
  held within ``WORKSPACE``; the joints come from Pinocchio's IK, warm-started from the last goal.
- The gripper, in both: -1 closed, +1 open (each finger's travel between), squeezing with the
  robot's grasp force (a suction cup: below 0 its vacuum on, at 0 and above off); with
  ``gripper="opening_force"`` a second number sets the force, -1 none to +1 the hand's most (a
  Franka Hand's ``grasp(width, speed, force)``; the skill squeezes a small face less and a slipped
  object harder).

An action outside the action space, or not finite, is a ``ValueError`` naming the action; the
simulator never sees it. A part of the environments: numpy and the robot package, no Gymnasium.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.interfaces import Command, Observation
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.kinematics import Kinematics
from pickdemo.robot.rate_limit import RateLimiter

#: The joints are stopped this far inside their limits (rad).
POSITION_MARGIN_RAD = 0.01
#: An action this far outside a bound, relative to it (at least 1), is still within it: float32's rounding
#: (a relative 6e-8), with room for a policy's arithmetic; what is past the bound by so little is clipped.
BOUND_SLACK = 1e-6
#: Where ``ee_delta`` keeps the hand's goal (m, in the world: x, y, z low and high).
WORKSPACE = (np.array([-0.9, -0.9, 0.0]), np.array([0.9, 0.9, 0.9]))


@dataclass(frozen=True)
class Bounds:
    low: np.ndarray
    high: np.ndarray


def gripper_command(g: float, robot: RobotDescription) -> float:
    """Each finger's opening for a gripper action in [-1, 1]."""
    return float((g + 1.0) / 2.0 * robot.gripper.finger_max_m)


def gripper_action(finger_m: float, robot: RobotDescription) -> float:
    """The gripper action in [-1, 1] for each finger's opening ``finger_m`` (the inverse)."""
    return float(np.clip(2.0 * finger_m / robot.gripper.finger_max_m - 1.0, -1.0, 1.0))


GRIPPERS = ("opening", "opening_force")


def from_unit(action: np.ndarray, bounds: Bounds, name: str) -> np.ndarray:
    """An action in [-1, 1] each (an environment's ``unit_actions``) on ``bounds``, linearly; one outside
    [-1, 1] (by more than float32 rounds it), of another shape, or not finite raises ``ValueError``."""
    a = np.asarray(action, dtype=float)
    if a.shape != bounds.low.shape:
        raise ValueError(f"{name} action of shape {a.shape}: expected {bounds.low.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} action is not finite: {a.tolist()}")
    out = np.flatnonzero(np.abs(a) > 1.0 + BOUND_SLACK)
    if out.size:
        i = int(out[0])
        raise ValueError(f"{name} action[{i}] = {float(a[i])!r} is outside the unit action space [-1.0, 1.0]")
    return bounds.low + (np.clip(a, -1.0, 1.0) + 1.0) / 2.0 * (bounds.high - bounds.low)


class _Mode:
    """What both modes share: the held joint goal, its line over the step's ticks, the limiter; the
    gripper's one number (its opening) or two (its opening and force)."""

    name = ""

    def __init__(
        self, kin: Kinematics, q0: np.ndarray, dt_s: float, ticks: int, grip_force_n: float, gripper: str = "opening"
    ) -> None:
        self.kin, self.robot, self.ticks, self.grip_force_n = kin, kin.robot, ticks, grip_force_n
        self.gripper_size = GRIPPERS.index(gripper) + 1
        self.limiter = RateLimiter(q0, dt_s, kin.robot.limits)
        self.q_from = np.asarray(q0, dtype=float).copy()
        self.q_goal = self.q_from.copy()
        self.finger_m = kin.robot.gripper.finger_max_m  # open, as the robot starts
        self.vacuum = False  # (a suction cup's valve: shut, as the robot starts)
        self.tick = ticks  # the held goal is reached: hold it

    @property
    def bounds(self) -> Bounds:
        raise NotImplementedError

    def check(self, action: np.ndarray) -> np.ndarray:
        a = np.asarray(action, dtype=float)
        b = self.bounds
        if a.shape != b.low.shape:
            raise ValueError(f"{self.name} action of shape {a.shape}: expected {b.low.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{self.name} action is not finite: {a.tolist()}")
        # a bound as float32 holds it (policies and datasets are float32): 2.8973 is 2.8973000049591064 then
        slack = BOUND_SLACK * np.maximum(1.0, np.maximum(np.abs(b.low), np.abs(b.high)))
        out = np.flatnonzero((a < b.low - slack) | (a > b.high + slack))
        if out.size:
            i = int(out[0])
            raise ValueError(
                f"{self.name} action[{i}] = {float(a[i])!r} is outside the action space "
                f"[{float(b.low[i])!r}, {float(b.high[i])!r}] "
                f"(by more than float32 rounds it: {slack[i]:.1e})"
            )
        return np.clip(a, b.low, b.high)

    def _hold(self, q_goal: np.ndarray, g: np.ndarray) -> None:
        """Hold this joint goal and the gripper's part of the action (one number or two)."""
        self.q_from = self.limiter.q.copy()  # from where the joints were last sent
        self.q_goal = q_goal
        self.finger_m = gripper_command(float(g[0]), self.robot)
        self.vacuum = self.robot.gripper.suction and float(g[0]) < 0.0
        if len(g) > 1:
            self.grip_force_n = float((g[1] + 1.0) / 2.0 * self.robot.gripper.max_force_n)
        self.tick = 0

    def _gripper_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return -np.ones(self.gripper_size), np.ones(self.gripper_size)

    def _gripper_of(self, cmd: Command) -> list[float]:
        g = [
            (-1.0 if cmd.vacuum else 1.0)
            if self.robot.gripper.suction
            else gripper_action(cmd.finger_opening_m, self.robot)
        ]
        if self.gripper_size > 1:
            g.append(float(np.clip(2.0 * cmd.finger_force_n / self.robot.gripper.max_force_n - 1.0, -1.0, 1.0)))
        return g

    def _braked(self, q: np.ndarray) -> np.ndarray:
        """``q`` with each joint's step toward its nearer limit no faster than it can still stop at
        half its acceleration before it (the limiter bounds the rates, not the positions)."""
        lim, lm = self.robot.limits, self.limiter
        room_up = np.maximum(lim.max_position_rad - POSITION_MARGIN_RAD - lm.q, 0.0)
        room_down = np.maximum(lm.q - lim.min_position_rad - POSITION_MARGIN_RAD, 0.0)
        a = 0.5 * lm.lim.acceleration
        dt = lm.dt
        return np.clip(q, lm.q - np.sqrt(2.0 * a * room_down) * dt, lm.q + np.sqrt(2.0 * a * room_up) * dt)

    def __call__(self, obs: Observation) -> Command:
        """The command for this control tick."""
        if self.tick < self.ticks:
            self.tick += 1
        s = self.tick / self.ticks
        q = self.q_goal if s >= 1.0 else self.q_from + s * (self.q_goal - self.q_from)
        sent, _ = self.limiter(self._braked(q))
        return Command(sent, self.limiter.dq.copy(), self.finger_m, self.grip_force_n, self.vacuum)


class JointPos(_Mode):
    """``joint_pos``: (the arm's joint goals, the gripper)."""

    name = "joint_pos"

    @property
    def bounds(self) -> Bounds:
        lim = self.robot.limits
        lo, hi = self._gripper_bounds()
        return Bounds(np.concatenate([lim.min_position_rad, lo]), np.concatenate([lim.max_position_rad, hi]))

    def set(self, action: np.ndarray) -> None:
        a = self.check(action)
        n = self.robot.dof
        self._hold(a[:n].copy(), a[n:])

    def action_for(self, cmd: Command) -> np.ndarray:
        """The action that asks for ``cmd`` (the expert's command, at one tick a step)."""
        b = self.bounds
        n = self.robot.dof
        q = np.clip(np.asarray(cmd.arm_q, dtype=float), b.low[:n], b.high[:n])
        return np.append(q, self._gripper_of(cmd))


class EeDelta(_Mode):
    """``ee_delta``: (dx, dy, dz, dyaw, gripper[, force]), each in [-1, 1]."""

    name = "ee_delta"

    def __init__(
        self,
        kin: Kinematics,
        q0: np.ndarray,
        dt_s: float,
        ticks: int,
        grip_force_n: float,
        gripper: str = "opening",
        *,
        max_speed_m_s: float = 0.5,
        max_yaw_rate_rad_s: float = 2.0,
    ) -> None:
        super().__init__(kin, q0, dt_s, ticks, grip_force_n, gripper)
        step_s = dt_s * ticks
        self.max_step_m, self.max_turn_rad = max_speed_m_s * step_s, max_yaw_rate_rad_s * step_s
        home = kin.forward(self.q_from)
        self.position = home.position.copy()
        self.down = _level(home.rotation)  # the hand's orientation at home, yawed to none: pointing down
        self.yaw = float(np.arctan2(home.rotation[1, 0], home.rotation[0, 0]))

    @property
    def bounds(self) -> Bounds:
        return Bounds(-np.ones(4 + self.gripper_size), np.ones(4 + self.gripper_size))

    def goal_pose(self) -> Pose:
        c, s = np.cos(self.yaw), np.sin(self.yaw)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        return Pose(self.position.copy(), turn @ self.down)

    def set(self, action: np.ndarray) -> None:
        a = self.check(action)
        self.position = np.clip(self.position + a[:3] * self.max_step_m, *WORKSPACE)
        yaw = self.yaw + a[3] * self.max_turn_rad
        self.yaw = float(np.arctan2(np.sin(yaw), np.cos(yaw)))
        ik = self.kin.track(self.goal_pose(), self.q_goal, max_iterations=20)
        self._hold(ik.q, a[4:])  # (not reached: as near as the arm gets, within its joint limits)

    def action_for(self, cmd: Command) -> np.ndarray:
        """The action nearest to asking for ``cmd``: where its joints put the hand, from the held goal
        (clipped to one step's reach; a hand not pointing down is asked for pointing down)."""
        pose = self.kin.forward(np.asarray(cmd.arm_q, dtype=float))
        d = (pose.position - self.position) / self.max_step_m
        yaw = float(np.arctan2(pose.rotation[1, 0], pose.rotation[0, 0]))
        turn = float(np.arctan2(np.sin(yaw - self.yaw), np.cos(yaw - self.yaw))) / self.max_turn_rad
        return np.clip(np.array([*d, turn, *self._gripper_of(cmd)]), -1.0, 1.0)


def _level(R: np.ndarray) -> np.ndarray:
    """``R`` turned about the world's vertical so that its x axis has no yaw."""
    yaw = np.arctan2(R[1, 0], R[0, 0])
    c, s = np.cos(-yaw), np.sin(-yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R


MODES = {"joint_pos": JointPos, "ee_delta": EeDelta}
