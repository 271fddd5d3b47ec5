"""One frame split into instances: every object standing on the table in view, each a blob of points
with its footprint, its top, its colour and how sure its centre is; the table, the robot's own links
and the cell's fixtures left out (:class:`SceneView`).

Pure: a frame in, a :class:`SceneView` out; no simulator. What makes a pixel evidence of a surface
is the sensor's own noise model at that range (:meth:`~pickdemo.core.camera.RGBDFrame.depth_variance`,
which the presets carry): a pixel is above the table when the 3x3 mixture of its height (eq. 9)
stands 4 of that mixture's sigmas above the table's plane, and a blob is an object when its
footprint on the table covers :data:`MIN_OBJECT_AREA_M2`. So a far D415's speckle makes no object
(single pixels a few sigmas off), and a flat object near the camera stays one. Objects touching one
another are told apart where the depth steps between neighbouring pixels (a nearer object's edge)
by more than the noise allows, or the colour steps (:func:`~pickdemo.perception.unknown.colour_steps`).

The frame is read every :data:`STRIDE` pixels: the instances are for what the hand must keep out of
and which object is which (a pose estimate reads the full frame).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np

from pickdemo.core.camera import Intrinsics, RGBDFrame, holes_as_nan, project, strided_intrinsics
from pickdemo.core.geometry import Pose
from pickdemo.perception.equations import MIXTURE_KERNEL
from pickdemo.perception.model import PerceptionParams
from pickdemo.perception.neighbours import TABLE_BAND_M, TABLE_OFF_MAX_M, TABLE_OFF_SIGMAS, TABLE_SLOPE_MAX
from pickdemo.perception.segmentation import crop_frame, robot_pixels
from pickdemo.perception.unknown import FOOTPRINT_QUANTILE, MIXTURE_NOISE_FRACTION, colour_steps

#: Every this many pixels across and down are read.
STRIDE = 2
#: A pixel is above the table when its mixed height is this many of the mixture's sigmas above it.
ABOVE_SIGMAS = 4.0
PIXEL_SIGMAS = 2.0
#: Neighbouring pixels whose depth differs by more than this (m), and this many sigmas of a
#: difference of two readings, are on two objects (one in front of the other).
DEPTH_STEP_M = 0.01
DEPTH_STEP_SIGMAS = 4.0
#: A step's pixel joins the blob beside it nearest in colour (this far in RGB, the channels' absolute
#: differences summed, weighs as a depth step)
COLOUR_UNIT = 50.0
#: The least footprint an object covers on the table, as seen (m^2): 1 cm x 1 cm. A blob smaller is
#: noise (a pixel or two off by a few sigmas) or a sliver of an edge.
MIN_OBJECT_AREA_M2 = 1e-4
#: ... and it has at least this many (strided) pixels.
MIN_OBJECT_PX = 4
#: A blob most of whose points (this share) lie within this gap (m) of the robot's boxes or the
#: fixtures', moved along their line of sight by up to this many sigmas of their depth's noise, is theirs
ROBOT_NOISE_SIGMAS = 3.0
ROBOT_SHARE = 0.5
ROBOT_GAP_M = 0.003
#: ... and a blob with a point this near one of them (m) touches the robot
TOUCH_M = 0.01
#: Points an instance keeps at most (a regular thinning beyond).
MAX_INSTANCE_POINTS = 2000
#: An instance's footprint, top and colour are read off this many of its points at most.
STATS_POINTS = 300
#: Two blobs of one colour (their chromaticities this near, as a colour step is told: 8-bit units) whose
#: footprints meet (this near across the table, m) are one object: one that hides a part of itself
#: (a depth step between its parts in the image, as one in front of another) is not two. (Joining
#: also pieces whose gap something nearer hides, up to 8 cm, cleared 30 of a bin's 50 objects against
#: 36: a bin's wall hides the gap between two objects of one colour as well.)
JOIN_CHROMA = 12.0
JOIN_GAP_M = 0.01


@dataclass(frozen=True)
class Instance:
    """One object as one frame shows it."""

    points: np.ndarray  # (N, 3) world, m
    centre: np.ndarray  # (3,): the middle of its footprint, at half its top
    extents: tuple[float, float]  # its footprint's longer and shorter side seen (m)
    yaw_rad: float  # the footprint's longer side's direction
    top_m: float  # its top's height over the table
    colour: tuple[float, float, float]  # its median colour, 0..1
    area_m2: float  # its footprint seen, as the pixels' footprints on the table add up
    cov: np.ndarray  # (3, 3) the centre's covariance: the points' spread over their count, and the calibration's
    clipped: bool = False  # it reaches the image's edge (a region's): only part of it is in view
    hidden: bool = False  # something nearer stands beside it in the image (it may hide part of it)
    n_px: int = 1  # the (strided) pixels it took


@dataclass(frozen=True)
class SceneView:
    """Every object one frame showed, and what is needed to tell what it could not show: the frame's
    (strided) depth, intrinsics and pose, and the pixels its robot's body took (:meth:`sees`)."""

    instances: tuple[Instance, ...]
    time_s: float
    camera: str
    depth_m: np.ndarray = dataclasses.field(repr=False)  # (h, w) strided depth, NaN: no reading
    intrinsics: Intrinsics = dataclasses.field(repr=False)  # of the strided depth
    T_world_cam: Pose = dataclasses.field(repr=False)
    #: (h, w) the pixels the robot's own body (or a fixture) took: what lies there is not seen
    robot_mask: np.ndarray | None = dataclasses.field(default=None, repr=False)

    def shows(self, xy: tuple[float, float], radius_m: float, top_m: float) -> bool:
        """Whether the view's image holds all of the square ``radius_m`` about ``xy`` on the table, up to
        ``top_m`` above it (a spot looked at: what stands there is in view, or nothing does)."""
        corners = np.array([[xy[0] + dx, xy[1] + dy, z] for dx in (-radius_m, radius_m)
                            for dy in (-radius_m, radius_m) for z in (0.0, top_m)])  # fmt: skip
        cam = (corners - self.T_world_cam.position) @ self.T_world_cam.rotation
        if np.any(cam[:, 2] <= 1e-3):
            return False
        u, v = project(cam, self.intrinsics).T
        h, w = self.depth_m.shape
        return bool(np.all((u >= 0) & (v >= 0) & (u <= w - 1) & (v <= h - 1)))

    def sees(self, points: np.ndarray, margin_m: float = 0.02) -> np.ndarray:
        """(N,) bool: which world ``points`` this view would have shown had they been there: in its
        image, and nothing read nearer than them (by ``margin_m``) where they project (a hole is no
        reading: not seen)."""
        p = np.atleast_2d(points)
        cam = (p - self.T_world_cam.position) @ self.T_world_cam.rotation
        out = np.zeros(len(p), dtype=bool)
        front = cam[:, 2] > 1e-3
        z = np.where(front, cam[:, 2], 1.0)
        u, v = np.round(project(np.column_stack([cam[:, :2], z]), self.intrinsics)).astype(int).T
        h, w = self.depth_m.shape
        inside = front & (u >= 0) & (v >= 0) & (u < w) & (v < h)
        d = self.depth_m[v[inside], u[inside]]
        out[inside] = np.isfinite(d) & (d >= cam[inside, 2] - margin_m)
        if self.robot_mask is not None:
            out[inside] &= ~self.robot_mask[v[inside], u[inside]]
        return out


