"""The start of a pose: the top face's plane (weighted by eq. 14) and the known rectangle or circle
fitted to its outline in that plane.

Pure: arrays in, dataclasses out; no simulator.
"""

from __future__ import annotations

import cv2
import numpy as np

from pickdemo.core.camera import RGBDFrame, pixel_rays_cam
from pickdemo.core.shapes import Box, Cylinder
from pickdemo.perception.model import PerceptionError, TargetModel


def fit_plane_weighted(points: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, np.ndarray]:
    """Weighted least-squares plane ``z = a x + b y + c`` through (N, 3) points.

    Returns the unit normal (z up), the plane's height at the weighted centroid's (x, y), the 3x3
    covariance of (a, b, height), and the weighted centroid.
    """
    w = weights / weights.sum()
    centroid = (w[:, None] * points).sum(axis=0)
    d = points - centroid
    A = np.column_stack([d[:, 0], d[:, 1], np.ones(len(d))])
    W = weights[:, None]
    normal_eq = A.T @ (W * A)
    sol = np.linalg.solve(normal_eq, A.T @ (weights * d[:, 2]))
    resid = d[:, 2] - A @ sol
    # Scale the information by the observed residual spread when it exceeds the model's (chi2/dof).
    dof = max(len(points) - 3, 1)
    scale = max(float((weights * resid * resid).sum()) / dof, 1.0)
    cov = np.linalg.inv(normal_eq) * scale
    a, b = sol[0], sol[1]
    normal = np.array([-a, -b, 1.0])
    normal /= np.linalg.norm(normal)
    return normal, float(centroid[2] + sol[2]), cov, centroid


def plane_basis(normal: np.ndarray) -> np.ndarray:
    """Columns e1, e2, n: an orthonormal frame whose first axis is world x projected on the plane."""
    e1 = np.array([1.0, 0.0, 0.0]) - normal[0] * normal
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return np.column_stack([e1, e2, normal])


def intersect_rays_plane(frame: RGBDFrame, uv: np.ndarray, normal: np.ndarray, point: np.ndarray) -> np.ndarray:
    """World points where the pixels' rays meet the plane through ``point`` with ``normal``."""
    T = frame.T_world_cam
    rays = pixel_rays_cam(uv, frame.intrinsics) @ T.rotation.T
    t = ((point - T.position) @ normal) / (rays @ normal)
    return T.position + t[:, None] * rays


