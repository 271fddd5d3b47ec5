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
