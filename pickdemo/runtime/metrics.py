"""Scoring an episode against the truth. Pure: poses and numbers in, scores out.

The simulator's true poses reach this module and the labels only, never the controller.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.result import PerceptionScore
from pickdemo.core.shapes import Mesh, Shape
from pickdemo.perception import PoseEstimate
from pickdemo.runtime.evaluation import pose_errors


def seen_truth(truth: Pose, shape: Shape) -> Pose:
    """What an estimate is scored against: the true pose, a mesh's moved to its centre as it rests
    (:meth:`~pickdemo.core.shapes.Mesh.centre_turned`), which an object nobody described is seen by."""
    if not isinstance(shape, Mesh):
        return truth
    return Pose(truth.transform_points(shape.centre_turned(truth.rotation)[None, :])[0], truth.rotation)


def position_nees(estimate: PoseEstimate, true: Pose) -> float:
    """Normalised estimation error squared of the 3-D position (expected value 3 when honest)."""
    e = estimate.pose.position - true.position
    return float(e @ np.linalg.solve(estimate.position_cov, e))


def score_perception(estimate: PoseEstimate, true: Pose, *, oriented: bool = True) -> PerceptionScore:
    """``oriented``: whether the estimate's orientation is the body's (not an unknown object's
    principal axes, which are no axis of its file's body frame)."""
    errors = pose_errors(estimate.pose, true, estimate.yaw_symmetry_rad, has_orientation=oriented)
    return PerceptionScore(
        estimated_pose=estimate.to_dict(),
        true_pose=true.to_dict(),
        position_error_mm=errors["position_error_mm"],
        yaw_error_deg=errors["yaw_error_deg"],
        position_nees=position_nees(estimate, true),
    )


@dataclass(frozen=True)
class PlaceOutcome:
    lifted_m: float  # how far the target rose above its start at most
    place_error_m: float  # horizontal distance of its final centre from the place position
    upright: bool  # ended on its base (tilt below 10 deg, centre at its resting height)
    at_rest: bool
    success: bool
    reason: str  # why it failed, or ""


def score_place(
    *,
    start: Pose,
    max_z_m: float,
    final: Pose,
    final_speed_m_s: float,
    place_xy: tuple[float, float],
    shape: Shape,
    lift_height_m: float,
    place_tolerance_m: float,
    upright_required: bool = True,
) -> PlaceOutcome:
    """Success: rose at least ``lift_height_m``, ended within tolerance of the place position, upright
    (when ``upright_required``) and at rest. Upright: on the face it stood on, or one the same height
    (a cube on any face) with that face within 10 deg of level; a cylinder on a cap, or on its side if
    it started so; a mesh with its body z within 10 deg of the vertical, resting on the table.

    ``shape``: the target's :class:`~pickdemo.core.shapes.Shape`."""
    height_m = float(shape.height_m)
    lifted = max_z_m - float(start.position[2])
    # A mesh's centre: the middle of its footprint as it ended (its file's origin and its centre of mass
    # may lie anywhere).
    centre = seen_truth(final, shape).position
    err = float(np.hypot(centre[0] - place_xy[0], centre[1] - place_xy[1]))
    tilt, extent = shape.resting_face(final.rotation)
    if isinstance(shape, Mesh):  # its centre of mass at the height it rests at, turned as it ended
        upright = tilt < 10.0 and abs(float(final.position[2]) - shape.resting_height_m(final.rotation)) < 0.01
    else:  # as it started: standing on a face as tall (a cylinder lying on its side, lying)
        start_tilt, _ = shape.resting_face(start.rotation)
        rest_z = height_m / 2.0 if start_tilt < 10.0 else shape.resting_height_m(start.rotation)
        upright = (
            abs(tilt - start_tilt) < 10.0
            and abs(extent - height_m) < 2e-3
            and abs(float(final.position[2]) - rest_z) < 0.01
        )
    at_rest = final_speed_m_s < 0.01
    reason = ""
    if lifted < lift_height_m:
        reason = f"target rose {lifted * 1e3:.1f} mm, less than {lift_height_m * 1e3:.0f} mm"
    elif err > place_tolerance_m:
        reason = f"target ended {err * 1e3:.1f} mm from the place position (tolerance {place_tolerance_m * 1e3:.0f} mm)"
    elif upright_required and not upright:
        reason = (
            f"target did not end upright on the table (resting face tilted {tilt:.1f} deg, "
            f"{extent * 1e3:.0f} mm tall against {height_m * 1e3:.0f} mm, z {final.position[2] * 1e3:.1f} mm)"
        )
    elif not at_rest:
        reason = f"target still moving at {final_speed_m_s:.3f} m/s"
    return PlaceOutcome(lifted, err, upright, at_rest, reason == "", reason)
