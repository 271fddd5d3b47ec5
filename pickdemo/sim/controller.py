"""The robot's joint-level interface in simulation: reads its sensors, applies a command.

Non-blocking: :meth:`RobotInterface.observe` and :meth:`RobotInterface.apply` each do one thing for
one tick and return; the episode's control loop is the only place that advances simulated time.
The arm is position-controlled with velocity feed-forward; both finger joints are driven (PyBullet
ignores ``<mimic>``; the scene couples them with a gear constraint).
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from pickdemo.core.interfaces import Command, Observation
from pickdemo.robot import panda as rm
from pickdemo.robot.rate_limit import Reflex
from pickdemo.sim.scene import Scene

ARM_EFFORT_NM = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])
FINGER_SPEED_M_S = 0.1
POSITION_GAIN = 0.3
VELOCITY_GAIN = 1.0
# The motor call's constant arguments, built once (it runs every control tick).
_ARM_FORCES = [float(v) for v in ARM_EFFORT_NM]
_POSITION_GAINS = [POSITION_GAIN] * 7
_VELOCITY_GAINS = [VELOCITY_GAIN] * 7


class RobotInterface:
    """The Panda's encoders, finger contacts, wrist force and motors inside a :class:`Scene`.

    Like the Franka's controller, it checks each arm command against the datasheet before it sends
    it (:class:`~pickdemo.robot.rate_limit.Reflex`, one check per control tick of ``dt_s``): a command beyond
    raises :class:`~pickdemo.robot.rate_limit.ReflexError` and is not sent.
    """

    def __init__(self, scene: Scene, dt_s: float) -> None:
        self.scene = scene
        self._fingers: tuple[float, float] | None = None
        self.reflex = Reflex(scene.joint_state().arm_q, dt_s)

    def observe(self) -> Observation:
        js = self.scene.joint_state()
        return Observation(
            time_s=self.scene.sim_time_s,
            arm_q=js.arm_q,
            arm_dq=js.arm_dq,
            fingers_m=js.fingers_m,
            finger_contacts=self.scene.finger_contacts(),
            wrist_force_n=self.scene.wrist_force(),
        )

    def apply(self, cmd: Command) -> None:
        s = self.scene
        self.reflex.check(cmd.arm_q, s.sim_time_s)
        s.client.setJointMotorControlArray(
            s.bodies["robot"],
            s.arm_joints,
            p.POSITION_CONTROL,
            targetPositions=np.asarray(cmd.arm_q, dtype=float).tolist(),
            targetVelocities=np.asarray(cmd.arm_dq, dtype=float).tolist(),
            forces=_ARM_FORCES,
            positionGains=_POSITION_GAINS,
            velocityGains=_VELOCITY_GAINS,
        )
        fingers = (min(max(float(cmd.finger_opening_m), 0.0), rm.FINGER_MAX_M), float(cmd.finger_force_n))
        if fingers != self._fingers:  # motors keep their last command: send only changes
            for j in s.finger_joints:
                s.client.setJointMotorControl2(
                    s.bodies["robot"],
                    j,
                    p.POSITION_CONTROL,
                    targetPosition=fingers[0],
                    force=fingers[1],
                    maxVelocity=FINGER_SPEED_M_S,
                )
            self._fingers = fingers
