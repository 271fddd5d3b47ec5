"""The 6-DoF covariance-weighted fit of the known box or cylinder to every target pixel and the
outline, and its covariance.

Pure: arrays in, dataclasses out; no simulator.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pickdemo.core.camera import RGBDFrame, pixel_rays_cam
from pickdemo.core.geometry import Pose, wrap_angle
from pickdemo.perception.equations import SIGMA_UV_PX
from pickdemo.perception.model import FitQuality, TargetModel

#: Smallest position uncertainty reported in any direction (see :func:`~pickdemo.perception.pipeline.estimate_pose`), m.
MODEL_FLOOR_M = 10e-6


def closest_on_model(points: np.ndarray, model: TargetModel) -> tuple[np.ndarray, np.ndarray]:
    """Closest points on the model's surface (model frame, centred) and the outward normals there."""
    return model.geometry.closest_points(points)


def surface_along_rays(
    points: np.ndarray, origin: np.ndarray, model: TargetModel, *, reach_m: float = 0.01
) -> tuple[np.ndarray, np.ndarray]:
    """Where each point's viewing ray (from ``origin``, the camera) first meets the model's surface
    (model frame, centred), and the outward normal there; the closest surface point where the ray
    misses the model or meets it further than ``reach_m`` from the point, or where the shape cannot
    cast rays.

    A depth reading errs along its ray, so the surface it belongs to is the one its ray meets, not
    the one nearest to it: beside an edge, a reading pushed behind the top face by noise lies nearer
    the side face, and matching it there would drag the top face up (evidence:
    docs/decisions.md#perception).
    """
    cast = getattr(model.geometry, "ray_entry", None)
    if cast is None:
        return closest_on_model(points, model)
    q, n, hit = cast(np.broadcast_to(origin, points.shape), points - origin)
    gap = q - points
    dist = np.sqrt(gap[:, 0] * gap[:, 0] + gap[:, 1] * gap[:, 1] + gap[:, 2] * gap[:, 2])  # (norm's arithmetic)
    off = ~(hit & (dist < reach_m))
    if off.any():
        q[off], n[off] = closest_on_model(points[off], model)
    return q, n


def _rpy_jacobian(R: np.ndarray) -> np.ndarray:
    """d(roll, pitch, yaw) / d(rotation vector in the body frame) at R (numeric)."""
    base = pin.rpy.matrixToRpy(R)
    J = np.zeros((3, 3))
    for k in range(3):
        w = np.zeros(3)
        w[k] = 1e-7
        J[:, k] = wrap_angle(pin.rpy.matrixToRpy(R @ pin.exp3(w)) - base) / 1e-7
    return J


