"""The conveyor belt: a slab that slides along the belt's direction and carries what rests on it by
friction, as a real belt does.

The slab is the one link of a fixed-base multibody, on a prismatic joint along the belt's
direction, driven by a velocity motor (force high enough that nothing on it slows it down). A real
belt is endless; the slab is longer than the strip by :data:`REWIND_M` and slid back by that much
whenever it has travelled it (``resetJointState``: a surface of uniform colour looks the same before
and after). Measured: a rewind under a riding cube moves it 0.2 mm once and leaves its speed as it
was. The slab does not collide with the table it lies on.

The belt's clock starts with :meth:`Belt.start` (the robot's first control tick); at that moment
everything resting on it is given the belt's velocity, as if it had been riding for a while. Speed
changes ramp (:meth:`~pickdemo.scenario.load.ConveyorSpec.speed_at`). Stepped by the scene before each physics step; all
of it is a function of the simulated step count, so an episode is the same in any process.
"""

from __future__ import annotations

import numpy as np
import pybullet as p
from pybullet_utils.bullet_client import BulletClient

from pickdemo.scenario.load import BELT_REWIND_M, ConveyorSpec

#: How far the slab travels before it is slid back (m); the geometry is :meth:`ConveyorSpec.slab`'s.
REWIND_M = BELT_REWIND_M
#: The motor's force (N): far more than friction from anything the belt carries.
MOTOR_FORCE_N = 2000.0


class Belt:
    """The belt's body in one PyBullet world."""

    def __init__(self, client: BulletClient, spec: ConveyorSpec) -> None:
        self.client = client
        self._joint_state = client.getJointState  # bound once: read every physics step
        self.spec = spec
        self.slab = slab = spec.slab()  # the one description of its geometry (checks.py keeps off it)
        self.direction = np.array(slab.direction)
        half = list(slab.half_extents)
        col = client.createCollisionShape(p.GEOM_BOX, halfExtents=half)
        # Seen from above only its top: two triangles (a box's twelve cost TinyRenderer more per frame;
        # evidence: docs/decisions.md#speed).
        hx, hy, hz = half
        vis = client.createVisualShape(
            p.GEOM_MESH,
            vertices=[[-hx, -hy, hz], [hx, -hy, hz], [hx, hy, hz], [-hx, hy, hz]],
            normals=[[0.0, 0.0, 1.0]] * 4,
            indices=[0, 1, 2, 0, 2, 3],
            rgbaColor=[*spec.color, 1.0],
        )
        self.body = client.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=-1,
            basePosition=list(slab.centre),
            linkMasses=[5.0],
            linkCollisionShapeIndices=[col],
            linkVisualShapeIndices=[vis],
            linkPositions=[[0.0, 0.0, 0.0]],
            linkOrientations=[[0.0, 0.0, 0.0, 1.0]],
            linkInertialFramePositions=[[0.0, 0.0, 0.0]],
            linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]],
            linkParentIndices=[0],
            linkJointTypes=[p.JOINT_PRISMATIC],
            linkJointAxis=[[float(self.direction[0]), float(self.direction[1]), 0.0]],
        )
        client.changeDynamics(self.body, 0, lateralFriction=spec.friction, linearDamping=0.0, angularDamping=0.0)
        client.resetJointState(self.body, 0, slab.travel_m[0], 0.0)
        self._hold(0.0)
        self.start_s: float | None = None
        self.rewinds = 0

    def ignore(self, body: int) -> None:
        """No collisions with ``body`` (the table it lies on)."""
        self.client.setCollisionFilterPair(self.body, body, 0, -1, 0)

    def _hold(self, speed: float) -> None:
        self.client.setJointMotorControl2(self.body, 0, p.VELOCITY_CONTROL, targetVelocity=speed, force=MOTOR_FORCE_N)
        self._speed = speed

    def start(self, now_s: float, riders: list[int]) -> None:
        """Run from now; the bodies in ``riders`` (resting on it) move with it from the start."""
        self.start_s = now_s
        v = self.spec.speed * self.direction
        pos = self.client.getJointState(self.body, 0)[0]
        self.client.resetJointState(self.body, 0, pos, self.spec.speed)
        for body in riders:
            self.client.resetBaseVelocity(body, [float(v[0]), float(v[1]), 0.0], [0.0, 0.0, 0.0])
        self._hold(self.spec.speed)

    def before_step(self, now_s: float) -> None:
        """Drive the belt for the next physics step (and slide the slab back when it has run out)."""
        if self.start_s is None:
            return
        pos, vel = self._joint_state(self.body, 0)[:2]
        if pos > self.slab.travel_m[0] + self.slab.rewind_m:
            self.client.resetJointState(self.body, 0, pos - self.slab.rewind_m, vel)
            self.rewinds += 1
        speed = self.spec.speed_at(now_s - self.start_s)
        if speed != self._speed:
            self._hold(speed)
