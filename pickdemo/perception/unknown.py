"""An object nobody described: found by its geometry, its pose by the paper's method, its points for
the grasp.

Pure: arrays in, dataclasses out; no simulator. Steps:

1. Segmentation by geometry: the pixels whose points stand above the table's plane (z = 0 in the
   world frame: the camera's pose is known), less the robot's own body (its links where its joint
   states put them: the self-filter), grouped into clusters by where their points stand on the
   table (a grid seen from above: an object hiding part of itself is still one, two objects a
   grid cell apart are two); first on a strided frame to find the region, then at full resolution
   in it.
2. Which cluster: a colour the task names is a cue (the cluster whose median colour is nearest
   it), not a requirement; else, on a region the robot asked for around its belief, the cluster
   nearest that region's centre; on the whole image, the one whose size seen is nearest a size the
   task names (:attr:`~pickdemo.core.shapes.Unknown.size_cue_m`), else the largest.
3. The paper's method on it: Shi-Tomasi features on the cluster, each with the 3x3 mixture's depth
   and colour (eqs. 9-12), back-projected (eqs. 5-7) with eq. (14)'s covariance. Features whose
   window spans a depth step (the object's silhouette against the table behind it) are left out:
   their mixture depth lies between two surfaces.
4. The pose, from every pixel of the cluster off its silhouette (its 3x3 mixture within one surface),
   each taken as the paper takes a feature: mixture depth (eqs. 9-10), back-projection (eqs. 5-7),
   covariance (eq. 14). The paper's features are Shi-Tomasi corners, and the pose their mean with
   the principal axes of their spread; on an object of plain colour there are too few corners (0 to
   7 on the duck, off its silhouette) and their mean moves with them, so every pixel is a feature
   here (the corners are still found and reported). Its yaw: the principal axes of their spread seen
   from above (the object is taken to stand as it rests: no roll or pitch), with the variance of a
   principal axis from that many independent points (a round object has none to speak of). Its
   position: the middle of its footprint along those axes (the far side's top edge bounds it) at
   half its height (it stands on the table up to its top seen, or on what the cell's ``support``
   says is under it: a shelf's board): what the camera sees from any side alike, where the visible
   surface's mean moves with the view.
5. Whether it is seen whole: something nearer the camera bordering its silhouette (the hand as it
   comes down, another object) hides part of it, and its centre seen is then off (the controller
   does not act on such a view).
6. Its points: every cluster pixel back-projected, thinned to a few thousand, with the other
   clusters' points near it as obstacles (:class:`~pickdemo.perception.model.ObjectCloud`): the grasp
   is planned from them (:mod:`pickdemo.grasping.cloud`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import cv2
import numpy as np

from pickdemo.core.camera import RGBDFrame, holes_as_nan, strided_intrinsics
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Unknown
from pickdemo.perception.equations import MIXTURE_KERNEL, mixture_moments, point_covariance
from pickdemo.perception.features import measure_features, shi_tomasi_features
from pickdemo.perception.model import ObjectCloud, PerceptionError, PerceptionParams, PoseEstimate, TargetModel
from pickdemo.perception.segmentation import crop_frame, nearest_in_colour, robot_pixels, world_points

#: The noise of the 3x3 mixture's mean (eq. 9) against one pixel's: sqrt(sum of the squared weights).
MIXTURE_NOISE_FRACTION = float(np.sqrt(np.sum(MIXTURE_KERNEL**2)))
#: The grid on the table in which points above it are clustered (m): objects this far apart are two.
CLUSTER_CELL_M = 0.005
#: ... and at least this many of a pixel's footprints on the table, seen straight on.
CLUSTER_CELL_FOOTPRINTS = 2.5
#: Clusters with up to twice this many empty cells between them are one object (a gap of 10 mm at
#: 5 mm cells: two objects closer than that are taken for one).
CLUSTER_BRIDGE_CELLS = 1
#: At most this many of the object's points are kept for the grasp (a regular thinning beyond).
MAX_CLOUD_POINTS = 3000
#: A pixel whose mixture standard deviation exceeds this many times the sensor's spans a depth step.
FEATURE_STEP_SIGMAS = 4.0
#: The least uncertainty (m, each axis) of the visible surface's centroid: which pixels are the object
#: at its silhouette changes with the noise, by a pixel or so.
SILHOUETTE_FLOOR_M = 0.0005
#: The spread of its seen centre from its true one per metre of its height, along the line of sight,
#: across it and up: what the view hides of its shape. Calibrated on held-out test-split meshes, on
#: other seeds than those it is evaluated on (evidence: docs/decisions.md#perception).
HIDDEN_SHAPE_PER_HEIGHT = (0.079, 0.054, 0.083)
#: The footprint's ends are taken at these quantiles of its points (a stray pixel does not move them).
FOOTPRINT_QUANTILE = 0.01
#: In a heap, objects touching one another are told apart where the depth between neighbouring pixels
#: steps by more than this (and than 4 sigma of the 3x3 mixture's noise of a difference)
DEPTH_STEP_M = 0.01
#: ... or where the colour steps: the chromaticity (r, g over r + g + b, in 1/255; the same under the
#: light's shading of one colour) of the 3x3 mixture's colour, two pixels apart, by more than this (and
#: than 4 sigma of the image's noise there)
COLOUR_STEP = 12.0
#: (a dark pixel's chromaticity is noisy: its sum is floored by this, 8-bit units)
CHROMA_DARK_FLOOR = 30.0


@dataclasses.dataclass(frozen=True)
class Clusters:
    """Connected regions of pixels above the table: ``labels`` (H, W) int32, 0 for none, and each
    label's pixel count."""

    labels: np.ndarray
    areas: np.ndarray  # (n,) for labels 1..n


