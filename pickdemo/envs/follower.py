"""A LeRobot follower's channels (``<motor>.pos``, as a robot file's ``[lerobot]`` names them) from what
the environment records: the state's measured joints and jaw opening, the action's joint goals and jaw
opening. What a dataset of such an arm holds as ``observation.state`` and ``action``, so that it sits
beside a real follower's recording (:mod:`pickdemo.apps.lerobot_dataset`); the environment's own state
and actions are kept beside them, for replay.

The units are LeRobot's ``MotorNormMode``: "degrees" from the joint's zero (a URDF whose zero is the
calibrated range's middle, as LeRobot's own kinematics take it), "range_0_100" over the joint's range,
bounded to it as LeRobot's motor bus bounds a reading.
"""

from __future__ import annotations

import numpy as np

from pickdemo.envs.control import gripper_command
from pickdemo.robot.description import LeRobotProfile, RobotDescription


class FollowerChannels:
    """The follower's state and action for a robot's rows, its environment's state laid out by ``state_names``."""

    def __init__(self, profile: LeRobotProfile, robot: RobotDescription, state_names: list[str]) -> None:
        self.profile, self.robot = profile, robot
        self.names = [c.name for c in profile.channels]
        self._q = [state_names.index(f"joint_pos.{i}") for i in range(robot.dof)]
        self._fingers = [state_names.index("finger.0"), state_names.index("finger.1")]

    def _values(self, q_arm: np.ndarray, jaw_rad: float) -> np.ndarray:
        arm = dict(zip(self.robot.arm_joints, np.asarray(q_arm, dtype=float), strict=True))
        out = []
        for c in self.profile.channels:
            if c.unit == "degrees":
                out.append(float(np.degrees(arm[c.joint])))
            else:  # the jaw, over its range
                out.append(float(np.clip(100.0 * (jaw_rad - c.low) / (c.high - c.low), 0.0, 100.0)))
        return np.array(out, dtype=np.float64)

    def state(self, state: np.ndarray) -> np.ndarray:
        """The measured positions: the arm's joints, and the jaw's angle at its measured opening."""
        s = np.asarray(state, dtype=float)
        jaw = self.robot.gripper.joint_positions(s[self._fingers])[0]
        return self._values(s[self._q], float(jaw))

    def action(self, action: np.ndarray) -> np.ndarray:
        """The goals sent: the arm's joint goals, and the jaw's angle at the commanded opening."""
        a = np.asarray(action, dtype=float)
        n = self.robot.dof
        jaw = self.robot.gripper.joint_targets(gripper_command(float(a[n]), self.robot))[0] if len(a) > n else 0.0
        return self._values(a[:n], float(jaw))
