"""Online motion: Ruckig's online form in Cartesian space with one IK solve per tick."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.geometry import Pose
from pickdemo.motion.online import CartesianLimits, OnlineMotion, hand_frame, pose_to_x4, top_down_pose
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of

ROBOT = robot_named()

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
    kin = kinematics_of(ROBOT)
    lim = CartesianLimits(velocity=0.3, acceleration=1.5, jerk=15.0)
    m = OnlineMotion(kin, ROBOT.home_q, DT, lim)
    goal = np.array([0.5, 0.1, 0.15, 0.4])
    m.set_target(goal)
    samples = _run(m, 2000)
    assert samples[-1].finished
    np.testing.assert_allclose(samples[-1].setpoint, goal, atol=1e-9)
    tcp = pose_to_x4(kin.forward(samples[-1].q))
    np.testing.assert_allclose(tcp, goal, atol=1e-4)


def test_retargets_mid_motion_stay_within_limits() -> None:
    """Re-targeted every 0.1 s to a drifting goal: velocity, acceleration and jerk stay within the limits."""
    kin = kinematics_of(ROBOT)
    lim = CartesianLimits(velocity=0.2, acceleration=1.0, jerk=10.0)
    m = OnlineMotion(kin, ROBOT.home_q, DT, lim)
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
    kin = kinematics_of(ROBOT)
    m = OnlineMotion(kin, ROBOT.home_q, DT, CartesianLimits())
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


def test_a_turn_of_the_hand_goes_the_way_round_the_joints_can_follow() -> None:
    """Which way round a Cartesian turn goes is chosen by IK (every joint's limits); where that way
    ends within the limits, the motion turns that way with the per-tick IK never losing the setpoint
    and every joint in range. 36 moves from home across the table, turns of up to 175 deg."""
    from pickdemo.motion.ik_goals import turn_path
    from pickdemo.skills.actions import Move

    kin = kinematics_of(ROBOT)
    lim = CartesianLimits(velocity=0.3, acceleration=1.5, jerk=15.0)
    followed = 0
    for xy in ((0.45, 0.25), (0.5, -0.3), (0.35, 0.0), (0.6, 0.1)):
        for yaw_deg in (-175.0, -120.0, -60.0, 0.0, 60.0, 120.0, 175.0, 90.0, -90.0):
            m = OnlineMotion(kin, ROBOT.home_q, DT, lim)
            move = Move(m, chase_fraction=0.5, meet_horizon_s=5.0)
            goal = np.array([*xy, 0.2, m.setpoint[3] + np.radians(yaw_deg)])
            x4 = move.x4(goal)
            assert abs(np.angle(np.exp(1j * (x4[3] - goal[3])))) < 1e-9  # the same hand angle, some way round
            if turn_path(kin, m.q, m.setpoint, x4)[1] <= 0.0:
                continue  # neither way stays within the joint limits (the skill never asks for it)
            move.to(x4)
            samples = _run(m, 3000)  # a MotionError (IK lost, a joint too fast) would raise here
            assert samples[-1].finished
            assert all(kin.within_limits(s.q) for s in samples)
            np.testing.assert_allclose(pose_to_x4(kin.forward(samples[-1].q))[:3], goal[:3], atol=1e-4)
            followed += 1
    assert followed >= 28


def test_a_half_turn_the_nearer_way_would_stop_joint_7_goes_the_other_way() -> None:
    from pickdemo.motion.ik_goals import way_round

    kin = kinematics_of(ROBOT)
    sp = pose_to_x4(kin.forward(ROBOT.home_q))
    near_ok = way_round(kin, ROBOT.home_q, sp, sp + np.array([0.0, 0.0, 0.0, np.radians(170.0)]))
    assert np.isclose(near_ok[3] - sp[3], np.radians(170.0))  # the nearer way is within range: taken
    blocked = way_round(kin, ROBOT.home_q, sp, sp + np.array([0.0, 0.0, 0.0, np.radians(-170.0)]))
    assert np.isclose(blocked[3] - sp[3], np.radians(190.0))  # the nearer way would pass joint 7's stop


def test_a_move_with_no_turn_never_goes_a_whole_revolution_round() -> None:
    """With a joint already near its limit, a straight move down with the hand's angle unchanged (up
    to the last bit) keeps the angle: the other way round is a whole revolution (seen: a lowering
    after an over-the-top carry turned the hand 2 pi and lost the setpoint)."""
    from pickdemo.motion.ik_goals import way_round

    kin = kinematics_of(ROBOT)
    q = np.array(ROBOT.home_q, dtype=float)
    q[6] = kin.upper[6] - 0.1  # joint 7 within 0.15 rad of its stop
    sp = pose_to_x4(kin.forward(q))
    for eps in (0.0, 1e-15, -1e-15, 1e-3):
        x4 = way_round(kin, q, sp, sp + np.array([0.0, 0.0, -0.1, eps]))
        assert abs(x4[3] - sp[3]) < 2e-3


def test_a_tilted_hand_keeps_its_tilt_along_a_straight_line_into_the_grasp() -> None:
    """A grasp from the side: the motion is re-seated in the tilted hand's frame (where a joint transfer
    left the arm at the pregrasp), then goes in along the approach axis: a straight line, the hand's
    orientation kept to a tenth of a milliradian, and its yaw the approach's heading."""
    kin = kinematics_of(ROBOT)
    tilt = np.radians(35.0)
    # the approach 35 deg from straight down, heading +x; the fingers closing along world y
    z = np.array([np.sin(tilt), 0.0, -np.cos(tilt)])
    y = np.array([0.0, 1.0, 0.0])
    R = np.column_stack([np.cross(y, z), y, z])
    grasp = Pose(np.array([0.55, 0.05, 0.06]), R)
    pregrasp = Pose(grasp.position - z * 0.08, R)
    res = kin.solve(pregrasp, ROBOT.home_q, np.random.default_rng(0))
    assert res.success
    frame = hand_frame(R)
    assert frame is not None and hand_frame(top_down_pose(np.array([0.5, 0.0, 0.2, 0.3])).rotation) is None
    m = OnlineMotion(kin, res.q, DT, CartesianLimits(velocity=0.1, acceleration=0.5, jerk=5.0))
    m.reset_at(res.q, frame)
    np.testing.assert_allclose(m.setpoint, [*pregrasp.position, 0.0], atol=1e-4)  # heading +x: yaw 0
    m.set_target(pose_to_x4(grasp, frame))
    samples = _run(m, 4000)
    assert samples[-1].finished
    for s in samples:
        tcp = kin.forward(s.q)
        assert np.allclose(tcp.rotation, R, atol=1e-4)
        off = tcp.position - pregrasp.position
        assert np.linalg.norm(off - z * (off @ z)) < 2e-4  # on the approach axis
    assert np.allclose(kin.forward(samples[-1].q).position, grasp.position, atol=1e-4)


