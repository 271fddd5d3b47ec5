"""Perception: the target's pose from one RGB-D frame, by the paper's method (``shared/paper``).

Pure: arrays in, dataclasses out. It reads only what a real robot has: the RGB image, the metric
depth image, the intrinsics and the camera pose, plus the task's description of the target (its
colour, shape and size, as a pick order or a CAD model would give them). Nothing from the simulator.

Steps (equation numbers as in the paper):

1. Segment the target: pixels above the table plane (z = 0) whose colour matches the target's,
   searched first on a subsampled frame to find a region of interest; all else runs on that crop.
2. The top face: of the target's pixels, the region of one uniform colour holding its highest
   points (flat faces shade uniformly, so its edges are crisp in the noise-free RGB image). Its
   outline: the boundary pixels moved half a pixel outwards, less any stretch where something
   nearer the camera hides it (and, for a cylinder, less the arc along its smooth-shaded side).
3. The 3x3 Gaussian mixture of depth, eqs. (9)-(10), with eq. (8) as each pixel's variance, for
   every pixel at once (a convolution).
4. A start: the face's plane fitted to the mixture points (eqs. 5-7) weighted by eq. (14), and the
   known rectangle or circle fitted to the outline intersected with that plane.
5. Shi-Tomasi feature points on the target (sub-pixel refined), each with its mixture depth and
   colour (eqs. 9-12), back-projection (eqs. 5-7) and covariance (eqs. 13-14). Each is conditioned
   on the face's plane; those lying on the face's outline (in the image and in the plane) are
   edge observations with their own covariance.
6. The pose: a 6-DoF covariance-weighted fit of the known shape (:func:`refine_pose_6dof`): every
   target pixel's point against the model's surface, weighted by eq. (14) with the mixture's
   variance (so a pixel whose window spans a depth step weighs little), and the outline rays and
   edge features against the top face's edges, at the paper's one-pixel uncertainty. Its 6x6
   covariance comes from the information matrix, each residual group rescaled by its observed
   spread, with a floor for what the model of the scene cannot resolve.

Measured choices are documented where they are made (the mixture's variance but each pixel's own
depth; features selected on the outline in the image; the cylinder's side arc left out).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import cv2
import numpy as np
import pinocchio as pin

from pickdemo.camera import Intrinsics, RGBDFrame, backproject_image, holes_as_nan, pixel_rays_cam
from pickdemo.geometry import Pose, wrap_angle

#: Eqs. (9)-(12): weight 1/4 at the feature, 1/8 on the four edge neighbours, 1/16 on the diagonals.
MIXTURE_KERNEL = np.array([[1.0, 2.0, 1.0], [2.0, 4.0, 2.0], [1.0, 2.0, 1.0]]) / 16.0
#: The paper's feature-location uncertainty (eq. 14): one pixel.
SIGMA_UV_PX = 1.0
#: Smallest position uncertainty reported in any direction (see estimate_pose), m.
MODEL_FLOOR_M = 10e-6
#: Constant colour deviation sigma_c of eq. (12), in 8-bit units.
SIGMA_COLOR = 2.0


class PerceptionError(RuntimeError):
    """The target could not be found or measured in the frame."""


@dataclass(frozen=True)
class PerceptionParams:
    """Tuning of the perception stage, validated when built."""

    min_height_m: float = 0.006  # a pixel belongs to an object when this far above the table
    color_cos_min: float = 0.985  # cosine between a pixel's colour and the target's
    min_target_px: int = 30
    max_features: int = 40
    feature_quality: float = 0.05
    feature_min_distance_px: int = 3
    face_color_tol: float = 12.0  # 8-bit units: how far a top-face pixel's colour may stray
    face_depth_sigmas: float = 3.0
    edge_sigma_px: float = 1.0  # an outline point's location uncertainty (the paper's sigma_u = 1 px)
    fit_points: int = 4000  # depth points in the 6-DoF fit at most (a regular thinning beyond)
    denoise_rgb_sigma: float = 8.0  # from this RGB noise (8-bit) on, a median filter first

    def __post_init__(self) -> None:
        if not 0.0 < self.color_cos_min <= 1.0:
            raise ValueError("color_cos_min must be in (0, 1]")
        if self.min_height_m <= 0.0 or self.min_target_px < 3 or self.max_features < 1:
            raise ValueError("min_height_m, min_target_px and max_features must be positive")


@dataclass(frozen=True)
class TargetModel:
    """What the task says about the target: shape, size (m) and nominal colour (0-1)."""

    shape: str  # "box" | "cylinder"
    size: tuple[float, ...]  # box: x, y, z; cylinder: diameter, height
    color: tuple[float, float, float]

    @property
    def height_m(self) -> float:
        return self.size[2] if self.shape == "box" else self.size[1]


@dataclass(frozen=True)
class FeaturePoint:
    """One Shi-Tomasi feature after the Gaussian mixture: p = [x, y, z, r, g, b] with covariance (eq. 13)."""

    uv: np.ndarray  # (2,) px
    mean_cam: np.ndarray  # (3,) m, camera frame (eqs. 5-7)
    cov_cam: np.ndarray  # (3, 3) m^2 (eq. 14)
    mean_world: np.ndarray  # (3,) m
    cov_world: np.ndarray  # (3, 3) m^2
    rgb: np.ndarray  # (3,) mixture colour (eq. 11)
    rgb_var: np.ndarray  # (3,) its variances (eq. 12)


@dataclass(frozen=True)
class PoseEstimate:
    """The target's pose with its uncertainty."""

    pose: Pose  # world pose of the object's centre
    position_cov: np.ndarray  # (3, 3) m^2
    rpy_cov: np.ndarray  # (3, 3) rad^2 of (roll, pitch, yaw)
    yaw_symmetry_rad: float  # the model looks the same after this rotation about its axis (0: any)
    top_face_size_m: tuple[float, float]  # measured extents of the top face (box) or diameter twice
    n_features: int
    n_face_pixels: int
    n_features_fused: int = 0  # features that lay on the face's outline and joined its fit
    features: tuple[FeaturePoint, ...] = field(repr=False, default=())

    def to_dict(self) -> dict[str, object]:
        d = self.pose.to_dict()
        d["position_std_mm"] = [float(v) for v in 1e3 * np.sqrt(np.diag(self.position_cov))]
        d["yaw_std_deg"] = float(np.degrees(np.sqrt(self.rpy_cov[2, 2])))
        d["n_features"] = self.n_features
        d["n_features_fused"] = self.n_features_fused
        d["n_face_pixels"] = self.n_face_pixels
        return d


