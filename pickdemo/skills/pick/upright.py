"""The carry of an item held from the side, kept upright (issue 59): the way down in the hand's frame
kept where it was at the lift, in joint space with each point moved to that attitude
(:func:`~pickdemo.motion.lines.upright_in_joints`), or about the robot's base at the arm's posture
(:func:`~pickdemo.motion.lines.around_the_base`); the hand turns about the vertical on the way, and the
item is put down turned as much about its own vertical.

Why: a grasp from the side holds a shelf's item off its centre; carried in joint space, the hand
tilted under it by up to 45 deg on the way, and the item turned in the fingers by 7 to 35 deg (each of the
9 of `pick_shelf`'s 15 place failures traced, seeds 18 to 91), so that it stood tilted at the place and fell
over or was dragged by the retreat. Held at the attitude it was lifted at, the pull of its weight about
the fingers stays what the lift showed the grip holds.

A part of the pick skill: it returns the carry (the plan turned at the place, the joint path), never
writes the machine's state.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pickdemo.grasping.top_down import GraspPlan
from pickdemo.motion.lines import around_the_base, carry_in_joints, upright_in_joints
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.pick.plans import turned_place

#: The turns of the place tried (rad), about the one that keeps the hand's bearing from the base: the
#: nearest first, every 20 deg round.
TURNS_RAD = tuple(float(np.radians(a)) for k in range(10) for a in ((20 * k,) if k in (0, 9) else (20 * k, -20 * k)))
#: How much higher the carry's way about the base goes at its middle (m), tried in turn.
RISES_M = (0.0, 0.05, 0.1, 0.15)


@dataclass(frozen=True)
class Upright:
    """An upright carry: ``plan`` with its place turned, and the joint path to above its place."""

    plan: GraspPlan
    waypoints: np.ndarray
    turn_rad: float
    rise_m: float | None  # (how much higher about the base; None: in joint space)


def _heading(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


def keeping_bearing(kin: Kinematics, q: np.ndarray, plan: GraspPlan) -> float:
    """The turn of ``plan``'s place (rad) that puts the hand there at the bearing it has now from the base
    (its approach's heading less the TCP's bearing): the arm then holds it as it does now, turned about
    its first joint."""
    here = kin.forward(q)
    keep = _heading(here.rotation[:, 2]) - _heading(here.position)
    turn = 0.0
    for _ in range(3):  # (the TCP turns about the item's centre with the place: its bearing moves a little)
        above = turned_place(plan, turn).place_above
        turn = keep + _heading(above.position) - _heading(plan.place_above.rotation[:, 2])
        turn = float(np.angle(np.exp(1j * turn)))
    return turn


def upright_carry(
    kin: Kinematics,
    q: np.ndarray,
    plan: GraspPlan,
    clear: Callable[[np.ndarray], bool] | None,
    goal: Callable[[GraspPlan, np.ndarray], np.ndarray | None],
) -> Upright | None:
    """The first upright carry from the arm at ``q`` to above ``plan``'s place turned by one of
    :data:`TURNS_RAD`, whose path keeps ``clear`` and ends where the lowering can follow (``goal(plan,
    q_near)``: the IK goal above the place nearest ``q_near`` from which the lowering is followed and
    clear, ``q_near`` itself where it is one; None: none, that turn is not tried). First each turn in
    joint space to the goal nearest the arm (:func:`~pickdemo.motion.lines.upright_in_joints`: a shelf's
    bin is reached with the elbow turned over, and the arm changes its posture on the way); then each
    turn that had a goal about the base at the arm's posture, risen by each of :data:`RISES_M` (over
    what is in the way), drawn at its end to the goal nearest there. None: none (a path planned around
    what is in the way, each point then moved to the attitude as in joint space, found none that the
    plain ones did not, on the shelf's seeds where they found none, at a second a carry)."""
    here = kin.forward(q)
    base = keeping_bearing(kin, q, plan)
    tried: list[tuple[float, GraspPlan, np.ndarray]] = []
    for dturn in TURNS_RAD:
        turned = turned_place(plan, base + dturn)
        q_goal = goal(turned, q)
        if q_goal is None:
            continue  # (put down so, the lowering cannot be followed)
        waypoints = upright_in_joints(kin, q, q_goal, clear)
        if waypoints is not None:
            return Upright(turned, waypoints, base + dturn, None)
        tried.append((base + dturn, turned, q_goal))
    for turn, turned, _ in tried:
        for rise in RISES_M:  # about the base at the arm's posture, over what is in the way
            poses = around_the_base(here, turned.place_above, rise)
            if poses is None:
                return None  # (the place's attitude is not the hand's: not an upright carry)
            waypoints = carry_in_joints(kin, q, poses, clear)
            if waypoints is None:
                continue  # (higher, it may keep clear)
            q_end = goal(turned, waypoints[-1])
            if q_end is not waypoints[-1]:  # (drawn to the goal nearest its end; none: higher ends the same)
                waypoints = None if q_end is None else carry_in_joints(kin, q, poses, clear, q_end)
            if waypoints is None:
                break
            return Upright(turned, waypoints, turn, rise)
    return None
