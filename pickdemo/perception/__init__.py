"""Perception: the target's pose from one RGB-D frame, by the paper's method (``shared/paper``).

Pure: arrays in, dataclasses out. It reads only what a real robot has: the RGB image, the metric
depth image, the intrinsics and the camera pose, where its own links were when the frame was taken
(from its joint states), plus the task's description of the target (its colour, shape and size, as a
pick order or a CAD model would give them). Nothing from the simulator.

Steps (equation numbers as in the paper):

1. Segment the target: pixels above the table plane (z = 0) whose colour matches the target's and
   whose point is not in the robot's own body (the frame's ``robot_boxes``: the self-filter),
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

The modules, in the order the method runs: :mod:`.model` (what crosses the boundary), :mod:`.equations`
(the paper's eqs. 8-14), :mod:`.segmentation`, :mod:`.features`, :mod:`.fit2d`, :mod:`.fit6d` and
:mod:`.pipeline` (:func:`estimate_pose`); :mod:`.neighbours`, what stands around the target (for
any estimator's estimate). Everything is re-exported here.

Each choice is stated where it is made (the mixture's variance but each pixel's own depth; features
selected on the outline in the image; the cylinder's side arc left out); its evidence is in
docs/decisions.md#perception.
"""

from pickdemo.perception.equations import (
    MIXTURE_KERNEL,
    SIGMA_COLOR,
    SIGMA_UV_PX,
    mixture_at,
    mixture_moments,
    point_covariance,
)
from pickdemo.perception.features import condition_on_plane, measure_features, shi_tomasi_features
from pickdemo.perception.fit2d import (
    circle_residuals,
    fit_face_plane,
    fit_outline,
    fit_plane_weighted,
    intersect_rays_plane,
    plane_basis,
    rectangle_residuals,
    refine_circle,
    refine_rectangle,
)
from pickdemo.perception.fit6d import MODEL_FLOOR_M, closest_on_model, refine_pose_6dof
from pickdemo.perception.model import (
    FeaturePoint,
    FitQuality,
    ObjectCloud,
    PerceptionError,
    PerceptionParams,
    PoseEstimate,
    TargetModel,
)
from pickdemo.perception.neighbours import neighbour_points, with_neighbours
from pickdemo.perception.pipeline import estimate_pose
from pickdemo.perception.segmentation import (
    color_match,
    crop_frame,
    outline_pixels,
    segment_target,
    target_roi,
    top_face_mask,
    unoccluded,
    world_heights,
    world_points,
)

__all__ = [
    "MIXTURE_KERNEL", "MODEL_FLOOR_M", "SIGMA_COLOR", "SIGMA_UV_PX", "FeaturePoint", "FitQuality", "ObjectCloud",
    "PerceptionError", "PerceptionParams", "PoseEstimate", "TargetModel", "circle_residuals",
    "closest_on_model", "color_match", "condition_on_plane", "crop_frame", "estimate_pose", "fit_face_plane",
    "fit_outline", "fit_plane_weighted", "intersect_rays_plane", "measure_features", "mixture_at",
    "mixture_moments", "neighbour_points", "outline_pixels", "plane_basis", "point_covariance",
    "rectangle_residuals", "refine_circle", "refine_pose_6dof", "refine_rectangle", "segment_target",
    "shi_tomasi_features", "target_roi", "top_face_mask", "unoccluded", "with_neighbours", "world_heights",
    "world_points",
]  # fmt: skip
