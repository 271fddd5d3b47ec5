"""A straight line of the hand's as a joint path (:mod:`pickdemo.motion.lines`): the Panda's hand level,
backed out of a shelf's bin toward the arm's base, where one straight leg in joint space leaves the line."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.motion.ik_goals import choose_goal, goal_candidates
from pickdemo.motion.lines import JOINT_LINE_M, JOINT_LINE_RAD, line_in_joints, rise_followed
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import IKParams, kinematics_of

KIN = kinematics_of(robot_named())
LEVEL = np.column_stack([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # pointing +y, closing along x


def _at(y: float, z: float = 0.24) -> Pose:
    return Pose(np.array([0.02, y, z]), LEVEL)


def test_a_level_line_back_toward_the_base_is_run_as_legs_that_keep_to_it() -> None:
    rng = np.random.default_rng(0)
    start, end = _at(0.55), _at(0.40)
    q0 = KIN.solve(start, KIN.robot.home_q, rng).q
    one = KIN.solve(end, q0, rng, IKParams()).q  # (straight in joint space, the hand leaves the line)
    off = max(
        float(np.linalg.norm(np.cross(KIN.forward(q0 + (one - q0) * t).position - start.position, [0.0, 1.0, 0.0])))
        for t in np.linspace(0.0, 1.0, 11)
    )
    assert off > JOINT_LINE_M
    waypoints = line_in_joints(KIN, q0, end, rng, IKParams())
    assert waypoints is not None and len(waypoints) >= 2
    assert np.allclose(KIN.forward(waypoints[-1]).position, end.position, atol=1e-3)
    legs = [q0, *waypoints]
    for qa, qb in zip(legs[:-1], legs[1:], strict=True):
        for t in np.linspace(0.0, 1.0, 21):
            at = KIN.forward(qa + (qb - qa) * t)
            assert abs(at.position[0] - 0.02) < JOINT_LINE_M + 1e-4 and abs(at.position[2] - 0.24) < JOINT_LINE_M + 1e-4
            turn = np.arccos(np.clip((np.trace(at.rotation.T @ LEVEL) - 1.0) / 2.0, -1.0, 1.0))
            assert turn < JOINT_LINE_RAD + 1e-3


def test_a_line_that_brings_the_level_hand_to_the_base_cannot_be_followed() -> None:
    rng = np.random.default_rng(0)
    q0 = KIN.solve(_at(0.55), KIN.robot.home_q, rng).q
    assert line_in_joints(KIN, q0, _at(0.15), rng, IKParams()) is None
    assert line_in_joints(KIN, q0, _at(0.45), rng, IKParams()) is not None


def test_a_level_hand_rises_only_so_far_55_cm_out_in_front() -> None:
    """The Panda's level hand reaches 5-20 cm over the table there, each posture near a joint's stop
    (tests/hand_reach.py): a lift from 8 cm to 40 cm is followed part of the way, and rise_followed says
    how far; a lift of 4 cm all of it."""
    rng = np.random.default_rng(0)
    forward = np.column_stack([np.cross([0.0, 1.0, 0.0], [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    at = lambda z: Pose(np.array([0.55, 0.0, z]), forward)  # noqa: E731
    start = choose_goal(goal_candidates(KIN, [at(0.08)], KIN.robot.home_q, rng))
    assert start is not None
    assert 0.0 < rise_followed(KIN, start.q, at(0.40), rng, IKParams()) < 0.2
    assert abs(rise_followed(KIN, start.q, at(0.12), rng, IKParams()) - 0.04) < 1e-3


def test_a_line_checked_against_what_is_in_the_way_ends_before_it() -> None:
    rng = np.random.default_rng(0)
    q0 = KIN.solve(_at(0.55), KIN.robot.home_q, rng).q
    beyond = lambda q: KIN.forward(q).position[1] > 0.47  # noqa: E731 - (something from 47 cm back on)
    waypoints = line_in_joints(KIN, q0, _at(0.40), rng, IKParams(), clear=beyond)
    assert waypoints is not None
    legs = [q0, *waypoints]
    assert all(beyond(qa + (qb - qa) * t) for qa, qb in zip(legs[:-1], legs[1:], strict=True) for t in (0.5, 1.0))
    assert KIN.forward(waypoints[-1]).position[1] < 0.49  # (within a step of it)
