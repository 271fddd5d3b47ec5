"""The robot's low-level controller in simulation: tracks joint trajectories, drives the gripper.

It commands position (with velocity feed-forward) on the seven arm joints and both finger joints
(PyBullet ignores ``<mimic>``). Every loop is bounded by simulated steps; the episode's step budget
is enforced here, raising :class:`StepBudgetExceeded` when spent.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from pickdemo import robot_model as rm
from pickdemo.sim.scene import JointState, Scene
from pickdemo.trajectory import JointTrajectory

ARM_EFFORT_NM = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])
GRIPPER_FORCE_N = 20.0  # per finger; measured: holds a 5 cm cube with ~1 mm slip
FINGER_SPEED_M_S = 0.1
POSITION_GAIN = 0.3
VELOCITY_GAIN = 1.0


class StepBudgetExceeded(RuntimeError):
    """The episode used up its simulated-time budget."""


class Controller:
    """Joint-space position control of the Panda inside a :class:`Scene`."""

    def __init__(self, scene: Scene, *, max_steps: int) -> None:
        self.scene = scene
        self.max_steps = max_steps
        self._finger_target = rm.FINGER_MAX_M
        self._finger_force = GRIPPER_FORCE_N
        self.arm_command = np.array(rm.HOME_Q)
        self.tracking_error_rad = 0.0  # worst joint error seen while following trajectories

    def _step(self) -> None:
        if self.scene.steps >= self.max_steps:
            raise StepBudgetExceeded(f"simulated-time budget of {self.max_steps * self.scene.time_step_s:.1f} s spent")
        self.scene.step()

    def _command_arm(self, q: np.ndarray, dq: np.ndarray) -> None:
        s = self.scene
        s.client.setJointMotorControlArray(
            s.bodies["robot"],
            s.arm_joints,
            p.POSITION_CONTROL,
            targetPositions=[float(v) for v in q],
            targetVelocities=[float(v) for v in dq],
            forces=[float(v) for v in ARM_EFFORT_NM],
            positionGains=[POSITION_GAIN] * 7,
            velocityGains=[VELOCITY_GAIN] * 7,
        )
        self.arm_command = np.array(q)

    def _command_fingers(self) -> None:
        s = self.scene
        for j in s.finger_joints:
            s.client.setJointMotorControl2(
                s.bodies["robot"],
                j,
                p.POSITION_CONTROL,
                targetPosition=self._finger_target,
                force=self._finger_force,
                maxVelocity=FINGER_SPEED_M_S,
            )

    def joint_state(self) -> JointState:
        return self.scene.joint_state()

    def follow(self, traj: JointTrajectory, *, settle_steps: int = 60) -> None:
        """Track a sampled trajectory (one sample per simulation step), then hold its end."""
        if abs(traj.dt_s - self.scene.time_step_s) > 1e-12:
            raise ValueError("trajectory must be sampled at the simulation time step")
        for q, dq in zip(traj.positions, traj.velocities, strict=True):
            self._command_arm(q, dq)
            self._step()
            err = float(np.max(np.abs(self.scene.joint_state().arm_q - q)))
            self.tracking_error_rad = max(self.tracking_error_rad, err)
        self.hold(settle_steps)

    def hold(self, steps: int) -> None:
        """Hold the last arm command for ``steps`` steps, or until the arm has come to rest."""
        self._command_arm(self.arm_command, np.zeros(7))
        for i in range(steps):
            self._step()
            if i >= 5 and float(np.max(np.abs(self.scene.joint_state().arm_dq))) < 1e-3:
                break

    def gripper(self, opening_per_finger_m: float, *, max_steps: int = 240, force_n: float = GRIPPER_FORCE_N) -> float:
        """Drive both fingers towards an opening; stop when they stall. Returns the final opening (m)."""
        self._finger_target = float(np.clip(opening_per_finger_m, 0.0, rm.FINGER_MAX_M))
        self._finger_force = force_n
        self._command_fingers()
        prev = self.scene.joint_state().fingers_m.copy()
        still = 0
        for _ in range(max_steps):
            self._step()
            now = self.scene.joint_state().fingers_m
            still = still + 1 if float(np.max(np.abs(now - prev))) < 2e-6 else 0
            prev = now.copy()
            if still >= 10:
                break
        return float(np.sum(self.scene.joint_state().fingers_m))
