"""The methods the paper is compared with, on the same frames and segmentation as ``perception``.

Pure. Each takes an :class:`RGBDFrame` and the :class:`TargetModel` and returns a
:class:`PoseEstimate` with a covariance, or raises :class:`PerceptionError`:

- ``pixel``: the naive baseline: back-project the one pixel at the centre of the target's image
  region (eqs. 5-7), covariance from eq. (14); no orientation.
- ``centroid``: centroid of the target's top points and principal axes of its point cloud.
- ``icp``: point-to-plane ICP of the object's model (its analytic surface) against the target's
  point cloud, started from ``centroid`` (the class of the paper's refs. [4]-[6]).

None reads simulator state.
"""

from __future__ import annotations

import cv2
import numpy as np
import pinocchio as pin

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Box
from pickdemo.perception import (
    PerceptionError,
    PerceptionParams,
    PoseEstimate,
    TargetModel,
    closest_on_model,
    crop_frame,
    point_covariance,
    segment_target,
    target_roi,
    world_points,
)

NO_ORIENTATION = np.full((3, 3), np.inf)


def _segment(frame: RGBDFrame, model: TargetModel, params: PerceptionParams):
    x0, y0, x1, y1 = target_roi(frame, model, params)
    f = crop_frame(frame, x0, y0, x1, y1)
    pts = world_points(f)
    mask = segment_target(f, model, params, pts[..., 2])
    cloud = pts[mask]
    cloud = cloud[np.all(np.isfinite(cloud), axis=1)]
    if len(cloud) < 10:
        raise PerceptionError("too few depth readings on the target")
    return f, mask, cloud


def _estimate(pose: Pose, pos_cov: np.ndarray, rpy_cov: np.ndarray, model: TargetModel, n: int) -> PoseEstimate:
    return PoseEstimate(
        pose=pose,
        position_cov=pos_cov,
        rpy_cov=rpy_cov,
        yaw_symmetry_rad=model.geometry.yaw_symmetry_rad,
        top_face_size_m=(0.0, 0.0),
        n_features=0,
        n_face_pixels=n,
    )


def estimate_pixel(frame: RGBDFrame, model: TargetModel, params: PerceptionParams | None = None) -> PoseEstimate:
    """Back-project the pixel at the centre of the target's image region; the centre lies h/2 below."""
    params = params or PerceptionParams()
    f, mask, _ = _segment(frame, model, params)
    m = cv2.moments(mask.astype(np.uint8), binaryImage=True)
    u, v = int(round(m["m10"] / m["m00"])), int(round(m["m01"] / m["m00"]))
    z = float(f.depth_m[v, u])
    if not np.isfinite(z) or not mask[v, u]:
        raise PerceptionError("no depth at the target's centre pixel")
    K = f.intrinsics
    p_cam = np.array([z * (u - K.cx) / K.fx, z * (v - K.cy) / K.fy, z])
    p = f.T_world_cam.transform_points(p_cam[None])[0]
    R = f.T_world_cam.rotation
    cov = R @ point_covariance(u, v, z, float(f.depth_variance(z)), K.fx, K.fy, K.cx, K.cy) @ R.T
    centre = p - np.array([0.0, 0.0, model.height_m / 2.0])
    return _estimate(Pose(centre, np.eye(3)), cov, NO_ORIENTATION, model, int(mask.sum()))


