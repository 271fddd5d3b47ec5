"""6-DoF antipodal grasps on a cloud (no simulator): from above where that holds, tilted where the
object leans, never into a wall beside it, none where nothing fits; the same draw gives the same grasps;
a tilted place puts the tracked centre over the place."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Unknown
from pickdemo.grasping.antipodal import DOWN, AnySideGrasps, sample_antipodal
from pickdemo.grasping.selection import GraspRequest
from pickdemo.perception import ObjectCloud, TargetModel
from pickdemo.robot import robot_named

GRIPPER = robot_named().gripper


def box_cloud(size: tuple[float, float, float], roll_deg: float = 0.0, yaw_deg: float = 0.0) -> np.ndarray:
    """Points 2 mm apart on a box's faces, turned by ``roll_deg`` about x and ``yaw_deg`` about z, resting
    on the table (z = 0) at (0.5, 0); the bottom's points (hidden by the table) left out."""
    faces = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        gu, gv = np.meshgrid(*(np.arange(-size[a] / 2.0, size[a] / 2.0 + 1e-9, 0.002) for a in (u, v)))
        for side in (-size[axis] / 2.0, size[axis] / 2.0):
            face = np.zeros((gu.size, 3))
            face[:, u], face[:, v], face[:, axis] = gu.ravel(), gv.ravel(), side
            faces.append(face)
    pose = Pose.from_xyz_rpy(np.array([0.5, 0.0, 0.0]), roll=np.radians(roll_deg), yaw=np.radians(yaw_deg))
    pts = pose.transform_points(np.vstack(faces))
    pts[:, 2] -= pts[:, 2].min()
    return pts[pts[:, 2] > 0.001]


def test_an_upright_box_is_grasped_from_above_across_its_narrower_side() -> None:
    grasps = sample_antipodal(box_cloud((0.04, 0.03, 0.06), yaw_deg=20.0), 0.0, GRIPPER, np.random.default_rng(0))
    best = grasps[0]
    assert np.degrees(best.tilt_rad) < 5.0
    assert abs(best.width_m - 0.03) < 0.005
    assert np.allclose(best.position[:2], [0.5, 0.0], atol=0.01)
    # the hand frame: y the closing axis, z the approach, right-handed
    R = best.rotation
    assert np.allclose(R.T @ R, np.eye(3), atol=1e-9) and np.isclose(np.linalg.det(R), 1.0)


def test_a_leaning_plate_is_grasped_tilted_across_its_thickness() -> None:
    """A 9 x 9 cm plate 1.5 cm thick leaning 50 deg: too wide for the hand from above; across its
    thickness, the approach tilts 40 deg (square to the closing axis, as low as it allows)."""
    grasps = sample_antipodal(box_cloud((0.09, 0.09, 0.015), roll_deg=50.0), 0.0, GRIPPER, np.random.default_rng(0))
    best = grasps[0]
    assert abs(np.degrees(best.tilt_rad) - 40.0) < 8.0
    assert abs(best.width_m - 0.015) < 0.004


def test_no_grasp_fits_a_flat_plate_wider_than_the_hand() -> None:
    """Lying flat, a 9 cm plate's only narrow span is vertical: the fingers cannot close across it on a table."""
    assert sample_antipodal(box_cloud((0.09, 0.09, 0.015)), 0.0, GRIPPER, np.random.default_rng(0)) == []


def test_no_finger_goes_into_a_wall_beside_the_object() -> None:
    """A 3 cm cube 4 mm from a wall (a plane of points at x = 0.519): the fingers may not close across
    the wall's side; the grasps left close along the wall, or lean away from it."""
    cube = box_cloud((0.03, 0.03, 0.03))
    gu, gv = np.meshgrid(np.arange(-0.1, 0.1, 0.003), np.arange(0.0, 0.1, 0.003))
    wall = np.column_stack([np.full(gu.size, 0.519), gu.ravel(), gv.ravel()])
    grasps = sample_antipodal(cube, 0.0, GRIPPER, np.random.default_rng(0), obstacles=wall)
    assert grasps
    for g in grasps:
        # the open fingers' outer faces stay on the cube's side of the wall
        for sy in (-1.0, 1.0):
            finger = g.position + g.rotation[:, 1] * sy * (GRIPPER.finger_max_m + GRIPPER.finger_thickness_m)
            assert finger[0] < 0.519 or g.rotation[:, 2] @ DOWN < 0.9
    best = grasps[0]
    assert abs(best.rotation[:, 1][0]) < 0.3  # closing along the wall (y), not into it (x)


def test_the_same_draw_gives_the_same_grasps() -> None:
    cloud = box_cloud((0.05, 0.03, 0.04), roll_deg=30.0)
    a = sample_antipodal(cloud, 0.0, GRIPPER, np.random.default_rng(3))
    b = sample_antipodal(cloud, 0.0, GRIPPER, np.random.default_rng(3))
    assert len(a) == len(b) and all(
        np.array_equal(x.position, y.position) and np.array_equal(x.rotation, y.rotation)
        for x, y in zip(a, b, strict=True)
    )


def test_a_tilted_place_puts_the_tracked_centre_over_the_place() -> None:
    """The place's TCP is offset from the place by where the hand holds the object from its tracked
    centre (the middle of its footprint, which the camera checks at the place), not from the mean of
    the points seen, which crowd on the faces the camera sees."""
    cloud = box_cloud((0.09, 0.09, 0.015), roll_deg=50.0)
    seen = cloud[cloud[:, 1] < 0.02]  # one side seen more: the points' mean is off the middle
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    pose = Pose(np.array([(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0, hi[2] / 2.0]), np.eye(3))
    request = GraspRequest(
        pose, TargetModel(Unknown(), (0.5, 0.5, 0.5)), (0.4, 0.3),
        cloud=ObjectCloud(seen, np.zeros((0, 3)), 0.0), gripper=GRIPPER,
    )  # fmt: skip
    plans = list(AnySideGrasps(np.random.default_rng(0)).candidates(request))
    assert plans
    for plan in plans:
        offset = plan.grasp.position[:2] - pose.position[:2]
        assert np.allclose(plan.place_offset_xy, offset, atol=1e-9)
        assert np.allclose(plan.place.position[:2] - offset, (0.4, 0.3), atol=1e-9)
    assert np.linalg.norm(seen.mean(axis=0)[:2] - pose.position[:2]) > 0.005  # (the case the rule is for)