def segment_objects(frame: RGBDFrame, params: PerceptionParams, pts: np.ndarray | None = None) -> Clusters:
    """The frame's pixels above the table, the robot's own body left out, in clusters: pixels whose
    points fall in touching cells of a grid on the table (seen from above, ``CLUSTER_CELL_M``) are
    one object, however the object hides parts of itself from the camera. ``pts``: the frame's
    world points (:func:`world_points`), if already computed."""
    pts = world_points(frame) if pts is None else pts
    z = pts[..., 2]
    # Above the table by more than the depth noise can put a table pixel: its height as the 3x3
    # mixture sees it (eq. 9: the noise of a weighted mean of nine, 0.375 of one pixel's), 4 sigma.
    z_mix = cv2.filter2D(np.nan_to_num(z, nan=-1.0), cv2.CV_64F, MIXTURE_KERNEL, borderType=cv2.BORDER_REPLICATE)
    depth = np.nan_to_num(frame.depth_m, nan=0.0, posinf=0.0)
    noise = MIXTURE_NOISE_FRACTION * np.sqrt(frame.depth_variance(depth))
    above = (np.nan_to_num(z, nan=-1.0) > params.min_height_m) & (z_mix > np.maximum(params.min_height_m, 4.0 * noise))
    above &= ~robot_pixels(frame, above)
    labels = np.zeros(above.shape, dtype=np.int32)
    if not above.any():
        return Clusters(labels, np.zeros(0, dtype=np.int64))
    xy = pts[above][:, :2]
    # Neighbouring pixels' points lie a pixel's footprint apart, more on a surface seen obliquely: the
    # cells are at least a few footprints wide (a strided frame's pixels are wide).
    footprint = float(np.nanmedian(frame.depth_m[above])) / frame.intrinsics.fx
    size = max(CLUSTER_CELL_M, CLUSTER_CELL_FOOTPRINTS * footprint)
    cell = np.floor((xy - xy.min(axis=0)) / size).astype(np.int64)
    grid = np.zeros(tuple(cell.max(axis=0) + 1), dtype=np.uint8)
    grid[cell[:, 0], cell[:, 1]] = 1
    # Cells with up to 2 x CLUSTER_BRIDGE_CELLS empty ones between them join: where an object hides
    # part of itself (a duck's head in front of its body), its footprint seen has a gap.
    k = 2 * CLUSTER_BRIDGE_CELLS + 1
    joined = cv2.dilate(np.pad(grid, CLUSTER_BRIDGE_CELLS), np.ones((k, k), np.uint8))
    n, cells = cv2.connectedComponents(joined, connectivity=8)
    cells = cells[CLUSTER_BRIDGE_CELLS:-CLUSTER_BRIDGE_CELLS, CLUSTER_BRIDGE_CELLS:-CLUSTER_BRIDGE_CELLS]
    labels[above] = cells[cell[:, 0], cell[:, 1]]
    areas = np.bincount(labels[above], minlength=n)[1:].astype(np.int64)
    return Clusters(labels, areas)