def split_view(frame: RGBDFrame, params: PerceptionParams | None = None) -> SceneView:
    """The frame's instances (see the module docstring), largest first."""
    params = params or PerceptionParams()
    s = STRIDE
    small = dataclasses.replace(
        frame,
        rgb=frame.rgb[::s, ::s],
        depth_m=holes_as_nan(frame.depth_m[::s, ::s]),
        intrinsics=strided_intrinsics(frame.intrinsics, s),
    )
    depth = small.depth_m
    valid = np.isfinite(depth)
    rays = _Rays(small.intrinsics, frame.T_world_cam, depth.shape)
    height = _above_table(rays, depth, valid, frame)
    # The 3x3 mixture of the heights over the readings there are (a hole pulls nothing to 0).
    kernel = MIXTURE_KERNEL.astype(np.float32)
    w = cv2.filter2D(valid.astype(np.float32), cv2.CV_32F, kernel, borderType=cv2.BORDER_REPLICATE)
    hm = cv2.filter2D(np.where(valid, height, 0.0).astype(np.float32), cv2.CV_32F, kernel,
                      borderType=cv2.BORDER_REPLICATE)  # fmt: skip
    with np.errstate(invalid="ignore", divide="ignore"):
        h_mix = np.where(w > 0.3, hm / np.maximum(w, 1e-9), np.nan)
    sigma = np.sqrt(small.depth_variance(np.nan_to_num(depth, nan=0.0)))
    with np.errstate(invalid="ignore"):
        # (and the pixel itself 2 of its own sigmas up: the mixture of a table pixel beside an object
        # takes some of the object's height)
        above = valid & (height > np.maximum(params.min_height_m, PIXEL_SIGMAS * sigma))
        above &= h_mix > np.maximum(params.min_height_m, ABOVE_SIGMAS * MIXTURE_NOISE_FRACTION * sigma)
    robot = robot_pixels(small, above) if above.any() else np.zeros_like(above)
    above &= ~robot
    empty = SceneView((), frame.time_s, frame.camera, depth, small.intrinsics, frame.T_world_cam, robot)
    if not above.any():
        return empty
    # (the colour's steps only about what stands above the table: they need a pixel or two beyond it)
    ys, xs = np.nonzero(above)
    y0, y1, x0, x1 = max(ys.min() - 2, 0), ys.max() + 3, max(xs.min() - 2, 0), xs.max() + 3
    cut, behind = _steps(depth, sigma)
    cut[y0:y1, x0:x1] |= colour_steps(crop_frame(small, x0, y0, x1, y1))
    labels = _labels(above, cut, depth, small.rgb)
    # hidden in part: beside something nearer (the hand over it, another object in front), or the
    # robot's own body in front of it (what of it is the robot's was left out above)
    near_robot = cv2.dilate(robot.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    hidden = set(np.unique(labels[behind | near_robot]).tolist()) - {0}
    # (a blob may be a sliver of the robot only beside its pixels: the others are not tested)
    by_robot = set(np.unique(labels[cv2.dilate(robot.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0]).tolist())
    if frame.support_boxes:  # (what rests on a belt is tested against its top too)
        by_robot |= set(range(1, int(labels.max()) + 1))
    instances, robot_labels = _instances(labels, rays, small, depth, frame, hidden, by_robot - {0})
    if robot_labels:  # (what was the robot's is not seen there either)
        robot = robot | np.isin(labels, robot_labels)
    return dataclasses.replace(empty, instances=_joined(instances, frame), robot_mask=robot)


class _Rays:
    """Each pixel's line of sight in the world, as (h, w) coefficients: a pixel's world point is its
    depth times its ray plus the camera's position, and each of the ray's components is a plane in the
    pixel's (u, v) (no (h, w, 3) array of points is made: only the points asked for)."""

    def __init__(self, K: Intrinsics, T_world_cam: Pose, shape: tuple[int, int]) -> None:
        h, w = shape
        self.u = (np.arange(w) - K.cx) / K.fx
        self.v = (np.arange(h) - K.cy) / K.fy
        self.R, self.t = T_world_cam.rotation, T_world_cam.position

    def along(self, a: np.ndarray) -> np.ndarray:
        """(h, w): the rays' component along the world direction ``a`` (3,)."""
        c = a @ self.R
        return c[0] * self.u[None, :] + c[1] * self.v[:, None] + c[2]

    def points(self, ys: np.ndarray, xs: np.ndarray, depth: np.ndarray) -> np.ndarray:
        """(N, 3) world points of pixels (ys, xs) at their ``depth``."""
        cam = np.column_stack([self.u[xs] * depth, self.v[ys] * depth, depth])
        return cam @ self.R.T + self.t


def _above_table(rays: _Rays, depth: np.ndarray, valid: np.ndarray, frame: RGBDFrame) -> np.ndarray:
    """(h, w) each pixel's height above the table as this view sees it: above a plane fitted to the
    points near z = 0 (a camera known to its calibration sees the table some millimetres off and
    tilted), else the world's z."""
    cal = frame.calibration_cov_at(frame.T_world_cam.position * np.array([1.0, 1.0, 0.0]))
    off = TABLE_OFF_MAX_M if cal is None else max(TABLE_OFF_MAX_M, TABLE_OFF_SIGMAS * float(np.sqrt(cal[2, 2])))
    ys, xs = np.nonzero(valid[::6, ::6])
    ys, xs = ys * 6, xs * 6
    d = depth[ys, xs]
    sub = rays.points(ys, xs, d)
    sel = np.abs(sub[:, 2]) < off
    coef = np.zeros(3)
    if sel.sum() >= 50:
        # the table's points lie within 3 sigmas of one reading's noise of its plane
        band = max(TABLE_BAND_M, 3.0 * float(np.sqrt(frame.depth_variance(float(np.median(d))))))
        for _ in range(3):
            A = np.column_stack([sub[sel, 0], sub[sel, 1], np.ones(int(sel.sum()))])
            coef = np.linalg.lstsq(A, sub[sel, 2], rcond=None)[0]
            inliers = np.abs(sub[:, 2] - (sub[:, :2] @ coef[:2] + coef[2])) < band
            if inliers.sum() < 30:
                break
            sel = inliers
        if float(np.hypot(coef[0], coef[1])) > TABLE_SLOPE_MAX or abs(coef[2]) > off:
            coef = np.zeros(3)
    # height = z - (a x + b y + c), each linear in the depth along the pixel's ray
    normal = np.array([-coef[0], -coef[1], 1.0])
    return depth * rays.along(normal) + float(normal @ rays.t) - coef[2]


def _steps(depth: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(h, w) bool each: pixels whose depth steps to a 4-neighbour's by more than :data:`DEPTH_STEP_M`
    and the noise of such a difference allows; and those of them behind the step (something nearer
    beside them hides what lies beyond)."""
    d = np.nan_to_num(depth, nan=0.0)
    thr = np.maximum(DEPTH_STEP_M, DEPTH_STEP_SIGMAS * np.sqrt(2.0) * sigma)
    out = np.zeros(d.shape, dtype=bool)
    behind = np.zeros(d.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        both_x = (d[:, 1:] > 0) & (d[:, :-1] > 0)
        tx = np.minimum(thr[:, 1:], thr[:, :-1])
        right_nearer = both_x & (d[:, :-1] - d[:, 1:] > tx)
        left_nearer = both_x & (d[:, 1:] - d[:, :-1] > tx)
        both_y = (d[1:] > 0) & (d[:-1] > 0)
        ty = np.minimum(thr[1:], thr[:-1])
        down_nearer = both_y & (d[:-1] - d[1:] > ty)
        up_nearer = both_y & (d[1:] - d[:-1] > ty)
    dx, dy = right_nearer | left_nearer, down_nearer | up_nearer
    out[:, 1:] |= dx
    out[:, :-1] |= dx
    out[1:] |= dy
    out[:-1] |= dy
    behind[:, :-1] |= right_nearer
    behind[:, 1:] |= left_nearer
    behind[:-1] |= down_nearer
    behind[1:] |= up_nearer
    return out, behind


def _labels(above: np.ndarray, cut: np.ndarray, depth: np.ndarray, rgb: np.ndarray) -> np.ndarray:
    """(h, w) int32: the blobs of ``above`` cut along ``cut`` (1, 2, ...; 0 none). A cut's own pixels
    join the neighbouring blob most like them: the nearest in colour, then in depth (a step between two
    objects is a pixel or two wide, its pixels each one object's or the other's)."""
    inner = (above & ~cut).astype(np.uint8)
    _, labels = cv2.connectedComponents(inner, connectivity=4)
    labels = labels.astype(np.int32)
    rest = above & (labels == 0)
    if not rest.any():
        return labels
    d = np.nan_to_num(depth, nan=0.0)
    c = rgb[..., :3].astype(np.int16)
    h, w = labels.shape
    for _ in range(2):
        ys, xs = np.nonzero(rest)
        if len(ys) == 0:
            break
        best = np.full(len(ys), np.inf)
        take = np.zeros(len(ys), dtype=np.int32)
        own_c, own_d = c[ys, xs], d[ys, xs]
        for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            yy, xx = np.clip(ys + dy, 0, h - 1), np.clip(xs + dx, 0, w - 1)
            lab = labels[yy, xx]
            # (colour: the channels' absolute differences, summed)
            cost = np.abs(c[yy, xx] - own_c).sum(axis=1) / COLOUR_UNIT + np.abs(d[yy, xx] - own_d) / DEPTH_STEP_M
            better = (lab > 0) & (cost < best)
            best[better], take[better] = cost[better], lab[better]
        done = take > 0
        labels[ys[done], xs[done]] = take[done]
        rest[ys[done], xs[done]] = False
    return labels


def _footprint(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """The middle of the points' footprint along its principal axes (its 1st to 99th percentiles),
    its extents along them, the longer axis' direction, and the points' covariance (2, 2)."""
    mean = xy.mean(axis=0)
    cov = np.cov((xy - mean).T) if len(xy) > 2 else np.eye(2) * 1e-4
    _, axes = np.linalg.eigh(cov)
    along = np.sort((xy - mean) @ axes, axis=0)  # (the quantiles by rank: a few hundred points)
    k = int(FOOTPRINT_QUANTILE * (len(along) - 1) + 0.5)
    lo, hi = along[k], along[len(along) - 1 - k]
    yaw = 0.5 * float(np.arctan2(2.0 * cov[0, 1], cov[0, 0] - cov[1, 1]))
    return mean + axes @ (0.5 * (lo + hi)), hi - lo, yaw, cov


def _robots(points: np.ndarray, depth: np.ndarray, frame: RGBDFrame) -> tuple[bool, bool]:
    """Whether a blob is the robot's own body (or a fixture): most of its points lie in one of the
    frame's robot boxes once moved along their line of sight by up to :data:`ROBOT_NOISE_SIGMAS` of
    their depth's noise (a sliver of a link the padded boxes leave out, seen from afar: depth noise
    moves a point along its ray, not across it; an object between the fingers stays beside them);
    and whether it touches the robot's body (a point within :data:`TOUCH_M` of a box: the hand about it
    hides some of it)."""
    boxes = (*frame.robot_boxes, *frame.fixture_boxes, *frame.support_boxes)
    if not boxes or len(points) == 0:
        return False, False
    sigma = float(np.sqrt(frame.depth_variance(float(np.median(depth)))))
    ray = points - frame.T_world_cam.position
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    steps = np.linspace(-ROBOT_NOISE_SIGMAS, ROBOT_NOISE_SIGMAS, 7) * sigma
    moved = points[None, :, :] + steps[:, None, None] * ray[None, :, :]  # (7, N, 3)
    gap = np.full(moved.shape[:2], np.inf)
    for box in boxes:
        local = (moved - box.pose.position) @ box.pose.rotation
        gap = np.minimum(gap, np.linalg.norm(local - np.clip(local, box.lo, box.hi), axis=2))
    # (and as far as the camera's calibration may put a point from where it is: told, not guessed)
    cal = frame.calibration_cov_at(points.mean(axis=0))
    slack = ROBOT_GAP_M + (0.0 if cal is None else ROBOT_NOISE_SIGMAS * float(np.sqrt(cal[0, 0])))
    on_ray = gap.min(axis=0) <= slack
    return float(np.mean(on_ray)) > ROBOT_SHARE, bool(np.any(gap[len(steps) // 2] <= TOUCH_M + slack - ROBOT_GAP_M))


def _instances(
    labels: np.ndarray,
    rays: _Rays,
    small: RGBDFrame,
    depth: np.ndarray,
    frame: RGBDFrame,
    hidden: set[int],
    by_robot: set[int],
) -> tuple[tuple[Instance, ...], list[int]]:
    n = int(labels.max())
    if n == 0:
        return (), []
    flat = labels.ravel()
    order = np.argsort(flat, kind="stable")
    bounds = np.searchsorted(flat[order], np.arange(1, n + 2))
    D = depth.ravel()
    width = depth.shape[1]
    rgb = small.rgb.reshape(-1, small.rgb.shape[-1])[:, :3]
    fx = small.intrinsics.fx
    edge = set(np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])).tolist())
    out = []
    robot_labels: list[int] = []  # the blobs that are the robot's
    for k in range(n):
        idx = order[bounds[k] : bounds[k + 1]]
        if len(idx) < MIN_OBJECT_PX:
            continue
        # each pixel's footprint on the table, seen straight on: (depth / f)^2
        area = float(np.sum(np.square(D[idx] / fx)))
        if area < MIN_OBJECT_AREA_M2:
            continue
        p = rays.points(idx // width, idx % width, D[idx])
        robot, touches = (
            _robots(p[:: max(1, len(p) // STATS_POINTS)], D[idx], frame) if k + 1 in by_robot else (False, False)
        )
        if robot:
            robot_labels.append(k + 1)
            continue
        if len(p) > MAX_INSTANCE_POINTS:
            p = p[:: int(np.ceil(len(p) / MAX_INSTANCE_POINTS))]
        step = max(1, len(p) // STATS_POINTS)
        few = p[::step]  # (its figures from a few hundred of them)
        centre_xy, extents, yaw, cov_xy = _footprint(few[:, :2])
        # its top: the highest of its points less what the depth noise adds to the highest (2.33 sigma
        # is the 99th percentile's), no lower than their median
        z = np.sort(few[:, 2])
        mid, high = z[len(z) // 2], z[int(0.99 * (len(z) - 1) + 0.5)]
        sigma_z = float(np.sqrt(frame.depth_variance(float(D[idx[len(idx) // 2]]))))
        top = max(float(high) - 2.33 * sigma_z, float(mid))
        cov = np.zeros((3, 3))
        cov[:2, :2] = cov_xy / len(idx)
        cov[2, 2] = float(np.var(few[:, 2])) / len(idx)
        cal = frame.calibration_cov_at(np.array([centre_xy[0], centre_xy[1], 0.5 * top]))
        if cal is not None:
            cov = cov + cal
        rgb_few = np.sort(rgb[idx[::step]], axis=0)
        colour = tuple(float(c) for c in rgb_few[len(rgb_few) // 2] / 255.0)  # (the median, by rank)
        out.append(
            Instance(
                p,
                np.array([*centre_xy, 0.5 * top]),
                (float(extents.max()), float(extents.min())),
                yaw,
                top,
                colour,
                area,
                cov,
                clipped=k + 1 in edge,
                hidden=touches or k + 1 in hidden,
                n_px=len(idx),
            )  # fmt: skip
        )
    out.sort(key=lambda i: -i.area_m2)
    return tuple(out), robot_labels


def _chroma(colour: tuple[float, float, float]) -> np.ndarray:
    c = np.asarray(colour)
    return 255.0 * c[:2] / max(float(c.sum()), 1e-3)


def _joined(found: tuple[Instance, ...], frame: RGBDFrame) -> tuple[Instance, ...]:
    """The blobs of one object joined (:data:`JOIN_CHROMA`, :data:`JOIN_GAP_M`): pieces of one colour
    whose footprints meet, however the image cut them; largest first."""
    n = len(found)
    if n < 2:
        return found
    group = list(range(n))

    def root(i: int) -> int:
        while group[i] != i:
            i = group[i]
        return i

    few = [i.points[:: max(1, len(i.points) // STATS_POINTS), :2] for i in found]
    for a in range(n):
        for b in range(a + 1, n):
            A, B = found[a], found[b]
            reach = 0.5 * (A.extents[0] + B.extents[0]) + JOIN_GAP_M
            if float(np.hypot(*(A.centre[:2] - B.centre[:2]))) > reach:
                continue
            if float(np.linalg.norm(_chroma(A.colour) - _chroma(B.colour))) > JOIN_CHROMA:
                continue
            if np.min(np.linalg.norm(few[a][:, None, :] - few[b][None, :, :], axis=2)) <= JOIN_GAP_M:
                group[root(b)] = root(a)
    roots: dict[int, list[Instance]] = {}
    for i in range(n):
        roots.setdefault(root(i), []).append(found[i])
    out = [parts[0] if len(parts) == 1 else _merged(parts, frame) for parts in roots.values()]
    return tuple(sorted(out, key=lambda i: -i.area_m2))


def _merged(parts: list[Instance], frame: RGBDFrame) -> Instance:
    """One instance of an object's pieces: their points, the footprint of all, the highest top, the
    colour of the largest, the centre's covariance as its points' spread over their count."""
    p = np.vstack([i.points for i in parts])
    if len(p) > MAX_INSTANCE_POINTS:
        p = p[:: int(np.ceil(len(p) / MAX_INSTANCE_POINTS))]
    few = p[:: max(1, len(p) // STATS_POINTS)]
    centre_xy, extents, yaw, cov_xy = _footprint(few[:, :2])
    top = max(i.top_m for i in parts)
    area = sum(i.area_m2 for i in parts)
    n_px = sum(i.n_px for i in parts)
    cov = np.zeros((3, 3))
    cov[:2, :2] = cov_xy / n_px
    cov[2, 2] = float(np.var(few[:, 2])) / n_px
    cal = frame.calibration_cov_at(np.array([centre_xy[0], centre_xy[1], 0.5 * top]))
    if cal is not None:
        cov = cov + cal
    big = max(parts, key=lambda i: i.area_m2)
    return Instance(p, np.array([*centre_xy, 0.5 * top]), (float(extents.max()), float(extents.min())), yaw, top,
                    big.colour, area, cov, clipped=any(i.clipped for i in parts),
                    hidden=any(i.hidden for i in parts), n_px=n_px)  # fmt: skip
