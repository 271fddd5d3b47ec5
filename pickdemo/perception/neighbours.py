"""What stands around the target: the points of everything else near it (another object, a carton
flush against it), which a grasp's fingers and palm must keep out of.

Pure: arrays in, arrays out; no simulator. What stands around the target, and at the place, in
the loop, is the world model's (:mod:`pickdemo.worldmodel`); :func:`with_neighbours` remains for an
estimator of one's own that wants the points of a frame about its estimate (the skill reads an
estimate's ``neighbours`` where the world model has no object at all).
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np

from pickdemo.core.camera import RGBDFrame, project
from pickdemo.perception.model import PerceptionParams, PoseEstimate, TargetModel
from pickdemo.perception.segmentation import robot_pixels, world_points

#: How far from the target's centre a hand about it reaches (m, across the table): the palm's half
#: length along the closing axis, with room (a parallel hand's body is some 0.2 m long).
NEIGHBOURHOOD_M = 0.13
#: ... and up to how high above the target's top the frame must show it (m): the hand's lower part
NEIGHBOURHOOD_ABOVE_M = 0.08
#: Points higher than this above the table are no neighbour's (m).
NEIGHBOURHOOD_TOP_M = 0.5
#: A point within this of the target's own surface, as estimated, is the target's (m).
OWN_MARGIN_M = 0.006
#: The table as a view sees it: points within this of its plane (m) ...
TABLE_BAND_M = 0.003
#: ... a plane at most this far from z = 0 (m) and this steep: a calibration's error, not a box top
TABLE_OFF_MAX_M = 0.03
TABLE_SLOPE_MAX = 0.1
#: ... or as far as this many standard deviations of the height a point at the spot takes from the
#: camera's calibration (:meth:`RGBDFrame.calibration_cov_at`: a camera told it may be off by 10 mm
#: and 2 deg sees a table 1.3 m away up to 5 cm off; 3 sigma there is 79 mm)
TABLE_OFF_SIGMAS = 3.0
#: Neighbours' points kept at most (a regular thinning beyond).
MAX_POINTS = 3000


def neighbourhood_px(
    frame: RGBDFrame, centre: np.ndarray, top: float, r: float = NEIGHBOURHOOD_M
) -> tuple[int, int, int, int] | None:
    """The pixel box (x0, y0, x1, y1, of the frame as cropped) of the square ``r`` about ``centre``
    up to ``top`` above the table, or None when the frame does not show all of it (a region of
    interest about the target alone)."""
    corners = np.array([[centre[0] + dx, centre[1] + dy, z] for dx in (-r, r) for dy in (-r, r) for z in (0.0, top)])
    cam = frame.T_world_cam.inverse().transform_points(corners)
    if np.any(cam[:, 2] <= 1e-3):
        return None
    uv = project(cam, frame.intrinsics)
    K = frame.intrinsics
    x0, y0 = np.floor(uv.min(axis=0)).astype(int)
    x1, y1 = np.ceil(uv.max(axis=0)).astype(int) + 1
    if x0 < 0 or y0 < 0 or x1 > K.width or y1 > K.height:
        return None
    return int(x0), int(y0), int(x1), int(y1)


def neighbour_points(
    frame: RGBDFrame, estimate: PoseEstimate, model: TargetModel, params: PerceptionParams
) -> np.ndarray | None:
    """World points (M, 3) of everything above the table within :data:`NEIGHBOURHOOD_M` of the target
    but the target itself and the robot's own body; specks of a pixel or two (depth noise) left out.
    None when the frame does not show the whole neighbourhood. The target's own points are those
    within its footprint's circle about the estimated centre, :data:`OWN_MARGIN_M` wider, up to its
    top: whatever its yaw (an estimator's yaw may be a quarter turn off, and then a box's own corners
    would stand beside it); a neighbour flush against a face reaches past that circle."""
    centre = estimate.pose.position
    top = float(centre[2]) + model.height_m / 2.0 + NEIGHBOURHOOD_ABOVE_M
    p = _standing(frame, centre, top, NEIGHBOURHOOD_M, params)
    if p is None:
        return None
    shape = model.geometry
    across = np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1]) <= shape.footprint_radius_m + OWN_MARGIN_M
    own = across & (p[:, 2] <= float(centre[2]) + shape.height_m / 2.0 + OWN_MARGIN_M)
    others = p[~own]
    if len(others) > MAX_POINTS:
        others = others[:: int(np.ceil(len(others) / MAX_POINTS))]
    return others


def _standing(
    frame: RGBDFrame, centre: np.ndarray, top: float, r: float, params: PerceptionParams
) -> np.ndarray | None:
    """The points (M, 3) of what stands on the table within the square ``r`` about ``centre`` (the
    frame showing it up to ``top``; None if it does not), the robot's own body and specks left out."""
    box = neighbourhood_px(frame, centre, top, r)
    if box is None:
        return None
    x0, y0, x1, y1 = box
    window = dataclasses.replace(
        frame,
        rgb=frame.rgb[y0:y1, x0:x1],
        depth_m=frame.depth_m[y0:y1, x0:x1],
        intrinsics=dataclasses.replace(frame.intrinsics, width=x1 - x0, height=y1 - y0,
                                       cx=frame.intrinsics.cx - x0, cy=frame.intrinsics.cy - y0),
    )  # fmt: skip
    pts = world_points(window)
    cal = frame.calibration_cov_at(centre)
    off_max = TABLE_OFF_MAX_M if cal is None else max(TABLE_OFF_MAX_M, TABLE_OFF_SIGMAS * float(np.sqrt(cal[2, 2])))
    with np.errstate(invalid="ignore"):
        near = (np.abs(pts[..., 0] - centre[0]) < r) & (np.abs(pts[..., 1] - centre[1]) < r)
        height = _above_table(pts, near, off_max)
        cand = near & (height > params.min_height_m) & (pts[..., 2] < NEIGHBOURHOOD_TOP_M)
    # (a speck of noise is no object: an opening keeps what is 3 px wide and more)
    cand = cv2.morphologyEx(cand.astype(np.uint8), cv2.MORPH_OPEN, np.ones((3, 3), np.uint8)).astype(bool)
    cand &= ~robot_pixels(window, cand)
    return pts[cand]


