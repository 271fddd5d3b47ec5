"""What crosses perception's boundary: the target as the task describes it, the tuning, the estimate
with its uncertainty, and the error.

Pure: arrays in, dataclasses out; no simulator.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pickdemo.core.camera import Intrinsics
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Shape


class PerceptionError(RuntimeError):
    """The target could not be found or measured in the frame, or perception's own checks rejected
    what it measured (then ``estimate`` holds that estimate, for scoring and reading only)."""

    def __init__(self, reason: str, estimate: PoseEstimate | None = None) -> None:
        super().__init__(reason)
        self.estimate = estimate


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
    fit_points: int = 8000  # depth points in the 6-DoF fit at most (a regular thinning beyond)
    # The fit checks itself: an estimate is rejected when its normalised residuals' RMS exceeds this
    # (the noise model says 1), when more than these fractions of the depth points or of the outline
    # lie beyond 4 sigma, or when fewer depth points than this fit at all.
    max_residual_rms: float = 5.0
    max_depth_outliers: float = 0.3
    max_edge_outliers: float = 0.5
    min_fit_points: int = 30
    denoise_rgb_sigma: float = 8.0  # from this RGB noise (8-bit) on, a median filter first

    def __post_init__(self) -> None:
        if not 0.0 < self.color_cos_min <= 1.0:
            raise ValueError("color_cos_min must be in (0, 1]")
        if self.min_height_m <= 0.0 or self.min_target_px < 3 or self.max_features < 1:
            raise ValueError("min_height_m, min_target_px and max_features must be positive")
        outliers_ok = 0.0 < self.max_depth_outliers <= 1.0 and 0.0 < self.max_edge_outliers <= 1.0
        if self.max_residual_rms <= 1.0 or not outliers_ok:
            raise ValueError("max_residual_rms must exceed 1 and the outlier fractions lie in (0, 1]")


@dataclass(frozen=True)
class TargetModel:
    """What the task says about the target: its shape with its size (m), and its nominal colour (0-1;
    None: not said, for an object nobody described, whose shape is :class:`~pickdemo.core.shapes.Unknown`)."""

    geometry: Shape
    color: tuple[float, float, float] | None

    @property
    def shape(self) -> str:
        """The shape's name (``"box"``, ``"cylinder"``)."""
        return self.geometry.kind

    @property
    def size(self) -> tuple[float, ...]:
        """Box: x, y, z; cylinder: diameter, height (m)."""
        return self.geometry.size

    @property
    def height_m(self) -> float:
        return self.geometry.height_m


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
class FitQuality:
    """How well the model fitted what was seen, in units of perception's own noise model: the RMS of
    the normalised residuals (1 when the noise model holds) of the depth points and of the outline,
    over the points kept, and the fractions dropped as gross outliers (beyond 4 sigma)."""

    depth_rms: float
    edge_rms: float
    depth_outliers: float
    edge_outliers: float
    points: int = 0  # depth points kept in the fit

    def problem(self, params: PerceptionParams) -> str:
        """Why the fit is not to be believed ("" when it is): residuals far beyond the noise model."""
        if self.points < params.min_fit_points:
            return f"only {self.points} depth points fit the model"
        if self.depth_outliers > params.max_depth_outliers:
            return f"{self.depth_outliers:.0%} of the depth points lie beyond 4 sigma of the model"
        if self.edge_outliers > params.max_edge_outliers:
            return f"{self.edge_outliers:.0%} of the outline lies beyond 4 sigma of the model"
        for which, rms in (("depth", self.depth_rms), ("outline", self.edge_rms)):
            if not rms <= params.max_residual_rms:  # (NaN included)
                return f"the {which} residuals are {rms:.3g} times the noise model"
        return ""


@dataclass(frozen=True)
class ObjectCloud:
    """What the camera saw of an object nobody described: its points in the world frame (m, thinned
    to a few thousand), the points of what stands near it (other objects: obstacles to a grasp), and
    the time of the frame."""

    points: np.ndarray  # (N, 3)
    obstacles: np.ndarray  # (M, 3)
    time_s: float
    #: the view it was seen in (the depth image, its intrinsics, the camera's pose): where the camera
    #: saw past a point, that point is free; where something nearer hid it, it is unknown
    depth_m: np.ndarray | None = field(default=None, repr=False)
    intrinsics: Intrinsics | None = None
    T_world_cam: Pose | None = None

    def unknown(self, points: np.ndarray, tolerance_m: float = 0.003) -> np.ndarray:
        """Which of (..., 3) world points the camera did not see to be free: hidden behind something
        nearer (or out of the view, or a hole in its depth)."""
        if self.depth_m is None or self.intrinsics is None or self.T_world_cam is None:
            return np.ones(points.shape[:-1], dtype=bool)
        K = self.intrinsics
        flat = points.reshape(-1, 3)
        cam = self.T_world_cam.inverse().transform_points(flat)
        z = cam[:, 2]
        ok = z > 1e-3
        u = np.full(len(flat), -1, dtype=np.int64)
        v = np.full(len(flat), -1, dtype=np.int64)
        u[ok] = np.round(K.fx * cam[ok, 0] / z[ok] + K.cx).astype(np.int64)
        v[ok] = np.round(K.fy * cam[ok, 1] / z[ok] + K.cy).astype(np.int64)
        inside = ok & (u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)
        seen = np.full(len(flat), np.nan)
        seen[inside] = self.depth_m[v[inside], u[inside]]
        free = np.isfinite(seen) & (seen >= z - tolerance_m)
        return (~free).reshape(points.shape[:-1])


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
    fit: FitQuality | None = None  # how well the model fitted (None: an estimator that does not say)
    features: tuple[FeaturePoint, ...] = field(repr=False, default=())
    #: an object nobody described: the points it was seen as (what grasps are planned from)
    cloud: ObjectCloud | None = field(repr=False, default=None)
    #: something nearer the camera (the hand, another object) hides part of it: a partial view
    occluded: bool = False
    #: the points (M, 3) of everything else near it, which a grasp's fingers and palm must keep out of
    #: (:func:`~pickdemo.perception.neighbours.with_neighbours`; None: the frame did not show all around it)
    neighbours: np.ndarray | None = field(repr=False, default=None)
    #: the part of ``position_cov`` that every frame from this view shares (m^2; an object nobody
    #: described: what the view hides of its shape), a bias rather than noise: it does not average
    #: away over frames, and it does not move when the object does (None: nothing shared)
    shared_cov: np.ndarray | None = field(repr=False, default=None)
    #: the part of ``position_cov`` that comes of the camera's pose being known only to its calibration
    #: (m^2): the same error in every frame of that camera, a bias; one camera's is independent of
    #: another's, which is how a second camera corrects the first (None: the camera's pose is exact)
    calibration_cov: np.ndarray | None = field(repr=False, default=None)

    @property
    def frame_cov(self) -> np.ndarray:
        """The position's covariance from one frame to the next (what a tracker fuses): ``position_cov``
        less what every frame shares."""
        return self.position_cov if self.shared_cov is None else self.position_cov - self.shared_cov

    def to_dict(self) -> dict[str, object]:
        d = self.pose.to_dict()
        d["position_std_mm"] = [float(v) for v in 1e3 * np.sqrt(np.diag(self.position_cov))]
        d["yaw_std_deg"] = float(np.degrees(np.sqrt(self.rpy_cov[2, 2])))
        d["n_features"] = self.n_features
        d["n_features_fused"] = self.n_features_fused
        d["n_face_pixels"] = self.n_face_pixels
        return d