# ------------------------------------------------------------------------------- the paper's maths
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


# -------------------------------------------------------------------------------------- segmentation
def world_heights(frame: RGBDFrame) -> np.ndarray:
    """(H, W) world z of every pixel (nan where there is no depth): z is linear in the depth."""
    K, T = frame.intrinsics, frame.T_world_cam
    h, w = frame.depth_m.shape
    r = T.rotation[2]
    slope = r[0] * (np.arange(w) - K.cx)[None, :] / K.fx + r[1] * (np.arange(h) - K.cy)[:, None] / K.fy + r[2]
    depth = np.where(np.isfinite(frame.depth_m), frame.depth_m, np.nan)
    return depth * slope + T.position[2]


def world_points(frame: RGBDFrame) -> np.ndarray:
    """(H, W, 3) world coordinates of every pixel (nan where there is no depth)."""
    depth = np.where(np.isfinite(frame.depth_m), frame.depth_m, np.nan)
    pts = backproject_image(depth, frame.intrinsics)
    return pts @ frame.T_world_cam.rotation.T + frame.T_world_cam.position


def color_match(rgb: np.ndarray, color: tuple[float, float, float], cos_min: float) -> np.ndarray:
    """Pixels whose colour points the same way as ``color`` in RGB space (robust to shading)."""
    c = np.asarray(color, dtype=np.float32)
    c = c / np.linalg.norm(c)
    x = rgb.astype(np.float32)
    dot = x @ c
    norm2 = np.einsum("...c,...c->...", x, x)
    # cos >= cos_min without a square root: dot >= 0 and dot^2 >= cos_min^2 |x|^2.
    return (dot > 0.0) & (dot * dot >= np.float32(cos_min * cos_min) * norm2) & (norm2 > 400.0)


