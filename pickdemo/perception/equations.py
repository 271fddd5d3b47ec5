"""The paper's equations: the 3x3 Gaussian mixture of depth and colour (eqs. 9-12) and a back-
projected point's covariance (eqs. 13-14).

Pure: arrays in, dataclasses out; no simulator.
"""

from __future__ import annotations

import cv2
import numpy as np

#: Eqs. (9)-(12): weight 1/4 at the feature, 1/8 on the four edge neighbours, 1/16 on the diagonals.
MIXTURE_KERNEL = np.array([[1.0, 2.0, 1.0], [2.0, 4.0, 2.0], [1.0, 2.0, 1.0]]) / 16.0


#: The paper's feature-location uncertainty (eq. 14): one pixel.
SIGMA_UV_PX = 1.0


#: Constant colour deviation sigma_c of eq. (12), in 8-bit units.
SIGMA_COLOR = 2.0


def mixture_moments(mu: np.ndarray, var: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. (9)-(12) for every pixel at once: mean and variance of the 3x3 Gaussian mixture.

    ``mu`` (H, W) holds each pixel's mean, ``var`` its variance (array or constant). Returns
    ``mu_mix = sum w_i mu_i`` and ``var_mix = sum w_i (var_i + mu_i^2) - mu_mix^2``. Borders replicate.
    """
    mu = np.asarray(mu, dtype=np.float64)
    second = np.asarray(var, dtype=np.float64) + mu * mu
    second = np.broadcast_to(second, mu.shape).astype(np.float64)
    m = cv2.filter2D(mu, cv2.CV_64F, MIXTURE_KERNEL, borderType=cv2.BORDER_REPLICATE)
    s = cv2.filter2D(second, cv2.CV_64F, MIXTURE_KERNEL, borderType=cv2.BORDER_REPLICATE)
    return m, np.maximum(s - m * m, 0.0)


def mixture_at(mu: np.ndarray, var: np.ndarray | float, u: int, v: int) -> tuple[float, float]:
    """Eqs. (9)-(10) at one pixel (u, v), written out over its 3x3 window (for checking by hand)."""
    mu = np.asarray(mu, dtype=np.float64)
    win = mu[v - 1 : v + 2, u - 1 : u + 2]
    var_win = np.broadcast_to(np.asarray(var, dtype=np.float64), mu.shape)[v - 1 : v + 2, u - 1 : u + 2]
    mean = float(np.sum(MIXTURE_KERNEL * win))
    return mean, float(np.sum(MIXTURE_KERNEL * (var_win + win * win)) - mean * mean)


def point_covariance(
    u: float,
    v: float,
    mu_z: float,
    var_z: float,
    fx: float,
    fy: float,
    cx: float,
    cy: float,
    sigma_u: float = SIGMA_UV_PX,
    sigma_v: float = SIGMA_UV_PX,
) -> np.ndarray:
    """Eq. (14): the 3x3 covariance of a back-projected point, camera frame (m^2).

    With ``x = z (u - cx) / fx`` and ``y = z (v - cy) / fy`` (non-square pixels use fx, fy where the
    paper writes f), u, v and z independent.
    """
    du, dv = u - cx, v - cy
    sxx = (var_z * du * du + sigma_u**2 * mu_z**2) / fx**2
    syy = (var_z * dv * dv + sigma_v**2 * mu_z**2) / fy**2
    sxy = var_z * du * dv / (fx * fy)
    sxz = var_z * du / fx
    syz = var_z * dv / fy
    return np.array([[sxx, sxy, sxz], [sxy, syy, syz], [sxz, syz, var_z]])
