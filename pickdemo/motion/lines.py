"""A straight line of the hand's as a joint path: the joints solved along it (as MoveIt's Cartesian
paths), joined into as few straight legs in joint space as keep the hand to the line. A transfer from
rest to rest keeps to its straight line in joint space, so such a path is run by the joint transfers,
where the per-tick IK loses a tilted line near the arm's joint limits (a grasp from the side in a
shelf's bin). Pure: no simulator.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.motion.online import LOST_M, LOST_RAD
from pickdemo.robot.kinematics import IKParams, Kinematics

#: Each leg keeps the TCP this close to the line (m) ...
JOINT_LINE_M = 0.003
#: ... and its orientation this close to the line's (rad).
JOINT_LINE_RAD = float(np.radians(3.0))
#: The line's joints are solved every this far along it (m).
JOINT_LINE_STEP_M = 0.01


def line_in_joints(
    kin: Kinematics,
    q_from: np.ndarray,
    pose: Pose,
    rng: np.random.Generator,
    ik: IKParams,
    *,
    partial: bool = False,
    clear: Callable[[np.ndarray], bool] | None = None,
) -> np.ndarray | None:
    """The joints of a straight line of the hand's (a grasp from the side's way in, its descent, its
    lift and way out: the per-tick IK loses tilted lines near the arm's joint limits, as in a shelf's
    bin) as a joint path: its waypoints (K, dof) after ``q_from``, each leg's straight joint path
    keeping the TCP within :data:`JOINT_LINE_M` of the line and its orientation within
    :data:`JOINT_LINE_RAD` of ``pose``'s; or None. One leg to the IK goal on ``q_from``'s branch where
    it keeps so; else the line's joints every :data:`JOINT_LINE_STEP_M` (the IK warm-started from
    the last, as MoveIt's Cartesian paths), joined into as few legs as keep so. ``partial``: where the
    arm cannot follow the whole line, the path as far along it as it can (None: not a step). ``clear(q)``:
    whether the arm keeps clear there; the line ends before where it does not (as ``partial``)."""
    a, b = kin.forward(q_from).position, pose.position
    res = kin.solve(pose, q_from, rng, ik)
    if res.success and _keeps_to(kin, q_from, res.q, a, b, pose.rotation):
        if clear is None or all(clear(q_from + (res.q - q_from) * t) for t in np.linspace(0.0, 1.0, 11)[1:]):
            return res.q[None, :]
    n = max(2, int(np.ceil(float(np.linalg.norm(b - a)) / JOINT_LINE_STEP_M)))
    qs = [np.asarray(q_from, dtype=float)]
    for k in range(1, n + 1):  # (held to the start's posture; lost as the per-tick IK would lose it)
        res = kin.track(Pose(a + (b - a) * (k / n), pose.rotation), qs[-1], max_iterations=8, posture=qs[0])
        lost = not res.success and (res.position_error_m > LOST_M or res.rotation_error_rad > LOST_RAD)
        if lost or (clear is not None and not clear(res.q)):
            if not (partial or clear is not None) or k == 1:
                return None
            b, n = kin.forward(qs[-1]).position, k - 1  # (the line as far as it was followed)
            break
        qs.append(res.q)

    def leg_ok(qa: np.ndarray, qb: np.ndarray) -> bool:
        keeps = _keeps_to(kin, qa, qb, a, b, pose.rotation)
        return keeps and (clear is None or all(clear(qa + (qb - qa) * t) for t in np.linspace(0.0, 1.0, 11)[1:-1]))

    out, i = [], 0
    while i < n:  # (the farthest point each leg can go to and keep to the line, and clear)
        j = next((j for j in range(n, i + 1, -1) if leg_ok(qs[i], qs[j])), i + 1)
        if j == i + 1 and not leg_ok(qs[i], qs[j]):
            return None
        out.append(qs[j])
        i = j
    return np.array(out)


def _keeps_to(
    kin: Kinematics, qa: np.ndarray, qb: np.ndarray, a: np.ndarray, b: np.ndarray, rotation: np.ndarray
) -> bool:
    """Whether the straight joint path from ``qa`` to ``qb`` keeps the TCP within :data:`JOINT_LINE_M`
    of the line from ``a`` to ``b``, and its orientation within :data:`JOINT_LINE_RAD` of ``rotation``."""
    ab = b - a
    length2 = float(ab @ ab)
    for t in np.linspace(0.0, 1.0, 11)[1:-1]:
        at = kin.forward(qa + (qb - qa) * t)
        s = 0.0 if length2 == 0.0 else float(np.clip((at.position - a) @ ab / length2, 0.0, 1.0))
        off = float(np.linalg.norm(at.position - (a + s * ab)))
        turn = np.arccos(np.clip((np.trace(at.rotation.T @ rotation) - 1.0) / 2.0, -1.0, 1.0))
        if off > JOINT_LINE_M or turn > JOINT_LINE_RAD:
            return False
    return True


def rise_followed(kin: Kinematics, q: np.ndarray, lift: Pose, rng: np.random.Generator, ik: IKParams) -> float:
    """How high (m) the arm at ``q`` can follow the straight lift to ``lift`` (0: not a step; the
    whole rise where it follows all of it), each step as :func:`line_in_joints`."""
    z0 = kin.forward(q).position[2]
    waypoints = line_in_joints(kin, q, lift, rng, ik, partial=True)
    return 0.0 if waypoints is None else float(kin.forward(waypoints[-1]).position[2] - z0)
