"""Measure the SO-101 jaw's opening at each angle, as ``robots/so101.toml``'s ``jaw_table`` has it.

The arm held still with its hand pointing down; a block of each width (28 mm tall, 30 mm deep) fixed
against the fixed jaw's face, 3 mm up from its tip; the jaw closed on it at 0.3 N m; the angle it
stops at. Run: ``python tests/robot/so101_jaw_table.py`` (a few seconds); it prints the rows.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from pickdemo.robot import robot_named

WIDTHS_M = (0.0, 0.005, 0.01, 0.015, 0.02, 0.025, 0.03, 0.035, 0.04, 0.045, 0.05, 0.055)


def measure() -> list[tuple[float, float]]:
    robot = robot_named("so101")
    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(robot.render_urdf()), useFixedBase=True, physicsClientId=client)
        joints = {
            p.getJointInfo(body, j, physicsClientId=client)[1].decode(): j
            for j in range(p.getNumJoints(body, physicsClientId=client))
        }
        links = {
            p.getJointInfo(body, j, physicsClientId=client)[12].decode(): j
            for j in range(p.getNumJoints(body, physicsClientId=client))
        }
        arm = [joints[n] for n in robot.arm_joints]
        jaw = joints[robot.gripper.finger_joints[0]]
        q = [0.0, -0.45, 0.8, 1.22, -2.3]
        for j, v in zip(arm, q, strict=True):
            p.resetJointState(body, j, v, physicsClientId=client)
        p.setJointMotorControlArray(
            body, arm, p.POSITION_CONTROL, targetPositions=q, forces=[100.0] * 5, physicsClientId=client
        )
        state = p.getLinkState(body, links["gripper_frame_link"], physicsClientId=client)
        origin, quat = np.array(state[4]), state[5]
        rot = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        rows = []
        for width in WIDTHS_M:
            p.resetJointState(body, jaw, 1.2, physicsClientId=client)
            block = None
            if width > 0.0:
                centre = origin + rot @ np.array([-width / 2.0, 0.0, -0.012])  # against the face, 3 mm up from the tip
                shape = p.createCollisionShape(
                    p.GEOM_BOX, halfExtents=[width / 2.0, 0.015, 0.013], physicsClientId=client
                )
                block = p.createMultiBody(0.0, shape, -1, list(centre), quat, physicsClientId=client)
            p.setJointMotorControl2(
                body, jaw, p.POSITION_CONTROL, targetPosition=-0.17, force=0.3, maxVelocity=2.0, physicsClientId=client
            )
            for _ in range(480):
                p.stepSimulation(physicsClientId=client)
            rows.append((p.getJointState(body, jaw, physicsClientId=client)[0], width))
            if block is not None:
                p.removeBody(block, physicsClientId=client)
        return rows
    finally:
        p.disconnect(client)


if __name__ == "__main__":
    for angle, width in measure():
        print(f"[{angle:.4f}, {width:.3f}],")
