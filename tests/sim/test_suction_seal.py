"""The simulated vacuum cup against its own physics: a cup on a flat face holds what the vacuum's
force holds and drops what is heavier; a cup across an edge, or on a porous face, leaks."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest
from pybullet_utils.bullet_client import BulletClient

from pickdemo.robot import robot_named
from pickdemo.robot.suction import GRAVITY_M_S2, Seal
from pickdemo.sim.suction import VacuumCup

TOOL = "pickdemo/robot/robots/ur5_suction/suction_tool.urdf"
CUP = robot_named("ur5_suction").gripper.cup


def _world(box_half: float, mass_kg: float, cup_xy: tuple[float, float], porous: bool = False):
    """A box on the ground and the suction tool pointing down with its lip a millimetre over the box's top,
    moved as a hand moves it: by a stiff constraint to a point (on its base's centre of mass, 1 cm into
    the plate and 35 cm from the lip; PyBullet loads a URDF by its link's frame, and a constraint takes
    the centre of mass)."""
    c = BulletClient(connection_mode=p.DIRECT)
    c.setGravity(0, 0, -GRAVITY_M_S2)
    c.setTimeStep(1 / 240)
    c.createMultiBody(0, c.createCollisionShape(p.GEOM_PLANE))
    box = c.createMultiBody(mass_kg, c.createCollisionShape(p.GEOM_BOX, halfExtents=[box_half] * 3),
                            basePosition=[0, 0, box_half])  # fmt: skip
    down = p.getQuaternionFromEuler([np.pi, 0, 0])
    z0 = 2 * box_half + 0.35 + 0.001
    tool = c.loadURDF(TOOL, basePosition=[cup_xy[0], cup_xy[1], z0 + 0.01], baseOrientation=down)
    hand = c.createConstraint(tool, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [cup_xy[0], cup_xy[1], z0],
                              childFrameOrientation=down)  # fmt: skip
    c.changeConstraint(hand, maxForce=5000)
    joints = [c.getJointInfo(tool, j) for j in range(c.getNumJoints(tool))]
    links = {info[12].decode(): info[0] for info in joints}
    bellows = next(info[0] for info in joints if info[2] == p.JOINT_PRISMATIC)
    c.setJointMotorControl2(tool, bellows, p.POSITION_CONTROL, targetPosition=0.0, force=CUP.bellows_force_n)
    cup = VacuumCup(c, tool, links["suction_tcp"], links["suction_cup"], CUP)
    if porous:
        cup.porous.add(box)
    return c, (hand, cup_xy), box, cup, z0


def _lift(c: BulletClient, tool: tuple, cup: VacuumCup, z0: float, box: int, close: bool = True) -> tuple[float, Seal]:
    """Vacuum on, the cup pressed 3 mm onto the face, then the tool raised 10 cm over a second
    (smoothly: its acceleration at most 0.9 m/s^2): the box's height at the end, and the seal before
    the lift."""
    cup.set(True)
    hand, xy = tool
    z0 -= 0.004
    for _ in range(60):
        c.changeConstraint(hand, [xy[0], xy[1], z0], maxForce=5000)
        c.stepSimulation()
        cup.after_step(0.0)
    before = cup.state
    for i in range(300):
        rise = 0.05 * (1.0 - np.cos(np.pi * min(1.0, i / 240)))
        c.changeConstraint(hand, [xy[0], xy[1], z0 + rise], maxForce=5000)
        c.stepSimulation()
        cup.after_step(i / 240)
    z = c.getBasePositionAndOrientation(box)[0][2]
    if close:
        c.disconnect()
    return z, before


@pytest.mark.parametrize("share, held", [(0.8, True), (1.25, False)])
def test_a_cup_on_a_flat_face_holds_up_to_its_force_and_drops_above_it(share: float, held: bool) -> None:
    mass = share * CUP.holding_force_n / GRAVITY_M_S2
    c, tool, box, cup, z0 = _world(0.04, mass, (0.0, 0.0))
    z, before = _lift(c, tool, cup, z0, box)
    assert before is Seal.SEALED
    assert (z > 0.04 + 0.07) is held
    assert (cup.state is Seal.SEALED) is held


def test_a_cup_across_an_edge_leaks() -> None:
    c, tool, box, cup, z0 = _world(0.04, 1.0, (0.04, 0.0))  # its centre over the box's edge (1 kg: it does not tip)
    z, before = _lift(c, tool, cup, z0, box)
    assert before is Seal.LEAK and z < 0.05


def test_a_porous_face_leaks() -> None:
    c, tool, box, cup, z0 = _world(0.04, 0.2, (0.0, 0.0), porous=True)
    z, before = _lift(c, tool, cup, z0, box)
    assert before is Seal.LEAK and z < 0.05


def test_a_broken_seal_stays_broken_until_the_valve_is_shut() -> None:
    """A part made heavier than the hold while it hangs still: it drops, and the cup does not take it
    again on the next step (it is still within a touch of the lip then); shut and opened, it may."""
    c, (hand, xy), box, cup, z0 = _world(0.04, 0.3, (0.0, 0.0))
    _, before = _lift(c, (hand, xy), cup, z0, box, close=False)
    assert before is Seal.SEALED and cup.held == box
    c.changeDynamics(box, -1, mass=1.5 * CUP.holding_force_n / GRAVITY_M_S2)
    for _ in range(30):
        c.stepSimulation()
        cup.after_step(1.0)
    assert cup.held is None and cup.state is Seal.LEAK and cup.vacuum_kpa() < CUP.switch_kpa
    c.disconnect()


def test_a_tilted_cup_seals_at_any_turn_about_the_vertical() -> None:
    """The tool tilted 10 deg about its hand over a light box, pressed onto it and turned in 10 deg steps:
    it seals at each turn. A rim ray starts inside the cup's own shape, and Bullet's ray at times met that
    shape at once: 10 of the 36 turns leaked so before the rays passed over the robot."""
    leaked = []
    for yaw in range(0, 360, 10):
        c, (hand, _), _, cup, z0 = _world(0.04, 0.1, (0.0, 0.0))
        tilted = p.getQuaternionFromEuler([np.pi + np.radians(10), 0, np.radians(yaw)])
        c.changeConstraint(hand, [0.0, 0.0, z0 - 0.004], tilted, maxForce=5000)
        cup.set(True)
        for _ in range(120):
            c.stepSimulation()
            cup.after_step(0.0)
        if cup.state is not Seal.SEALED:
            leaked.append(yaw)
        c.disconnect()
    assert not leaked


def test_a_bump_inside_the_rim_does_not_hold_the_lip_off_the_face() -> None:
    """A bellows cup is hollow: a bump on the face narrower than the lip goes into it, and the lip meets
    the face all round it (the cup's collision shape was a solid cylinder, and a bump 3 mm high held the
    rim 3 mm off a flat face: no seal, as on the dome of a convex part)."""
    c = BulletClient(connection_mode=p.DIRECT)
    c.setGravity(0, 0, -GRAVITY_M_S2)
    c.setTimeStep(1 / 240)
    c.createMultiBody(0, c.createCollisionShape(p.GEOM_PLANE))
    half, bump = 0.02, 0.003
    shape = c.createCollisionShapeArray(
        [p.GEOM_BOX, p.GEOM_BOX], halfExtents=[[half] * 3, [0.002, 0.002, bump / 2]],
        collisionFramePositions=[[0, 0, 0], [0, 0, half + bump / 2]],
    )  # fmt: skip
    c.createMultiBody(0.05, shape, basePosition=[0, 0, half])
    down = p.getQuaternionFromEuler([np.pi, 0, 0])
    z0 = 2 * half + 0.35 + bump + 0.002  # (the lip 2 mm over the bump)
    tool = c.loadURDF(TOOL, basePosition=[0, 0, z0 + 0.01], baseOrientation=down)
    hand = c.createConstraint(
        tool, -1, -1, -1, p.JOINT_FIXED, [0, 0, 0], [0, 0, 0], [0, 0, z0], childFrameOrientation=down
    )
    joints = [c.getJointInfo(tool, j) for j in range(c.getNumJoints(tool))]
    links = {info[12].decode(): info[0] for info in joints}
    bellows = next(info[0] for info in joints if info[2] == p.JOINT_PRISMATIC)
    c.setJointMotorControl2(tool, bellows, p.POSITION_CONTROL, targetPosition=0.0, force=CUP.bellows_force_n)
    cup = VacuumCup(c, tool, links["suction_tcp"], links["suction_cup"], CUP)
    cup.set(True)
    for i in range(120):  # down 7 mm over half a second: the lip 2 mm past the face
        c.changeConstraint(hand, [0, 0, z0 - 0.007 * min(1.0, i / 100)], maxForce=5000)
        c.stepSimulation()
        cup.after_step(i / 240)
    assert cup.state is Seal.SEALED, cup.state
    c.disconnect()