def refine_pose_6dof(
    frame: RGBDFrame,
    pixels: np.ndarray,
    depth: np.ndarray,
    model: TargetModel,
    start: Pose,
    outline_uv: np.ndarray,
    outline_var: np.ndarray,
    *,
    iterations: int = 4,
    max_points: int = 2000,
) -> tuple[Pose, np.ndarray, FitQuality]:
    """The object's pose by a covariance-weighted fit of its known shape (our design; the paper
    leaves the pose step open).

    Residuals, each divided by its own standard deviation:

    * every target pixel's point (eqs. 5-7, its own depth) against the face of the model its
      viewing ray meets (:func:`surface_along_rays`), point to plane; its variance is eq. (14)'s
      covariance projected on the face's normal, with eq. (8) at the depth the model predicts there;
    * every outline ray of the top face (and each Shi-Tomasi feature on it): where it meets the
      model's top plane, its distance to the top face's edge; variance ``outline_var``.

    Gauss-Newton on a twist at the object's centre, ``T = T0 exp(xi)``. Returns the pose, the 6x6
    covariance of (translation in the world frame, roll / pitch / yaw) and how well the model fitted
    (:class:`FitQuality`).
    """
    K = frame.intrinsics
    Tc = frame.T_world_cam
    vs, us = np.nonzero(pixels)
    if len(vs) > max_points:  # a regular, deterministic thinning: the fit's cost grows with the points
        keep = np.arange(0, len(vs), int(np.ceil(len(vs) / max_points)))
        vs, us = vs[keep], us[keep]
    z = depth[vs, us]
    ok = np.isfinite(z)
    vs, us, z = vs[ok], us[ok], z[ok]
    du, dv = us - K.cx, vs - K.cy
    ray = np.column_stack([du / K.fx, dv / K.fy, np.ones(len(z))])  # a = (x/z, y/z, 1)
    pts = Tc.transform_points(ray * z[:, None])
    # Eq. (14) is var_z a a^T + sigma_uv^2 z^2 diag(1/fx^2, 1/fy^2, 0); projected on a unit normal
    # n (camera frame) that is var_z (n.a)^2 + sigma_uv^2 z^2 (n_x^2/fx^2 + n_y^2/fy^2), per point.
    s2z2 = SIGMA_UV_PX**2 * z * z
    Rc = Tc.rotation
    rays = pixel_rays_cam(outline_uv, K) @ Rc.T
    shape = model.geometry
    half_h = shape.height_m / 2.0

    def edge_residuals(T: pin.SE3) -> np.ndarray:
        """Outline rays against the model's top plane and its top face's edges (m)."""
        R, t = T.rotation, T.translation
        normal = R[:, 2]
        top = t + normal * half_h
        tr = ((top - Tc.position) @ normal) / (rays @ normal)
        lp = (Tc.position + tr[:, None] * rays - t) @ R
        return shape.outline_residuals(lp)

    T = start.to_se3()
    edge_sd = np.sqrt(outline_var)
    keep_pts = np.ones(len(pts), dtype=bool)
    keep_edge = np.ones(len(rays), dtype=bool)
    used = len(pts)
    for it in range(iterations):
        R, t = T.rotation, T.translation
        # Point to plane, the closest model points held fixed in this step (as in ICP):
        # r = n_w . (p - T q); for T exp(xi): dr/dv = -n, dr/dw = n x q (model frame).
        local = (pts - t) @ R
        q, n = surface_along_rays(local, (Tc.position - t) @ R, model)
        nw = n @ R.T
        r_d = np.einsum("ij,ij->i", nw, pts - (q @ R.T + t))
        # Each point's depth variance (eq. 8) at the depth the model predicts there, not at its own
        # noisy reading: weights drawn from the noise they weigh would pull the fit toward the camera
        # (a nearer reading would count for more; evidence: docs/decisions.md#perception).
        vz = frame.depth_variance(((q @ R.T + t) - Tc.position) @ Rc[:, 2])
        nc = nw @ Rc  # normals in the camera frame
        var_n = vz * np.einsum("ij,ij->i", nc, ray) ** 2 + s2z2 * (nc[:, 0] ** 2 / K.fx**2 + nc[:, 1] ** 2 / K.fy**2)
        sd = np.sqrt(np.maximum(var_n, 1e-14))
        J_d = np.empty((len(n), 6))  # [-n, n x q] (np.cross's arithmetic, without its overhead)
        J_d[:, :3] = -n
        J_d[:, 3] = n[:, 1] * q[:, 2] - n[:, 2] * q[:, 1]
        J_d[:, 4] = n[:, 2] * q[:, 0] - n[:, 0] * q[:, 2]
        J_d[:, 5] = n[:, 0] * q[:, 1] - n[:, 1] * q[:, 0]
        J_d /= sd[:, None]
        r_d = r_d / sd
        r_e = edge_residuals(T) / edge_sd
        if it == 0:  # numeric, once: near the solution the edges' Jacobian barely changes
            J_e = np.empty((len(r_e), 6))
            for k in range(6):
                d = np.zeros(6)
                d[k] = 1e-6
                J_e[:, k] = (edge_residuals(T * pin.exp6(pin.Motion(d[:3], d[3:]))) / edge_sd - r_e) / 1e-6
        if it == 1:  # drop gross outliers (mis-segmented pixels) once the fit has settled
            keep_pts = np.abs(r_d) < 4.0
            keep_edge = np.abs(r_e) < 4.0
        J = np.vstack([J_d[keep_pts], J_e[keep_edge]])
        r = np.concatenate([r_d[keep_pts], r_e[keep_edge]])
        # Minimum-norm least squares on the 6x6 normal equations: a direction that nothing observes
        # (a cylinder's turn about its axis) is left alone (singular values of J below 1e-9 of
        # the largest, i.e. of J^T J below 1e-18, are cut).
        step = np.linalg.lstsq(J.T @ J, -(J.T @ r), rcond=1e-18)[0]
        T = T * pin.exp6(pin.Motion(step[:3], step[3:]))
        used = int(keep_pts.sum())
        if np.linalg.norm(step) < 1e-6:  # 1 um and 1 urad: converged
            break
    # Covariance: each group's modelled deviations rescaled by what its residuals show (one step of
    # variance-component estimation): eq. (10)'s variance counts the noisy spread of the window on
    # top of the noise itself, and one pixel is generous for a crisp edge.
    s_d = float(np.sqrt(np.mean(r_d[keep_pts] ** 2))) if keep_pts.any() else 1.0
    s_e = float(np.sqrt(np.mean(r_e[keep_edge] ** 2))) if keep_edge.any() else 1.0
    J = np.vstack([J_d[keep_pts] / max(s_d, 1e-3), J_e[keep_edge] / max(s_e, 1e-3)])
    info = J.T @ J
    cov_local = np.linalg.pinv(info, rcond=1e-15, hermitian=True)  # pinv: a cylinder has no yaw
    R = T.rotation
    # Local translation -> world; local rotation -> roll, pitch, yaw.
    A = np.zeros((6, 6))
    A[:3, :3] = R
    A[3:, 3:] = _rpy_jacobian(R)
    quality = FitQuality(
        depth_rms=s_d,
        edge_rms=s_e,
        depth_outliers=float(1.0 - keep_pts.mean()) if len(keep_pts) else 1.0,
        edge_outliers=float(1.0 - keep_edge.mean()) if len(keep_edge) else 1.0,
        points=used,
    )
    return Pose.from_se3(T), A @ cov_local @ A.T, quality
