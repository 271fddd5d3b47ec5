"""A pose estimator of your own, in pickdemo's loop (the example of docs/extending.md).

    cd docs/examples
    python -m pickdemo perceive pick_cube --seeds 0-9 --methods paper,my_estimator:estimate
    python -m pickdemo bench pick_cube --seeds 0-9 --perception my_estimator:estimate

The contract: ``estimate(frame, model) -> PoseEstimate``, raising ``PerceptionError`` with a reason
when the target cannot be measured. ``frame`` is what a real robot has (RGB, metric depth with holes
as 0 or NaN, the intrinsics and the calibrated camera pose, its sensor's noise model, its own links'
boxes); ``model`` is what the task says of the target (shape, size, colour). Report an honest
covariance: the tracker weighs every estimate by it and turns away the ones it does not believe.

This one is deliberately simple: the target's pixels by colour, its top face as the points within
5 mm of the highest, the centre below the face's middle by half the height, the yaw from the face's
rectangle. It knows nothing of the paper's mixture or fit; compare it with ``paper`` in ``perceive``.
"""

from __future__ import annotations

import cv2
import numpy as np

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import Pose
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel, world_points

COS_MIN = 0.97  # a pixel is the target's when its colour points this close to the model's (cosine in RGB)
TOP_BAND_M = 0.005  # the top face: points this close to the highest
STD_M = 0.002  # what this estimator claims of its position (1 sigma, each axis)
YAW_STD_RAD = np.radians(2.0)


def estimate(frame: RGBDFrame, model: TargetModel) -> PoseEstimate:
    if model.color is None or model.shape != "box":
        raise PerceptionError("this example estimates boxes of a known colour only")
    rgb = frame.rgb.astype(np.float32)
    colour = np.asarray(model.color, dtype=np.float32)
    cos = rgb @ (colour / np.linalg.norm(colour)) / (np.linalg.norm(rgb, axis=2) + 1e-6)
    points = world_points(frame)  # (H, W, 3) in the world frame; NaN where there is no depth
    mask = (cos > COS_MIN) & np.all(np.isfinite(points), axis=2) & (rgb.sum(axis=2) > 60.0)
    cloud = points[mask]
    if len(cloud) < 30:
        raise PerceptionError(f"only {len(cloud)} pixels of the target's colour with depth")
    top = cloud[cloud[:, 2] > cloud[:, 2].max() - TOP_BAND_M]
    (cx, cy), (w, h), angle_deg = cv2.minAreaRect(top[:, :2].astype(np.float32))
    # minAreaRect's angle is its first side's; the model's x side is its longer or shorter one
    sx, sy = model.size[0], model.size[1]
    yaw = np.radians(angle_deg if (w >= h) == (sx >= sy) else angle_deg + 90.0)
    centre = np.array([cx, cy, float(np.median(top[:, 2])) - model.height_m / 2.0])
    rotation = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    return PoseEstimate(
        pose=Pose(centre, rotation),
        position_cov=np.eye(3) * STD_M**2,
        rpy_cov=np.diag([1.0, 1.0, YAW_STD_RAD**2]),  # roll and pitch: not measured (a loose 1 rad^2)
        yaw_symmetry_rad=model.geometry.yaw_symmetry_rad,
        top_face_size_m=(max(w, h), min(w, h)),
        n_features=0,
        n_face_pixels=len(top),
    )
