"""The robot's collision model from its robot file, and the boxes it must keep out of (issue 59).

Pure: Pinocchio's geometry model and coal (no simulator). The links' collision geometry is the
URDF's own (``pin.buildGeomFromUrdf``: boxes and cylinders as themselves, a mesh as its convex hull,
as PyBullet takes a moving body's mesh, so that the model and the simulator meet things alike), posed
by the arm's joint angles and the fingers' openings, which the robot measures.
What it must keep out of is a set of boxes fixed in the world (the table, the fixtures' known
geometry, the world model's objects grown by their uncertainty, :class:`Obstacle`); a held object
goes with the hand (a box in the TCP's frame). MoveIt's planning scene is the same design.

Which contacts are allowed is written here once: the links that no joint moves (the base) stand on
the table, so they are not checked against it; a held object touches the hand, so it is checked
against the obstacles, the robot's base (it is carried past it) and the arm's links but the hand's
and those it touched where it was taken (MoveIt's touch links), and not against the table: it is
lifted straight off it and lowered straight onto it at its place (its box, grown by a margin, would
meet the table at both), and carried above it. Everything else the caller decides by what it passes
as obstacles (the target is none while the hand goes to it; the place's surface is none at the release).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import coal
import numpy as np
import pinocchio as pin

from pickdemo.core.geometry import OrientedBox
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.kinematics import link_frame_id
from pickdemo.robot.urdf_files import model_urdf

#: The obstacle the base stands on (its links are not checked against it).
TABLE = "table"


@dataclass(frozen=True)
class Obstacle:
    """A box the robot must keep out of, by name (what a failure to plan names)."""

    name: str
    box: OrientedBox


class RobotGeometry:
    """A robot's full model (fingers included) and its links' collision geometry, read once."""

    def __init__(self, robot: RobotDescription) -> None:
        files = robot.files()
        urdf, renamed = model_urdf(files)
        self.model = pin.buildModelFromUrdf(str(urdf))
        dirs = [str(files.package_root), str(files.package_root.parent), str(files.urdf.parent)]
        self.geometry = pin.buildGeomFromUrdf(self.model, str(urdf), pin.COLLISION, package_dirs=dirs)
        for obj in self.geometry.geometryObjects:  # a mesh as its convex hull, as the simulator takes it
            if isinstance(obj.geometry, coal.BVHModelBase):
                obj.geometry.buildConvexHull(
                    True, "Qt"
                )  # (buildConvexRepresentation keeps the mesh's faces: not a hull)
                obj.geometry = obj.geometry.convex
        self.robot = robot

        def q_index(joint: str) -> int:
            return self.model.joints[self.model.getJointId(renamed.get(joint, joint))].idx_q

        self._arm = [q_index(n) for n in robot.arm_joints]
        self._fingers = [q_index(n) for n in robot.gripper.finger_joints]
        self.tcp_frame = link_frame_id(self.model, robot.tcp_frame)
        #: the links no joint moves (the base): they stand on the table
        self.fixed = {i for i, g in enumerate(self.geometry.geometryObjects) if g.parentJoint == 0}
        #: the hand's links: those the TCP's joint or a joint after it moves (they touch what it holds)
        tcp_joint = self.model.frames[self.tcp_frame].parentJoint

        def after_tcp(j: int) -> bool:
            while j > tcp_joint:
                j = self.model.parents[j]
            return j == tcp_joint

        self.hand = {i for i, g in enumerate(self.geometry.geometryObjects) if after_tcp(g.parentJoint)}

    def q(self, arm_q: np.ndarray, fingers_m: np.ndarray | float) -> np.ndarray:
        """The full model's configuration at these joint states."""
        q = pin.neutral(self.model)
        q[self._arm] = np.asarray(arm_q, dtype=float)
        opening = np.broadcast_to(np.asarray(fingers_m, dtype=float), (2,))
        q[self._fingers] = self.robot.gripper.joint_positions(opening)
        return q

    def link_name(self, index: int) -> str:
        return self.model.frames[self.geometry.geometryObjects[index].parentFrame].name


def _arm_links_against(
    gm: pin.GeometryModel, geometry: RobotGeometry, held_id: int, links: list[int], at: tuple[np.ndarray, float]
) -> None:
    """Pairs of the held object and each of the arm's ``links`` but those it meets at ``at`` (the arm's
    joints and the fingers' opening where it was taken: a contact it was taken with is no collision). A
    part hanging from a tilted cup, swung about in joint space, met the forearm and held the wrist back
    17 cm short of the place (`suction_clear_bin` seed 80)."""
    pairs = [pin.CollisionPair(i, held_id) for i in links]
    for pair in pairs:
        gm.addCollisionPair(pair)
    data = pin.GeometryData(gm)
    pin.computeCollisions(geometry.model, geometry.model.createData(), gm, data, geometry.q(*at), False)
    met = {(p.first, p.second) for k, p in enumerate(gm.collisionPairs) if data.collisionResults[k].isCollision()}
    for pair in pairs:
        if (pair.first, pair.second) in met:
            gm.removeCollisionPair(pair)