def colour_steps(frame: RGBDFrame) -> np.ndarray:
    """(H, W) bool: the pixels where the colour steps (its chromaticity through the 3x3 mixture, two
    pixels apart across or down, by more than ``COLOUR_STEP`` and 4 sigma of the noise of such a
    difference): the edge between two objects of different colours. Shading (one colour lit more or
    less) keeps the chromaticity, and so does not step."""
    rgb = cv2.filter2D(np.asarray(frame.rgb[..., :3], dtype=np.float64), cv2.CV_64F, MIXTURE_KERNEL,
                       borderType=cv2.BORDER_REPLICATE)  # fmt: skip
    total = np.maximum(rgb.sum(axis=2), CHROMA_DARK_FLOOR)
    chroma = 255.0 * rgb[..., :2] / total[..., None]
    # the noise of a difference of two such chromaticities: each channel's (the mixture's share of the
    # sensor's), over the pixel's sum, about sqrt(2) for the two channels' shares
    sigma = 255.0 * np.sqrt(2.0) * MIXTURE_NOISE_FRACTION * float(frame.rgb_noise_sigma) * np.sqrt(2.0) / total
    thr = np.maximum(COLOUR_STEP, 4.0 * sigma)
    out = np.zeros(total.shape, dtype=bool)
    dx = np.linalg.norm(chroma[:, 2:] - chroma[:, :-2], axis=2) > np.minimum(thr[:, 2:], thr[:, :-2])
    dy = np.linalg.norm(chroma[2:] - chroma[:-2], axis=2) > np.minimum(thr[2:], thr[:-2])
    out[:, 1:-1] |= dx
    out[1:-1] |= dy
    return out


def split_heap(frame: RGBDFrame, clusters: Clusters, min_px: int) -> Clusters:
    """The clusters split where the depth steps between neighbouring pixels (``DEPTH_STEP_M``, seen
    through the 3x3 mixture), or their colour (``COLOUR_STEP``): objects in a heap, touching one
    another, are seen so, one in front of or on top of another, or beside another of another colour.
    The steps' own pixels join the part beside them; parts smaller than ``min_px`` are left out."""
    if not len(clusters.areas):
        return clusters
    # (only about the clusters: the steps need a pixel or two beyond them)
    ys, xs = np.nonzero(clusters.labels)
    h, w = clusters.labels.shape
    y0, y1, x0, x1 = max(ys.min() - 4, 0), min(ys.max() + 5, h), max(xs.min() - 4, 0), min(xs.max() + 5, w)
    parts = np.zeros_like(clusters.labels, dtype=np.int32)
    parts[y0:y1, x0:x1] = _split(crop_frame(frame, x0, y0, x1, y1), clusters.labels[y0:y1, x0:x1], min_px)
    areas = np.bincount(parts.ravel())[1:].astype(np.int64)
    return Clusters(parts, areas)


