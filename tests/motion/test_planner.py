"""The robot's collision model from its URDF and joint paths planned around boxes (issue 59): no
simulator, the shipped robots' own geometry."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.motion.planner import plan_joint_path
from pickdemo.robot import robot_named
from pickdemo.robot.collision import TABLE, CollisionScene, Obstacle, robot_geometry
from pickdemo.robot.kinematics import kinematics_of

DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def _box(centre: tuple[float, float, float], size: tuple[float, float, float]) -> OrientedBox:
    half = np.asarray(size) / 2.0
    return OrientedBox(Pose(np.asarray(centre, dtype=float), np.eye(3)), -half, half)


TABLE_BOX = Obstacle(TABLE, _box((0.5, 0.0, -0.011), (2.0, 2.0, 0.02)))


def _ends(name: str) -> tuple[object, np.ndarray, np.ndarray]:
    robot = robot_named(name)
    kin = kinematics_of(robot)
    rng = np.random.default_rng(0)
    qa = kin.solve(Pose(np.array([0.5, -0.2, 0.12]), DOWN), robot.home_q, rng).q
    qb = kin.solve(Pose(np.array([0.5, 0.25, 0.12]), DOWN), robot.home_q, rng).q
    return kin, qa, qb


def test_the_robots_own_geometry_meets_what_stands_where_its_links_are() -> None:
    robot = robot_named("panda")
    kin, qa, _ = _ends("panda")
    geometry = robot_geometry(robot)
    # at home on the table: free (the base stands on it: not checked against it)
    assert CollisionScene(geometry, [TABLE_BOX]).free(robot.home_q, robot.gripper.finger_max_m)
    # a box about the hand: the hand's or a finger's link meets it, by name
    tcp = kin.forward(qa).position
    scene = CollisionScene(geometry, [TABLE_BOX, Obstacle("carton", _box(tuple(tcp + [0.0, 0.0, 0.05]), (0.1,) * 3))])
    link, obstacle = scene.contact(qa, 0.04)
    assert obstacle == "carton" and ("hand" in link or "finger" in link), link
    # a held box under the hand reaches a block the empty hand clears
    block = Obstacle("block", _box((tcp[0], tcp[1], 0.03), (0.06, 0.06, 0.06)))
    assert CollisionScene(geometry, [TABLE_BOX, block]).free(qa, 0.02)
    held = _box((0.0, 0.0, 0.05), (0.04, 0.04, 0.06))  # (in the TCP's frame: z along the approach, down)
    assert CollisionScene(geometry, [TABLE_BOX, block], held).contact(qa, 0.02) == ("the held object", "block")
    # a held box carried against the robot's own base meets it (the links no joint moves)
    at_base = kin.forward(qa).inverse() @ Pose(np.array([0.0, 0.0, 0.08]), np.eye(3))
    by_base = OrientedBox(at_base, -np.full(3, 0.03), np.full(3, 0.03))
    link, what = CollisionScene(geometry, [TABLE_BOX], by_base).contact(qa, 0.02)
    assert what == "the held object" and link in {geometry.link_name(i) for i in geometry.fixed}, link


@pytest.mark.parametrize("name", ["panda", "ur5_franka_hand"])
def test_a_path_is_planned_over_a_wall_free_all_along_and_the_same_for_the_same_seed(name: str) -> None:
    kin, qa, qb = _ends(name)
    wall = Obstacle("wall", _box((0.5, 0.025, 0.12), (0.3, 0.02, 0.24)))
    scene = CollisionScene(robot_geometry(kin.robot), [TABLE_BOX, wall], _box((0.0, 0.0, 0.03), (0.04, 0.04, 0.04)))
    assert scene.free(qa, 0.02) and scene.free(qb, 0.02)
    assert not scene.segment_free(qa, qb, 0.02)  # (the straight joint path goes through the wall)
    path = plan_joint_path(qa, qb, kin.lower, kin.upper, lambda q: scene.free(q, 0.02), seed=3)
    assert path is not None
    assert np.allclose(path.waypoints[0], qa) and np.allclose(path.waypoints[-1], qb)
    assert all(
        scene.segment_free(a, b, 0.02, 0.01) for a, b in zip(path.waypoints[:-1], path.waypoints[1:], strict=True)
    )
    again = plan_joint_path(qa, qb, kin.lower, kin.upper, lambda q: scene.free(q, 0.02), seed=3)
    assert again is not None and np.array_equal(path.waypoints, again.waypoints)


def test_no_path_to_a_goal_the_hand_cannot_be_at() -> None:
    kin, qa, qb = _ends("panda")
    tcp = kin.forward(qb).position
    cage = Obstacle("cage", _box(tuple(tcp), (0.2, 0.2, 0.2)))
    scene = CollisionScene(robot_geometry(kin.robot), [TABLE_BOX, cage])
    assert plan_joint_path(qa, qb, kin.lower, kin.upper, lambda q: scene.free(q, 0.02), seed=0, max_checks=500) is None


@pytest.mark.parametrize("name", ["panda", "ur5_franka_hand", "so101"])
def test_each_links_mesh_is_its_convex_hull_which_holds_every_vertex_of_the_mesh(name: str) -> None:
    """As PyBullet takes a moving body's mesh (a hull built from the mesh's faces alone is not one:
    it missed a UR5's forearm 8 cm from a wall's top, measured)."""
    import coal
    import pinocchio as pin

    geometry = robot_geometry(robot_named(name))
    files = geometry.robot.files()
    from pickdemo.robot.urdf_files import model_urdf

    urdf, _ = model_urdf(files)
    dirs = [str(files.package_root), str(files.package_root.parent), str(files.urdf.parent)]
    meshes = pin.buildGeomFromUrdf(geometry.model, str(urdf), pin.COLLISION, package_dirs=dirs)
    dot = coal.Sphere(1e-4)
    for hull, mesh in zip(geometry.geometry.geometryObjects, meshes.geometryObjects, strict=True):
        if not isinstance(mesh.geometry, coal.BVHModelBase):
            continue
        assert isinstance(hull.geometry, coal.ConvexBase), hull.name
        with warnings.catch_warnings():  # (coal's vertices(i) is marked deprecated, and is what it has)
            warnings.simplefilter("ignore", DeprecationWarning)
            vertices = [mesh.geometry.vertices(i) for i in range(0, mesh.geometry.num_vertices, 7)]
        for v in vertices:
            result = coal.CollisionResult()
            at = coal.Transform3s(np.eye(3), np.asarray(v, dtype=float))
            assert coal.collide(hull.geometry, coal.Transform3s(), dot, at, coal.CollisionRequest(), result), hull.name
