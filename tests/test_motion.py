"""Online motion: Ruckig's online form in Cartesian space with one IK solve per tick."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo import robot_model as rm
from pickdemo.kinematics import panda_kinematics
from pickdemo.motion import CartesianLimits, OnlineMotion, pose_to_x4, top_down_pose

DT = 1.0 / 120.0


def _run(m: OnlineMotion, ticks: int, retarget: dict[int, np.ndarray] | None = None) -> list:
    samples = []
    for k in range(ticks):
        if retarget and k in retarget:
            m.set_target(retarget[k])
        samples.append(m.step())
        if samples[-1].finished and not (retarget and any(t > k for t in retarget)):
            break
    return samples


def test_pose_x4_round_trip() -> None:
    for yaw in (-2.5, -0.4, 0.0, 0.7, 3.0):
        x4 = np.array([0.4, -0.1, 0.2, yaw])
        np.testing.assert_allclose(pose_to_x4(top_down_pose(x4)), x4, atol=1e-12)


def test_reaches_the_target_and_the_joints_follow() -> None:
    kin = panda_kinematics()
    lim = CartesianLimits(velocity=0.3, acceleration=1.5, jerk=15.0)
    m = OnlineMotion(kin, rm.HOME_Q, DT, lim)
    goal = np.array([0.5, 0.1, 0.15, 0.4])
    m.set_target(goal)
    samples = _run(m, 2000)
    assert samples[-1].finished
    np.testing.assert_allclose(samples[-1].setpoint, goal, atol=1e-9)
    tcp = pose_to_x4(kin.forward(samples[-1].q))
    np.testing.assert_allclose(tcp, goal, atol=1e-4)


def test_retargets_mid_motion_stay_within_limits() -> None:
    """Re-targeted every 0.1 s to a drifting goal: velocity, acceleration and jerk stay within the limits."""
    kin = panda_kinematics()
    lim = CartesianLimits(velocity=0.2, acceleration=1.0, jerk=10.0)
    m = OnlineMotion(kin, rm.HOME_Q, DT, lim)
    rng = np.random.default_rng(1)
    goals = {k: np.array([0.5, 0.0, 0.2, 0.3]) + rng.uniform(-0.05, 0.05, 4) for k in range(0, 240, 12)}
    s = _run(m, 2000, goals)
    vel = np.array([x.velocity for x in s])
    acc = np.array([x.acceleration for x in s])
    v, a, j = (np.array(x) for x in lim.arrays())
    assert np.all(np.abs(vel) <= v * (1 + 1e-9) + 1e-12)
    assert np.all(np.abs(acc) <= a * (1 + 1e-9) + 1e-12)
    assert np.all(np.abs(np.diff(acc, axis=0)) / DT <= j * (1 + 1e-6) + 1e-9)
    assert m.retargets >= 10 and s[-1].finished


def test_a_vertical_move_is_a_straight_line() -> None:
    kin = panda_kinematics()
    m = OnlineMotion(kin, rm.HOME_Q, DT, CartesianLimits())
    start = m.setpoint.copy()
    m.set_target(start - np.array([0.0, 0.0, 0.2, 0.0]))
    s = _run(m, 2000)
    xy = np.array([pose_to_x4(kin.forward(x.q))[:2] for x in s])
    assert np.max(np.linalg.norm(xy - start[:2], axis=1)) < 1e-4


def test_invalid_limits_rejected() -> None:
    with pytest.raises(ValueError):
        CartesianLimits(velocity=0.0)
    with pytest.raises(ValueError):
        CartesianLimits(jerk=float("inf"))
