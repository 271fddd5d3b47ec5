"""Finding the target in a frame: pixels above the table of its colour, its top face and that face's
outline, and the region of interest.

Pure: arrays in, dataclasses out; no simulator.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from pickdemo.core.camera import (
    Intrinsics,
    RGBDFrame,
    backproject,
    backproject_image,
    holes_as_nan,
    strided_intrinsics,
)
from pickdemo.core.geometry import CORNER_IS_HI
from pickdemo.perception.model import PerceptionError, PerceptionParams, TargetModel

#: A blob of the target's colour is the target only if its brightness (the norm of its median RGB) is
#: within these factors of the target colour's: shade darkens a face to a third or so, and no light
#: makes black white.
BRIGHTNESS_RATIO = (0.2, 4.0)


def world_heights(frame: RGBDFrame) -> np.ndarray:
    """(H, W) world z of every pixel (nan where there is no depth): z is linear in the depth."""
    K, T = frame.intrinsics, frame.T_world_cam
    h, w = frame.depth_m.shape
    r = T.rotation[2]
    slope = r[0] * (np.arange(w) - K.cx)[None, :] / K.fx + r[1] * (np.arange(h) - K.cy)[:, None] / K.fy + r[2]
    depth = holes_as_nan(frame.depth_m)  # (a driver's 0 is no point at the camera)
    return depth * slope + T.position[2]


def world_points(frame: RGBDFrame) -> np.ndarray:
    """(H, W, 3) world coordinates of every pixel (nan where there is no depth)."""
    depth = holes_as_nan(frame.depth_m)  # (a driver's 0 is no point at the camera)
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


#: A point this near a fixture's surface, or as near as its depth noise reaches (in sigmas of one
#: pixel's), is the fixture's (m): the table's rule (:func:`~pickdemo.perception.unknown.segment_objects`:
#: 4 sigmas of the 3x3 mixture's noise) for a fixture
FIXTURE_MARGIN_M = 0.006
FIXTURE_NOISE_SIGMAS = 1.5


def fixture_pixels(frame: RGBDFrame, candidates: np.ndarray) -> np.ndarray:
    """Which of the ``candidates`` (an (H, W) mask) are the cell's fixtures: their points lie within
    ``FIXTURE_MARGIN_M``, or ``FIXTURE_NOISE_SIGMAS`` of their depth's noise, of one of the frame's
    :attr:`~pickdemo.core.camera.RGBDFrame.fixture_boxes`."""
    out = np.zeros(candidates.shape, dtype=bool)
    ys, xs = np.nonzero(candidates)
    z = frame.depth_m[ys, xs]
    ok = np.isfinite(z) & (z > 0)
    ys, xs, z = ys[ok], xs[ok], z[ok]
    if len(z) == 0:
        return out
    pts = frame.T_world_cam.transform_points(backproject(np.column_stack([xs, ys]).astype(float), z, frame.intrinsics))
    margin = np.maximum(FIXTURE_MARGIN_M, FIXTURE_NOISE_SIGMAS * np.sqrt(frame.depth_variance(z)))
    near = np.zeros(len(z), dtype=bool)
    for box in frame.fixture_boxes:
        local = (pts - box.pose.position) @ box.pose.rotation
        near |= np.linalg.norm(local - np.clip(local, box.lo, box.hi), axis=1) <= margin
    out[ys[near], xs[near]] = True
    return out


def robot_pixels(frame: RGBDFrame, candidates: np.ndarray) -> np.ndarray:
    """Which of the ``candidates`` (an (H, W) mask) are the robot's own body: their points lie in one
    of the frame's :attr:`~pickdemo.core.camera.RGBDFrame.robot_boxes` (the links where the joint states
    put them); and which are the cell's fixtures (:func:`fixture_pixels`). A box wholly in front of
    the camera is tested only on the candidates within its image's bounding box (a point in the box
    projects inside the hull of its corners' projections): none if that misses the frame."""
    out = np.zeros(candidates.shape, dtype=bool)
    boxes = frame.robot_boxes
    if frame.fixture_boxes and candidates.any():
        out |= fixture_pixels(frame, candidates)
    if not boxes or not candidates.any():
        return out
    K, T = frame.intrinsics, frame.T_world_cam
    ys, xs = np.nonzero(candidates)
    z = frame.depth_m[ys, xs]
    ok = np.isfinite(z) & (z > 0)
    ys, xs, z = ys[ok], xs[ok], z[ok]
    if len(z) == 0:
        return out
    # Every box's corners in the camera frame at once: (boxes, 8, 3).
    local = np.where(
        CORNER_IS_HI, np.array([b.hi for b in boxes])[:, None, :], np.array([b.lo for b in boxes])[:, None, :]
    )
    R = np.array([b.pose.rotation for b in boxes])
    world = np.einsum("bij,bkj->bki", R, local) + np.array([b.pose.position for b in boxes])[:, None, :]
    cam = (world - T.position) @ T.rotation
    zc = cam[:, :, 2]
    front = np.all(zc > 1e-3, axis=1)  # wholly in front of the camera
    across = ~front & np.any(zc > 1e-3, axis=1)  # the camera within its depth span: any candidate may be in it
    zs = np.where(front[:, None], zc, 1.0)
    u = K.fx * cam[:, :, 0] / zs + K.cx
    v = K.fy * cam[:, :, 1] / zs + K.cy
    u0, u1 = u.min(axis=1) - 1.0, u.max(axis=1) + 1.0  # (a pixel for rounding)
    v0, v1 = v.min(axis=1) - 1.0, v.max(axis=1) + 1.0
    seen = across | (front & (u1 >= xs.min()) & (u0 <= xs.max()) & (v1 >= ys.min()) & (v0 <= ys.max()))
    if not seen.any():
        return out
    pts = T.transform_points(backproject(np.column_stack([xs, ys]).astype(float), z, K))
    inside = np.zeros(len(z), dtype=bool)
    for k in np.flatnonzero(seen):
        if front[k]:
            sel = np.flatnonzero((xs >= u0[k]) & (xs <= u1[k]) & (ys >= v0[k]) & (ys <= v1[k]))
            if len(sel) == 0:
                continue
            inside[sel] |= boxes[k].contains(pts[sel])
        else:
            inside |= boxes[k].contains(pts)
    out[ys[inside], xs[inside]] = True
    return out


