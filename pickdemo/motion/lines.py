"""A straight line of the hand's as a joint path: the joints solved along it (as MoveIt's Cartesian
paths), joined into as few straight legs in joint space as keep the hand to the line. A transfer from
rest to rest keeps to its straight line in joint space, so such a path is run by the joint transfers,
where the per-tick IK loses a tilted line near the arm's joint limits (a grasp from the side in a
shelf's bin). Pure: no simulator.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from pickdemo.core.geometry import Pose, about_vertical
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


#: A carry keeps what the hand holds at its attitude: the way down, in the hand's frame, within this
#: of where it was (rad). Held off its centre from the side, an item turns in the fingers as the
#: hand tilts under it (a shelf's items carried in joint space turned 7-35 deg, and fell over at the place).
UPRIGHT_RAD = float(np.radians(3.0))
#: ... and the TCP within this of the carry's path (m; what it passes is the collision check's to say).
CARRY_PATH_M = 0.02
#: A carry's path is solved every this far along it (m) ...
CARRY_STEP_M = 0.01
#: ... or, a transfer in joint space, every this far along it (rad, the joint that moves most).
CARRY_STEP_RAD = 0.02


def around_the_base(start: Pose, end: Pose, rise_m: float = 0.0, step_m: float = CARRY_STEP_M) -> list[Pose] | None:
    """The hand's way from ``start`` to ``end`` about the robot's base (the vertical through the world's
    origin: the base's frame), keeping its attitude: the bearing, the distance from the base and the
    height each go evenly (the height ``rise_m`` higher at the middle, a half sine), and the hand turns
    about the vertical with the bearing, by ``end``'s turn from ``start``. The poses after ``start``, the
    last ``end``, about ``step_m`` apart; None where ``end`` is not ``start`` turned about the vertical
    (within the per-tick IK's :data:`~pickdemo.motion.online.LOST_RAD`)."""
    turn = end.rotation @ start.rotation.T
    if turn[2, 2] < np.cos(LOST_RAD):
        return None
    yaw = float(np.arctan2(turn[1, 0], turn[0, 0]))
    (x0, y0, z0), (x1, y1, z1) = start.position, end.position
    r0, r1 = float(np.hypot(x0, y0)), float(np.hypot(x1, y1))
    b0 = float(np.arctan2(y0, x0))
    db = float(np.angle(np.exp(1j * (np.arctan2(y1, x1) - b0))))  # (the shorter way round)
    length = 0.5 * (r0 + r1) * abs(db) + abs(r1 - r0) + abs(z1 - z0) + 2.0 * abs(rise_m)
    n = max(2, int(np.ceil(length / step_m)))
    poses = []
    for t in np.arange(1, n + 1) / n:
        r, b = r0 + (r1 - r0) * t, b0 + db * t
        z = z0 + (z1 - z0) * t + rise_m * float(np.sin(np.pi * t))
        poses.append(Pose(np.array([r * np.cos(b), r * np.sin(b), z]), about_vertical(yaw * t) @ start.rotation))
    poses[-1] = end
    return poses


def carry_in_joints(
    kin: Kinematics,
    q_from: np.ndarray,
    poses: list[Pose],
    clear: Callable[[np.ndarray], bool] | None = None,
    q_to: np.ndarray | None = None,
) -> np.ndarray | None:
    """A carry along ``poses`` (dense, from :func:`around_the_base`) as a joint path: its waypoints
    (K, dof) after ``q_from``, each leg's straight joint path keeping what the hand holds at its attitude
    (:data:`UPRIGHT_RAD`), the TCP within :data:`CARRY_PATH_M` of the poses' path, and ``clear``; None
    where the per-tick IK would lose the path or the arm would not keep clear on it. The joints are
    solved along it warm-started (as :func:`line_in_joints`), drawn in the arm's free swing from
    ``q_from``'s posture towards ``q_to``'s (an IK goal at the last pose, from which what follows can be
    followed: the path then ends there), then joined into as few legs as keep so."""
    qs = [np.asarray(q_from, dtype=float)]
    for k, pose in enumerate(poses, start=1):
        posture = qs[0] if q_to is None else qs[0] + (q_to - qs[0]) * (k / len(poses))
        res = kin.track(pose, qs[-1], max_iterations=8, posture=posture)
        if not res.success and (res.position_error_m > LOST_M or res.rotation_error_rad > LOST_RAD):
            return None
        if clear is not None and not clear(res.q):
            return None
        qs.append(res.q)
    if q_to is not None:
        qs.append(np.asarray(q_to, dtype=float))
    return _upright_legs(kin, qs, clear)


def upright_in_joints(
    kin: Kinematics,
    q_from: np.ndarray,
    q_to: np.ndarray,
    clear: Callable[[np.ndarray], bool] | None = None,
    via: Sequence[np.ndarray] = (),
) -> np.ndarray | None:
    """A transfer in joint space from ``q_from`` to ``q_to`` (the TCP at the same attitude at both, turned
    about the vertical), through ``via`` (a path planned around what is in the way), keeping what the
    hand holds at its attitude: the straight joint path, each point every :data:`CARRY_STEP_RAD` moved by
    the IK to the nearest pose at the attitude (the TCP where the point puts it, the hand turned about
    the vertical as the point turns it), then joined into as few legs as keep so (as
    :func:`carry_in_joints`); None where the IK cannot hold the attitude near a point, or the arm would
    not keep ``clear``. Where the arm must change its posture on the way (a shelf's bin reached with the
    elbow turned over), a way about the base at one posture cannot."""
    corners = [np.asarray(q, dtype=float) for q in (q_from, *via, q_to)]
    start = kin.forward(corners[0]).rotation
    heading0 = float(np.arctan2(start[1, 2], start[0, 2]))
    qs = [corners[0]]
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        n = max(2, int(np.ceil(float(np.max(np.abs(b - a))) / CARRY_STEP_RAD)))
        for k in range(1, n + 1):
            q_t = a + (b - a) * (k / n)
            if k == n and b is corners[-1]:
                break  # (the goal is at the attitude)
            at = kin.forward(q_t)
            turn = float(np.arctan2(at.rotation[1, 2], at.rotation[0, 2])) - heading0
            res = kin.track(Pose(at.position, about_vertical(turn) @ start), qs[-1], max_iterations=20, posture=q_t)
            if res.rotation_error_rad > UPRIGHT_RAD / 2.0 or res.position_error_m > CARRY_PATH_M / 4.0:
                return None
            if clear is not None and not clear(res.q):
                return None
            qs.append(res.q)
    qs.append(corners[-1])
    return _upright_legs(kin, qs, clear)


def _upright_legs(
    kin: Kinematics, qs: list[np.ndarray], clear: Callable[[np.ndarray], bool] | None
) -> np.ndarray | None:
    """The joints ``qs`` along a carry (the first where the arm is) joined into as few legs as keep what
    the hand holds at its attitude, the TCP within :data:`CARRY_PATH_M` of their path, and ``clear``:
    the legs' ends (K, dof) after the first; None where even one step does not."""
    down = np.array([0.0, 0.0, -1.0])
    down_in_hand = kin.forward(qs[0]).rotation.T @ down
    path = np.array([kin.forward(q).position for q in qs])
    ts = np.linspace(0.0, 1.0, 11)[1:-1]

    def leg_ok(i: int, j: int) -> bool:
        on_leg = [qs[i] + (qs[j] - qs[i]) * t for t in ts]
        for q in on_leg:
            at = kin.forward(q)
            if float(np.arccos(np.clip((at.rotation.T @ down) @ down_in_hand, -1.0, 1.0))) > UPRIGHT_RAD:
                return False
            if _from_polyline(at.position, path[i : j + 1]) > CARRY_PATH_M:
                return False
        return clear is None or all(clear(q) for q in on_leg)

    out, i, n = [], 0, len(qs) - 1
    while i < n:  # (each leg as long as it keeps so: doubled while it does, then halved back)
        if not leg_ok(i, i + 1):
            return None
        good, step = i + 1, 1
        while good < n:
            j = min(i + 2 * step, n)
            if not leg_ok(i, j):
                bad = j
                while bad - good > 1:
                    mid = (good + bad) // 2
                    good, bad = (mid, bad) if leg_ok(i, mid) else (good, mid)
                break
            good, step = j, 2 * step
        out.append(qs[good])
        i = good
    return np.array(out)


def _from_polyline(p: np.ndarray, pts: np.ndarray) -> float:
    """How far (m) ``p`` is from the polyline through ``pts`` (N, 3)."""
    a, b = pts[:-1], pts[1:]
    ab = b - a
    length2 = np.einsum("ij,ij->i", ab, ab)
    s = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.where(length2 > 0.0, length2, 1.0), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + s[:, None] * ab - p, axis=1)))
