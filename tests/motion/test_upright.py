"""A held item carried upright (:mod:`pickdemo.motion.lines`' carries, :mod:`pickdemo.skills.pick.upright`):
the Panda's hand tilted 75 deg, as from the side out of a shelf's bin beside the base, carried to a
place in front of it. A straight joint path tilts the hand under the item (it turned in the fingers);
the carries keep the way down in the hand within :data:`~pickdemo.motion.lines.UPRIGHT_RAD`."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import Pose, about_vertical
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.motion.ik_goals import choose_goal, goal_candidates
from pickdemo.motion.lines import UPRIGHT_RAD, around_the_base, carry_in_joints, upright_in_joints
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.skills.pick.plans import turned_place
from pickdemo.skills.pick.upright import keeping_bearing, upright_carry

KIN = kinematics_of(robot_named())
DOWN = np.array([0.0, 0.0, -1.0])


def _tilted(heading_rad: float, tilt_deg: float = 75.0) -> np.ndarray:
    """A TCP rotation pointing along ``heading_rad``, tilted ``tilt_deg`` from straight down, its fingers
    closing level."""
    t = np.radians(tilt_deg)
    approach = np.array([np.sin(t), 0.0, -np.cos(t)])
    closing = np.array([0.0, 1.0, 0.0])
    return about_vertical(heading_rad) @ np.column_stack([np.cross(closing, approach), closing, approach])


def _goal(pose: Pose) -> np.ndarray:
    g = choose_goal(goal_candidates(KIN, [pose], KIN.robot.home_q, np.random.default_rng(0)))
    assert g is not None and g.margin_rad > 0.0
    return g.q


def _worst_tilt(legs: list[np.ndarray]) -> float:
    """The most the way down in the hand turns from the first leg's start along straight joint legs (rad)."""
    down0 = KIN.forward(legs[0]).rotation.T @ DOWN
    worst = 0.0
    for qa, qb in zip(legs[:-1], legs[1:], strict=True):
        for t in np.linspace(0.0, 1.0, 41):
            d = KIN.forward(qa + (qb - qa) * t).rotation.T @ DOWN
            worst = max(worst, float(np.arccos(np.clip(d @ down0, -1.0, 1.0))))
    return worst


SHELF = Pose(np.array([-0.04, 0.42, 0.17]), _tilted(np.pi / 2))  # (out of a bin to the robot's left)


def _place(turn_rad: float) -> Pose:
    return Pose(np.array([0.45, -0.25, 0.24]), about_vertical(turn_rad) @ SHELF.rotation)


def test_the_way_about_the_base_keeps_the_attitude_and_ends_at_the_end() -> None:
    end = _place(-2.0)
    poses = around_the_base(SHELF, end, rise_m=0.05)
    assert poses is not None and poses[-1] is end
    for p in poses:
        assert abs(float((p.rotation.T @ DOWN) @ (SHELF.rotation.T @ DOWN)) - 1.0) < 1e-9
    bearings = np.unwrap([np.arctan2(p.position[1], p.position[0]) for p in poses])
    assert np.all(np.diff(bearings) < 0.0)  # (the shorter way round, clockwise here)
    assert max(p.position[2] for p in poses) > 0.24  # (risen at its middle)
    tipped = Pose(end.position, end.rotation @ np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]))
    assert around_the_base(SHELF, tipped) is None  # (not the same attitude: no upright way)


def test_a_straight_joint_path_tilts_the_hand_and_the_upright_one_does_not() -> None:
    q0, q1 = _goal(SHELF), _goal(_place(-2.6))
    assert _worst_tilt([q0, q1]) > np.radians(5.0)  # (what turned the shelf's items in the fingers)
    waypoints = upright_in_joints(KIN, q0, q1)
    assert waypoints is not None
    assert np.allclose(waypoints[-1], q1)
    assert _worst_tilt([q0, *waypoints]) < UPRIGHT_RAD + 1e-3