def _above_table(pts: np.ndarray, near: np.ndarray, off_max_m: float = TABLE_OFF_MAX_M) -> np.ndarray:
    """(H, W) each point's height above the table as this view sees it: a plane fitted to the lower half
    of the points ``near`` the spot, then to those within :data:`TABLE_BAND_M` of it. A camera whose pose
    is known only to its calibration sees the table tilted and raised by some millimetres (the world's
    z = 0 is not where it sees the table); a plane farther than ``off_max_m`` from z = 0 (the spot
    covered by something) is not the table, and the world's z is kept."""
    ok = near & np.isfinite(pts[..., 2])
    P = pts[ok]
    if len(P) < 50:
        return pts[..., 2]
    sel = P[:, 2] <= np.quantile(P[:, 2], 0.5)
    coef = np.zeros(3)
    for _ in range(3):
        A = np.column_stack([P[sel, 0], P[sel, 1], np.ones(int(sel.sum()))])
        coef = np.linalg.lstsq(A, P[sel, 2], rcond=None)[0]
        res = P[:, 2] - (P[:, :2] @ coef[:2] + coef[2])
        inliers = np.abs(res) < TABLE_BAND_M
        if inliers.sum() < 30:
            break
        sel = inliers
    at_spot = float(np.mean(P[:, :2], axis=0) @ coef[:2] + coef[2])
    if abs(at_spot) > off_max_m or float(np.hypot(coef[0], coef[1])) > TABLE_SLOPE_MAX:
        return pts[..., 2]
    return pts[..., 2] - (pts[..., 0] * coef[0] + pts[..., 1] * coef[1] + coef[2])


def with_neighbours(
    frame: RGBDFrame, estimate: PoseEstimate, model: TargetModel, params: PerceptionParams | None = None
) -> PoseEstimate:
    """The estimate with its :attr:`~pickdemo.perception.model.PoseEstimate.neighbours` from ``frame``
    (unchanged when it has them, or when the frame does not show all around the target)."""
    if estimate.neighbours is not None:
        return estimate
    points = neighbour_points(frame, estimate, model, params or PerceptionParams())
    return estimate if points is None else dataclasses.replace(estimate, neighbours=points)