def fit_face_plane(
    frame: RGBDFrame, pixels: np.ndarray, mu_z: np.ndarray, var_z: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted plane through the mixture points (eqs. 5-9) of the given pixels.

    Each point is weighted by the inverse of its variance along the vertical, which is eq. (14)'s
    covariance projected: for a point on the ray ``d`` (z component 1 in the camera) that is
    ``var_z * (R d)_z^2``. Returns the unit normal, a point on the plane and the plane's covariance.
    """
    K = frame.intrinsics
    vs, us = np.nonzero(pixels)
    z = mu_z[vs, us]
    keep = np.isfinite(z)
    vs, us, z = vs[keep], us[keep], z[keep]
    if len(z) < 6:
        raise PerceptionError(f"too few depth readings on the target's top face ({len(z)})")
    rays = np.column_stack([(us - K.cx) / K.fx, (vs - K.cy) / K.fy, np.ones(len(z))])
    pts = frame.T_world_cam.transform_points(rays * z[:, None])
    ray_z = rays @ frame.T_world_cam.rotation[2]
    var_vert = np.maximum(var_z[vs, us] * ray_z**2, 1e-14)
    normal, height, cov, centroid = fit_plane_weighted(pts, 1.0 / var_vert)
    return normal, np.array([centroid[0], centroid[1], height]), cov


def fit_outline(
    xy: np.ndarray, model: TargetModel, weights: np.ndarray | None = None, init: tuple[np.ndarray, float] | None = None
) -> tuple[np.ndarray, float, tuple[float, float], np.ndarray]:
    """Centre (2,), in-plane yaw (rad), measured size and 3x3 covariance of (cx, cy, yaw) of the top
    face from outline points in plane coordinates (yaw variance 0 for a cylinder)."""
    shape = model.geometry
    if isinstance(shape, Box):
        sx, sy = shape.size_m[0], shape.size_m[1]
        (cx2, cy2), (w2, h2), ang = cv2.minAreaRect(xy.astype(np.float32))
        if init is None:
            yaw = float(np.radians(ang))
            if (w2 < h2) == (sx >= sy):
                yaw += np.pi / 2.0
                w2, h2 = h2, w2
            init = (np.array([cx2, cy2], dtype=np.float64), yaw)
        center, yaw, cov = refine_rectangle(xy, init[0], init[1], sx, sy, weights)
        return center, yaw, (float(max(w2, h2)), float(min(w2, h2))), cov
    if not isinstance(shape, Cylinder):
        raise TypeError(f"no outline fit for a {shape.kind}")
    (cx2, cy2), (a2, b2), _ = cv2.fitEllipse(xy.astype(np.float32))
    start = np.array([cx2, cy2], dtype=np.float64) if init is None else init[0]
    center, cov2 = refine_circle(xy, start, shape.diameter_m / 2.0, weights)
    cov = np.zeros((3, 3))
    cov[:2, :2] = cov2
    return center, 0.0, (float(a2), float(b2)), cov


def _gauss_newton(
    residual_jacobian, x0: np.ndarray, weights: np.ndarray, iterations: int = 6, tol: float = 1e-8
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted Gauss-Newton; returns the solution and its covariance.

    The covariance is ``(J^T W J)^-1``, scaled up by the reduced chi-square of the residuals when
    they scatter more than the weights say (outline pixels are not independent samples).
    """
    x = np.asarray(x0, dtype=np.float64).copy()
    r, J = residual_jacobian(x)
    for _ in range(iterations):
        JW = J.T * weights
        step = np.linalg.solve(JW @ J + 1e-15 * np.eye(len(x)), -(JW @ r))
        x = x + step
        r, J = residual_jacobian(x)
        if np.linalg.norm(step) < tol:
            break
    info = (J.T * weights) @ J
    dof = max(len(r) - len(x), 1)
    chi2 = float(np.sum(weights * r * r)) / dof
    return x, np.linalg.inv(info) * max(chi2, 1.0)


def rectangle_residuals(xy: np.ndarray, sx: float, sy: float):
    """Residuals (signed distance to the nearest side) of points to a rectangle (cx, cy, yaw)."""
    hx, hy = sx / 2.0, sy / 2.0

    def f(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        ct, st = np.cos(x[2]), np.sin(x[2])
        d = xy - x[:2]
        lx = d[:, 0] * ct + d[:, 1] * st
        ly = -d[:, 0] * st + d[:, 1] * ct
        on_x = np.abs(np.abs(lx) - hx) < np.abs(np.abs(ly) - hy)
        r = np.where(on_x, np.abs(lx) - hx, np.abs(ly) - hy)
        ones = np.ones_like(lx)
        dlx = np.column_stack([-ct * ones, -st * ones, ly])
        dly = np.column_stack([st * ones, -ct * ones, -lx])
        J = np.where(on_x[:, None], np.sign(lx)[:, None] * dlx, np.sign(ly)[:, None] * dly)
        return r, J

    return f


def circle_residuals(xy: np.ndarray, radius: float):
    def f(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = xy - x
        dist = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        return dist - radius, -d / dist[:, None]

    return f


def refine_rectangle(
    xy: np.ndarray, center: np.ndarray, yaw: float, sx: float, sy: float, weights: np.ndarray | None = None
) -> tuple[np.ndarray, float, np.ndarray]:
    """Weighted least-squares rectangle of known size through outline points.

    Each point is assigned to its nearest side; its residual is its signed distance to that side.
    Returns the centre (2,), the yaw (rad) and the 3x3 covariance of (cx, cy, yaw).
    """
    w = np.ones(len(xy)) if weights is None else weights
    x, cov = _gauss_newton(rectangle_residuals(xy, sx, sy), np.array([center[0], center[1], yaw]), w)
    return x[:2], float(x[2]), cov


def refine_circle(
    xy: np.ndarray, center: np.ndarray, radius: float, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares centre of a circle of known radius; returns it and its 2x2 covariance."""
    w = np.ones(len(xy)) if weights is None else weights
    return _gauss_newton(circle_residuals(xy, radius), np.asarray(center, dtype=np.float64), w)
