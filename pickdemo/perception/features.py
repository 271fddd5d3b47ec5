"""Shi-Tomasi feature points on the target, each with its mixture depth and colour, back-projected
with its covariance, and conditioned on the top face's plane.

Pure: arrays in, dataclasses out; no simulator.
"""

from __future__ import annotations

import cv2
import numpy as np

from pickdemo.core.camera import RGBDFrame
from pickdemo.perception.equations import MIXTURE_KERNEL, SIGMA_COLOR, point_covariance
from pickdemo.perception.model import FeaturePoint, PerceptionParams


def shi_tomasi_features(frame: RGBDFrame, mask: np.ndarray, params: PerceptionParams) -> np.ndarray:
    """Shi-Tomasi corners on the target (sub-pixel refined), (N, 2) in (u, v) px; the work is on a crop."""
    ys, xs = np.nonzero(mask)
    pad = 6
    h, w = mask.shape
    y0, y1 = max(int(ys.min()) - pad, 0), min(int(ys.max()) + pad + 1, h)
    x0, x1 = max(int(xs.min()) - pad, 0), min(int(xs.max()) + pad + 1, w)
    gray = cv2.cvtColor(np.ascontiguousarray(frame.rgb[y0:y1, x0:x1]), cv2.COLOR_RGB2GRAY)
    roi = cv2.dilate(mask[y0:y1, x0:x1].astype(np.uint8), np.ones((5, 5), np.uint8))
    corners = cv2.goodFeaturesToTrack(
        gray,
        maxCorners=params.max_features,
        qualityLevel=params.feature_quality,
        minDistance=params.feature_min_distance_px,
        mask=roi,
        blockSize=3,
        useHarrisDetector=False,
    )
    if corners is None:
        return np.zeros((0, 2))
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 20, 0.01)
    corners = cv2.cornerSubPix(gray, corners.astype(np.float32), (2, 2), (-1, -1), criteria)
    return corners.reshape(-1, 2).astype(np.float64) + np.array([x0, y0], dtype=np.float64)


def measure_features(
    frame: RGBDFrame, uv: np.ndarray, mu_z: np.ndarray, var_z: np.ndarray, *, offset: tuple[int, int] = (0, 0)
) -> tuple[FeaturePoint, ...]:
    """Eqs. (9)-(14) at each feature: mixture depth and colour, back-projection, covariance.

    ``offset`` is added to the reported pixel coordinates (for features found on a crop).
    """
    K = frame.intrinsics
    R = frame.T_world_cam.rotation
    # Eqs. (11)-(12) for each channel, over the whole (cropped) image at once.
    if len(uv) == 0:
        return ()
    iu = np.round(uv[:, 0]).astype(int)
    iv = np.round(uv[:, 1]).astype(int)
    ok = (iu >= 1) & (iu < K.width - 1) & (iv >= 1) & (iv < K.height - 1)
    uv, iu, iv = uv[ok], iu[ok], iv[ok]
    z, vz = mu_z[iv, iu], var_z[iv, iu]
    ok = np.isfinite(z) & np.isfinite(vz)
    uv, iu, iv, z, vz = uv[ok], iu[ok], iv[ok], z[ok], vz[ok]
    # Eqs. (11)-(12) for r, g, b over each feature's 3x3 window.
    dv, du = np.mgrid[-1:2, -1:2]
    win = frame.rgb[iv[:, None, None] + dv, iu[:, None, None] + du].astype(np.float64)  # (N, 3, 3, 3)
    col = np.einsum("ij,nijc->nc", MIXTURE_KERNEL, win)
    col_var = np.maximum(np.einsum("ij,nijc->nc", MIXTURE_KERNEL, SIGMA_COLOR**2 + win * win) - col * col, 0.0)
    mean_cam = np.column_stack([z * (uv[:, 0] - K.cx) / K.fx, z * (uv[:, 1] - K.cy) / K.fy, z])
    mean_world = frame.T_world_cam.transform_points(mean_cam)
    shift = np.array(offset, dtype=np.float64)
    out = []
    for n in range(len(z)):
        cov_cam = point_covariance(uv[n, 0], uv[n, 1], z[n], vz[n], K.fx, K.fy, K.cx, K.cy)
        out.append(
            FeaturePoint(
                uv=uv[n] + shift,
                mean_cam=mean_cam[n],
                cov_cam=cov_cam,
                mean_world=mean_world[n],
                cov_world=R @ cov_cam @ R.T,
                rgb=col[n],
                rgb_var=col_var[n],
            )
        )
    return tuple(out)


def condition_on_plane(
    mean: np.ndarray, cov: np.ndarray, normal: np.ndarray, point: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A point's Gaussian (mean, cov) conditioned on lying on the plane ``normal . (x - point) = 0``.

    ``mean - cov n (n . (mean - point)) / (n^T cov n)``, ``cov - cov n n^T cov / (n^T cov n)``: a
    feature on an edge, whose mixture depth is uncertain (eq. 10), slides along its uncertain
    direction (mostly the ray) onto the plane; its remaining spread lies in the plane.
    """
    cn = cov @ normal
    s = float(normal @ cn)
    if s <= 0.0:
        return mean, cov
    return mean - cn * float(normal @ (mean - point)) / s, cov - np.outer(cn, cn) / s
