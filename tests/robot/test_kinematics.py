"""Pinocchio IK: round trips through forward kinematics, limits, typed failure."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.grasping.top_down import top_down
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of

ROBOT = robot_named()


def test_home_tcp_matches_field_notes() -> None:
    tcp = kinematics_of(ROBOT).forward(ROBOT.home_q)
    np.testing.assert_allclose(tcp.position, [0.30689, 0.0, 0.48688], atol=1e-4)
    np.testing.assert_allclose(tcp.rotation[:, 2], [0.0, 0.0, -1.0], atol=1e-6)  # pointing down


def test_ik_round_trip_on_random_reachable_targets() -> None:
    kin = kinematics_of(ROBOT)
    rng = np.random.default_rng(0)
    for _ in range(25):
        q_true = rng.uniform(kin.lower + 0.2, kin.upper - 0.2)
        target = kin.forward(q_true)
        res = kin.solve(target, ROBOT.home_q, rng)
        assert res.success, res.reason
        assert kin.within_limits(res.q)
        reached = kin.forward(res.q)
        assert np.linalg.norm(reached.position - target.position) < 1e-4
        assert np.allclose(reached.rotation, target.rotation, atol=1e-3)


def test_top_down_grasps_over_the_workspace() -> None:
    kin = kinematics_of(ROBOT)
    rng = np.random.default_rng(1)
    for x in (0.35, 0.5, 0.65):
        for y in (-0.2, 0.0, 0.3):
            for yaw in (-np.pi / 2, 0.0, np.pi / 4):
                res = kin.solve(top_down(np.array([x, y, 0.025]), yaw), ROBOT.home_q, rng)
                assert res.success, (x, y, yaw, res.reason)


def test_the_ur5_reaches_the_table_from_above_from_its_home() -> None:
    """An arm with offset wrists: a full Gauss-Newton step from its home overshoots into a fold for
    spots low beside it; the solver's trust-region pass finds them (every one of this grid)."""
    ur5 = robot_named("ur5_franka_hand")
    kin = kinematics_of(ur5)
    rng = np.random.default_rng(0)
    full_step_only = 0
    for x in (0.3, 0.45, 0.6, 0.7):
        for y in (-0.35, -0.15, 0.0, 0.2, 0.35):
            for yaw in (0.0, 1.5, -2.5):
                target = top_down(np.array([x, y, 0.025]), yaw)
                res = kin.solve(target, ur5.home_q, rng)
                assert res.success and kin.within_limits(res.q), (x, y, yaw, res.reason)
                full_step_only += res.restarts_used <= 8
    assert full_step_only < 60  # (the trust region was needed for some: the test tests it)


def test_unreachable_target_fails_with_reason() -> None:
    far = Pose.from_xyz_rpy([2.0, 0.0, 0.5], roll=np.pi)
    res = kinematics_of(ROBOT).solve(far, ROBOT.home_q, np.random.default_rng(0))
    assert not res.success
    assert "no solution" in res.reason
    assert res.position_error_m > 0.5


def test_tracking_a_setpoint_as_se3_is_the_same_solve_as_from_a_pose() -> None:
    """The control tick's fast path (an SE3 built straight from (x, y, z, yaw)) changes no number."""
    from pickdemo.motion.online import top_down_pose, top_down_se3

    kin = kinematics_of(ROBOT)
    rng = np.random.default_rng(2)
    for _ in range(50):
        x4 = np.array([rng.uniform(0.3, 0.6), rng.uniform(-0.3, 0.3), rng.uniform(0.05, 0.4), rng.uniform(-3, 3)])
        slow, fast = top_down_pose(x4).to_se3(), top_down_se3(x4)
        assert np.array_equal(slow.rotation, fast.rotation) and np.array_equal(slow.translation, fast.translation)
        q0 = ROBOT.home_q + rng.normal(0.0, 0.05, 7)
        a, b = kin.track(top_down_pose(x4), q0), kin.track(fast, q0)
        assert np.array_equal(a.q, b.q) and (a.position_error_m, a.rotation_error_rad) == (
            b.position_error_m,
            b.rotation_error_rad,
        )


def test_the_posture_task_swings_the_elbow_without_moving_the_hand() -> None:
    """The per-tick IK's posture term moves only in the hand's null space: tracking one pose tick
    after tick from a posture off the reference, the hand stays on it (to the solver's tolerance)
    and the arm's free swing comes back towards the reference."""
    kin = kinematics_of(ROBOT)
    rng = np.random.default_rng(3)
    target = top_down(np.array([0.45, 0.10, 0.20]), 0.3)
    ref = kin.solve(target, ROBOT.home_q, rng).q
    # the same hand pose with the elbow swung: a solution from a start far from the reference
    other = next(
        r.q for r in (kin.solve(target, rng.uniform(kin.lower, kin.upper), rng) for _ in range(40))
        if r.success and np.max(np.abs(r.q - ref)) > 0.3
    )  # fmt: skip
    q, wobble = other, 0.0
    nudge = Pose(target.position + np.array([0.0, 0.0, 1e-4]), target.rotation)  # a moving target: a step each tick
    for k in range(300):
        res = kin.track(nudge if k % 2 else target, q, posture=ref)
        assert res.success, res.reason
        q = res.q
        wobble = max(wobble, float(np.linalg.norm(kin.forward(q).position - target.position)))
    assert wobble < 2e-4  # the hand stays where it is told
    assert np.max(np.abs(q - ref)) < 0.5 * np.max(np.abs(other - ref))  # the elbow came back
    # without a posture the swing stays where it was
    q = other
    for k in range(300):
        q = kin.track(nudge if k % 2 else target, q).q
    assert np.max(np.abs(q - other)) < 0.05


def test_the_posture_task_keeps_off_the_joint_limits() -> None:
    """A joint inside the avoidance zone is pushed away from its limit, in the null space."""
    from pickdemo.robot.kinematics import POSTURE

    kin = kinematics_of(ROBOT)
    q = np.array(ROBOT.home_q, dtype=float)
    q[2] = kin.upper[2] - 0.05  # joint 3 near its upper limit
    step = kin._posture_step(q, q, POSTURE)
    assert step[2] < 0.0 and np.count_nonzero(step) == 1  # only that joint, away from its limit
    q[2] = 0.0
    assert not np.any(kin._posture_step(q, q, POSTURE))  # outside every zone: nothing
