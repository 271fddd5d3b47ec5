"""Pinocchio IK: round trips through forward kinematics, limits, typed failure."""

from __future__ import annotations

import numpy as np

from pickdemo import robot_model as rm
from pickdemo.geometry import Pose
from pickdemo.grasp import top_down
from pickdemo.kinematics import panda_kinematics


def test_home_tcp_matches_field_notes() -> None:
    tcp = panda_kinematics().forward(rm.HOME_Q)
    np.testing.assert_allclose(tcp.position, [0.30689, 0.0, 0.48688], atol=1e-4)
    np.testing.assert_allclose(tcp.rotation[:, 2], [0.0, 0.0, -1.0], atol=1e-6)  # pointing down


def test_ik_round_trip_on_random_reachable_targets() -> None:
    kin = panda_kinematics()
    rng = np.random.default_rng(0)
    for _ in range(25):
        q_true = rng.uniform(kin.lower + 0.2, kin.upper - 0.2)
        target = kin.forward(q_true)
        res = kin.solve(target, rm.HOME_Q, rng)
        assert res.success, res.reason
        assert kin.within_limits(res.q)
        reached = kin.forward(res.q)
        assert np.linalg.norm(reached.position - target.position) < 1e-4
        assert np.allclose(reached.rotation, target.rotation, atol=1e-3)


def test_top_down_grasps_over_the_workspace() -> None:
    kin = panda_kinematics()
    rng = np.random.default_rng(1)
    for x in (0.35, 0.5, 0.65):
        for y in (-0.2, 0.0, 0.3):
            for yaw in (-np.pi / 2, 0.0, np.pi / 4):
                res = kin.solve(top_down(np.array([x, y, 0.025]), yaw), rm.HOME_Q, rng)
                assert res.success, (x, y, yaw, res.reason)


def test_unreachable_target_fails_with_reason() -> None:
    res = panda_kinematics().solve(Pose.from_xyz_rpy([2.0, 0.0, 0.5], roll=np.pi), rm.HOME_Q, np.random.default_rng(0))
    assert not res.success
    assert "no solution" in res.reason
    assert res.position_error_m > 0.5


def test_tracking_a_setpoint_as_se3_is_the_same_solve_as_from_a_pose() -> None:
    """The control tick's fast path (an SE3 built straight from (x, y, z, yaw)) changes no number."""
    from pickdemo.motion import top_down_pose, top_down_se3

    kin = panda_kinematics()
    rng = np.random.default_rng(2)
    for _ in range(50):
        x4 = np.array([rng.uniform(0.3, 0.6), rng.uniform(-0.3, 0.3), rng.uniform(0.05, 0.4), rng.uniform(-3, 3)])
        slow, fast = top_down_pose(x4).to_se3(), top_down_se3(x4)
        assert np.array_equal(slow.rotation, fast.rotation) and np.array_equal(slow.translation, fast.translation)
        q0 = rm.HOME_Q + rng.normal(0.0, 0.05, 7)
        a, b = kin.track(top_down_pose(x4), q0), kin.track(fast, q0)
        assert np.array_equal(a.q, b.q) and (a.position_error_m, a.rotation_error_rad) == (
            b.position_error_m,
            b.rotation_error_rad,
        )
