"""IK goals chosen, not taken: for a TCP pose (and its equivalents: a parallel gripper turned by
half a turn), several IK solutions, and of them the one a transfer should go to.

Pure: no simulator. A solution is kept if its nearest joint stays :attr:`GoalParams.min_margin_rad`
from its limit and the arm is not near a singularity there (manipulability above a floor); of those
(first those from which the straight line that follows, a descent or a lowering, can be tracked),
the one reached soonest from where the arm is (the largest joint travel over that joint's speed
limit: the time a synchronised transfer needs at its cruise). Without any kept, the one with the
most joint margin. A transfer whose path would take the hand down below both of its ends
(:func:`path_dip`) is avoided: another goal, or over the top (the skill's via).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose, wrap_angle
from pickdemo.motion.online import hand_se3
from pickdemo.robot.kinematics import IKParams, Kinematics


@dataclass(frozen=True)
class GoalParams:
    min_margin_rad: float = 0.15  # a goal this far from every joint limit, at least
    min_manipulability: float = 0.02  # ... and this far from a singularity (sqrt(det(J J^T)))
    starts: int = 4  # IK starts a pose: the arm's configuration, home, and random ones
    ik: IKParams = IKParams(restarts=0)
    line_steps: int = 24  # a straight line that follows the goal is checked at this many points
    line_speed_m_s: float = 0.1  # ... as the hand moves along it (the near-object limits)
    line_velocity_share: float = 0.8  # ... the joints it needs within this share of their speed limits
    min_line_speed_scale: float = 0.1  # a line slower than this share of the speed (near a singular posture): refused
    #: a straight carry keeps its joints this far inside their limits at every checked point: the per-tick
    #: IK walks it in finer steps and drifts off the checked path (evidence: docs/decisions.md#motion-and-ik)
    line_margin_rad: float = 0.1
    max_dip_m: float = 0.01  # a transfer's hand may pass at most this far below the lower of its two ends
    path_steps: int = 16  # ... checked at this many points of its path
    via_heights_m: tuple[float, ...] = (0.1, 0.2, 0.3)  # a transfer that would dip goes over the top: this much higher
    turn_step_rad: float = 0.1  # a Cartesian turn's path is walked by the per-tick IK in steps of this ...
    turn_step_m: float = 0.02  # ... and of this


@dataclass(frozen=True)
class Goal:
    q: np.ndarray  # (7,) rad
    pose: Pose  # the TCP pose it reaches (one of the equivalents asked for)
    index: int  # which of the equivalent poses
    margin_rad: float
    manipulability: float
    travel_s: float  # max |dq| / v_max over the joints: the transfer's length in time, roughly
    line_ok: bool = True  # the straight line that follows (a descent, a lowering) can be tracked from here
    dip_m: float = 0.0  # how far the transfer to it would take the hand below the lower of its two ends


def along_line(
    kin: Kinematics, q: np.ndarray, start: Pose, end: Pose, n: int, posture: np.ndarray | None = None
) -> Iterator[np.ndarray | None]:
    """The per-tick IK's joints at ``n`` points of the straight line from ``start`` (the arm at ``q``)
    to ``end`` (its orientation), each warm-started from the last and held to the posture at ``q`` (or
    ``posture``: the Cartesian motion's, where it is under way); ``None`` where it does not converge
    (and nothing after)."""
    q_prev = np.asarray(q, dtype=float)
    q_start = q_prev if posture is None else np.asarray(posture, dtype=float)
    for k in range(1, n + 1):
        p = start.position + (end.position - start.position) * (k / n)
        res = kin.track(Pose(p, end.rotation), q_prev, max_iterations=8, posture=q_start)
        if not res.success:
            yield None
            return
        yield res.q
        q_prev = res.q


def line_trackable(kin: Kinematics, q: np.ndarray, start: Pose, end: Pose, params: GoalParams = GoalParams()) -> bool:
    """Whether the per-tick IK can follow the straight line from ``start`` (where the arm is at ``q``)
    to ``end`` (same orientation): converging at every point with joint speeds within a share of
    their limits at the line's speed. (That is the test of a singular posture that matters: a floor on
    manipulability alone turns down lines the joints follow at full speed; evidence:
    docs/decisions.md#motion-and-ik.)"""
    n = params.line_steps
    dt = float(np.linalg.norm(end.position - start.position)) / params.line_speed_m_s / n
    q_prev = np.asarray(q, dtype=float)
    for q_k in along_line(kin, q, start, end, n):
        if q_k is None:
            return False
        v_max = params.line_velocity_share * kin.robot.limits.max_velocity_rad_s
        if dt > 0 and np.any(np.abs(q_k - q_prev) / dt > v_max):
            return False
        q_prev = q_k
    return kin.limit_margin(q_prev) > 0.0


def _line_rates(
    kin: Kinematics, q: np.ndarray, start: Pose, end: Pose, params: GoalParams
) -> Iterator[tuple[np.ndarray, float] | None]:
    """Along the straight line from ``start`` (the arm at ``q``) to ``end``, at each of ``line_steps``
    points: the per-tick IK's joints and the largest joint rate per metre of the line, as a share of
    its speed limit (``line_velocity_share`` of it); ``None`` where the IK does not converge (and
    nothing after)."""
    n = params.line_steps
    length = float(np.linalg.norm(end.position - start.position))
    v_max = params.line_velocity_share * kin.robot.limits.max_velocity_rad_s
    q_prev = np.asarray(q, dtype=float)
    for q_k in along_line(kin, q, start, end, n):
        if q_k is None:
            yield None
            return
        yield q_k, (float(np.max(np.abs(q_k - q_prev) / (length / n) / v_max)) if length > 0 else 0.0)
        q_prev = q_k


def line_speed_scale(
    kin: Kinematics, q: np.ndarray, start: Pose, end: Pose, params: GoalParams = GoalParams()
) -> float:
    """The share of the near-object speed (``params.line_speed_m_s``) at which the per-tick IK can
    follow the straight line from ``start`` (the arm at ``q``) to ``end`` with every joint within
    ``line_velocity_share`` of its speed limit: 1.0 when the full speed will do, less near a singular
    posture (where the joints turn fast for a small move of the hand), 0.0 when the IK does not converge
    along it or it ends beyond a joint limit."""
    q_last = np.asarray(q, dtype=float)
    worst = 0.0  # the largest joint rate per metre of the line, as a share of its speed limit
    for point in _line_rates(kin, q, start, end, params):
        if point is None:
            return 0.0
        q_last, rate = point
        worst = max(worst, rate)
    if kin.limit_margin(q_last) <= 0.0:
        return 0.0
    return 1.0 if worst * params.line_speed_m_s <= 1.0 else 1.0 / (worst * params.line_speed_m_s)


def line_followed(kin: Kinematics, q: np.ndarray, start: Pose, end: Pose, params: GoalParams = GoalParams()) -> bool:
    """Whether the per-tick IK follows the straight line from ``start`` (the arm at ``q``) to ``end`` at
    ``min_line_speed_scale`` of the near-object speed at least (slower, near a singular posture: refused)."""
    return line_speed_scale(kin, q, start, end, params) >= params.min_line_speed_scale


def line_reach(kin: Kinematics, q: np.ndarray, start: Pose, end: Pose, params: GoalParams = GoalParams()) -> float:
    """How far along the straight line from ``start`` (the arm at ``q``) to ``end`` (a share, 0 to 1) the
    per-tick IK follows it, converging at each of ``line_steps`` points with its joints fast enough for
    ``min_line_speed_scale`` of the near-object speed (:func:`line_speed_scale`'s test, point by point)."""
    reached = 0.0
    for k, point in enumerate(_line_rates(kin, q, start, end, params), start=1):
        if point is None or point[1] * params.line_speed_m_s * params.min_line_speed_scale > 1.0:
            break
        reached = k / params.line_steps
    return reached


def straight_carry_ok(
    kin: Kinematics,
    q: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    place: Pose,
    *,
    speed_m_s: float,
    posture: np.ndarray,
    params: GoalParams = GoalParams(),
    frame: np.ndarray | None = None,
) -> bool:
    """Whether the per-tick IK, from the arm at ``q`` with its TCP at ``start`` (x, y, z, yaw; the hand's
    orientation at yaw 0 ``frame``, None: pointing down), can carry the hand along the straight line to
    ``end`` at ``speed_m_s`` on the branch it is on:
    converging at ``line_steps`` points with its joints within ``line_velocity_share`` of their speed
    limits and ``line_margin_rad`` inside their position limits, and arriving where it can follow the
    lowering onto ``place``."""

    start, end = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    n = params.line_steps
    step_s = float(np.linalg.norm(end[:3] - start[:3])) / n / speed_m_s
    max_step = params.line_velocity_share * kin.robot.limits.max_velocity_rad_s * step_s
    q = np.asarray(q, dtype=float)
    for k in range(1, n + 1):
        res = kin.track(hand_se3(start + (end - start) * (k / n), frame), q, max_iterations=8, posture=posture)
        if not res.success or np.any(np.abs(res.q - q) > max_step):
            return False
        if kin.limit_margin(res.q) < params.line_margin_rad:
            return False
        q = res.q
    return line_followed(kin, q, kin.forward(q), place, params)


def path_dip(kin: Kinematics, q_from: np.ndarray, q_to: np.ndarray, params: GoalParams = GoalParams()) -> float:
    """How far (m) the hand (its TCP) passes below the lower of its two ends on a transfer from
    ``q_from`` to ``q_to`` (0 if never). A transfer from rest to rest with Ruckig's phase
    synchronisation follows the straight line in joint space, and that line can swing the hand down
    through the table and whatever stands on it (evidence: docs/decisions.md#motion-and-ik)."""
    z_from = kin.forward(np.asarray(q_from, dtype=float)).position[2]
    z_to = kin.forward(np.asarray(q_to, dtype=float)).position[2]
    return max(0.0, float(min(z_from, z_to) - path_low_z(kin, q_from, q_to, params)))


def path_low_z(kin: Kinematics, q_from: np.ndarray, q_to: np.ndarray, params: GoalParams = GoalParams()) -> float:
    """The lowest height (m) of the hand's TCP inside the straight joint-space path from ``q_from``
    to ``q_to`` (at ``params.path_steps`` points)."""
    q_from, q_to = np.asarray(q_from, dtype=float), np.asarray(q_to, dtype=float)
    n = params.path_steps
    return float(min(kin.forward(q_from + (q_to - q_from) * (k / n)).position[2] for k in range(1, n)))


def goal_candidates(
    kin: Kinematics,
    poses: Sequence[Pose],
    q_from: np.ndarray,
    rng: np.random.Generator,
    params: GoalParams = GoalParams(),
    *,
    lines_to: Sequence[Pose] | None = None,
) -> list[Goal]:
    """Every distinct IK solution found for each of ``poses`` (equivalent TCP poses), from the arm's
    configuration, home, and random starts. ``lines_to``: for each pose, where the straight line that
    follows it ends (a descent's grasp, a lowering's place): a goal from which it cannot be tracked is
    marked so."""

    def goal(q: np.ndarray, i: int) -> Goal:
        travel = float(np.max(np.abs(q - q_from) / kin.robot.limits.max_velocity_rad_s))
        line_ok = lines_to is None or line_trackable(kin, q, poses[i], lines_to[i], params)
        dip = path_dip(kin, q_from, q, params)
        return Goal(q, poses[i], i, kin.limit_margin(q), kin.manipulability(q), travel, line_ok, dip)

    out: list[Goal] = []
    for i, pose in enumerate(poses):
        seeds = [np.asarray(q_from, dtype=float), kin.robot.home_q]
        seeds += [rng.uniform(kin.lower, kin.upper) for _ in range(max(params.starts - 2, 0))]
        found: list[np.ndarray] = []
        for seed in seeds:
            res = kin.solve(pose, seed, rng, params.ik)
            if res.success and not any(np.max(np.abs(res.q - q)) < 1e-2 for q in found):
                found.append(res.q)
                out.append(goal(res.q, i))
    if not out:  # none from those starts: the solver's own random restarts, before saying there is none
        for i, pose in enumerate(poses):
            res = kin.solve(pose, q_from, rng, IKParams())
            if res.success:
                out.append(goal(res.q, i))
    return out


def choose_goal(goals: Sequence[Goal], params: GoalParams = GoalParams()) -> Goal | None:
    """The goal a transfer should go to (None: no solution at all): first those from which the line
    that follows can be tracked, then those the transfer reaches without dipping."""
    if not goals:
        return None
    goals = [g for g in goals if g.line_ok] or list(goals)  # the line that follows first
    goals = [g for g in goals if g.dip_m <= params.max_dip_m] or goals  # ... then no dip on the way
    kept = [g for g in goals if g.margin_rad >= params.min_margin_rad and g.manipulability >= params.min_manipulability]
    if kept:
        return min(kept, key=lambda g: (g.travel_s, -g.margin_rad))
    return max(goals, key=lambda g: g.margin_rad)


def turn_path(
    kin: Kinematics,
    q: np.ndarray,
    start_x4: np.ndarray,
    end_x4: np.ndarray,
    params: GoalParams = GoalParams(),
    frame: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """The per-tick IK walked along a Cartesian motion from ``start_x4`` (the arm at ``q``) to
    ``end_x4`` (x, y, z and the hand's yaw, unwrapped: 3 rad is not -3.28 rad), as the motion will
    follow it (a phase-synchronised Ruckig move is the straight line between them in x, y, z, yaw):
    the joints it ends in, and the least joint-limit margin (rad) on the way; ``-inf`` if the IK
    loses the path (a joint held at its stop). Which of a pose's IK solutions the arm ends in
    depends on the way round; every joint counts, not one joint's rule. ``frame``: the hand's
    orientation at yaw 0 (None: pointing down)."""

    start, end = np.asarray(start_x4, dtype=float), np.asarray(end_x4, dtype=float)
    d = end - start
    n = int(
        min(max(np.ceil(abs(d[3]) / params.turn_step_rad), np.ceil(np.linalg.norm(d[:3]) / params.turn_step_m), 1), 64)
    )
    q_prev = q_start = np.asarray(q, dtype=float)
    margin = kin.limit_margin(q_start)
    for k in range(1, n + 1):
        res = kin.track(hand_se3(start + d * (k / n), frame), q_prev, max_iterations=8, posture=q_start)
        if not res.success:
            return res.q, -np.inf
        q_prev = res.q
        margin = min(margin, kin.limit_margin(q_prev))
    return q_prev, margin


def way_round(
    kin: Kinematics,
    q: np.ndarray,
    setpoint: np.ndarray,
    x4: np.ndarray,
    params: GoalParams = GoalParams(),
    frame: np.ndarray | None = None,
) -> np.ndarray:
    """``x4`` (x, y, z, yaw) with its yaw unwrapped to the way round a Cartesian turn of the hand
    should go from ``setpoint`` (the arm at ``q``): the nearer way, unless on its path
    (:func:`turn_path`) a joint would come within ``min_margin_rad`` of a limit (or lose the path)
    and on the other way's it would keep further from them. A turn of near half a revolution can run
    a joint into its stop the nearer way."""
    x4 = np.array(x4, dtype=float)
    d = float(wrap_angle(x4[3] - setpoint[3]))
    x4[3] = setpoint[3] + d
    if abs(d) < params.turn_step_rad:  # a small turn: the other way is a whole revolution
        return x4
    _, margin_near = turn_path(kin, q, setpoint, x4, params, frame)
    if margin_near >= params.min_margin_rad:
        return x4
    other = x4.copy()
    other[3] -= 2.0 * np.pi * np.sign(d)
    _, margin_other = turn_path(kin, q, setpoint, other, params, frame)
    return other if margin_other > margin_near else x4
