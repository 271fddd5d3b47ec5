"""The Unitree Z1's jaw (``files/z1.toml``, its URDF unmodified) in the simulator: it closes on a cube
where a grasp puts one and reads the cube's width.

Before, every pick missed with the jaw "stopped at 70.3 mm" (wide open): the simulator collided each
gripper link's mesh as its convex hull, and the fixed jaw's hull (its body and the jaw under it) filled
the space above the jaw's face, 12 mm into a cube beside it, the moving jaw's its notch; and the
table gave the gap at the pads, 70 mm at -0.8 rad, where a 5 cm cube's top edge already touches the
tilted jaw (it read 66.8 mm on the cube once the links collided as their decompositions).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pickdemo import load_scenario
from pickdemo.runtime.world import World

SCENARIO = Path(__file__).resolve().parent / "files" / "z1_pick_cube.toml"
WIDTH_M = 0.05


@pytest.mark.sim
def test_the_z1_jaw_clears_a_cube_beside_its_face_and_closes_on_it_to_its_width() -> None:
    with World(load_scenario(SCENARIO), 0).open() as world:
        scene, gripper = world.scene, world.robot.gripper
        c, robot = scene.client, scene.bodies["robot"]
        pos, quat = c.getLinkState(robot, scene.tcp_link, computeForwardKinematics=True)[4:6]
        rot = np.array(c.getMatrixFromQuaternion(quat)).reshape(3, 3)
        assert rot[2, 2] < -0.99  # (home: the hand pointing down, as it grasps)

        def cube_at(tcp_offset_m: float) -> int:
            """A fixed 5 cm cube with its middle at the TCP's height, the TCP ``tcp_offset_m`` from its centre."""
            shape = c.createCollisionShape(c.GEOM_BOX, halfExtents=[WIDTH_M / 2.0] * 3)
            centre = np.array(pos) - rot[:, 1] * tcp_offset_m
            return c.createMultiBody(0.0, shape, -1, centre.tolist(), quat)

        # Lowered beside it, open: neither jaw touches it (before: the fixed jaw's hull 12 mm deep in it).
        cube = cube_at(gripper.tcp_offset_m(WIDTH_M))
        for link in scene.finger_links:
            gaps = [pt[8] for pt in c.getClosestPoints(cube, robot, 0.05, linkIndexB=link)]
            assert gaps and min(gaps) > 0.0, (link, min(gaps))
        c.removeBody(cube)

        # Against the fixed jaw, closed on at the grip force: the jaw stops on it and reads its width.
        cube_at(gripper.held_offset_m(WIDTH_M))
        (jaw,) = scene.finger_joints
        c.setJointMotorControl2(
            robot, jaw, c.POSITION_CONTROL, targetPosition=gripper.joint_targets(0.0)[0],
            force=gripper.joint_force(gripper.grip_force_n), maxVelocity=gripper.joint_speed(),
        )  # fmt: skip
        scene.step(240)  # 1 s
        opening = 2.0 * float(scene.joint_state().fingers_m[0])
        assert opening == pytest.approx(WIDTH_M, abs=0.003), opening  # (before: 70.3 mm, then 66.8)
        assert min(scene.finger_contacts()) > 0