def test_the_carries_stop_where_the_arm_would_not_keep_clear() -> None:
    q0, q1 = _goal(SHELF), _goal(_place(-2.6))
    assert upright_in_joints(KIN, q0, q1, clear=lambda q: KIN.forward(q).position[0] < 0.2) is None
    poses = around_the_base(SHELF, _place(-2.6))
    assert poses is not None
    assert carry_in_joints(KIN, q0, poses, clear=lambda q: KIN.forward(q).position[0] < 0.2) is None


def test_a_carry_about_the_base_keeps_the_attitude_along_its_legs() -> None:
    """In front of the base, at the arm's usual posture: turned about its first joint, one leg."""
    start = Pose(np.array([0.45 * np.cos(0.8), 0.45 * np.sin(0.8), 0.3]), _tilted(0.8))
    end = Pose(np.array([0.45 * np.cos(-0.8), 0.45 * np.sin(-0.8), 0.3]), about_vertical(-1.6) @ start.rotation)
    q0 = _goal(start)
    poses = around_the_base(start, end)
    assert poses is not None
    waypoints = carry_in_joints(KIN, q0, poses)
    assert waypoints is not None
    assert np.allclose(KIN.forward(waypoints[-1]).position, end.position, atol=2e-3)
    assert _worst_tilt([q0, *waypoints]) < UPRIGHT_RAD + 1e-3
    high = around_the_base(start, end, rise_m=0.05)
    assert high is not None
    assert carry_in_joints(KIN, q0, high, clear=lambda q: KIN.forward(q).position[2] < 0.32) is None  # (too high)


def _plan(place: Pose, offset: tuple[float, float]) -> GraspPlan:
    up = np.array([0.0, 0.0, 0.1])
    return GraspPlan(
        pregrasp=SHELF, grasp=SHELF, lift=SHELF, place_above=Pose(place.position + up, place.rotation),
        place=place, retreat=place, hand_yaw_rad=0.0, object_width_m=0.06, place_offset_xy=offset,
    )  # fmt: skip


def test_a_place_turned_about_the_item_keeps_the_item_where_it_was() -> None:
    plan = _plan(_place(0.0), (0.0, 0.04))
    centre = plan.place.position[:2] - np.array(plan.place_offset_xy)
    turned = turned_place(plan, 1.0)
    assert np.allclose(turned.place.position[:2] - np.array(turned.place_offset_xy), centre)
    assert np.isclose(np.linalg.norm(turned.place_offset_xy), 0.04)
    assert np.allclose(turned.place.rotation, about_vertical(1.0) @ plan.place.rotation)


def test_the_upright_carry_keeps_the_hand_s_bearing_from_the_base_first() -> None:
    q0 = _goal(SHELF)
    plan = _plan(_place(0.0), (0.0, 0.0))
    turn = keeping_bearing(KIN, q0, plan)
    above = turned_place(plan, turn).place_above
    heading = np.arctan2(above.rotation[1, 2], above.rotation[0, 2]) - np.arctan2(above.position[1], above.position[0])
    here = KIN.forward(q0)
    keep = np.arctan2(here.rotation[1, 2], here.rotation[0, 2]) - np.arctan2(here.position[1], here.position[0])
    assert np.isclose(np.angle(np.exp(1j * (heading - keep))), 0.0, atol=1e-6)

    def goal(p: GraspPlan, q_near: np.ndarray) -> np.ndarray | None:
        found = goal_candidates(KIN, [p.place_above], q_near, np.random.default_rng(1))
        return None if not found else min((g.q for g in found), key=lambda g: float(np.max(np.abs(g - q_near))))

    carry = upright_carry(KIN, q0, plan, None, goal)
    assert carry is not None
    assert _worst_tilt([q0, *carry.waypoints]) < UPRIGHT_RAD + 1e-3
    assert np.allclose(KIN.forward(carry.waypoints[-1]).position, carry.plan.place_above.position, atol=2e-3)
    assert upright_carry(KIN, q0, plan, None, lambda p, q: None) is None  # (no place it can lower to)