@pytest.mark.parametrize("tilt_deg, new_tilt_deg", [(25.0, None), (9.0, 6.0)])
def test_a_hand_reseated_in_another_tilt_turns_to_it_within_the_joints_limits(tilt_deg, new_tilt_deg) -> None:
    """A tilted hand re-seated pointing down (back from a tilted grasp), or in a plan's new tilt (it
    changed while a transfer went to the old one): the difference is turned out within the joints'
    velocity limits, not asked of them in one tick, and the hand ends in the new frame at the target."""
    kin = kinematics_of(ROBOT)

    def tilted(deg: float) -> np.ndarray:
        t = np.radians(deg)
        z = np.array([np.sin(t), 0.0, -np.cos(t)])
        y = np.array([0.0, 1.0, 0.0])
        return np.column_stack([np.cross(y, z), y, z])

    at = Pose(np.array([0.5, 0.05, 0.15]), tilted(tilt_deg))
    res = kin.solve(at, ROBOT.home_q, np.random.default_rng(0))
    assert res.success
    frame = None if new_tilt_deg is None else hand_frame(tilted(new_tilt_deg))
    m = OnlineMotion(kin, res.q, DT, CartesianLimits(velocity=0.1, acceleration=0.5, jerk=5.0))
    m.reset_at(res.q, frame)
    assert m.turning
    goal = m.setpoint + np.array([0.0, 0.0, 0.02, 0.0])
    m.set_target(goal)
    samples = []
    while len(samples) < 4000 and (not m.finished or m.turning or not samples):
        samples.append(m.step())
    assert samples[-1].finished and not m.turning
    q = np.array([res.q] + [s.q for s in samples])
    speed = np.abs(np.diff(q, axis=0)) / DT
    assert np.all(speed <= ROBOT.limits.max_velocity_rad_s)
    end = kin.forward(samples[-1].q)
    if frame is None:
        np.testing.assert_allclose(end.rotation, top_down_pose(goal).rotation, atol=1e-3)
    else:
        assert np.degrees(np.arccos(-end.rotation[2, 2])) == pytest.approx(new_tilt_deg, abs=0.05)
    np.testing.assert_allclose(end.position, goal[:3], atol=1e-4)


def test_a_tilt_the_joints_can_take_at_once_is_taken_at_once() -> None:
    """Re-seated within the per-tick IK's tolerance of its frame, the hand takes the difference in its
    first tick, as it always did: nothing is turned out."""
    kin = kinematics_of(ROBOT)
    t = np.radians(30.3)
    z = np.array([np.sin(t), 0.0, -np.cos(t)])
    y = np.array([0.0, 1.0, 0.0])
    res = kin.solve(Pose(np.array([0.45, 0.0, 0.3]), np.column_stack([np.cross(y, z), y, z])), ROBOT.home_q,
                    np.random.default_rng(0))  # fmt: skip
    t = np.radians(30.0)
    z = np.array([np.sin(t), 0.0, -np.cos(t)])
    m = OnlineMotion(kin, res.q, DT, CartesianLimits())
    m.reset_at(res.q, hand_frame(np.column_stack([np.cross(y, z), y, z])))
    assert not m.turning and m.finished


def test_a_joint_running_at_its_stop_fails_the_motion_while_a_brake_still_fits() -> None:
    """Turning the hand drives joint 7 at its stop: the motion fails with the joint still short of it by
    what braking from its speed needs (the brake after a failed motion ran a joint past its stop, and
    the robot's reflex stopped the arm)."""
    from pickdemo.motion.online import MotionError

    kin = kinematics_of(ROBOT)
    q0 = np.array(ROBOT.home_q, dtype=float)
    q0[6] = kin.upper[6] - 0.3
    m = OnlineMotion(kin, q0, DT, CartesianLimits(yaw_velocity=2.0, yaw_acceleration=10.0, yaw_jerk=100.0))
    goal = pose_to_x4(kin.forward(q0))
    goal[3] -= 0.6  # (joint 7 turns up to its stop this way)
    m.set_target(goal)
    with pytest.raises(MotionError, match="too fast to brake"):
        _run(m, 600)
    assert kin.upper[6] - m.q[6] > 0.05  # (well short of the stop: room to brake from its speed)
