"""Pose errors against the truth, fair to symmetric objects (values worked by hand)."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.geometry import Pose
from pickdemo.runtime.evaluation import pose_errors


def test_cube_quarter_turn_is_no_error() -> None:
    true = Pose.from_xyz_rpy([0.5, 0.0, 0.025], yaw=np.radians(10.0))
    est = Pose.from_xyz_rpy([0.5003, 0.0004, 0.025], yaw=np.radians(100.5))  # a quarter turn + 0.5 deg
    e = pose_errors(est, true, np.pi / 2)
    assert e["yaw_error_deg"] == pytest.approx(0.5, abs=1e-9)
    assert e["position_error_mm"] == pytest.approx(0.5)  # 0.3 and 0.4 mm: a 3-4-5 triangle
    assert (e["x_error_mm"], e["y_error_mm"], e["z_error_mm"]) == pytest.approx((0.3, 0.4, 0.0))


def test_box_half_turn_but_not_quarter() -> None:
    true = Pose.from_xyz_rpy([0, 0, 0], yaw=0.0)
    assert pose_errors(Pose.from_xyz_rpy([0, 0, 0], yaw=np.pi), true, np.pi)["yaw_error_deg"] == pytest.approx(0.0)
    assert pose_errors(Pose.from_xyz_rpy([0, 0, 0], yaw=np.pi / 2), true, np.pi)["yaw_error_deg"] == pytest.approx(90.0)


def test_tilt_errors_by_hand() -> None:
    true = Pose.from_xyz_rpy([0, 0, 0], roll=np.radians(2.0), pitch=np.radians(1.0), yaw=np.radians(-25.0))
    est = Pose.from_xyz_rpy([0, 0, 0], roll=np.radians(2.3), pitch=np.radians(0.8), yaw=np.radians(-25.4))
    e = pose_errors(est, true, np.pi)
    assert e["roll_error_deg"] == pytest.approx(0.3, abs=1e-9)
    assert e["pitch_error_deg"] == pytest.approx(0.2, abs=1e-9)
    assert e["yaw_error_deg"] == pytest.approx(0.4, abs=1e-9)


def test_cylinder_has_no_yaw_but_has_tilt() -> None:
    true = Pose.from_xyz_rpy([0, 0, 0], roll=np.radians(3.0), yaw=np.radians(40.0))
    spin = Pose.from_xyz_rpy([0, 0, 0], yaw=np.radians(-110.0))
    est = Pose(true.position, true.rotation @ spin.rotation)  # spun about its own axis
    e = pose_errors(est, true, 0.0)
    assert e["yaw_error_deg"] is None
    assert e["rotation_error_deg"] == pytest.approx(0.0, abs=1e-6)


def test_no_orientation() -> None:
    e = pose_errors(Pose.identity(), Pose.identity(), np.pi, has_orientation=False)
    assert e["yaw_error_deg"] is None and e["pitch_error_deg"] is None and e["position_error_mm"] == 0.0


def test_place_scoring_accepts_a_cube_on_any_face_but_not_a_box_on_its_side() -> None:
    from pickdemo.core.shapes import Box, Cylinder
    from pickdemo.runtime.metrics import score_place

    start = Pose.from_xyz_rpy([0.5, 0.0, 0.025])
    common = dict(start=start, max_z_m=0.2, final_speed_m_s=0.0, place_xy=(0.45, 0.3), lift_height_m=0.05,
                  place_tolerance_m=0.02)  # fmt: skip
    on_side = Pose.from_xyz_rpy([0.45, 0.3, 0.025], roll=np.pi / 2, yaw=0.3)
    assert score_place(final=on_side, shape=Box((0.05, 0.05, 0.05)), **common).success
    box_on_side = Pose.from_xyz_rpy([0.45, 0.3, 0.0175], roll=np.pi / 2)
    out = score_place(final=box_on_side, shape=Box((0.07, 0.035, 0.04)), **common)
    assert not out.success and "upright" in out.reason
    lying = Pose.from_xyz_rpy([0.45, 0.3, 0.02], roll=np.pi / 2)
    assert not score_place(final=lying, shape=Cylinder(0.04, 0.08), **common).success
    upside_down = Pose.from_xyz_rpy([0.45, 0.3, 0.04], roll=np.pi)
    assert score_place(final=upside_down, shape=Cylinder(0.04, 0.08), **common).success