def segment_target(frame: RGBDFrame, model: TargetModel, params: PerceptionParams, z_world: np.ndarray) -> np.ndarray:
    """Binary mask of the target: above the table, of its colour, the largest such blob.

    ``z_world`` is the (H, W) world height of every pixel (:func:`world_heights`).
    """
    above = np.nan_to_num(z_world, nan=-1.0) > params.min_height_m
    mask = (above & color_match(frame.rgb, model.color, params.color_cos_min)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        raise PerceptionError("no pixel above the table has the target's colour")
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[best, cv2.CC_STAT_AREA] < params.min_target_px:
        raise PerceptionError(f"target blob too small ({stats[best, cv2.CC_STAT_AREA]} px)")
    return labels == best


def top_face_mask(frame: RGBDFrame, mask: np.ndarray, z_world: np.ndarray, params: PerceptionParams) -> np.ndarray:
    """The target's top face: the region of one uniform colour that holds its highest points.

    Flat faces under a directional light render in one colour each, so the face's edges are crisp
    in RGB (which has no noise) where they would be blurred in depth.
    """
    z = z_world
    zs = z[mask]
    zs = zs[np.isfinite(zs)]
    top = np.quantile(zs, 0.9)
    sigma = float(np.sqrt(frame.depth_variance(np.nanmedian(frame.depth_m[mask]))))
    high = mask & (np.nan_to_num(z, nan=-1.0) > top - params.face_depth_sigmas * sigma)
    face_rgb = np.median(frame.rgb[high].astype(np.float64), axis=0)
    diff = frame.rgb.astype(np.float32) - face_rgb.astype(np.float32)
    close = np.einsum("...c,...c->...", diff, diff) <= np.float32(params.face_color_tol**2)
    face = (mask & close).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(face, connectivity=4)
    if n <= 1:
        raise PerceptionError("the target's top face was not found")
    best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return labels == best


# -------------------------------------------------------------------------------------- features
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


# -------------------------------------------------------------------------------------- pose fit
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


def _plane_basis(normal: np.ndarray) -> np.ndarray:
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


def outline_pixels(mask: np.ndarray) -> np.ndarray:
    """Pixel coordinates (N, 2) of the region's boundary, each moved half a pixel outwards.

    The boundary pixel's centre lies half a pixel inside the true edge on average; moving it
    outwards along the local outward normal of the contour removes that bias.
    """
    contours, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=len).reshape(-1, 2).astype(np.float64)
    if len(c) < 5:
        return c
    tangent = np.roll(c, -2, axis=0) - np.roll(c, 2, axis=0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    norm = np.linalg.norm(normal, axis=1, keepdims=True)
    normal = np.where(norm > 0, normal / np.maximum(norm, 1e-12), 0.0)
    # OpenCV's outer contours run so that this normal points outwards; check with the centroid.
    if np.mean(np.sum((c - c.mean(axis=0)) * normal, axis=1)) < 0:
        normal = -normal
    return c + 0.5 * normal


def unoccluded(
    outline_uv: np.ndarray, depth_m: np.ndarray, face_depth_m: float, *, step_px: float = 2.5, margin_m: float = 0.005
) -> np.ndarray:
    """Which outline points are the face's own edge, not the edge of something in front of it.

    Just outside an occluded stretch of outline lies a surface nearer the camera than the face.
    """
    c = np.round(outline_uv).astype(int)
    centre = c.mean(axis=0)
    out_dir = outline_uv - centre
    out_dir /= np.maximum(np.linalg.norm(out_dir, axis=1, keepdims=True), 1e-9)
    probe = np.round(outline_uv + step_px * out_dir).astype(int)
    h, w = depth_m.shape
    probe[:, 0] = np.clip(probe[:, 0], 0, w - 1)
    probe[:, 1] = np.clip(probe[:, 1], 0, h - 1)
    d = depth_m[probe[:, 1], probe[:, 0]]
    return ~(np.isfinite(d) & (d < face_depth_m - margin_m))


def crop_frame(frame: RGBDFrame, x0: int, y0: int, x1: int, y1: int) -> RGBDFrame:
    """A frame cut to columns x0:x1 and rows y0:y1, with the principal point moved to match, and
    every depth hole (0, NaN, inf, nearer than any reading) as NaN: a hole is never a point."""
    K = frame.intrinsics
    Kc = Intrinsics(width=x1 - x0, height=y1 - y0, fx=K.fx, fy=K.fy, cx=K.cx - x0, cy=K.cy - y0)
    return dataclasses.replace(
        frame, rgb=frame.rgb[y0:y1, x0:x1], depth_m=holes_as_nan(frame.depth_m[y0:y1, x0:x1]), intrinsics=Kc
    )


def _target_roi(
    frame: RGBDFrame, model: TargetModel, params: PerceptionParams, pad: int = 8, stride: int = 4
) -> tuple[int, int, int, int]:
    """Bounding box of the pixels of the target's colour, padded.

    Searched on every ``stride``-th pixel (any blob wider than the stride is hit), which makes
    this whole-frame step 16x cheaper; everything after it runs on the box only.
    """
    cand = color_match(frame.rgb[::stride, ::stride], model.color, params.color_cos_min)
    ys, xs = np.nonzero(cand)
    if len(xs) == 0:
        raise PerceptionError("the target is not in view: no pixel has its colour")
    if len(xs) * stride * stride < params.min_target_px:
        raise PerceptionError(f"only about {len(xs) * stride * stride} pixels have the target's colour")
    h, w = frame.rgb.shape[:2]
    return (
        max(int(xs.min()) * stride - pad, 0),
        max(int(ys.min()) * stride - pad, 0),
        min(int(xs.max()) * stride + stride + pad, w),
        min(int(ys.max()) * stride + stride + pad, h),
    )


def _fit_face_plane(
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


def _fit_outline(
    xy: np.ndarray, model: TargetModel, weights: np.ndarray | None = None, init: tuple[np.ndarray, float] | None = None
) -> tuple[np.ndarray, float, tuple[float, float], np.ndarray]:
    """Centre (2,), in-plane yaw (rad), measured size and 3x3 covariance of (cx, cy, yaw) of the top
    face from outline points in plane coordinates (yaw variance 0 for a cylinder)."""
    if model.shape == "box":
        (cx2, cy2), (w2, h2), ang = cv2.minAreaRect(xy.astype(np.float32))
        if init is None:
            yaw = float(np.radians(ang))
            if (w2 < h2) == (model.size[0] >= model.size[1]):
                yaw += np.pi / 2.0
                w2, h2 = h2, w2
            init = (np.array([cx2, cy2], dtype=np.float64), yaw)
        center, yaw, cov = _refine_rectangle(xy, init[0], init[1], model.size[0], model.size[1], weights)
        return center, yaw, (float(max(w2, h2)), float(min(w2, h2))), cov
    (cx2, cy2), (a2, b2), _ = cv2.fitEllipse(xy.astype(np.float32))
    start = np.array([cx2, cy2], dtype=np.float64) if init is None else init[0]
    center, cov2 = _refine_circle(xy, start, model.size[0] / 2.0, weights)
    cov = np.zeros((3, 3))
    cov[:2, :2] = cov2
    return center, 0.0, (float(a2), float(b2)), cov


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


def estimate_pose(frame: RGBDFrame, model: TargetModel, params: PerceptionParams | None = None) -> PoseEstimate:
    """The target's pose from one frame (see the module docstring for the method).

    Raises :class:`PerceptionError` with the reason when the target cannot be measured, a degenerate
    fit included (too little of it visible: a singular system); nothing else escapes.
    """
    try:
        return _estimate_pose(frame, model, params or PerceptionParams())
    except (np.linalg.LinAlgError, cv2.error, ValueError, IndexError) as exc:
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise PerceptionError(
            f"degenerate fit ({type(exc).__name__}: {reason}): too little of the target seen"
        ) from None


def _estimate_pose(frame: RGBDFrame, model: TargetModel, params: PerceptionParams) -> PoseEstimate:
    x0, y0, x1, y1 = _target_roi(frame, model, params)
    f = crop_frame(frame, x0, y0, x1, y1)
    if f.rgb_noise_sigma >= params.denoise_rgb_sigma:
        # A noisy colour image breaks the top face into specks: a 5x5 median restores its flat colour
        # (noise / ~2.5) and keeps its edges where they are (a median does not blur a step).
        f = dataclasses.replace(f, rgb=cv2.medianBlur(np.ascontiguousarray(f.rgb), 5))
    K = f.intrinsics
    pts = world_heights(f)
    mask = segment_target(f, model, params, pts)
    face = top_face_mask(f, mask, pts, params)

    # Eqs. (9)-(10) for every pixel, with eq. (8) as each pixel's own variance.
    depth = np.where(np.isfinite(f.depth_m), f.depth_m, np.nan)
    mu_z, var_z = mixture_moments(depth, f.depth_variance(depth))

    # Pass 1: plane from the face pixels whose whole 3x3 window lies on the face (no edge mixing).
    inner = cv2.erode(face.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    normal, plane_point, _ = _fit_face_plane(f, inner if inner.sum() >= 6 else face, mu_z, var_z)

    outline_uv = outline_pixels(face)
    if model.shape == "cylinder":
        # Only the arc that is also the silhouette: where the flat cap meets the smooth-shaded side,
        # the colour boundary sits up to a pixel off (measured: 0.24 mm bias toward the camera).
        rim = mask & ~cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        rim = cv2.dilate(rim.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        iu = np.clip(np.round(outline_uv[:, 0]).astype(int), 0, K.width - 1)
        iv = np.clip(np.round(outline_uv[:, 1]).astype(int), 0, K.height - 1)
        if rim[iv, iu].sum() >= 10:
            outline_uv = outline_uv[rim[iv, iu]]
    px_m = float(np.nanmedian(depth[face])) / K.fx  # one pixel's footprint, m
    # An outline point is an image feature: the paper's sigma_u = sigma_v = 1 px (eq. 14) applies.
    var_edge = (params.edge_sigma_px * px_m) ** 2
    # Where something stands in front of the face, its outline is that thing's edge: leave it out.
    face_depth = float(np.nanmedian(depth[face]))
    visible = unoccluded(outline_uv, depth, face_depth)
    if visible.sum() >= 10:
        outline_uv = outline_uv[visible]

    # The start of the 6-DoF fit below: the outline on the first plane, fitted with the known shape.
    B = _plane_basis(normal)
    xy = (intersect_rays_plane(f, outline_uv, normal, plane_point) - plane_point) @ B[:, :2]
    center2, yaw_face, size_face, _ = _fit_outline(xy, model)

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
        if model.shape == "box":
            r, J = _rectangle_residuals(p2a, model.size[0], model.size[1])(np.array([*center2, yaw_face]))
        else:
            r, J = _circle_residuals(p2a, model.size[0] / 2.0)(center2)
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
    symmetry = (
        0.0 if model.shape == "cylinder" else (np.pi / 2.0 if abs(model.size[0] - model.size[1]) < 1e-9 else np.pi)
    )

    top_center = plane_point + B[:, :2] @ center2
    center = top_center - normal * (model.height_m / 2.0)
    x_axis = B[:, :2] @ np.array([np.cos(yaw_face), np.sin(yaw_face)])
    R = np.column_stack([x_axis, np.cross(normal, x_axis), normal])

    # Last, the 6-DoF covariance-weighted fit of the whole model: every target pixel's mixture point
    # against its surface, and the outline (with the features on it) against its top face's edges.
    edge_uv = np.vstack([outline_uv, feat_uv])
    edge_var = np.concatenate([np.full(len(outline_uv), var_edge), feat_var])
    # Dense points: each pixel's own depth, with the mixture's variance (eq. 10) as its uncertainty,
    # which grows where the 3x3 window spans a depth step. (The mixture's mean, eq. 9, would smear a
    # surface across such a step; measured: 0.09 mm median error with it, 0.04 mm without.)
    pose, cov6, _ = refine_pose_6dof(
        f, mask, depth, var_z, model, Pose(center, R), edge_uv, edge_var, max_points=params.fit_points
    )
    # A floor for what the fit cannot see: the scene itself is modelled to some 10-20 um (a cylinder's
    # 64-sided mesh deviates 24 um from the circle; rasterisation quantises edges), so no direction
    # is reported better than that, however many points agree.
    w, V = np.linalg.eigh(0.5 * (cov6[:3, :3] + cov6[:3, :3].T))
    pos_cov = V @ np.diag(np.maximum(w, 0.0) + MODEL_FLOOR_M**2) @ V.T
    # The camera's pose is known only to its calibration's accuracy: an error of that size in any
    # direction moves every point alike (a turn by the range times the angle), a third of its square
    # on each axis.
    s_t, s_r = f.calibration_sigma
    if s_t > 0.0 or s_r > 0.0:
        rng_m = float(np.linalg.norm(pose.position - f.T_world_cam.position))
        pos_cov = pos_cov + np.eye(3) * (s_t**2 + (s_r * rng_m) ** 2) / 3.0
    rpy_cov = cov6[3:, 3:]
    if model.shape == "cylinder":
        rpy_cov = rpy_cov.copy()
        rpy_cov[2, :] = rpy_cov[:, 2] = 0.0  # no yaw to speak of
    return PoseEstimate(
        pose=pose,
        position_cov=pos_cov,
        rpy_cov=rpy_cov,
        yaw_symmetry_rad=symmetry,
        top_face_size_m=size_face,
        n_features=len(features),
        n_features_fused=n_used,
        n_face_pixels=int(face.sum()),
        features=features,
    )


def closest_on_model(points: np.ndarray, model: TargetModel) -> tuple[np.ndarray, np.ndarray]:
    """Closest points on the model's surface (model frame, centred) and the outward normals there."""
    if model.shape == "box":
        h = np.array(model.size) / 2.0
        inside = np.all(np.abs(points) <= h, axis=1)
        q = np.clip(points, -h, h)
        # Points inside the box go to their nearest face.
        gap = h - np.abs(points)
        axis_in = np.argmin(gap, axis=1)
        idx = np.nonzero(inside)[0]
        q[idx, axis_in[idx]] = np.sign(points[idx, axis_in[idx]] + 1e-15) * h[axis_in[idx]]
        # The normal of the face the closest point lies on (the axis where it sits on the boundary,
        # preferring the one the point is furthest out along).
        out = np.abs(points) - h
        out[inside] = -gap[inside]
        axis = np.argmax(out, axis=1)
        n = np.zeros_like(points)
        n[np.arange(len(points)), axis] = np.sign(points[np.arange(len(points)), axis] + 1e-15)
        return q, n
    r, hh = model.size[0] / 2.0, model.size[1] / 2.0
    rho = np.hypot(points[:, 0], points[:, 1])
    radial = np.column_stack([points[:, 0], points[:, 1]]) / np.maximum(rho, 1e-12)[:, None]
    d_side = np.where(np.abs(points[:, 2]) <= hh, np.abs(rho - r), np.inf)
    d_cap = np.where(rho <= r, np.abs(np.abs(points[:, 2]) - hh), np.inf)
    on_side = d_side <= d_cap
    q = points.copy()
    n = np.zeros_like(points)
    q[on_side, :2] = radial[on_side] * r
    q[on_side, 2] = np.clip(points[on_side, 2], -hh, hh)
    n[on_side, :2] = radial[on_side]
    caps = ~on_side
    clip_rho = np.minimum(rho[caps], r)
    q[caps, :2] = radial[caps] * clip_rho[:, None]
    q[caps, 2] = np.sign(points[caps, 2] + 1e-15) * hh
    n[caps, 2] = np.sign(points[caps, 2] + 1e-15)
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
    mu_z: np.ndarray,
    var_z: np.ndarray,
    model: TargetModel,
    start: Pose,
    outline_uv: np.ndarray,
    outline_var: np.ndarray,
    *,
    iterations: int = 4,
    max_points: int = 2000,
) -> tuple[Pose, np.ndarray, int]:
    """The object's pose by a covariance-weighted fit of its known shape (our design; the paper
    leaves the pose step open).

    Residuals, each divided by its own standard deviation:

    * every target pixel's mixture point (eqs. 5-10) against the model's surface, point to plane;
      its variance is eq. (14)'s covariance projected on the surface normal, so a pixel on an edge,
      whose 3x3 mixture spans two depths (eq. 10), weighs little;
    * every outline ray of the top face (and each Shi-Tomasi feature on it): where it meets the
      model's top plane, its distance to the top face's edge; variance ``outline_var``.

    Gauss-Newton on a twist at the object's centre, ``T = T0 exp(xi)``. Returns the pose, the 6x6
    covariance of (translation in the world frame, roll / pitch / yaw) and the points used.
    """
    K = frame.intrinsics
    Tc = frame.T_world_cam
    vs, us = np.nonzero(pixels)
    if len(vs) > max_points:  # a regular, deterministic thinning: the fit's cost grows with the points
        keep = np.arange(0, len(vs), int(np.ceil(len(vs) / max_points)))
        vs, us = vs[keep], us[keep]
    z = mu_z[vs, us]
    vz = var_z[vs, us]
    ok = np.isfinite(z) & np.isfinite(vz)
    vs, us, z, vz = vs[ok], us[ok], z[ok], vz[ok]
    du, dv = us - K.cx, vs - K.cy
    ray = np.column_stack([du / K.fx, dv / K.fy, np.ones(len(z))])  # a = (x/z, y/z, 1)
    pts = Tc.transform_points(ray * z[:, None])
    # Eq. (14) is var_z a a^T + sigma_uv^2 z^2 diag(1/fx^2, 1/fy^2, 0); projected on a unit normal
    # n (camera frame) that is var_z (n.a)^2 + sigma_uv^2 z^2 (n_x^2/fx^2 + n_y^2/fy^2), per point.
    s2z2 = SIGMA_UV_PX**2 * z * z
    Rc = Tc.rotation
    rays = pixel_rays_cam(outline_uv, K) @ Rc.T
    half_h = model.height_m / 2.0

    def edge_residuals(T: pin.SE3) -> np.ndarray:
        """Outline rays against the model's top plane and its top face's edges (m)."""
        R, t = T.rotation, T.translation
        normal = R[:, 2]
        top = t + normal * half_h
        tr = ((top - Tc.position) @ normal) / (rays @ normal)
        lp = (Tc.position + tr[:, None] * rays - t) @ R
        if model.shape == "box":
            hx, hy = model.size[0] / 2.0, model.size[1] / 2.0
            on_x = np.abs(np.abs(lp[:, 0]) - hx) < np.abs(np.abs(lp[:, 1]) - hy)
            return np.where(on_x, np.abs(lp[:, 0]) - hx, np.abs(lp[:, 1]) - hy)
        return np.hypot(lp[:, 0], lp[:, 1]) - model.size[0] / 2.0

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
        q, n = closest_on_model(local, model)
        nw = n @ R.T
        r_d = np.einsum("ij,ij->i", nw, pts - (q @ R.T + t))
        nc = nw @ Rc  # normals in the camera frame
        var_n = vz * np.einsum("ij,ij->i", nc, ray) ** 2 + s2z2 * (nc[:, 0] ** 2 / K.fx**2 + nc[:, 1] ** 2 / K.fy**2)
        sd = np.sqrt(np.maximum(var_n, 1e-14))
        J_d = np.hstack([-n, np.cross(n, q)]) / sd[:, None]
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
    return Pose.from_se3(T), A @ cov_local @ A.T, used


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


def _rectangle_residuals(xy: np.ndarray, sx: float, sy: float):
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


def _circle_residuals(xy: np.ndarray, radius: float):
    def f(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        d = xy - x
        dist = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        return dist - radius, -d / dist[:, None]

    return f


def _refine_rectangle(
    xy: np.ndarray, center: np.ndarray, yaw: float, sx: float, sy: float, weights: np.ndarray | None = None
) -> tuple[np.ndarray, float, np.ndarray]:
    """Weighted least-squares rectangle of known size through outline points.

    Each point is assigned to its nearest side; its residual is its signed distance to that side.
    Returns the centre (2,), the yaw (rad) and the 3x3 covariance of (cx, cy, yaw).
    """
    w = np.ones(len(xy)) if weights is None else weights
    x, cov = _gauss_newton(_rectangle_residuals(xy, sx, sy), np.array([center[0], center[1], yaw]), w)
    return x[:2], float(x[2]), cov


def _refine_circle(
    xy: np.ndarray, center: np.ndarray, radius: float, weights: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares centre of a circle of known radius; returns it and its 2x2 covariance."""
    w = np.ones(len(xy)) if weights is None else weights
    return _gauss_newton(_circle_residuals(xy, radius), np.asarray(center, dtype=np.float64), w)
