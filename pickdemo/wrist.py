"""The Panda's wrist as a Cartesian yaw turn sees it: which way round the hand turns to a new angle.

A top-down hand's yaw and joint 7 turn together (``q7 ~ pi/4 + q1 - yaw``, ``q1 ~ atan2(y, x)`` of the
TCP). A Cartesian move to a yaw goes the nearest way round, unless that would carry joint 7 past half
a turn from mid-range, where its stop (2.90 rad) is; then the other way. This is the action layer's
mapping of a yaw target onto the arm (:class:`pickdemo.actions.Move`); which hand angle to take at
all is chosen by IK in the skill (joint-limit margin of every joint, not a rule of one).
"""

from __future__ import annotations

import numpy as np

from pickdemo.geometry import wrap_angle


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
