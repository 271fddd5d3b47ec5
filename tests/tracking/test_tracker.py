"""The target tracker: fuses estimates, compensates latency, gates outliers, restarts on a real move."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.geometry import Pose
from pickdemo.perception import PoseEstimate
from pickdemo.tracking.tracker import TargetTracker, TrackerParams


def _est(x: float, y: float, yaw_deg: float = 0.0, sd_m: float = 1e-4, z: float = 0.025) -> PoseEstimate:
    return PoseEstimate(
        pose=Pose.from_xyz_rpy([x, y, z], yaw=np.radians(yaw_deg)),
        position_cov=np.eye(3) * sd_m**2,
        rpy_cov=np.eye(3) * np.radians(0.1) ** 2,
        yaw_symmetry_rad=np.pi / 2,
        top_face_size_m=(0.05, 0.05),
        n_features=10,
        n_face_pixels=500,
    )


def test_static_target_fuses_and_predicts_in_place() -> None:
    rng = np.random.default_rng(0)
    tr = TargetTracker(np.pi / 2)
    for k in range(20):
        up = tr.update(_est(0.5 + rng.normal(0, 2e-4), rng.normal(0, 2e-4), 10.0), 0.1 * k)
        assert up.accepted
    tp = tr.predict(2.05)  # 50 ms of latency ahead of the newest frame
    assert np.linalg.norm(tp.position[:2] - [0.5, 0.0]) < 5e-4
    assert np.linalg.norm(tp.velocity) < 5e-3
    assert np.degrees(tp.yaw_rad) == pytest.approx(10.0, abs=0.2)


def test_moving_target_velocity_is_estimated_and_latency_compensated() -> None:
    tr = TargetTracker(np.pi / 2)
    v = 0.05  # m/s along y
    for k in range(30):
        tr.update(_est(0.5, v * 0.1 * k), 0.1 * k)
    tp = tr.predict(2.9 + 0.05)
    assert tp.velocity[1] == pytest.approx(v, abs=2e-3)
    assert tp.position[1] == pytest.approx(v * 2.95, abs=1e-3)


def test_single_outlier_is_rejected() -> None:
    tr = TargetTracker(np.pi / 2)
    for k in range(5):
        tr.update(_est(0.5, 0.0), 0.1 * k)
    up = tr.update(_est(0.53, 0.0), 0.5)
    assert not up.accepted and up.mahalanobis2 > 100
    assert tr.update(_est(0.5, 0.0), 0.6).accepted
    assert tr.predict(0.6).position[0] == pytest.approx(0.5, abs=1e-4)
    assert tr.rejected == 1 and tr.jumps == 0


def test_a_real_move_restarts_the_track_after_agreeing_rejections() -> None:
    tr = TargetTracker(np.pi / 2, TrackerParams(jump_confirm=3))
    for k in range(5):
        tr.update(_est(0.5, 0.0), 0.1 * k)
    ups = [tr.update(_est(0.54, 0.02, 20.0), 0.5 + 0.1 * k) for k in range(3)]
    assert [u.accepted for u in ups] == [False, False, True] and ups[-1].jumped
    assert tr.jumps == 1
    np.testing.assert_allclose(tr.predict(0.7).position[:2], [0.54, 0.02], atol=1e-4)


def test_partial_views_never_restart_the_track() -> None:
    tr = TargetTracker(np.pi / 2)
    for k in range(5):
        tr.update(_est(0.5, 0.0), 0.1 * k)
    for k in range(6):
        assert not tr.update(_est(0.51, 0.04), 0.5 + 0.1 * k, partial=True).accepted
    assert tr.jumps == 0
    assert tr.predict(1.1).position[0] == pytest.approx(0.5, abs=1e-4)


def test_yaw_wraps_with_the_symmetry() -> None:
    tr = TargetTracker(np.pi / 2)
    tr.update(_est(0.5, 0.0, 44.0), 0.0)
    up = tr.update(_est(0.5, 0.0, -45.5), 0.1)  # the same square face a quarter turn on
    assert up.accepted
    assert np.degrees(tr.predict(0.1).yaw_rad) == pytest.approx(44.3, abs=0.6)


def test_lost_after_a_second_without_an_accepted_estimate() -> None:
    tr = TargetTracker(0.0)  # a cylinder: no yaw
    assert tr.lost(0.0)
    tr.update(_est(0.5, 0.0), 0.0)
    assert not tr.lost(0.9) and tr.lost(1.1)


def test_an_estimate_without_orientation_updates_the_position_only() -> None:
    """The `pixel` method measures no orientation (its rpy covariance is infinite)."""
    import dataclasses

    tr = TargetTracker(np.pi / 2)
    blind = dataclasses.replace(_est(0.5, 0.0, 30.0), rpy_cov=np.full((3, 3), np.inf))
    assert tr.update(blind, 0.0).accepted
    assert np.isfinite(tr.predict(0.0).covariance).all() and tr.predict(0.0).covariance[3, 3] > 1.0
    assert tr.update(dataclasses.replace(blind, pose=Pose.from_xyz_rpy([0.5005, 0.0, 0.025])), 0.1).accepted
    assert tr.update(_est(0.5, 0.0, 30.0), 0.2).accepted  # a full estimate then sets the yaw
    assert np.degrees(tr.predict(0.2).yaw_rad) == pytest.approx(30.0, abs=1.0)


def test_tracker_learns_a_belts_speed_and_follows_a_speed_change() -> None:
    from pickdemo.skills.pick import MachineParams

    tracker = TargetTracker(np.pi / 2.0, MachineParams().on_a_belt().tracker)
    rng = np.random.default_rng(0)
    y, t, speed = -0.3, 0.0, 0.05
    for k in range(40):
        if k == 15:
            speed = 0.10  # the belt speeds up
        y += speed * 0.1
        t += 0.1
        x_n, y_n, z_n = np.array([0.5, y, 0.035]) + rng.normal(0.0, 5e-4, 3)
        tracker.update(_est(x_n, y_n, 17.0, sd_m=5e-4, z=z_n), t)
        if k == 14:
            assert tracker.predict(t).velocity[1] == pytest.approx(0.05, abs=0.004)
    tp = tracker.predict(t)
    assert tp.velocity[1] == pytest.approx(0.10, abs=0.004)
    assert tp.position[1] == pytest.approx(y, abs=0.002)


def _calibrated(x: float, y: float, noise_m: float, calibration_m: float) -> PoseEstimate:
    """An estimate whose camera's pose is known to ``calibration_m`` per axis (a bias in every frame of it)."""
    cal = np.eye(3) * calibration_m**2
    return PoseEstimate(
        pose=Pose.from_xyz_rpy([x, y, 0.025]),
        position_cov=np.eye(3) * noise_m**2 + cal,
        rpy_cov=np.eye(3) * np.radians(0.1) ** 2,
        yaw_symmetry_rad=np.pi / 2,
        top_face_size_m=(0.05, 0.05),
        n_features=10,
        n_face_pixels=500,
        calibration_cov=cal,
    )


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_cameras_calibration_is_a_bias_no_number_of_its_frames_averages_away(seed: int) -> None:
    rng = np.random.default_rng(seed)
    bias = rng.normal(0.0, 0.008, 2)  # this camera's pose is off: every frame of it alike
    tr = TargetTracker(np.pi / 2)
    for k in range(50):
        noise = rng.normal(0.0, 3e-4, 2)
        assert tr.update(_calibrated(*(np.array([0.5, 0.0]) + bias + noise), 3e-4, 0.008), 0.1 * k).accepted
    tp = tr.predict(5.0)
    assert tp.position_sigma_m < 0.002  # its noise averages away (to the floor of each estimate) ...
    assert tp.grasp_sigma_m >= 0.008  # ... its calibration does not: the track says so


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_better_calibrated_camera_corrects_the_track_of_a_worse_one(seed: int) -> None:
    rng = np.random.default_rng(seed)
    truth = np.array([0.5, 0.0])
    fixed_bias = rng.normal(0.0, 0.01, 2)
    fixed_bias *= 0.012 / np.linalg.norm(fixed_bias)  # 12 mm off: more than any gate of its own noise
    tr = TargetTracker(np.pi / 2)
    t = 0.0
    for _ in range(20):  # the fixed camera alone (a miscalibrated one, and told so)
        tr.update(_calibrated(*(truth + fixed_bias + rng.normal(0, 3e-4, 2)), 3e-4, 0.01), t, source="camera")
        t += 0.1
    for _ in range(10):  # then both, the hand's camera calibrated to the hand
        up_w = tr.update(_calibrated(*(truth + rng.normal(0, 2e-4, 2)), 2e-4, 0.0005), t, source="wrist_camera")
        up_f = tr.update(_calibrated(*(truth + fixed_bias + rng.normal(0, 3e-4, 2)), 3e-4, 0.01), t, source="camera")
        assert up_w.accepted and up_f.accepted and not up_w.jumped and not up_f.jumped  # one target, no jumps
        t += 0.1
    tp = tr.predict(t)
    assert np.linalg.norm(tp.position[:2] - truth) < 0.0015  # where the better camera sees it
    assert tp.grasp_sigma_m < 0.002  # and sure of it


def test_an_uncalibrated_trackers_arithmetic_is_unchanged_by_a_second_camera_name() -> None:
    """With exact camera poses the cameras' names change nothing: the same estimates, the same belief."""
    rng = np.random.default_rng(3)
    a, b = TargetTracker(np.pi / 2), TargetTracker(np.pi / 2)
    for k in range(20):
        e = _est(0.5 + rng.normal(0, 2e-4), rng.normal(0, 2e-4), 10.0)
        a.update(e, 0.1 * k)
        b.update(e, 0.1 * k, source="wrist_camera" if k % 2 else "camera")
    pa, pb = a.predict(2.0), b.predict(2.0)
    assert np.array_equal(pa.position, pb.position) and np.array_equal(pa.covariance, pb.covariance)
