"""Ruckig trajectories: exact end points, limits respected, sampled at the control period."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo import robot_model as rm
from pickdemo.trajectory import Limits, TrajectoryError, plan_joint_motion


def test_rest_to_rest_within_limits() -> None:
    lim = Limits.panda(0.5, 0.3, 0.1)
    q1 = rm.HOME_Q + np.array([0.5, -0.3, 0.2, 0.4, -0.6, 0.3, 1.0])
    dt = 1.0 / 240.0
    tr = plan_joint_motion(rm.HOME_Q, q1, lim, dt)
    np.testing.assert_allclose(tr.positions[0], rm.HOME_Q)
    np.testing.assert_allclose(tr.positions[-1], q1, atol=1e-9)
    np.testing.assert_allclose(tr.velocities[[0, -1]], 0.0, atol=1e-9)
    assert np.all(np.abs(tr.velocities) <= lim.velocity + 1e-9)
    assert np.all(np.abs(tr.accelerations) <= lim.acceleration + 1e-9)
    jerk = np.diff(tr.accelerations, axis=0) / dt
    assert np.all(np.abs(jerk) <= lim.jerk * 1.001 + 1e-6)
    assert tr.dt_s == dt and tr.duration_s == pytest.approx((len(tr.positions) - 1) * dt)


def test_slower_limits_take_longer() -> None:
    lim = Limits.panda(0.5, 0.3, 0.1)
    q1 = rm.HOME_Q + 0.4
    fast = plan_joint_motion(rm.HOME_Q, q1, lim, 1 / 240)
    slow = plan_joint_motion(rm.HOME_Q, q1, lim.scaled(0.4), 1 / 240)
    assert slow.duration_s > 2.0 * fast.duration_s


def test_invalid_limits_rejected() -> None:
    with pytest.raises(ValueError):
        Limits.panda(0.0, 0.3, 0.1)
    bad = Limits(np.full(7, -1.0), np.full(7, 1.0), np.full(7, 1.0))
    with pytest.raises(TrajectoryError):
        plan_joint_motion(rm.HOME_Q, rm.HOME_Q + 0.1, bad, 1 / 240)


def test_cartesian_line_stays_straight_and_within_limits() -> None:
    from pickdemo.grasp import top_down
    from pickdemo.kinematics import panda_kinematics
    from pickdemo.trajectory import CartesianLimits, plan_cartesian_line

    kin = panda_kinematics()
    rng = np.random.default_rng(0)
    joint_limits = Limits.panda(0.5, 0.3, 0.1)
    cart = CartesianLimits(velocity=0.1, acceleration=0.5, jerk=5.0)
    for x, y, yaw in [(0.35, -0.25, np.pi / 2), (0.6, 0.2, -np.pi / 4), (0.5, 0.0, 0.3)]:
        q_pre = kin.solve(top_down(np.array([x, y, 0.125]), yaw), rm.HOME_Q, rng).q
        goal = top_down(np.array([x, y, 0.025]), yaw)
        tr = plan_cartesian_line(kin, q_pre, goal, cart, joint_limits, 1 / 240, rng)
        tcp = np.array([kin.forward(q).position for q in tr.positions])
        assert np.max(np.linalg.norm(tcp[:, :2] - [x, y], axis=1)) < 1e-4  # on the vertical line
        assert np.all(np.diff(tcp[:, 2]) <= 1e-9)  # monotonic descent
        np.testing.assert_allclose(tcp[-1], goal.position, atol=1e-5)
        speed = np.linalg.norm(np.diff(tcp, axis=0), axis=1) * 240
        assert speed.max() <= cart.velocity * 1.01
        assert np.all(np.abs(tr.velocities) <= joint_limits.velocity)
