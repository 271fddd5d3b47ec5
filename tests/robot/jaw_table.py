"""Measure a jaw gripper's opening at each angle, as a robot file's ``jaw_table`` has it.

A hinged jaw's face tilts as it opens, so what it stops on is the edge of the held object nearest its
hinge: the opening it reads depends on how far up between the jaws the object reaches. This measures
it the way a pick holds an object: the arm held at its home (the hand pointing down); a block of each
width fixed against the fixed jaw's face (the TCP's y from 0 to the width, centred on the TCP's x),
from ``--top`` above the TCP (towards the palm) to ``--bottom`` below it; the jaw closed on it at
``--torque``; the angle it stops at. The grasp of a box puts the TCP at its middle, or as deep as the
palm allows (``top_down.plan_pick``): a 5 cm cube reaches 25 mm above the TCP (the Z1's table).

Run: ``python tests/robot/jaw_table.py tests/robot/files/z1.toml --open -1.2 --closed 0.05``
(a few seconds; ``--open``: the angle the jaw starts from, ``--closed``: the one it is driven to);
it prints the rows. The SO-101's was measured its own way (``so101_jaw_table.py``).
"""

from __future__ import annotations

import argparse

import numpy as np
import pybullet as p

from pickdemo.robot.robot_file import load_robot_file

WIDTHS_M = tuple(np.round(np.arange(0.0, 0.0801, 0.005), 3))


def measure(
    path: str, open_rad: float, closed_rad: float, top_m: float, bottom_m: float, along_m: float, torque_nm: float
) -> list[tuple[float, float]]:
    robot = load_robot_file(path)
    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(robot.render_urdf()), useFixedBase=True, physicsClientId=client)
        info = [
            p.getJointInfo(body, j, physicsClientId=client) for j in range(p.getNumJoints(body, physicsClientId=client))
        ]
        joints = {i[1].decode(): i[0] for i in info}
        links = {i[12].decode(): i[0] for i in info}
        arm = [joints[n] for n in robot.arm_joints]
        jaw = joints[robot.gripper.finger_joints[0]]
        q = [float(v) for v in robot.home_q]
        for j, v in zip(arm, q, strict=True):
            p.resetJointState(body, j, v, physicsClientId=client)
        p.setJointMotorControlArray(
            body, arm, p.POSITION_CONTROL, targetPositions=q, forces=[500.0] * len(arm), physicsClientId=client
        )
        state = p.getLinkState(body, links[robot.tcp_frame], computeForwardKinematics=True, physicsClientId=client)
        origin, quat = np.array(state[4]), state[5]
        rot = np.array(p.getMatrixFromQuaternion(quat)).reshape(3, 3)
        rows = []
        for width in WIDTHS_M:
            p.resetJointState(body, jaw, open_rad, physicsClientId=client)
            block = None
            if width > 0.0:
                centre = origin + rot @ np.array([0.0, width / 2.0, (bottom_m - top_m) / 2.0])
                half = [along_m / 2.0, width / 2.0, (top_m + bottom_m) / 2.0]
                shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client)
                block = p.createMultiBody(0.0, shape, -1, list(centre), quat, physicsClientId=client)
            p.setJointMotorControl2(
                body, jaw, p.POSITION_CONTROL, targetPosition=closed_rad, force=torque_nm, maxVelocity=2.0,
                physicsClientId=client,
            )  # fmt: skip
            for _ in range(720):
                p.stepSimulation(physicsClientId=client)
            rows.append((p.getJointState(body, jaw, physicsClientId=client)[0], float(width)))
            if block is not None:
                p.removeBody(block, physicsClientId=client)
        return rows
    finally:
        p.disconnect(client)


if __name__ == "__main__":
    a = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    a.add_argument("robot_file")
    a.add_argument("--open", type=float, required=True, help="the angle the jaw starts from (rad)")
    a.add_argument("--closed", type=float, required=True, help="the angle it is driven to (rad)")
    a.add_argument("--top", type=float, default=0.025, help="the block's top above the TCP (m)")
    a.add_argument("--bottom", type=float, default=0.025, help="its bottom below the TCP (m)")
    a.add_argument("--along", type=float, default=0.05, help="its length along the TCP's x (m)")
    a.add_argument("--torque", type=float, default=1.0, help="the jaw's torque (N m)")
    o = a.parse_args()
    for angle, width in measure(o.robot_file, o.open, o.closed, o.top, o.bottom, o.along, o.torque):
        print(f"[{angle:.4f}, {width:.3f}],")
