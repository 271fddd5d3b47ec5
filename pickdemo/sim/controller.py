"""The robot's joint-level interface in simulation: reads its sensors, applies a command.

Non-blocking: :meth:`RobotInterface.observe` and :meth:`RobotInterface.apply` each do one thing for
one tick and return; the episode's control loop is the only place that advances simulated time.
The arm is position-controlled with velocity feed-forward; both finger joints are driven (PyBullet
ignores ``<mimic>``; the scene couples them with a gear constraint); a suction cup's valve is opened
and shut as the command says, and its vacuum sensor read.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from pickdemo.core.interfaces import Command, Observation
from pickdemo.robot.rate_limit import Reflex
from pickdemo.sim.scene import Scene

POSITION_GAIN = 0.3
VELOCITY_GAIN = 1.0


class RobotInterface:
    """The robot's encoders, finger contacts, wrist force and motors inside a :class:`Scene`.

    Like the Franka's controller, it checks each arm command against the datasheet before it sends
    it (:class:`~pickdemo.robot.rate_limit.Reflex`, one check per control tick of ``dt_s``): a command beyond
    raises :class:`~pickdemo.robot.rate_limit.ReflexError` and is not sent.
    """

    def __init__(self, scene: Scene, dt_s: float) -> None:
        self.scene = scene
        self._fingers: tuple[float, float] | None = None
        robot = scene.robot
        self.reflex = Reflex(scene.joint_state().arm_q, dt_s, robot.limits)
        self.gripper = robot.gripper
        self.finger_max_m = robot.gripper.finger_max_m
        self.finger_speed = robot.gripper.joint_speed()
        # The motor call's constant arguments, built once (it runs every control tick).
        self._forces = [float(v) for v in robot.effort_nm]
        self._position_gains = [POSITION_GAIN] * robot.dof
        self._velocity_gains = [VELOCITY_GAIN] * robot.dof

    def observe(self) -> Observation:
        js = self.scene.joint_state()
        return Observation(
            time_s=self.scene.sim_time_s,
            arm_q=js.arm_q,
            arm_dq=js.arm_dq,
            fingers_m=js.fingers_m,
            finger_contacts=self.scene.finger_contacts(),
            wrist_force_n=self.scene.wrist_force(),
            vacuum_kpa=0.0 if self.scene.cup is None else self.scene.cup.vacuum_kpa(),
        )

    def apply(self, cmd: Command) -> None:
        """Check the arm's command against the datasheet, then :meth:`send` it."""
        self.reflex.check(cmd.arm_q, self.scene.sim_time_s)
        self.send(cmd)

    def send(self, cmd: Command) -> None:
        """The motors' calls for ``cmd``, unchecked (``profile``'s physics replay sends what was checked)."""
        s = self.scene
        s.client.setJointMotorControlArray(
            s.bodies["robot"],
            s.arm_joints,
            p.POSITION_CONTROL,
            targetPositions=np.asarray(cmd.arm_q, dtype=float).tolist(),
            targetVelocities=np.asarray(cmd.arm_dq, dtype=float).tolist(),
            forces=self._forces,
            positionGains=self._position_gains,
            velocityGains=self._velocity_gains,
        )
        if s.cup is not None:
            s.cup.set(bool(cmd.vacuum))
        fingers = (min(max(float(cmd.finger_opening_m), 0.0), self.finger_max_m), float(cmd.finger_force_n))
        if fingers != self._fingers:  # motors keep their last command: send only changes
            force = self.gripper.joint_force(fingers[1])
            for j, q in zip(s.finger_joints, self.gripper.joint_targets(fingers[0]), strict=True):
                s.client.setJointMotorControl2(
                    s.bodies["robot"],
                    j,
                    p.POSITION_CONTROL,
                    targetPosition=q,
                    force=force,
                    maxVelocity=self.finger_speed,
                )
            self._fingers = fingers
