"""The Franka Panda's wrist, as a top-down pick sees it: which of a grasp's equivalent hand angles
keeps joint 7 in range. Robot-specific rules, kept out of the pick skill (the motion issue replaces
them with joint-space goals chosen by IK).

Joint 7 turns against the hand's yaw and with the arm's bearing: ``q7 ~ pi/4 + q1 - yaw`` with
``q1 ~ atan2(y, x)`` of the TCP. Its limit is 2.90 rad; the rules keep it within
:data:`WRIST_TURN_LIMIT_RAD`.
"""

from __future__ import annotations

import numpy as np

from pickdemo.geometry import wrap_angle

#: A turned hand (a retry's other grasp yaw) is taken only if joint 7 stays within this (its limit: 2.90 rad).
WRIST_TURN_LIMIT_RAD = 2.4


def centre_yaw(*xy: tuple[float, float]) -> float:
    """The hand angle (rad) that puts joint 7 mid-range, on average over the given TCP positions."""
    q1 = np.mean([np.arctan2(y, x) for x, y in xy])
    return float(np.pi / 4.0 + q1)


def has_room(q7_rad: float) -> bool:
    """Whether joint 7 at ``q7_rad`` keeps the room a turned hand needs."""
    return not abs(q7_rad) > WRIST_TURN_LIMIT_RAD


def drifts_too_far(hand_yaw_rad: float, centre_rad: float, q7_then_rad: float) -> bool:
    """Whether a re-plan that keeps the hand's angle would leave joint 7's room: the angle too far
    from mid-range, or joint 7 predicted beyond it where the plan takes the hand. Kept re-plan after
    re-plan, a drifting yaw estimate walked the wrist into its stop (measured): take the equivalent
    angle nearest mid-range then."""
    return max(abs(hand_yaw_rad - centre_rad), abs(q7_then_rad)) > WRIST_TURN_LIMIT_RAD


def quarter_turn(usual_rad: float, centre_rad: float) -> float:
    """A square box's other pair of faces: a quarter turn from the usual angle, towards the middle
    of joint 7's range (``q7 ~ centre - psi``), so the wrist keeps room."""
    return usual_rad + (np.pi / 2.0 if usual_rad < centre_rad else -np.pi / 2.0)


def way_round(x4: np.ndarray, setpoint: np.ndarray, q7_rad: float) -> np.ndarray:
    """``x4`` (x, y, z, yaw) with its yaw the turn of the hand that keeps joint 7 in range: the
    equivalent nearest the current setpoint's, unless that one would take joint 7 beyond half a turn
    from mid-range, where the other way round does not (a turn near half a revolution: the nearest
    way can run into joint 7's stop). ``x4`` is changed in place and returned."""
    sp = setpoint
    x4[3] = sp[3] + wrap_angle(x4[3] - sp[3])
    q7 = float(q7_rad) + float(np.arctan2(x4[1], x4[0]) - np.arctan2(sp[1], sp[0])) - (x4[3] - sp[3])
    if abs(q7) > np.pi:
        x4[3] += 2.0 * np.pi * np.sign(q7)
    return x4