def _split(frame: RGBDFrame, labels: np.ndarray, min_px: int) -> np.ndarray:
    depth = np.nan_to_num(np.asarray(frame.depth_m, dtype=np.float64), nan=0.0, posinf=0.0)
    # The mixture over the readings there are: a hole (no return) is no step, and does not pull its
    # neighbours' depth to 0 (a sensor's scattered holes would cut an object into pieces).
    valid = (depth > 0.0).astype(np.float64)
    weight = cv2.filter2D(valid, cv2.CV_64F, MIXTURE_KERNEL, borderType=cv2.BORDER_REPLICATE)
    total = cv2.filter2D(depth, cv2.CV_64F, MIXTURE_KERNEL, borderType=cv2.BORDER_REPLICATE)
    with np.errstate(invalid="ignore", divide="ignore"):
        smooth = np.where(weight > 0.0, total / weight, np.nan)
    noise = MIXTURE_NOISE_FRACTION * np.sqrt(frame.depth_variance(depth))
    thr = np.maximum(DEPTH_STEP_M, 4.0 * np.sqrt(2.0) * noise)
    step = colour_steps(frame)
    with np.errstate(invalid="ignore"):  # (NaN, no reading about: no step)
        dx = np.abs(np.diff(smooth, axis=1)) > np.minimum(thr[:, 1:], thr[:, :-1])
        dy = np.abs(np.diff(smooth, axis=0)) > np.minimum(thr[1:, :], thr[:-1, :])
    step[:, 1:] |= dx
    step[:, :-1] |= dx
    step[1:, :] |= dy
    step[:-1, :] |= dy
    core = (labels > 0) & ~step
    _, cc = cv2.connectedComponents(core.astype(np.uint8), connectivity=4)
    key = np.where(core, labels.astype(np.int64) * (int(cc.max()) + 1) + cc, 0)
    uniq, inverse = np.unique(key, return_inverse=True)
    parts = inverse.reshape(key.shape).astype(np.int32)  # 0 stays 0 (the smallest key)
    counts = np.bincount(parts.ravel())
    small = counts < max(min_px // 2, 1)
    small[0] = False
    parts[small[parts]] = 0
    # the steps' pixels (and the small parts') join the part beside them, within their cluster
    todo = (labels > 0) & (parts == 0)
    for _ in range(4):
        if not todo.any():
            break
        grown = cv2.dilate(parts.astype(np.float32), np.ones((3, 3), np.uint8)).astype(np.int32)
        take = todo & (grown > 0)
        parts[take] = grown[take]
        todo &= ~take
    uniq, inverse = np.unique(parts, return_inverse=True)
    return inverse.reshape(parts.shape).astype(np.int32)


class NoneAsTall(PerceptionError):
    """No cluster in view stands as tall as the target's named size."""


#: What an object at (x, y), its lowest points seen at z, stands on (m above the table): the cell's
#: shelves and bins, as the task knows them (None: the table, z = 0).
Support = Callable[[float, float, float], float]


def base_z(points: np.ndarray, support: Support | None) -> float:
    """The height of what the object whose points these are stands on (0: the table)."""
    if support is None or len(points) == 0:
        return 0.0
    low = float(np.quantile(points[:, 2], FOOTPRINT_QUANTILE))
    return float(support(float(points[:, 0].mean()), float(points[:, 1].mean()), low))


def _choose(
    frame: RGBDFrame,
    clusters: Clusters,
    model: TargetModel,
    min_px: int,
    centre_uv: np.ndarray | None,
    pts: np.ndarray,
    support: Support | None = None,
    measurable: np.ndarray | None = None,
) -> tuple[Clusters, int]:
    """The clusters and the target's label (:func:`choose_cluster`); none as tall as named, the
    clusters split where the depth or the colour steps first (a nearer, taller object seen against the
    target joins it in one cluster), as a heap's are."""
    kw = dict(centre_uv=centre_uv, pts=pts, support=support, measurable=measurable)
    try:
        return clusters, choose_cluster(frame, clusters, model, min_px, **kw)
    except NoneAsTall:
        split = split_heap(frame, clusters, min_px)
        return split, choose_cluster(frame, split, model, min_px, **kw)


def choose_cluster(
    frame: RGBDFrame,
    clusters: Clusters,
    model: TargetModel,
    min_px: int,
    *,
    centre_uv: np.ndarray | None,
    pts: np.ndarray | None = None,
    support: Support | None = None,
    measurable: np.ndarray | None = None,
) -> int:
    """The label of the target's cluster (see the module docstring); raises :class:`PerceptionError`
    when no cluster is large enough. ``pts``: the frame's world points (for a size the task names);
    ``support``: what an object stands on (its height is measured from there); ``measurable``: the
    pixels the pose is measured from (off a silhouette): a cluster with fewer than ``min_px`` of them
    is a sliver the pose cannot come from, and is passed over while another can be measured."""
    big = [k + 1 for k, a in enumerate(clusters.areas) if a >= min_px]
    if not big:
        raise PerceptionError(
            "nothing stands on the table in view" if not len(clusters.areas) else "no object large enough in view"
        )
    if measurable is not None and len(big) > 1:
        # (measured: a heap's split left a 54-pixel sliver of a part, against a tote's wall, nearest the
        # region's centre, 24 of its pixels off its silhouette; the part beside it, 577 pixels, is the
        # object the survey saw, and the pick failed on the sliver 5 times: suction_clear_tote seed 39)
        counts = np.bincount(clusters.labels[measurable].ravel(), minlength=len(clusters.areas) + 1)
        big = [k for k in big if counts[k] >= min_px] or big
    if len(big) == 1:
        return big[0]
    if model.color is not None:
        return nearest_in_colour(frame.rgb, clusters.labels, big, model.color)
    if centre_uv is not None:
        d = []
        for k in big:
            ys, xs = np.nonzero(clusters.labels == k)
            d.append(float(np.min(np.hypot(xs - centre_uv[0], ys - centre_uv[1]))))
        return big[int(np.argmin(d))]
    cue = getattr(model.geometry, "size_cue_m", None)
    if cue is not None and pts is not None:
        if not getattr(model.geometry, "heap", False):  # (a heap's objects stand on one another)
            tall = [k for k in big if _as_tall(pts[clusters.labels == k], cue[0], support)]
            if not tall:
                raise NoneAsTall(
                    f"nothing in view stands {cue[0] * 1e3:.0f} mm tall, the target's size as named (another "
                    "object is not the target)"
                )
            big = tall
        return big[int(np.argmin([_size_mismatch(pts[clusters.labels == k], cue, support) for k in big]))]
    return big[int(np.argmax([clusters.areas[k - 1] for k in big]))]


def height_tolerance_m(height_m: float) -> float:
    """How far an object's height seen from above may be from the height a task names and still be
    it: 15 % or 1 cm, the larger. A cluster's top is seen to a few millimetres; its footprint is not
    (a partial view, a neighbour merged), so the height tells look-alikes apart (measured: a mug named
    80 mm tall among a 100 mm can and box; by the footprints' sizes alone the can was taken in 4 of 20
    seeds)."""
    return max(0.01, 0.15 * height_m)


def _as_tall(points: np.ndarray, height_m: float, support: Support | None = None) -> bool:
    p = points[np.all(np.isfinite(points), axis=1)]
    if len(p) < 3:
        return False
    top = float(np.quantile(p[:, 2], 1.0 - FOOTPRINT_QUANTILE)) - base_z(p, support)
    return abs(top - height_m) <= height_tolerance_m(height_m)


def _size_mismatch(points: np.ndarray, cue: tuple[float, float, float], support: Support | None = None) -> float:
    """How far a cluster's size seen (its height, and its footprint's extents along its principal axes)
    is from the size the task names (height, longer and shorter side), as a sum of log ratios."""
    p = points[np.all(np.isfinite(points), axis=1)]
    if len(p) < 3:
        return np.inf
    xy = p[:, :2] - p[:, :2].mean(axis=0)
    _, axes = np.linalg.eigh(np.cov(xy.T))
    along = xy @ axes
    extents = np.quantile(along, 1.0 - FOOTPRINT_QUANTILE, axis=0) - np.quantile(along, FOOTPRINT_QUANTILE, axis=0)
    seen = np.array([np.quantile(p[:, 2], 1.0 - FOOTPRINT_QUANTILE) - base_z(p, support), extents.max(), extents.min()])
    return float(np.sum(np.abs(np.log(np.maximum(seen, 1e-3) / np.maximum(np.asarray(cue), 1e-3)))))


def object_roi(
    frame: RGBDFrame, model: TargetModel, params: PerceptionParams, pad: int = 8, stride: int = 4
) -> tuple[int, int, int, int]:
    """Bounding box of the target's cluster, padded, found on every ``stride``-th pixel."""
    sub = dataclasses.replace(
        frame,
        rgb=frame.rgb[::stride, ::stride],
        depth_m=holes_as_nan(frame.depth_m[::stride, ::stride]),
        intrinsics=strided_intrinsics(frame.intrinsics, stride),
    )
    pts = world_points(sub)
    clusters = segment_objects(sub, params, pts)
    h, w = frame.rgb.shape[:2]
    centre = None if frame.roi is None else np.array([w, h], dtype=np.float64) / (2.0 * stride)
    min_px = max(params.min_target_px // (stride * stride), 2)
    clusters, label = _choose(sub, clusters, model, min_px, centre, pts)
    ys, xs = np.nonzero(clusters.labels == label)
    return (
        max(int(xs.min()) * stride - pad, 0),
        max(int(ys.min()) * stride - pad, 0),
        min(int(xs.max()) * stride + stride + pad, w),
        min(int(ys.max()) * stride + stride + pad, h),
    )


def principal_yaw(cov_xy: np.ndarray, n: int) -> tuple[float, float]:
    """The yaw (rad) of the major principal axis of a 2x2 covariance of ``n`` points, and its variance
    (rad^2): ``l1 l2 / ((n - 1) (l1 - l2)^2)``, the sampling variance of a principal axis (capped at
    that of a uniform angle over a half turn, pi^2 / 12: no axis at all)."""
    w, V = np.linalg.eigh(0.5 * (cov_xy + cov_xy.T))
    l2, l1 = max(float(w[0]), 0.0), max(float(w[1]), 0.0)
    yaw = float(np.arctan2(V[1, 1], V[0, 1]))
    gap = l1 - l2
    var = np.pi**2 / 12.0 if gap <= 1e-12 or n < 3 else min(l1 * l2 / ((n - 1) * gap * gap), np.pi**2 / 12.0)
    return yaw, float(var)


def estimate_unknown(
    frame: RGBDFrame, model: TargetModel, params: PerceptionParams | None = None, support: Support | None = None
) -> PoseEstimate:
    """The pose of an object nobody described (see the module docstring); ``support``: what an object
    stands on (None: the table). Raises :class:`PerceptionError` with the reason when it cannot be
    measured."""
    params = params or PerceptionParams()
    try:
        return _estimate_unknown(frame, model, params, support)
    except np.linalg.LinAlgError as exc:  # a singular system: what was seen leaves the fit undetermined
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
        raise PerceptionError(f"degenerate estimate ({type(exc).__name__}: {reason})") from None


def _estimate_unknown(
    frame: RGBDFrame, model: TargetModel, params: PerceptionParams, support: Support | None
) -> PoseEstimate:
    heap = getattr(model.geometry, "heap", False)
    if heap and frame.roi is not None:  # a region about one object of a heap: all of it at full resolution
        x0, y0, x1, y1 = 0, 0, frame.rgb.shape[1], frame.rgb.shape[0]  # (small objects vanish in a strided one)
    else:
        x0, y0, x1, y1 = object_roi(frame, model, params)
    f = crop_frame(frame, x0, y0, x1, y1)
    pts = world_points(f)
    clusters = segment_objects(f, params, pts)
    if heap:  # objects may touch one another: apart where the depth or the colour steps
        clusters = split_heap(f, clusters, params.min_target_px)
    h, w = frame.rgb.shape[:2]
    centre = None if frame.roi is None else np.array([w / 2.0 - x0, h / 2.0 - y0])
    depth = f.depth_m  # holes are NaN in a crop
    mu_z, var_z = mixture_moments(depth, f.depth_variance(depth))
    # Every pixel off a silhouette (its 3x3 mixture within one surface): the object's are back-projected
    # at their mixture depth (eqs. 5-10).
    sensor_sd = np.sqrt(f.depth_variance(np.nan_to_num(mu_z, nan=1.0)))
    off_edges = np.isfinite(mu_z) & (np.sqrt(var_z) <= FEATURE_STEP_SIGMAS * sensor_sd)
    clusters, label = _choose(f, clusters, model, params.min_target_px, centre, pts, support, off_edges)
    mask = clusters.labels == label
    features = measure_features(f, shi_tomasi_features(f, mask, params), mu_z, var_z, offset=(x0, y0))
    on = mask & off_edges
    n = int(on.sum())
    if n < params.min_target_px:
        raise PerceptionError(f"only {n} pixels of the object lie off its silhouette")
    vs, us = np.nonzero(on)
    K = f.intrinsics
    z = mu_z[vs, us]
    cam = np.column_stack([z * (us - K.cx) / K.fx, z * (vs - K.cy) / K.fy, z])
    surface = f.T_world_cam.transform_points(cam)
    mean = surface.mean(axis=0)
    # Eq. (14) at a sample of them, averaged, over their number: a 3x3 mixture shares its pixels with
    # its neighbours', so about one in nine is independent.
    R = f.T_world_cam.rotation
    pick = np.linspace(0, n - 1, min(n, 64)).astype(int)
    c_cam = np.mean(
        [point_covariance(us[i], vs[i], z[i], var_z[vs[i], us[i]], K.fx, K.fy, K.cx, K.cy) for i in pick], axis=0
    )
    n_independent = max(n / 9.0, 1.0)
    position_cov = R @ c_cam @ R.T / n_independent + np.eye(3) * SILHOUETTE_FLOOR_M**2
    yaw, yaw_var = principal_yaw(np.cov((surface[:, :2] - mean[:2]).T), int(n_independent))
    calibration = f.calibration_cov_at(mean)
    if calibration is not None:
        position_cov = position_cov + calibration

    occluded = hidden_in_part(depth, mask)
    cloud_pts = pts[mask]
    cloud_pts = cloud_pts[np.all(np.isfinite(cloud_pts), axis=1)]
    if len(cloud_pts) > MAX_CLOUD_POINTS:
        cloud_pts = cloud_pts[:: int(np.ceil(len(cloud_pts) / MAX_CLOUD_POINTS))]
    others = (clusters.labels > 0) & ~mask
    obstacles = pts[others]
    obstacles = obstacles[np.all(np.isfinite(obstacles), axis=1)]
    if len(obstacles) > MAX_CLOUD_POINTS:
        obstacles = obstacles[:: int(np.ceil(len(obstacles) / MAX_CLOUD_POINTS))]
    # Its footprint along its principal axes, seen from above (the far side's top edge bounds it): its
    # middle is the object's centre, which the camera sees from any side alike (the visible surface's
    # mean moves with the view; evidence: docs/decisions.md#perception).
    c, s = np.cos(yaw), np.sin(yaw)
    axes = np.array([[c, -s], [s, c]])
    seen = pts[mask]
    seen = seen[np.all(np.isfinite(seen), axis=1)]  # every pixel's own point, to its silhouette
    along = (seen[:, :2] - mean[:2]) @ axes
    lo, hi = np.quantile(along, FOOTPRINT_QUANTILE, axis=0), np.quantile(along, 1.0 - FOOTPRINT_QUANTILE, axis=0)
    extents = hi - lo
    # Its height: it stands on the table (z = 0), or what is under it, up to its top seen; its centre halfway.
    base = base_z(seen, support)
    top = float(np.quantile(surface[:, 2], 1.0 - FOOTPRINT_QUANTILE)) - base
    centre = np.array([*(mean[:2] + axes @ (0.5 * (lo + hi))), base + 0.5 * top])
    # What the view hides of its shape (its far side below its top edge, its base) moves the centre
    # seen, the more the taller it is: along the line of sight, across it and up.
    view = centre[:2] - f.T_world_cam.position[:2]
    view = view / max(float(np.linalg.norm(view)), 1e-9)
    basis = np.array([[view[0], -view[1], 0.0], [view[1], view[0], 0.0], [0.0, 0.0, 1.0]])
    hidden = basis @ np.diag((np.asarray(HIDDEN_SHAPE_PER_HEIGHT) * max(top, 0.0)) ** 2) @ basis.T
    position_cov = position_cov + hidden
    rpy_cov = np.diag([0.0, 0.0, yaw_var])
    return PoseEstimate(
        pose=Pose.from_xyz_rpy(centre, yaw=yaw),
        position_cov=position_cov,
        rpy_cov=rpy_cov,
        yaw_symmetry_rad=Unknown().yaw_symmetry_rad,
        top_face_size_m=(float(max(extents)), float(min(extents))),
        n_features=len(features),
        n_face_pixels=n,
        features=features,
        cloud=ObjectCloud(
            points=cloud_pts,
            obstacles=obstacles,
            time_s=f.time_s,
            depth_m=holes_as_nan(frame.depth_m),
            intrinsics=frame.intrinsics,
            T_world_cam=frame.T_world_cam,
        ),
        occluded=occluded,
        shared_cov=hidden,
        calibration_cov=calibration,
    )


def hidden_in_part(
    depth: np.ndarray, mask: np.ndarray, *, ring_px: int = 2, step_m: float = 0.01, min_px: int = 4
) -> bool:
    """Whether something nearer the camera borders the object's silhouette (the hand, another
    object): at least ``min_px`` pixels within ``ring_px`` of it whose depth is ``step_m`` nearer
    than the object's nearest depth about them."""
    k = np.ones((2 * ring_px + 1, 2 * ring_px + 1), np.uint8)
    ring = cv2.dilate(mask.astype(np.uint8), k).astype(bool) & ~mask
    own = np.where(mask & np.isfinite(depth), depth, np.inf).astype(np.float32)
    nearest_own = cv2.erode(own, k)  # the object's nearest depth within the ring's reach
    d = np.where(np.isfinite(depth), depth, np.inf)
    return int(np.sum(ring & np.isfinite(nearest_own) & (d < nearest_own - step_m))) >= min_px


@dataclasses.dataclass(frozen=True)
class SeenObject:
    """One object a survey of the table found: where it stands, its size seen, its points."""

    centre: np.ndarray  # (3,) m: the middle of its footprint seen from above, at half its top
    size_m: tuple[float, float, float]  # its top's height, its footprint's longer and shorter side
    n_px: int
    cloud: ObjectCloud


@dataclasses.dataclass(frozen=True)
class Survey:
    """What stands on the table in one frame (a clear round looks so after every place)."""

    objects: tuple[SeenObject, ...]
    time_s: float
