"""Pose errors against the truth, fair to symmetric objects. Pure.

A cube looks the same after a quarter turn about its axis, a non-square box after a half turn, a
cylinder after any turn: the estimate is compared with the truth after the equivalent rotation that
brings it closest. Angle errors are then differences of yaw ("trend"), pitch and roll ("flip") as in
the paper (``R = Rz(yaw) Ry(pitch) Rx(roll)``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pickdemo.core.geometry import Pose, wrap_angle


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def closest_equivalent(estimated: np.ndarray, true: np.ndarray, symmetry_rad: float) -> np.ndarray:
    """The rotation ``estimated @ Rz(k * symmetry)`` nearest ``true`` (any angle when symmetry is 0)."""
    if symmetry_rad > 0.0:
        n = max(int(round(2.0 * np.pi / symmetry_rad)), 1)
        candidates = [estimated @ _rz(k * symmetry_rad) for k in range(n)]
    else:
        # Continuous symmetry about z: the best angle aligns the x axes seen in the object's plane.
        rel = estimated.T @ true
        a = np.arctan2(rel[1, 0] - rel[0, 1], rel[0, 0] + rel[1, 1])
        candidates = [estimated @ _rz(a)]
    return min(candidates, key=lambda Rc: np.linalg.norm(pin.log3(Rc.T @ true)))


def pose_errors(estimated: Pose, true: Pose, symmetry_rad: float, *, has_orientation: bool = True) -> dict:
    """Position error (3-D and per axis, mm) and yaw, pitch, roll errors (deg, absolute).

    Angles are None when the method gives no orientation; yaw is None for a rotationally symmetric
    object (a cylinder).
    """
    d = (estimated.position - true.position) * 1e3
    out: dict[str, float | None] = {
        "position_error_mm": float(np.linalg.norm(d)),
        "x_error_mm": float(abs(d[0])),
        "y_error_mm": float(abs(d[1])),
        "z_error_mm": float(abs(d[2])),
        "yaw_error_deg": None,
        "pitch_error_deg": None,
        "roll_error_deg": None,
        "rotation_error_deg": None,
    }
    if not has_orientation:
        return out
    R = closest_equivalent(np.asarray(estimated.rotation), np.asarray(true.rotation), symmetry_rad)
    est_rpy = pin.rpy.matrixToRpy(R)
    true_rpy = pin.rpy.matrixToRpy(np.asarray(true.rotation))
    diff = np.degrees(np.abs(wrap_angle(est_rpy - true_rpy)))
    out["roll_error_deg"] = float(diff[0])
    out["pitch_error_deg"] = float(diff[1])
    out["yaw_error_deg"] = float(diff[2]) if symmetry_rad > 0.0 else None
    out["rotation_error_deg"] = float(np.degrees(np.linalg.norm(pin.log3(R.T @ np.asarray(true.rotation)))))
    return out
