"""The paper's method end to end: one RGB-D frame (or a region of it) in, the target's pose with its
covariance out.

Pure: arrays in, dataclasses out; no simulator.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Box, Cylinder, Unknown
from pickdemo.perception.equations import mixture_moments
from pickdemo.perception.features import measure_features, shi_tomasi_features
from pickdemo.perception.fit2d import (
    circle_residuals,
    fit_face_plane,
    fit_outline,
    intersect_rays_plane,
    plane_basis,
    rectangle_residuals,
)
from pickdemo.perception.fit6d import MODEL_FLOOR_M, refine_pose_6dof
from pickdemo.perception.model import PerceptionError, PerceptionParams, PoseEstimate, TargetModel
from pickdemo.perception.segmentation import (
    crop_frame,
    outline_pixels,
    segment_target,
    target_roi,
    top_face_mask,
    unoccluded,
    world_heights,
)
from pickdemo.perception.unknown import Support, estimate_unknown


def estimate_pose(
    frame: RGBDFrame, model: TargetModel, params: PerceptionParams | None = None, support: Support | None = None
) -> PoseEstimate:
    """The target's pose from one frame (see the module docstring for the method).

    Raises :class:`PerceptionError` with the reason when the target cannot be measured, a degenerate
    fit included (too few of its pixels; a singular system): what was seen. Any other exception is a
    bug, and escapes (the episode ends in ``error`` with its traceback). An object
    nobody described (:class:`~pickdemo.core.shapes.Unknown`) goes to
    :func:`~pickdemo.perception.unknown.estimate_unknown`.
    """
    if isinstance(model.geometry, Unknown):
        return estimate_unknown(frame, model, params, support)
    try:
        return _estimate_pose(frame, model, params or PerceptionParams())
    except np.linalg.LinAlgError as exc:  # a singular system: what was seen leaves the fit undetermined
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise PerceptionError(
            f"degenerate fit ({type(exc).__name__}: {reason}): too little of the target seen"
        ) from None


def _estimate_pose(frame: RGBDFrame, model: TargetModel, params: PerceptionParams) -> PoseEstimate:
    x0, y0, x1, y1 = target_roi(frame, model, params)
    f = crop_frame(frame, x0, y0, x1, y1)
    if f.rgb_noise_sigma >= params.denoise_rgb_sigma:
        # A noisy colour image breaks the top face into specks: a 5x5 median restores its flat colour
        # (noise / ~2.5) and keeps its edges where they are (a median does not blur a step).
        f = dataclasses.replace(f, rgb=cv2.medianBlur(np.ascontiguousarray(f.rgb), 5))
    K = f.intrinsics
    pts = world_heights(f)
    mask = segment_target(f, model, params, pts)
    face = top_face_mask(f, mask, pts, params)
    if int(face.sum()) < 3:  # (a plane needs three points)
        raise PerceptionError(f"degenerate fit: {int(face.sum())} pixel(s) of the target's top face seen")

    # Eqs. (9)-(10) for every pixel, with eq. (8) as each pixel's own variance.
    depth = np.where(np.isfinite(f.depth_m), f.depth_m, np.nan)
    mu_z, var_z = mixture_moments(depth, f.depth_variance(depth))

    # Pass 1: plane from the face pixels whose whole 3x3 window lies on the face (no edge mixing).
    inner = cv2.erode(face.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    normal, plane_point, _ = fit_face_plane(f, inner if inner.sum() >= 6 else face, mu_z, var_z)

    shape = model.geometry
    outline_uv = outline_pixels(face)
    if isinstance(shape, Cylinder):
        # Only the arc that is also the silhouette: where the flat cap meets the smooth-shaded side,
        # the colour boundary sits up to a pixel off, a bias toward the camera (evidence:
        # docs/decisions.md#perception).
        rim = mask & ~cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        rim = cv2.dilate(rim.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        iu = np.clip(np.round(outline_uv[:, 0]).astype(int), 0, K.width - 1)
        iv = np.clip(np.round(outline_uv[:, 1]).astype(int), 0, K.height - 1)
        if rim[iv, iu].sum() >= 10:
            outline_uv = outline_uv[rim[iv, iu]]
    face_depth = float(np.nanmedian(depth[face]))
    px_m = face_depth / K.fx  # one pixel's footprint, m
    # An outline point is an image feature: the paper's sigma_u = sigma_v = 1 px (eq. 14) applies.
    var_edge = (params.edge_sigma_px * px_m) ** 2
    # Where something stands in front of the face, its outline is that thing's edge: leave it out.
    visible = unoccluded(outline_uv, depth, face_depth)
    if visible.sum() >= 10:
        outline_uv = outline_uv[visible]

    # The start of the 6-DoF fit below: the outline on the first plane, fitted with the known shape.
    B = plane_basis(normal)
    xy = (intersect_rays_plane(f, outline_uv, normal, plane_point) - plane_point) @ B[:, :2]
    center2, yaw_face, size_face, _ = fit_outline(xy, model)

    # Shi-Tomasi features with the paper's mixture (eqs. 9-12) and covariance (eqs. 13-14),
    # conditioned on the face's plane. Those that lie on the face's outline join the outline fit,
    # each weighted by its own covariance across the outline.
    uv = shi_tomasi_features(f, mask, params)
    features = measure_features(f, uv, mu_z, var_z, offset=(x0, y0))
    feat_var, feat_uv = np.zeros(0), np.zeros((0, 2))
    if features:
        # condition_on_plane for every feature at once.
        means = np.array([fp.mean_world for fp in features])
        covs = np.array([fp.cov_world for fp in features])
        cn = covs @ normal  # (N, 3)
        sn = np.maximum(cn @ normal, 1e-30)
        m3 = means - cn * (((means - plane_point) @ normal) / sn)[:, None]
        c3 = covs - cn[:, :, None] * cn[:, None, :] / sn[:, None, None]
        p2a = (m3 - plane_point) @ B[:, :2]
        c2a = B[:, :2].T @ c3 @ B[:, :2]
        if isinstance(shape, Box):
            r, J = rectangle_residuals(p2a, shape.size_m[0], shape.size_m[1])(np.array([*center2, yaw_face]))
        elif isinstance(shape, Cylinder):
            r, J = circle_residuals(p2a, shape.diameter_m / 2.0)(center2)
        else:
            raise TypeError(f"no outline fit for a {shape.kind}")
        n2 = -J[:, :2]  # the outline's normal at each feature (the residual's gradient in the point)
        var = np.einsum("ij,ijk,ik->i", n2, c2a, n2) + var_edge
        # On the top face's outline in the image too: a corner elsewhere on the object (a bottom or
        # side corner) can land near the outline once conditioned on the top plane, and would bias it.
        uv_f = np.array([fp.uv for fp in features]) - np.array([x0, y0], dtype=np.float64)
        d_img = np.min(np.linalg.norm(uv_f[:, None, :] - outline_uv[None, :, :], axis=2), axis=1)
        on_outline = (np.abs(r) < 3.0 * np.sqrt(var)) & (d_img < 1.5)
        feat_var = var[on_outline]
        feat_uv = np.array([fp.uv for fp in features])[on_outline] - np.array([x0, y0], dtype=np.float64)
    n_used = len(feat_var)
    symmetry = shape.yaw_symmetry_rad

    top_center = plane_point + B[:, :2] @ center2
    center = top_center - normal * (shape.height_m / 2.0)
    x_axis = B[:, :2] @ np.array([np.cos(yaw_face), np.sin(yaw_face)])
    R = np.column_stack([x_axis, np.cross(normal, x_axis), normal])

    # Last, the 6-DoF covariance-weighted fit of the whole model: every target pixel's mixture point
    # against its surface, and the outline (with the features on it) against its top face's edges.
    edge_uv = np.vstack([outline_uv, feat_uv])
    edge_var = np.concatenate([np.full(len(outline_uv), var_edge), feat_var])
    # Dense points: each pixel's own depth with eq. (8)'s variance. Not the mixture (eqs. 9-10): its
    # mean smears a surface across a depth step, and its variance is undefined beside a hole, which
    # on a real sensor lies on the silhouette (edge dropout), so the points there would go and the
    # fit would lean inward (evidence: docs/decisions.md#perception).
    pose, cov6, quality = refine_pose_6dof(
        f, mask, depth, model, Pose(center, R), edge_uv, edge_var, max_points=params.fit_points
    )
    # A floor for what the fit cannot see: the scene itself is modelled to some 10-20 um (a cylinder's
    # 64-sided mesh deviates 24 um from the circle; rasterisation quantises edges), so no direction
    # is reported better than that, however many points agree.
    w, V = np.linalg.eigh(0.5 * (cov6[:3, :3] + cov6[:3, :3].T))
    pos_cov = V @ np.diag(np.maximum(w, 0.0) + MODEL_FLOOR_M**2) @ V.T
    calibration = f.calibration_cov_at(pose.position)  # the camera's pose known to its calibration's accuracy
    if calibration is not None:
        pos_cov = pos_cov + calibration
    rpy_cov = cov6[3:, 3:]
    if symmetry == 0.0:
        rpy_cov = rpy_cov.copy()
        rpy_cov[2, :] = rpy_cov[:, 2] = 0.0  # no yaw to speak of
    estimate = PoseEstimate(
        pose=pose,
        position_cov=pos_cov,
        rpy_cov=rpy_cov,
        yaw_symmetry_rad=symmetry,
        top_face_size_m=size_face,
        n_features=len(features),
        n_features_fused=n_used,
        n_face_pixels=int(face.sum()),
        fit=quality,
        features=features,
        calibration_cov=calibration,
    )
    problem = quality.problem(params)
    if problem:
        raise PerceptionError(f"the model does not fit what was seen: {problem}", estimate)
    return estimate
