"""Pinhole camera maths as small pure functions: intrinsics, extrinsics, projection, depth, noise.

Conventions: camera frame as in OpenCV (x right, y down, z forward along the optical axis); pixel
(u, v) with u along image columns and v along rows, integer values at pixel centres. Depth is
z-depth along the optical axis (not ray length), in metres. ``T_world_cam`` maps camera-frame points
into the world frame. The renderer-side code (``pickdemo.sim.render``) builds its OpenGL matrices
from the same numbers, so what is rendered and what is back-projected agree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from pickdemo.core.geometry import OrientedBox, Pose

#: Depth noise model of the paper's eq. (8) (Kinect / Xtion): sigma_z = 1.45e-3 z^2, z and sigma in m.
KINECT_NOISE_COEFF = 1.45e-3

# OpenGL's camera looks down -z with y up; OpenCV's looks down +z with y down.
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics (pixels)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    @staticmethod
    def from_fov(
        width: int, height: int, fov_x_deg: float, fov_y_deg: float, *, cx: float | None = None, cy: float | None = None
    ) -> Intrinsics:
        """Intrinsics of a camera with the given horizontal and vertical fields of view.

        ``fx = (W / 2) / tan(fov_x / 2)`` (the paper's eqs. 1-4 with ``P = 2 tan(angle / 2)``). The
        principal point defaults to the image centre ``((W - 1) / 2, (H - 1) / 2)``.
        """
        fx = (width / 2.0) / np.tan(np.radians(fov_x_deg) / 2.0)
        fy = (height / 2.0) / np.tan(np.radians(fov_y_deg) / 2.0)
        return Intrinsics(
            width=width,
            height=height,
            fx=float(fx),
            fy=float(fy),
            cx=float((width - 1) / 2.0 if cx is None else cx),
            cy=float((height - 1) / 2.0 if cy is None else cy),
        )

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix K."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


#: Where PyBullet's TinyRenderer puts the optical axis of a symmetric frustum, relative to the image
#: size (measured, and checked by the rendered-tile test): cx = W / 2 + 0, cy = H / 2 - 1.
TINY_CX_OFFSET = 0.0
TINY_CY_OFFSET = -1.0


def rendered_intrinsics(width: int, height: int, fov_x_deg: float, fov_y_deg: float) -> Intrinsics:
    """The intrinsics of images rendered by TinyRenderer with this field of view."""
    return Intrinsics.from_fov(
        width, height, fov_x_deg, fov_y_deg, cx=width / 2.0 + TINY_CX_OFFSET, cy=height / 2.0 + TINY_CY_OFFSET
    )


def look_at_pose(position: np.ndarray, target: np.ndarray, up: np.ndarray = (0.0, 0.0, 1.0)) -> Pose:
    """``T_world_cam`` of a camera at ``position`` whose optical axis points at ``target``."""
    position = np.asarray(position, dtype=float)
    z = np.asarray(target, dtype=float) - position
    z /= np.linalg.norm(z)
    up = np.asarray(up, dtype=float)
    if abs(float(np.dot(z, up))) > 0.999:  # looking straight along "up": pick another reference
        up = np.array([1.0, 0.0, 0.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return Pose(position, np.column_stack([x, y, z]))


def hand_camera_pose(T_tcp_mount: Pose, position: np.ndarray, look_at: np.ndarray) -> Pose:
    """``T_tcp_cam`` of a camera on the hand at ``position`` looking at ``look_at`` (both in the mount's
    frame), its image's rows across the hand's y axis (the fingers' direction): the image's width lies
    along the way it looks past the fingers."""
    return T_tcp_mount @ look_at_pose(np.asarray(position, float), np.asarray(look_at, float), up=(0.0, 1.0, 0.0))


def project(points_cam: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Project (N, 3) camera-frame points to (N, 2) pixel coordinates (eqs. 5-6 inverted)."""
    p = np.atleast_2d(points_cam)
    return np.column_stack([K.fx * p[:, 0] / p[:, 2] + K.cx, K.fy * p[:, 1] / p[:, 2] + K.cy])


def backproject(uv: np.ndarray, z_m: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Paper eqs. (5)-(7): pixel (u, v) with z-depth z to a camera-frame point (N, 3), metres."""
    uv = np.atleast_2d(uv)
    z = np.asarray(z_m, dtype=float).reshape(-1)
    return np.column_stack([z * (uv[:, 0] - K.cx) / K.fx, z * (uv[:, 1] - K.cy) / K.fy, z])


def backproject_image(depth_m: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Back-project a whole (H, W) depth image into an (H, W, 3) camera-frame point image."""
    h, w = depth_m.shape
    u = (np.arange(w, dtype=float) - K.cx) / K.fx
    v = (np.arange(h, dtype=float) - K.cy) / K.fy
    return np.stack([depth_m * u[None, :], depth_m * v[:, None], depth_m], axis=-1)


def pixel_rays_cam(uv: np.ndarray, K: Intrinsics) -> np.ndarray:
    """Directions (N, 3) of the rays through pixels, scaled so that their z component is 1."""
    uv = np.atleast_2d(uv)
    return np.column_stack([(uv[:, 0] - K.cx) / K.fx, (uv[:, 1] - K.cy) / K.fy, np.ones(len(uv))])


def depth_from_buffer(zbuf: np.ndarray, near_m: float, far_m: float) -> np.ndarray:
    """Metric z-depth from an OpenGL depth buffer in [0, 1] (non-linear)."""
    zbuf = np.asarray(zbuf, dtype=np.float64)
    return far_m * near_m / (far_m - (far_m - near_m) * zbuf)


def kinect_sigma_m(z_m: np.ndarray | float) -> np.ndarray:
    """Standard deviation of a depth reading (paper eq. 8): ``1.45e-3 z^2``, metres."""
    return KINECT_NOISE_COEFF * np.square(z_m)


#: Intel's depth RMS model for the D4xx stereo cameras: sigma_z = z^2 * subpixel / (f_px * baseline).
D4XX_SUBPIXEL = 0.08
D4XX_BASELINE_M = {"d415": 0.055, "d435": 0.050}
#: Depth below this is no reading at all (drivers write 0 for "no return"; nothing is this close).
MIN_VALID_DEPTH_M = 0.05


def depth_noise_coeff(model: str, fx_px: float) -> float:
    """``k`` of the sensor's depth noise ``sigma_z = k z^2`` (m^-1): Kinect's eq. (8), or Intel's RMS
    model with this camera's focal length. ``"none"`` keeps eq. (8) as the model perception assumes."""
    if model in D4XX_BASELINE_M:
        return D4XX_SUBPIXEL / (fx_px * D4XX_BASELINE_M[model])
    return KINECT_NOISE_COEFF


def holes_as_nan(depth_m: np.ndarray) -> np.ndarray:
    """Depth with every "no return" as NaN: 0 (what drivers write), NaN, inf, or nearer than any reading."""
    d = np.asarray(depth_m, dtype=np.float64)
    return np.where(np.isfinite(d) & (d > MIN_VALID_DEPTH_M), d, np.nan)


def depth_edges(depth_m: np.ndarray, jump_m: float = 0.01) -> np.ndarray:
    """Pixels next to a depth discontinuity (a jump of more than ``jump_m`` to a 4-neighbour)."""
    d = np.nan_to_num(np.asarray(depth_m, dtype=np.float64), nan=10.0, posinf=10.0)
    edge = np.zeros(d.shape, dtype=bool)
    dx = np.abs(np.diff(d, axis=1)) > jump_m
    dy = np.abs(np.diff(d, axis=0)) > jump_m
    edge[:, 1:] |= dx
    edge[:, :-1] |= dx
    edge[1:, :] |= dy
    edge[:-1, :] |= dy
    return edge


def sensor_faults(
    rgb: np.ndarray,
    depth_m: np.ndarray,
    rng: np.random.Generator,
    *,
    noise_coeff: float,
    holes: float = 0.0,
    edge_dropout: float = 0.0,
    invalid: float = 0.0,
    quantum_m: float = 0.0,
    rgb_sigma: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """What a real RGB-D camera does to a perfect frame: depth noise ``k z^2``, holes at random and
    at depth edges (written as ``invalid``: 0.0 like real drivers, or NaN), depth in steps of
    ``quantum_m``, Gaussian RGB noise. Draws from ``rng`` only for the faults that are on."""
    depth = np.asarray(depth_m, dtype=np.float64).copy()
    finite = np.isfinite(depth)
    if noise_coeff > 0.0:
        depth[finite] += noise_coeff * depth[finite] ** 2 * rng.standard_normal(int(finite.sum()))
    if quantum_m > 0.0:
        depth[finite] = np.round(depth[finite] / quantum_m) * quantum_m
    drop = np.zeros(depth.shape, dtype=bool)
    if edge_dropout > 0.0:
        drop |= depth_edges(depth_m) & (rng.random(depth.shape) < edge_dropout)
    if holes > 0.0:
        drop |= rng.random(depth.shape) < holes
    depth[drop] = invalid
    if rgb_sigma > 0.0:
        rgb = np.clip(rgb.astype(np.float64) + rng.normal(0.0, rgb_sigma, rgb.shape), 0, 255).astype(np.uint8)
    return rgb, depth


def calibration_error(error_mm: float, error_deg: float, rng: np.random.Generator) -> Pose | None:
    """A camera-frame pose error of exactly ``error_mm`` and ``error_deg``, in directions drawn from
    ``rng``: the robot is told ``T_world_cam_true @ error``. None when both are 0."""
    if error_mm <= 0.0 and error_deg <= 0.0:
        return None
    t = rng.standard_normal(3)
    axis = rng.standard_normal(3)
    t *= error_mm * 1e-3 / np.linalg.norm(t)
    axis *= np.radians(error_deg) / np.linalg.norm(axis)
    return Pose(t, pin.exp3(axis))


def add_kinect_noise(depth_m: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A noisy copy of a depth image, independent Gaussian per pixel with eq. (8)'s deviation."""
    noise = rng.standard_normal(depth_m.shape)
    return depth_m + kinect_sigma_m(depth_m) * noise


def opengl_view_matrix(T_world_cam: Pose) -> list[float]:
    """Column-major 4x4 OpenGL view matrix (world -> GL camera) for pybullet."""
    R_gl = T_world_cam.rotation @ _GL_FROM_CV  # world <- GL camera
    view = np.eye(4)
    view[:3, :3] = R_gl.T
    view[:3, 3] = -R_gl.T @ T_world_cam.position
    return [float(v) for v in view.T.reshape(-1)]


def opengl_projection_matrix(
    K: Intrinsics, near_m: float, far_m: float, roi: tuple[int, int, int, int] | None = None
) -> list[float]:
    """Column-major 4x4 OpenGL projection with K's focal lengths: the whole image's symmetric frustum,
    or the part of it that covers the region of interest ``roi = (x0, y0, x1, y1)`` (pixels, x1 and y1
    exclusive) of the whole image.

    The renderer decides at which pixel the optical axis lands (its pixel-centre convention); the
    simulator side measures that and sets ``K.cx``, ``K.cy`` to match (``pickdemo.sim.render``). The
    frustum is placed by the image's size, not by ``cx, cy``, so a crop rendered with this matrix
    holds exactly the pixels ``[y0:y1, x0:x1]`` of the whole frame (its principal point is
    ``(cx - x0, cy - y0)``: :func:`crop_intrinsics`).
    """
    x0, y0, x1, y1 = (0, 0, K.width, K.height) if roi is None else roi
    left = (x0 - K.width / 2.0) / K.fx * near_m
    right = (x1 - K.width / 2.0) / K.fx * near_m
    top = (K.height / 2.0 - y0) / K.fy * near_m  # OpenGL's y points up, image rows down
    bottom = (K.height / 2.0 - y1) / K.fy * near_m
    proj = np.zeros((4, 4))
    proj[0, 0] = 2.0 * near_m / (right - left)
    proj[0, 2] = (right + left) / (right - left)
    proj[1, 1] = 2.0 * near_m / (top - bottom)
    proj[1, 2] = (top + bottom) / (top - bottom)
    proj[2, 2] = -(far_m + near_m) / (far_m - near_m)
    proj[2, 3] = -2.0 * far_m * near_m / (far_m - near_m)
    proj[3, 2] = -1.0
    return [float(v) for v in proj.T.reshape(-1)]


def crop_intrinsics(K: Intrinsics, roi: tuple[int, int, int, int]) -> Intrinsics:
    """Intrinsics of the region ``(x0, y0, x1, y1)`` of an image: same focal lengths, shifted centre."""
    x0, y0, x1, y1 = roi
    return Intrinsics(width=x1 - x0, height=y1 - y0, fx=K.fx, fy=K.fy, cx=K.cx - x0, cy=K.cy - y0)


def strided_intrinsics(K: Intrinsics, stride: int) -> Intrinsics:
    """Intrinsics of every ``stride``-th pixel of an image (pixel ``i`` of the strided image is ``stride * i``)."""
    return Intrinsics(width=-(-K.width // stride), height=-(-K.height // stride), fx=K.fx / stride,
                      fy=K.fy / stride, cx=K.cx / stride, cy=K.cy / stride)  # fmt: skip


def roi_around(
    points_world: np.ndarray, K: Intrinsics, T_world_cam: Pose, *, pad_px: int, min_size_px: int = 48
) -> tuple[int, int, int, int] | None:
    """The pixel box ``(x0, y0, x1, y1)`` that holds the projections of the given world points, padded
    and clipped to the image; ``None`` when a point is behind the camera or the box misses the image."""
    p_cam = T_world_cam.inverse().transform_points(np.atleast_2d(points_world))
    if np.any(p_cam[:, 2] <= 1e-3):
        return None
    uv = project(p_cam, K)
    lo = np.floor(uv.min(axis=0)) - pad_px
    hi = np.ceil(uv.max(axis=0)) + pad_px + 1
    grow = np.maximum(min_size_px - (hi - lo), 0.0) / 2.0
    lo, hi = lo - np.floor(grow), hi + np.ceil(grow)
    x0, y0 = int(max(lo[0], 0)), int(max(lo[1], 0))
    x1, y1 = int(min(hi[0], K.width)), int(min(hi[1], K.height))
    if x1 - x0 < 8 or y1 - y0 < 8:
        return None
    return x0, y0, x1, y1


@dataclass(frozen=True)
class RGBDFrame:
    """One camera frame: what a real robot's driver would hand over, and nothing more."""

    rgb: np.ndarray  # (H, W, 3) uint8
    depth_m: np.ndarray  # (H, W) float64, z-depth in m; inf or nan where there is no return
    intrinsics: Intrinsics
    T_world_cam: Pose
    time_s: float  # simulated time at which it was taken
    roi: tuple[int, int, int, int] | None = None  # (x0, y0, x1, y1) of the whole image, when a crop
    # What the robot knows of its sensor (its datasheet and its calibration's accuracy):
    depth_noise_coeff: float = KINECT_NOISE_COEFF  # sigma_z = k z^2 (m^-1)
    depth_quantum_m: float = 0.0  # depth reported in steps of this (adds q^2 / 12 of variance)
    calibration_sigma: tuple[float, float] = (0.0, 0.0)  # (m, rad): how far T_world_cam may be off
    rgb_noise_sigma: float = 0.0  # 8-bit units, the colour image's noise
    depth_edge_dropout: float = 0.0  # fraction of pixels at depth edges that read no depth
    #: The robot's own links where its joint states put them when the frame was taken (padded boxes):
    #: a point inside one is the arm or the hand, not the scene (the self-filter). Empty: not known.
    robot_boxes: tuple[OrientedBox, ...] = ()
    #: The cell's fixtures (a bin, a shelf), known from the task: a point as near one as the depth noise
    #: can put a point of its surface is the fixture, not an object on it.
    fixture_boxes: tuple[OrientedBox, ...] = ()
    #: What objects rest on besides the table, known from the task (a belt's top): no object itself
    #: (the world model's instances leave it out; an estimate of the target is not told it)
    support_boxes: tuple[OrientedBox, ...] = ()
    camera: str = "camera"  # which camera took it: "camera" (the fixed one) or "wrist_camera"

    def calibration_cov_at(self, point_world: np.ndarray) -> np.ndarray | None:
        """The covariance (m^2) a point seen at ``point_world`` takes from the camera's pose being known
        only to its calibration: an error of that size in any direction moves every point alike (a turn
        by the range times the angle), a third of its square on each axis. None when the pose is exact."""
        s_t, s_r = self.calibration_sigma
        if s_t <= 0.0 and s_r <= 0.0:
            return None
        rng_m = float(np.linalg.norm(point_world - self.T_world_cam.position))
        return np.eye(3) * (s_t**2 + (s_r * rng_m) ** 2) / 3.0

    def depth_variance(self, z_m: np.ndarray | float) -> np.ndarray:
        """Variance (m^2) of a depth reading at ``z_m``: the sensor's noise and its quantisation."""
        return np.square(self.depth_noise_coeff * np.square(z_m)) + self.depth_quantum_m**2 / 12.0