def segment_target(frame: RGBDFrame, model: TargetModel, params: PerceptionParams, z_world: np.ndarray) -> np.ndarray:
    """Binary mask of the target: above the table, of its colour, not the robot's own body (its
    links where its joint states put them): the largest such blob as bright as the target's colour
    may look (else the largest).

    ``z_world`` is the (H, W) world height of every pixel (:func:`world_heights`).
    """
    above = np.nan_to_num(z_world, nan=-1.0) > params.min_height_m
    cand = above & color_match(frame.rgb, model.color, params.color_cos_min)
    mask = (cand & ~robot_pixels(frame, cand)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        raise PerceptionError("no pixel above the table has the target's colour")
    areas = stats[1:, cv2.CC_STAT_AREA].astype(np.int64)
    # The colour's direction matches every grey alike (a black cube, a white mesh beside it): a blob
    # far brighter or darker than the target's colour, whatever the light, is something else.
    cue = float(np.linalg.norm(255.0 * np.asarray(model.color, dtype=np.float64)))
    for k in np.argsort(-areas, kind="stable"):
        if areas[k] < params.min_target_px:
            break
        bright = float(np.linalg.norm(np.median(frame.rgb[labels == k + 1].astype(np.float64), axis=0)))
        if BRIGHTNESS_RATIO[0] * cue <= bright <= BRIGHTNESS_RATIO[1] * cue:
            return labels == k + 1
    best = 1 + int(np.argmax(areas))
    if stats[best, cv2.CC_STAT_AREA] < params.min_target_px:
        raise PerceptionError(f"target blob too small ({stats[best, cv2.CC_STAT_AREA]} px)")
    return labels == best


def nearest_in_colour(
    rgb: np.ndarray, labels: np.ndarray, candidates: list[int], color: tuple[float, float, float]
) -> int:
    """Of the labelled regions ``candidates``, the one whose median colour is nearest ``color`` (0-1)."""
    cue = 255.0 * np.asarray(color, dtype=np.float64)
    return min(
        candidates, key=lambda k: float(np.linalg.norm(np.median(rgb[labels == k].astype(np.float64), axis=0) - cue))
    )


def top_face_mask(frame: RGBDFrame, mask: np.ndarray, z_world: np.ndarray, params: PerceptionParams) -> np.ndarray:
    """The target's top face: the region of one uniform colour that holds its highest points.

    Flat faces under a directional light render in one colour each, so the face's edges are crisp
    in RGB (which has no noise) where they would be blurred in depth. Two faults of a real sensor
    would eat into that region from its edge, and its outline would then lie inside the true one:

    * depth dropped at depth edges (the face's silhouette): a pixel of the face's colour with no
      depth reading still belongs to it;
    * RGB noise: a pixel of the face strays beyond ``face_color_tol`` now and then (with sigma 5 in
      each channel, one in eight). Inside the face that is a hole the outline ignores; on its edge
      a notch. A 3x3 closing fills notches; it cannot grow a convex face beyond its edges.

    With both remedies the outline lies on the true one (evidence: docs/decisions.md#perception).
    """
    z = np.nan_to_num(z_world, nan=-1.0)
    zs = z_world[mask]
    zs = zs[np.isfinite(zs)]
    top = np.quantile(zs, 0.9)
    sigma = float(np.sqrt(frame.depth_variance(np.nanmedian(frame.depth_m[mask]))))
    high = mask & (z > top - params.face_depth_sigmas * sigma)
    face_rgb = np.median(frame.rgb[high].astype(np.float64), axis=0)
    diff = frame.rgb.astype(np.float32) - face_rgb.astype(np.float32)
    close = np.einsum("...c,...c->...", diff, diff) <= np.float32(params.face_color_tol**2)
    region = mask | ~np.isfinite(frame.depth_m)
    face = cv2.morphologyEx((region & close).astype(np.uint8), cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    n, labels = cv2.connectedComponents(face, connectivity=4)
    held = np.bincount(labels[high], minlength=n)
    held[0] = 0
    if held.max() == 0:
        raise PerceptionError("the target's top face was not found")
    return labels == int(np.argmax(held))  # the region that holds most of the highest points


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

    Just outside an occluded stretch of outline lies a surface nearer the camera than the face there:
    than the face just inside that point (seen close and obliquely a face spans more depth than the
    margin, and its median would take its own nearer neighbour for an occluder), or, where the face
    reads no depth just inside, than ``face_depth_m``.
    """
    c = np.round(outline_uv).astype(int)
    centre = c.mean(axis=0)
    out_dir = outline_uv - centre
    out_dir /= np.maximum(np.linalg.norm(out_dir, axis=1, keepdims=True), 1e-9)
    h, w = depth_m.shape

    def depth_at(offset_px: float) -> np.ndarray:
        probe = np.round(outline_uv + offset_px * out_dir).astype(int)
        probe[:, 0] = np.clip(probe[:, 0], 0, w - 1)
        probe[:, 1] = np.clip(probe[:, 1], 0, h - 1)
        return depth_m[probe[:, 1], probe[:, 0]]

    d = depth_at(step_px)
    inside = depth_at(-step_px)
    face = np.where(np.isfinite(inside), inside, face_depth_m)
    return ~(np.isfinite(d) & (d < face - margin_m))


def crop_frame(frame: RGBDFrame, x0: int, y0: int, x1: int, y1: int) -> RGBDFrame:
    """A frame cut to columns x0:x1 and rows y0:y1, with the principal point moved to match, and
    every depth hole (0, NaN, inf, nearer than any reading) as NaN: a hole is never a point."""
    K = frame.intrinsics
    Kc = Intrinsics(width=x1 - x0, height=y1 - y0, fx=K.fx, fy=K.fy, cx=K.cx - x0, cy=K.cy - y0)
    return dataclasses.replace(
        frame, rgb=frame.rgb[y0:y1, x0:x1], depth_m=holes_as_nan(frame.depth_m[y0:y1, x0:x1]), intrinsics=Kc
    )


def target_roi(
    frame: RGBDFrame, model: TargetModel, params: PerceptionParams, pad: int = 8, stride: int = 4
) -> tuple[int, int, int, int]:
    """Bounding box of the pixels of the target's colour above the table (the robot's own body
    left out), padded.

    Searched on every ``stride``-th pixel (any blob wider than the stride is hit), which makes
    this whole-frame step 16x cheaper; everything after it runs on the box only.
    """
    sub = dataclasses.replace(
        frame,
        rgb=frame.rgb[::stride, ::stride],
        depth_m=holes_as_nan(frame.depth_m[::stride, ::stride]),
        intrinsics=strided_intrinsics(frame.intrinsics, stride),
    )
    above = np.nan_to_num(world_heights(sub), nan=-1.0) > params.min_height_m
    cand = above & color_match(sub.rgb, model.color, params.color_cos_min)
    cand &= ~robot_pixels(sub, cand)
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