def _centroid_pose(cloud: np.ndarray, model: TargetModel) -> tuple[Pose, np.ndarray, np.ndarray]:
    top_z = np.quantile(cloud[:, 2], 0.95)
    top = cloud[cloud[:, 2] > top_z - 0.004]
    c = top.mean(axis=0)
    # Principal axes of the whole cloud: the smallest is the normal of its flattest extent; the largest
    # horizontal one gives the yaw.
    w, V = np.linalg.eigh(np.cov((cloud - cloud.mean(axis=0)).T))
    k = int(np.argmax(np.abs(V[2])))  # the principal axis nearest the vertical is taken as the normal
    normal = V[:, k] if V[2, k] >= 0 else -V[:, k]
    w = np.array([w[k], *np.delete(w, k)])
    xy = top[:, :2] - top[:, :2].mean(axis=0)
    w2, V2 = np.linalg.eigh(np.cov(xy.T))
    major = V2[:, 1]
    yaw = float(np.arctan2(major[1], major[0]))
    shape = model.geometry
    if isinstance(shape, Box) and shape.size_m[1] > shape.size_m[0]:
        yaw += np.pi / 2.0  # the model's x axis is its shorter side
    x_axis = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    x_axis -= normal * (x_axis @ normal)
    x_axis /= np.linalg.norm(x_axis)
    R = np.column_stack([x_axis, np.cross(normal, x_axis), normal])
    centre = c - np.array([0.0, 0.0, model.height_m / 2.0])  # the naive assumption: it stands upright
    pos_cov = np.cov(top.T) / max(len(top), 1)
    spread = max(float(w[0]), 1e-12)
    tilt_var = spread / max(float(w[1]), 1e-12) / len(cloud)
    yaw_var = float(w2[0] / max(w2[1] - w2[0], 1e-12)) / len(top)
    return Pose(centre, R), pos_cov, np.diag([tilt_var, tilt_var, yaw_var])


def estimate_centroid(frame: RGBDFrame, model: TargetModel, params: PerceptionParams | None = None) -> PoseEstimate:
    """Centroid of the target's top points (h/2 below it, the centre) and the cloud's principal axes."""
    params = params or PerceptionParams()
    _, mask, cloud = _segment(frame, model, params)
    pose, pos_cov, rpy_cov = _centroid_pose(cloud, model)
    return _estimate(pose, pos_cov, rpy_cov, model, int(mask.sum()))


def icp_point_to_plane(
    cloud: np.ndarray, model: TargetModel, start: Pose, *, iterations: int = 40, trim_m: float = 0.01
) -> tuple[Pose, np.ndarray, int]:
    """Point-to-plane ICP of the model against a world-frame cloud; returns the pose, its 6x6
    covariance (twist in the world frame: v, w) and the number of points used at the end."""
    T = start.to_se3()
    used = 0
    info = np.eye(6)
    sigma2 = 1.0
    for _ in range(iterations):
        local = (cloud - T.translation) @ T.rotation
        q, n = closest_on_model(local, model)
        x = q @ T.rotation.T + T.translation  # closest model points, world frame
        nw = n @ T.rotation.T
        r = np.sum(nw * (cloud - x), axis=1)
        dist = np.linalg.norm(cloud - x, axis=1)
        keep = dist < trim_m
        if keep.sum() < 6:
            raise PerceptionError("ICP lost the target (too few points near the model)")
        used = int(keep.sum())
        J = np.hstack([-nw[keep], -np.cross(x[keep], nw[keep])])
        info = J.T @ J
        step = np.linalg.solve(info + 1e-12 * np.eye(6), -J.T @ r[keep])
        T = pin.exp6(pin.Motion(step[:3], step[3:])) * T
        sigma2 = float(np.sum(r[keep] ** 2)) / max(used - 6, 1)
        if np.linalg.norm(step) < 1e-9:
            break
    return Pose.from_se3(T), np.linalg.pinv(info) * sigma2, used


def estimate_icp(frame: RGBDFrame, model: TargetModel, params: PerceptionParams | None = None) -> PoseEstimate:
    """Point-to-plane ICP of the object's model against its cloud, started from the centroid method."""
    params = params or PerceptionParams()
    _, mask, cloud = _segment(frame, model, params)
    start, _, _ = _centroid_pose(cloud, model)
    pose, cov6, used = icp_point_to_plane(cloud, model, start)
    # Position covariance of the centre: the twist's translation about the world origin maps to the
    # centre as v + w x c; keep the leading terms.
    c = pose.position
    Jc = np.hstack([np.eye(3), -pin.skew(c)])
    pos_cov = Jc @ cov6 @ Jc.T
    rpy_cov = cov6[3:, 3:]
    return _estimate(pose, pos_cov, rpy_cov, model, used)


METHODS = {
    "pixel": estimate_pixel,
    "centroid": estimate_centroid,
    "icp": estimate_icp,
}
