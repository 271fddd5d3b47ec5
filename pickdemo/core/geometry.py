"""Rigid poses that cross stage boundaries, with SE(3) maths delegated to Pinocchio.

Angles follow the paper: yaw ("trend") about world z, pitch about y, roll ("flip") about x, composed
as ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (Pinocchio's rpy convention).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class Pose:
    """A rigid transform: ``p_parent = rotation @ p_child + position`` (metres)."""

    position: np.ndarray  # (3,) m
    rotation: np.ndarray  # (3, 3)

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", _frozen(np.reshape(self.position, 3)))
        object.__setattr__(self, "rotation", _frozen(np.reshape(self.rotation, (3, 3))))

    @staticmethod
    def identity() -> Pose:
        return Pose(np.zeros(3), np.eye(3))

    @staticmethod
    def from_xyz_rpy(position: np.ndarray, *, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> Pose:
        """Build a pose from a position (m) and roll, pitch, yaw (rad)."""
        return Pose(np.asarray(position, dtype=float), pin.rpy.rpyToMatrix(roll, pitch, yaw))

    @staticmethod
    def from_se3(m: pin.SE3) -> Pose:
        return Pose(m.translation.copy(), m.rotation.copy())

    def to_se3(self) -> pin.SE3:
        return pin.SE3(np.array(self.rotation), np.array(self.position))

    def __matmul__(self, other: Pose) -> Pose:
        return Pose.from_se3(self.to_se3() * other.to_se3())

    def inverse(self) -> Pose:
        return Pose.from_se3(self.to_se3().inverse())

    def transform_points(self, points: np.ndarray) -> np.ndarray:
        """Map (N, 3) points from the child frame into the parent frame."""
        return np.asarray(points) @ self.rotation.T + self.position

    @property
    def rpy(self) -> np.ndarray:
        """(roll, pitch, yaw) in rad."""
        return pin.rpy.matrixToRpy(np.array(self.rotation))

    @property
    def quaternion_xyzw(self) -> np.ndarray:
        return pin.Quaternion(np.array(self.rotation)).coeffs().copy()

    @staticmethod
    def from_quaternion_xyzw(position: np.ndarray, quat_xyzw: np.ndarray) -> Pose:
        x, y, z, w = (float(v) for v in quat_xyzw)
        return Pose(np.asarray(position, dtype=float), pin.Quaternion(w, x, y, z).normalized().matrix())

    def to_dict(self) -> dict[str, list[float] | float]:
        roll, pitch, yaw = self.rpy
        return {
            "position_m": [float(v) for v in self.position],
            "yaw_deg": float(np.degrees(yaw)),
            "pitch_deg": float(np.degrees(pitch)),
            "roll_deg": float(np.degrees(roll)),
        }


def about_vertical(yaw: float) -> np.ndarray:
    """The rotation by ``yaw`` (rad) about the vertical."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def wrap_angle(angle_rad: float | np.ndarray, period_rad: float = 2.0 * np.pi) -> float | np.ndarray:
    """Wrap an angle into [-period/2, period/2)."""
    return (np.asarray(angle_rad) + period_rad / 2.0) % period_rad - period_rad / 2.0


#: Which of a box's 8 corners take the upper bound on each axis (x slowest, z fastest).
CORNER_IS_HI = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=bool)


@dataclass(frozen=True, eq=False)
class OrientedBox:
    """A box in the world: ``lo``..``hi`` (m) in the frame placed by ``pose`` (a robot link's
    collision geometry bounded in its own frame, say)."""

    pose: Pose
    lo: np.ndarray  # (3,) m, in the box's frame
    hi: np.ndarray  # (3,)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """Which of the (N, 3) world points lie inside it (NaN points do not)."""
        local = (np.asarray(points, dtype=float) - self.pose.position) @ self.pose.rotation
        return np.all((local >= self.lo) & (local <= self.hi), axis=-1)

    def corners(self) -> np.ndarray:
        """Its 8 corners in the world (8, 3)."""
        return self.pose.transform_points(np.where(CORNER_IS_HI, self.hi, self.lo))


