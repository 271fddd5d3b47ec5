"""Forward and inverse kinematics of a robot's arm joints with Pinocchio (damped least squares).

Pure: no simulator. The model is the same URDF that the simulator loads, with the two finger joints
locked (``buildReducedModel``). Joint limits are respected by projecting every iterate; when a solve
from the seed does not converge, it restarts from random configurations drawn with the caller's RNG.

The per-tick solve (:meth:`Kinematics.track`) may be given a posture: a pose of the hand leaves
the arm one degree of freedom (the elbow's swing), and damped least squares alone lets it drift along
a long line. Each tick then also steps in the task's null space (the motion that leaves the hand where
it is) towards the posture and away from any joint within :attr:`PostureParams.limit_zone_rad` of its
limit: a secondary task as in Siciliano's and Nakamura's redundancy resolution. Chosen over a QP
(pin-pink) by measurement (``tests/ik_bench.py``): faster a tick, as close to the line, and no new
dependency (evidence: docs/decisions.md#motion-and-ik).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickdemo.core.geometry import Pose
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.urdf_files import model_urdf


@dataclass(frozen=True)
class IKParams:
    """Solver settings; tolerances in m and rad."""

    max_iterations: int = 300
    tolerance_m: float = 1e-5
    tolerance_rad: float = 1e-4
    damping: float = 1e-6
    step: float = 1.0
    restarts: int = 8
    limit_margin_rad: float = 0.02  # stay this far inside the joint limits
    stall_iterations: int = 40  # a start whose error has not halved in this many steps is given up
    #: rad: the most a joint moves in one step (inf: a full Gauss-Newton step). A full step from far away
    #: may overshoot into a fold of the workspace (an arm with offset wrists, the UR5's, from its home to
    #: a spot low beside it); :meth:`Kinematics.solve` retries its starts with :data:`TRUST_STEP_RAD`.
    max_step_rad: float = math.inf

    def __post_init__(self) -> None:
        if (
            self.max_iterations < 1
            or self.restarts < 0
            or self.damping <= 0
            or not 0 < self.step <= 1
            or not self.max_step_rad > 0
        ):
            raise ValueError("invalid IK parameters")


@dataclass(frozen=True)
class IKResult:
    """The outcome of one IK solve. ``q`` is the best configuration found, even on failure."""

    success: bool
    q: np.ndarray  # (7,) rad
    position_error_m: float
    rotation_error_rad: float
    iterations: int
    restarts_used: int
    reason: str = ""


@dataclass(frozen=True)
class PostureParams:
    """The per-tick IK's secondary task, in the null space of the hand's pose (rad, per tick)."""

    gain: float = 0.02  # a tick pulls this share of the way to the posture (a 0.4 s time constant at 120 Hz)
    limit_zone_rad: float = 0.3  # joint-limit avoidance acts on a joint this close to a limit ...
    limit_step_rad: float = 0.002  # ... pushing it away up to this far a tick (at the limit; quadratic onset)

    def __post_init__(self) -> None:
        if not (0.0 <= self.gain < 1.0 and self.limit_zone_rad > 0.0 and self.limit_step_rad >= 0.0):
            raise ValueError("invalid posture parameters")


POSTURE = PostureParams()


def link_frame_id(model: pin.Model, link: str) -> int:
    """The frame of the URDF link ``link`` in ``model``, looked up by name and type: a URDF may name a
    joint as its child link (the Unitree Z1's fixed joint ``gripperStator``), and a lookup by bare
    name then finds two frames and raises. A ``KeyError`` if the model has no such link."""
    if not model.existFrame(link, pin.FrameType.BODY):
        raise KeyError(f"{link!r} is not a link of the model")
    return model.getFrameId(link, pin.FrameType.BODY)


def frame_id(model: pin.Model, name: str) -> int:
    """The frame of a link, or else of a joint, of this name (by name and type, as
    :func:`link_frame_id`): a camera's mount is a link, the wrist's sensor a joint. A joint's frame and
    its child link's are one placement, so a joint named as its child link finds the same pose."""
    for kind in (pin.FrameType.BODY, pin.FrameType.FIXED_JOINT, pin.FrameType.JOINT):
        if model.existFrame(name, kind):
            return model.getFrameId(name, kind)
    raise KeyError(f"{name!r} is not a link or a joint of the model")


class Kinematics:
    """Forward and inverse kinematics of a robot's TCP, on its own model reduced to its arm (its
    ``robot``: a :class:`~pickdemo.robot.description.RobotDescription`)."""

    def __init__(self, robot: RobotDescription) -> None:
        self.robot = robot
        urdf, renamed = model_urdf(robot.files())
        full = pin.buildModelFromUrdf(str(urdf))
        lock = [full.getJointId(renamed.get(n, n)) for n in robot.gripper.finger_joints]
        q_ref = pin.neutral(full)
        self.model = pin.buildReducedModel(full, lock, q_ref)
        self.data = self.model.createData()
        self.tcp_id = link_frame_id(self.model, robot.tcp_frame)
        revolute = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
        if self.model.nq != robot.dof or any(j.shortname() not in revolute for j in self.model.joints[1:]):
            raise RuntimeError(
                f"expected {robot.dof} revolute arm joints after locking the fingers (the solver steps q + v)"
            )
        self.lower = self.model.lowerPositionLimit.copy()
        self.upper = self.model.upperPositionLimit.copy()
        self._solver_constants: dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def forward(self, q: np.ndarray) -> Pose:
        """World pose of the TCP at configuration q (the robot's base is the world frame)."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return Pose.from_se3(self.data.oMf[self.tcp_id])

    def forward_se3(self, q: np.ndarray) -> pin.SE3:
        """:meth:`forward` as a ``pin.SE3`` (a copy), without a :class:`Pose`."""
        pin.framesForwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        return pin.SE3(self.data.oMf[self.tcp_id])

    def tcp_to_frame(self, name: str) -> Pose:
        """``T_tcp_frame`` of a frame fixed to the hand (a camera's mount, a link; the wrist's sensor, a
        joint): the same at any configuration."""
        pin.framesForwardKinematics(self.model, self.data, pin.neutral(self.model))
        return Pose.from_se3(self.data.oMf[self.tcp_id].actInv(self.data.oMf[frame_id(self.model, name)]))

    def manipulability(self, q: np.ndarray) -> float:
        """Yoshikawa's measure sqrt(det(J J^T)) of the TCP's Jacobian: near 0 close to a singularity."""
        J = pin.computeFrameJacobian(self.model, self.data, np.asarray(q, dtype=float), self.tcp_id, pin.LOCAL)
        return float(np.sqrt(max(np.linalg.det(J @ J.T), 0.0)))

    def limit_margin(self, q: np.ndarray) -> float:
        """How far (rad) the nearest joint is from its limit."""
        q = np.asarray(q, dtype=float)
        return float(np.min(np.minimum(q - self.lower, self.upper - q)))

    def within_limits(self, q: np.ndarray) -> bool:
        return bool(np.all(q >= self.lower - 1e-9) and np.all(q <= self.upper + 1e-9))

    def _posture_step(self, q: np.ndarray, q_ref: np.ndarray, params: PostureParams) -> np.ndarray:
        """The secondary task's joint step (before the null-space projection): towards ``q_ref``,
        and away from a joint limit within ``limit_zone_rad`` (zero outside it, growing as the square
        of the depth in it, so it sets in smoothly)."""
        zone = params.limit_zone_rad
        near_lo = np.maximum(zone - (q - self.lower), 0.0) / zone
        near_hi = np.maximum(zone - (self.upper - q), 0.0) / zone
        return params.gain * (q_ref - q) + params.limit_step_rad * (near_lo * near_lo - near_hi * near_hi)

    def _solve_from(
        self,
        target: pin.SE3,
        q0: np.ndarray,
        params: IKParams,
        q_ref: np.ndarray | None = None,
        posture: PostureParams = POSTURE,
    ) -> tuple[np.ndarray, float, float, int]:
        model, data = self.model, self.data
        key = (params.limit_margin_rad, params.damping)
        if key not in self._solver_constants:  # once per setting: this runs every control tick
            self._solver_constants[key] = (
                self.lower + params.limit_margin_rad,
                self.upper - params.limit_margin_rad,
                params.damping * np.eye(6),
            )
        lo, hi, reg = self._solver_constants[key]
        tcp, tol_m, tol_rad, step = self.tcp_id, params.tolerance_m, params.tolerance_rad, params.step
        # This runs every control tick: only the TCP's frame is placed (not all of the model's), and
        # each norm is taken once. np.minimum(np.maximum()) is np.clip without its dispatch cost.
        # A start that is stuck (a joint held at its limit, or no solution near) stops once its best
        # error has not halved in ``stall_iterations`` steps: Gauss-Newton converges much faster than
        # that when it converges at all (evidence: docs/decisions.md#speed).
        q = np.minimum(np.maximum(q0, lo), hi)
        e_pos = e_rot = 0.0
        stall = params.stall_iterations
        best = [math.inf]  # the best error up to each step
        rhs = np.empty((6, 2))
        for it in range(1, params.max_iterations + 1):
            pin.forwardKinematics(model, data, q)
            iMd = pin.updateFramePlacement(model, data, tcp).actInv(target)
            err = pin.log6(iMd).vector  # in the TCP frame
            e_pos, e_rot = math.sqrt(err[:3] @ err[:3]), math.sqrt(err[3:] @ err[3:])
            if e_pos < tol_m and e_rot < tol_rad:
                return q, e_pos, e_rot, it
            best.append(min(best[-1], e_pos + e_rot))
            if it > stall and best[it] > 0.5 * best[it - stall]:
                return q, e_pos, e_rot, it
            J = pin.computeFrameJacobian(model, data, q, tcp, pin.LOCAL)
            J = -pin.Jlog6(iMd.inverse()) @ J
            if q_ref is not None and it == 1:  # the posture's step, once a tick, in the task's null space
                g = self._posture_step(q, q_ref, posture)
                rhs[:, 0], rhs[:, 1] = err, J @ g
                y = np.linalg.solve(J @ J.T + reg, rhs)
                v = -J.T @ y[:, 0] + (g - J.T @ y[:, 1])
            else:
                v = -J.T @ np.linalg.solve(J @ J.T + reg, err)
            if params.max_step_rad != math.inf:
                v *= min(1.0, params.max_step_rad / max(float(np.max(np.abs(step * v))), 1e-12))
            # pin.integrate(model, q, v) is q + v for revolute joints (bit for bit)
            q = np.minimum(np.maximum(q + step * v, lo), hi)
        return q, e_pos, e_rot, params.max_iterations

    def track(
        self,
        target: Pose | pin.SE3,
        q_prev: np.ndarray,
        *,
        max_iterations: int = 4,
        posture: np.ndarray | None = None,
        posture_params: PostureParams = POSTURE,
    ) -> IKResult:
        """One warm-started solve per control tick: a few damped least-squares steps from the last
        command, no restarts (the target moved a millimetre or so since the last tick). ``posture``:
        the configuration the arm's free swing is pulled towards (and away from its joint limits), in
        the hand's null space; it acts while the hand moves (a target reached at the first step, the
        arm at rest, takes no step)."""
        params = (
            _TRACK_PARAMS
            if max_iterations == _TRACK_PARAMS.max_iterations
            else IKParams(restarts=0, max_iterations=max_iterations)
        )
        goal = target if isinstance(target, pin.SE3) else target.to_se3()
        q, e_pos, e_rot, its = self._solve_from(goal, np.asarray(q_prev, dtype=float), params, posture, posture_params)
        ok = e_pos < params.tolerance_m and e_rot < params.tolerance_rad
        reason = "" if ok else f"not converged in {its} steps ({e_pos * 1e3:.2f} mm, {np.degrees(e_rot):.3f} deg)"
        return IKResult(ok, q, e_pos, e_rot, its, 0, reason)

    def solve(
        self, target: Pose, q_seed: np.ndarray, rng: np.random.Generator, params: IKParams | None = None
    ) -> IKResult:
        """Joint angles that put the TCP at ``target``; restarts from random configurations if needed,
        and when none converges, the same starts again with steps of at most :data:`TRUST_STEP_RAD`
        (a trust region: slower, but it does not overshoot)."""
        params = params or IKParams()
        goal = target.to_se3()
        best: tuple[np.ndarray, float, float, int] | None = None
        starts = [np.asarray(q_seed, dtype=float)]
        trusted = dataclasses.replace(params, max_step_rad=min(params.max_step_rad, TRUST_STEP_RAD))
        passes = [params] if params.max_step_rad <= TRUST_STEP_RAD else [params, trusted]
        for attempt in range(len(passes) * (params.restarts + 1)):
            pass_params, i = passes[attempt // (params.restarts + 1)], attempt % (params.restarts + 1)
            if i >= len(starts):
                starts.append(rng.uniform(self.lower, self.upper))
            q, e_pos, e_rot, its = self._solve_from(goal, starts[i], pass_params)
            if best is None or e_pos + e_rot < best[1] + best[2]:
                best = (q, e_pos, e_rot, its)
            if e_pos < params.tolerance_m and e_rot < params.tolerance_rad:
                return IKResult(True, q, e_pos, e_rot, its, attempt)
        assert best is not None
        q, e_pos, e_rot, its = best
        return IKResult(
            False,
            q,
            e_pos,
            e_rot,
            its,
            params.restarts,
            reason=f"no solution within tolerance after {len(passes) * (params.restarts + 1)} starts "
            f"(best: {e_pos * 1e3:.1f} mm, {np.degrees(e_rot):.2f} deg)",
        )


_TRACK_PARAMS = IKParams(restarts=0, max_iterations=4)
#: rad: a step's largest joint motion when :meth:`Kinematics.solve` tries its starts again.
TRUST_STEP_RAD = 0.2


@functools.cache
def kinematics_of(robot: RobotDescription) -> Kinematics:
    """One shared, lazily built kinematics model per robot and process (loading the URDF costs a few ms)."""
    return Kinematics(robot)
