"""The whole perception stage and the baselines on synthetic frames with a known answer (no simulator).

An analytic ray caster renders an oriented box on the table: exact depth, flat-shaded faces, the same
camera conventions as the simulator's; then eq. (8) noise from a seeded generator.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from pickdemo.core.camera import Intrinsics, RGBDFrame, add_kinect_noise, look_at_pose
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Box, Cylinder
from pickdemo.perception import FitQuality, PerceptionError, PerceptionParams, TargetModel, estimate_pose
from pickdemo.perception.baselines import closest_on_model, estimate_centroid, estimate_icp, icp_point_to_plane
from pickdemo.runtime.evaluation import pose_errors

LIGHT = np.array([0.4, -0.3, 1.0]) / np.linalg.norm([0.4, -0.3, 1.0])


def render_box(pose: Pose, size, color, cam_pos, look_at, *, noise_seed: int | None = 0) -> RGBDFrame:
    """Ray-cast a box (and the table z = 0) into a 640x480 RGB-D frame."""
    K = Intrinsics.from_fov(640, 480, 57.0, 43.0, cx=320.0, cy=239.0)
    T = look_at_pose(np.asarray(cam_pos, float), np.asarray(look_at, float))
    v, u = np.mgrid[0:480, 0:640]
    d_cam = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u, dtype=float)], axis=-1)
    d_w = d_cam @ T.rotation.T
    o = T.position
    # Box: slab test in the box frame.
    R, c, h = pose.rotation, pose.position, np.asarray(size) / 2.0
    o_l = R.T @ (o - c)
    d_l = d_w @ R
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-h - o_l) / d_l
        t2 = (h - o_l) / d_l
    tmin = np.minimum(t1, t2)
    tmax = np.maximum(t1, t2)
    t_near = tmin.max(axis=-1)
    hit_box = (t_near <= tmax.min(axis=-1)) & (t_near > 0)
    face_axis = tmin.argmax(axis=-1)
    t_table = -o[2] / d_w[..., 2]
    t = np.where(hit_box, t_near, np.where(t_table > 0, t_table, np.inf))
    depth = t  # the ray's z component in the camera frame is 1, so t is the z-depth
    # Flat shading: each box face gets its own brightness from its normal.
    n_l = np.zeros(d_l.shape)
    ax = face_axis
    sign = -np.sign(np.take_along_axis(d_l, ax[..., None], axis=-1))[..., 0]
    np.put_along_axis(n_l, ax[..., None], sign[..., None], axis=-1)
    shade = 0.35 + 0.65 * np.clip((n_l @ R.T) @ LIGHT, 0.0, 1.0)
    rgb = np.where(hit_box[..., None], shade[..., None] * np.asarray(color) * 255.0, np.array([140.0, 105.0, 75.0]))
    if noise_seed is not None:
        depth = add_kinect_noise(depth, np.random.default_rng(noise_seed))
    return RGBDFrame(rgb=rgb.astype(np.uint8), depth_m=depth, intrinsics=K, T_world_cam=T, time_s=0.0)


MODEL = TargetModel(Box((0.06, 0.04, 0.05)), (0.85, 0.1, 0.1))


@pytest.mark.parametrize(
    ("yaw", "roll", "pitch", "cam"),
    [(20.0, 0.0, 0.0, (1.1, 0.0, 0.75)), (-60.0, 4.0, -3.0, (0.9, 0.4, 0.6)), (75.0, -6.0, 5.0, (0.6, -0.5, 0.7))],
)
def test_paper_method_recovers_a_known_pose(yaw: float, roll: float, pitch: float, cam) -> None:
    true = Pose.from_xyz_rpy([0.5, 0.02, 0.027], roll=np.radians(roll), pitch=np.radians(pitch), yaw=np.radians(yaw))
    frame = render_box(true, MODEL.size, MODEL.color, cam, (0.5, 0.0, 0.0))
    est = estimate_pose(frame, MODEL)
    e = pose_errors(est.pose, true, est.yaw_symmetry_rad)
    assert e["position_error_mm"] < 0.3
    assert e["yaw_error_deg"] < 0.3 and e["pitch_error_deg"] < 0.5 and e["roll_error_deg"] < 0.5
    assert est.n_features > 0 and est.position_cov.shape == (3, 3)
    assert np.all(np.linalg.eigvalsh(est.position_cov) > 0)


def test_noise_free_frame_is_nearly_exact() -> None:
    true = Pose.from_xyz_rpy([0.48, -0.03, 0.025], yaw=np.radians(33.0))
    frame = render_box(true, MODEL.size, MODEL.color, (1.0, 0.2, 0.7), (0.5, 0.0, 0.0), noise_seed=None)
    e = pose_errors(estimate_pose(frame, MODEL).pose, true, np.pi)
    assert e["position_error_mm"] < 0.1 and e["yaw_error_deg"] < 0.1


def test_closest_points_on_a_box_and_a_cylinder() -> None:
    box = TargetModel(Box((0.2, 0.1, 0.06)), (1, 0, 0))
    pts = np.array([[0.15, 0.0, 0.0], [0.0, 0.0, 0.01], [0.095, 0.02, 0.0]])
    q, n = closest_on_model(pts, box)
    np.testing.assert_allclose(q, [[0.1, 0.0, 0.0], [0.0, 0.0, 0.03], [0.1, 0.02, 0.0]])
    np.testing.assert_allclose(n, [[1, 0, 0], [0, 0, 1], [1, 0, 0]])
    cyl = TargetModel(Cylinder(0.04, 0.1), (1, 0, 0))
    q, n = closest_on_model(np.array([[0.03, 0.0, 0.01], [0.0, 0.005, 0.06]]), cyl)
    np.testing.assert_allclose(q, [[0.02, 0.0, 0.01], [0.0, 0.005, 0.05]], atol=1e-12)
    np.testing.assert_allclose(n, [[1, 0, 0], [0, 0, 1]], atol=1e-12)


def test_icp_recovers_a_perturbed_pose() -> None:
    rng = np.random.default_rng(2)
    true = Pose.from_xyz_rpy([0.5, 0.0, 0.025], yaw=0.3)
    # Points on the top and two sides of the box, with 0.3 mm noise.
    local = np.vstack([
        np.column_stack([rng.uniform(-0.03, 0.03, 300), rng.uniform(-0.02, 0.02, 300), np.full(300, 0.025)]),
        np.column_stack([np.full(200, 0.03), rng.uniform(-0.02, 0.02, 200), rng.uniform(-0.025, 0.025, 200)]),
        np.column_stack([rng.uniform(-0.03, 0.03, 200), np.full(200, -0.02), rng.uniform(-0.025, 0.025, 200)]),
    ])  # fmt: skip
    cloud = true.transform_points(local) + 3e-4 * rng.standard_normal((700, 3))
    start = Pose.from_xyz_rpy([0.503, -0.002, 0.027], yaw=0.33)
    pose, cov, used = icp_point_to_plane(cloud, MODEL, start)
    assert np.linalg.norm(pose.position - true.position) < 1e-4 and used > 600
    assert pose_errors(pose, true, np.pi)["yaw_error_deg"] < 0.1


def test_baselines_run_on_the_same_frame() -> None:
    true = Pose.from_xyz_rpy([0.5, 0.0, 0.025], yaw=np.radians(15.0))
    frame = render_box(true, MODEL.size, MODEL.color, (1.1, 0.0, 0.75), (0.5, 0.0, 0.0))
    for fn, tol_mm in ((estimate_centroid, 10.0), (estimate_icp, 2.0)):
        est = fn(frame, MODEL)
        assert np.linalg.norm(est.pose.position - true.position) * 1e3 < tol_mm, fn.__name__


def test_fit_reports_how_well_the_model_fitted() -> None:
    """On a frame that matches the model, the normalised residuals are about the noise model's
    (RMS near 1 or below) and no point is a gross outlier."""
    true = Pose.from_xyz_rpy([0.5, 0.02, 0.025], yaw=np.radians(20.0))
    frame = render_box(true, MODEL.size, MODEL.color, (1.1, 0.0, 0.75), (0.5, 0.0, 0.0))
    fit = estimate_pose(frame, MODEL).fit
    assert fit is not None and fit.points > 1000
    assert fit.depth_rms < 1.5 and fit.edge_rms < 1.5
    assert fit.depth_outliers < 0.01 and fit.edge_outliers < 0.01


def test_a_model_that_does_not_fit_is_rejected_with_the_reason() -> None:
    """Told the target is a 5 cm cylinder while the camera sees a 6 x 4 cm box of its colour: most of
    the outline lies far beyond the noise model, so perception says so instead of returning a pose
    (the rejected estimate travels with the error, for scoring only)."""
    true = Pose.from_xyz_rpy([0.5, 0.02, 0.025], yaw=np.radians(20.0))
    frame = render_box(true, MODEL.size, MODEL.color, (1.1, 0.0, 0.75), (0.5, 0.0, 0.0))
    wrong = TargetModel(Cylinder(0.05, 0.05), MODEL.color)
    with pytest.raises(PerceptionError, match="the model does not fit what was seen: .* outline") as info:
        estimate_pose(frame, wrong)
    assert info.value.estimate is not None and info.value.estimate.fit is not None
    assert info.value.estimate.fit.edge_outliers > 0.5


@pytest.mark.parametrize(
    ("fit", "reason"),
    [
        (FitQuality(0.6, 0.9, 0.0, 0.0, 1500), ""),
        (FitQuality(0.6, 0.9, 0.0, 0.0, 12), "only 12 depth points"),
        (FitQuality(0.6, 0.9, 0.45, 0.0, 1500), "45% of the depth points"),
        (FitQuality(0.6, 0.9, 0.0, 0.7, 1500), "70% of the outline"),
        (FitQuality(2.4e4, 0.9, 0.0, 0.0, 1500), "depth residuals are 2.4e\\+04 times"),
        (FitQuality(0.6, float("nan"), 0.0, 0.0, 1500), "outline residuals are nan times"),
    ],
)
def test_fit_quality_names_what_is_wrong(fit: FitQuality, reason: str) -> None:
    problem = fit.problem(PerceptionParams())
    assert (problem == "") if reason == "" else re.search(reason, problem), problem