def box_surface_points(boxes: tuple[OrientedBox, ...], spacing_m: float = 0.003) -> np.ndarray:
    """Points on the faces of ``boxes``, a grid ``spacing_m`` apart (M, 3) (a fixture as the grasps see
    an obstacle: as they see the points the camera showed near the target)."""
    out = []
    for box in boxes:
        size = box.hi - box.lo
        for axis in range(3):
            u, v = [a for a in range(3) if a != axis]
            nu, nv = (max(int(np.ceil(size[a] / spacing_m)), 1) + 1 for a in (u, v))
            gu, gv = np.meshgrid(np.linspace(box.lo[u], box.hi[u], nu), np.linspace(box.lo[v], box.hi[v], nv))
            for side in (box.lo[axis], box.hi[axis]):
                local = np.empty((gu.size, 3))
                local[:, u], local[:, v], local[:, axis] = gu.ravel(), gv.ravel(), side
                out.append(box.pose.transform_points(local))
    return np.vstack(out) if out else np.zeros((0, 3))


def _box_frames(boxes: tuple[OrientedBox, ...] | list[OrientedBox]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each box's centre in the world (N, 3), axes as columns (N, 3, 3) and half extents (N, 3)."""
    R = np.array([b.pose.rotation for b in boxes]).reshape(-1, 3, 3)
    mid = np.array([(b.lo + b.hi) / 2.0 for b in boxes]).reshape(-1, 3)
    centre = np.einsum("nij,nj->ni", R, mid) + np.array([b.pose.position for b in boxes]).reshape(-1, 3)
    half = np.array([(b.hi - b.lo) / 2.0 for b in boxes]).reshape(-1, 3)
    return centre, R, half


def boxes_meet(a: tuple[OrientedBox, ...] | list[OrientedBox], b: tuple[OrientedBox, ...] | list[OrientedBox]) -> bool:
    """Whether any box of ``a`` overlaps any box of ``b`` (the separating axis test over each pair's 15
    axes, every pair at once)."""
    return bool(meeting(a, b).any())


def meeting(
    a: tuple[OrientedBox, ...] | list[OrientedBox], b: tuple[OrientedBox, ...] | list[OrientedBox]
) -> np.ndarray:
    """(len(a),) bool: which boxes of ``a`` overlap a box of ``b`` (:func:`boxes_meet`, box by box)."""
    if not a or not b:
        return np.zeros(len(a), dtype=bool)
    ca, Ra, ha = _box_frames(a)
    cb, Rb, hb = _box_frames(b)
    A = Ra[:, None]  # (na, 1, 3, 3): columns are the axes
    B = Rb[None, :]
    edges = np.cross(A[:, :, :, :, None], B[:, :, :, None, :], axisa=2, axisb=2, axisc=2)  # (na, nb, 3, 3, 3)
    axes = np.concatenate(
        [np.broadcast_to(A, (len(a), len(b), 3, 3)), np.broadcast_to(B, (len(a), len(b), 3, 3)),
         edges.reshape(len(a), len(b), 3, 9)], axis=3,
    )  # fmt: skip  # (na, nb, 3, 15): each column an axis to test
    norm = np.linalg.norm(axes, axis=2, keepdims=True)
    axes = np.where(norm > 1e-9, axes / np.maximum(norm, 1e-12), 0.0)  # parallel edges: no axis
    d = cb[None, :, :] - ca[:, None, :]  # (na, nb, 3)
    dist = np.abs(np.einsum("abk,abkm->abm", d, axes))
    ra = np.einsum("ak,abkm->abm", ha, np.abs(np.einsum("aki,abkm->abim", Ra, axes)))
    rb = np.einsum("bk,abkm->abm", hb, np.abs(np.einsum("bki,abkm->abim", Rb, axes)))
    separated = (dist > ra + rb + 1e-12).any(axis=2)
    return (~separated).any(axis=1)


def top_below(boxes: tuple[OrientedBox, ...] | list[OrientedBox], x: float, y: float, z: float) -> float | None:
    """The highest point at or below ``z`` where a vertical line through (x, y) leaves one of the boxes
    upwards (the top of what stands under the point: a shelf's board), or None."""
    best = None
    for box in boxes:
        R, p = box.pose.rotation, box.pose.position
        o = R.T @ (np.array([x, y, 0.0]) - p)  # the line's point at z = 0, in the box's frame
        d = R.T @ np.array([0.0, 0.0, 1.0])
        lo_t, hi_t = -np.inf, np.inf
        for k in range(3):
            if abs(d[k]) < 1e-12:
                if not box.lo[k] <= o[k] <= box.hi[k]:
                    break
                continue
            t0, t1 = sorted(((box.lo[k] - o[k]) / d[k], (box.hi[k] - o[k]) / d[k]))
            lo_t, hi_t = max(lo_t, t0), min(hi_t, t1)
        else:
            if lo_t <= hi_t and hi_t <= z and (best is None or hi_t > best):
                best = float(hi_t)
    return best