@functools.cache
def robot_geometry(robot: RobotDescription) -> RobotGeometry:
    """One geometry per robot and process."""
    return RobotGeometry(robot)


def _placement(box: OrientedBox) -> tuple[pin.SE3, coal.Box]:
    """A box's pose (its middle) and its coal shape."""
    lo, hi = np.asarray(box.lo, dtype=float), np.asarray(box.hi, dtype=float)
    centre = box.pose.rotation @ (0.5 * (lo + hi)) + box.pose.position
    return pin.SE3(box.pose.rotation.copy(), centre), coal.Box(*(hi - lo))


class CollisionScene:
    """The robot among fixed boxes, and a held object's box in the hand (see the module docstring)."""

    def __init__(
        self,
        geometry: RobotGeometry,
        obstacles: Sequence[Obstacle],
        held: OrientedBox | None = None,
        held_at: tuple[np.ndarray, float] | None = None,
    ) -> None:
        """``held``: the held object's box in the TCP's frame (None: nothing held); ``held_at``: the arm's
        joints and the fingers' opening where it was taken (then it is checked against the arm's links
        too, but those it meets there)."""
        self.g = geometry
        gm = pin.GeometryModel()
        for obj in geometry.geometry.geometryObjects:
            gm.addGeometryObject(obj)
        n_robot = len(geometry.geometry.geometryObjects)
        self.names: list[str] = [geometry.link_name(i) for i in range(n_robot)]
        moving = [i for i in range(n_robot) if i not in geometry.fixed]
        held_id = None
        if held is not None:
            frame = geometry.model.frames[geometry.tcp_frame]
            M, shape = _placement(held)
            held_id = gm.addGeometryObject(
                pin.GeometryObject("held", frame.parentJoint, geometry.tcp_frame, frame.placement * M, shape)
            )
            self.names.append("the held object")
            for i in geometry.fixed:  # (carried past the base)
                gm.addCollisionPair(pin.CollisionPair(i, held_id))
            if held_at is not None:
                _arm_links_against(gm, geometry, held_id, [i for i in moving if i not in geometry.hand], held_at)
        for ob in obstacles:
            M, shape = _placement(ob.box)
            j = gm.addGeometryObject(pin.GeometryObject(ob.name, 0, 0, M, shape))
            self.names.append(ob.name)
            links = moving if ob.name == TABLE else range(n_robot)
            for i in links:
                gm.addCollisionPair(pin.CollisionPair(i, j))
            if held_id is not None and ob.name != TABLE:
                gm.addCollisionPair(pin.CollisionPair(held_id, j))
        self.model = gm
        self.data = pin.GeometryData(gm)
        self._pin = geometry.model.createData()
        self.checks = 0  # configurations checked (a planner's effort)
        #: the same scene with tighter margins, where its maker has one (a planner whose ends are within these)
        self.tighter: Callable[[], CollisionScene] | None = None

    def free(self, arm_q: np.ndarray, fingers_m: np.ndarray | float) -> bool:
        """Whether nothing of the robot (and what it holds) meets an obstacle at these joint states."""
        self.checks += 1
        if not self.model.collisionPairs:
            return True
        q = self.g.q(arm_q, fingers_m)
        return not pin.computeCollisions(self.g.model, self._pin, self.model, self.data, q, True)

    def contact(self, arm_q: np.ndarray, fingers_m: np.ndarray | float) -> tuple[str, str] | None:
        """The first link (or the held object) found meeting an obstacle, and the obstacle's name."""
        if self.free(arm_q, fingers_m):
            return None
        for k, pair in enumerate(self.model.collisionPairs):
            if self.data.collisionResults[k].isCollision():
                return self.names[pair.first], self.names[pair.second]
        return None

    def segment_contact(
        self, qa: np.ndarray, qb: np.ndarray, fingers_m: np.ndarray | float, step_rad: float = 0.02
    ) -> tuple[str, str] | None:
        """The first contact (as :meth:`contact`) on the straight joint path from ``qa`` to ``qb``,
        checked every ``step_rad`` of its largest joint's travel (ends included), or None."""
        n = max(1, int(np.ceil(float(np.max(np.abs(qb - qa))) / step_rad)))
        for t in np.linspace(0.0, 1.0, n + 1):
            hit = self.contact(qa + (qb - qa) * t, fingers_m)
            if hit is not None:
                return hit
        return None

    def segment_free(
        self, qa: np.ndarray, qb: np.ndarray, fingers_m: np.ndarray | float, step_rad: float = 0.02
    ) -> bool:
        """Whether the straight joint path from ``qa`` to ``qb`` is free (:meth:`segment_contact`)."""
        return self.segment_contact(qa, qb, fingers_m, step_rad) is None
