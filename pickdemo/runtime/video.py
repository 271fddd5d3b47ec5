"""Episode video: perception drawn on the camera's view, beside a third-person view, as H.264 MP4.

Pure: images (arrays) in, an MP4 file out. Drawing is OpenCV's; encoding is PyAV's (FFmpeg with
libx264 inside its wheel, nothing downloaded), an optional extra: the ``video`` extra.
What is drawn on the camera's view:

- the Shi-Tomasi feature points of the current estimate (from the newest frame, while perception
  looks: never an old one over a table it has left), each with its covariance ellipse (eq. 14,
  projected into the image; 3 sigma, magnified ``ELLIPSE_GAIN`` times, as they are sub-pixel);
- the estimated pose's axes (solid) beside the true pose's (thin, white: a label, for the viewer);
- while it tracks the target: the tracker's predicted path for the next second (a dotted line) and
  its position now; until the gripper closes: the chosen grasp, the two finger pads across the object;
- a caption: the state of the pick, the simulated time, the attempt; beneath it a legend of the colours.

The camera's view follows what matters (:func:`panel_centre`): the tracked target until the grasp,
then the hand that holds it, then the place once the target is let go (and verified there).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from pickdemo.core.camera import Intrinsics, project
from pickdemo.core.geometry import Pose
from pickdemo.perception import PoseEstimate

ELLIPSE_GAIN = 1.0  # covariance ellipses drawn at this many times their 3-sigma size
AXIS_M = 0.04  # length of the drawn pose axes
AXIS_COLOURS = ((230, 40, 40), (40, 200, 40), (60, 90, 240))  # x, y, z in RGB
TRUTH_COLOUR = (255, 255, 255)
ELLIPSE_COLOUR = (255, 200, 0)
FEATURE_COLOUR = (255, 255, 0)
PATH_COLOUR = (255, 0, 255)
GRASP_COLOUR = (255, 140, 0)
PLANNED_COLOUR = (80, 255, 80)  # the TCP along a path planned around something
ID_COLOUR = (120, 230, 255)  # the world model's ids (the target's in the tracker's colour)
CAPTION_BAR_PX = 28
LEGEND_BAR_PX = 20

#: States of the pick in which the tracker's belief and path are drawn (it looks at the target then).
TRACKER_STATES = frozenset({"look", "approach", "descend", "close", "back_off"})
#: States in which the planned grasp is drawn (until the gripper has closed on it).
GRASP_STATES = frozenset({"approach", "descend", "close"})
#: States in which the hand holds the target (the camera's view follows the hand).
HELD_STATES = frozenset({"lift", "transport", "lower", "release"})
#: States after the target is let go (the camera's view shows the place).
PLACED_STATES = frozenset({"retreat", "home", "verify", "done"})


def panel_centre(
    state: str, *, tracked: np.ndarray | None, hand: np.ndarray | None, place: np.ndarray
) -> np.ndarray | None:
    """Where the camera's view in the video is centred (world, m): the tracked target until the
    grasp, the hand (the held target) while carrying, the place once the target is let go. ``None``:
    nothing to follow yet (the whole image's centre)."""
    if state in HELD_STATES:
        return hand if hand is not None else tracked
    if state in PLACED_STATES:
        return place
    if state == "failed":
        return tracked if tracked is not None else hand
    return tracked


class VideoUnavailable(RuntimeError):
    """PyAV is not installed."""


@dataclass(frozen=True)
class Overlay:
    """What to draw on the camera's view at one video frame (world frame, metres)."""

    caption: str
    estimate: PoseEstimate | None = None
    truth: Pose | None = None  # a label for the viewer, never for control
    tracked: np.ndarray | None = None  # (3,) where the tracker puts the target now
    tracked_path: np.ndarray | None = None  # (N, 3) where it predicts the target over the next second
    grasp: Pose | None = None  # the planned grasp (TCP) pose
    grasp_width_m: float = 0.0
    #: the world model's objects: (id, where its top's middle is, whether it is the target)
    objects: tuple[tuple[int, np.ndarray, bool], ...] = ()
    planned_path: np.ndarray | None = None  # (N, 3) the TCP along a path planned around something


def _to_pixels(points_world: np.ndarray, K: Intrinsics, T_world_cam: Pose) -> np.ndarray | None:
    p_cam = T_world_cam.inverse().transform_points(np.atleast_2d(points_world))
    if np.any(p_cam[:, 2] <= 1e-3):
        return None
    return project(p_cam, K)


def _pt(uv: np.ndarray) -> tuple[int, int]:
    return int(round(float(uv[0]))), int(round(float(uv[1])))


def draw_axes(img: np.ndarray, pose: Pose, K: Intrinsics, T: Pose, *, thickness: int, colours=AXIS_COLOURS) -> None:
    ends = pose.transform_points(np.vstack([np.zeros(3), np.eye(3) * AXIS_M]))
    uv = _to_pixels(ends, K, T)
    if uv is None:
        return
    for k in range(3):
        cv2.line(img, _pt(uv[0]), _pt(uv[k + 1]), colours[k], thickness, cv2.LINE_AA)


def draw_overlay(img: np.ndarray, K: Intrinsics, T_world_cam: Pose, ov: Overlay) -> np.ndarray:
    """The camera's view with perception and the plan drawn on it (a copy)."""
    out = np.ascontiguousarray(img.copy())
    T = T_world_cam
    if ov.truth is not None:
        draw_axes(out, ov.truth, K, T, thickness=1, colours=(TRUTH_COLOUR,) * 3)
    if ov.estimate is not None:
        for fp in ov.estimate.features:
            uv = _to_pixels(fp.mean_world, K, T)
            if uv is None:
                continue
            # Eq. (14)'s covariance, projected: J C J^T with J the projection's Jacobian at the point.
            pc = T.inverse().transform_points(fp.mean_world[None])[0]
            Rcw = T.rotation.T
            J = np.array([[K.fx / pc[2], 0.0, -K.fx * pc[0] / pc[2] ** 2],
                          [0.0, K.fy / pc[2], -K.fy * pc[1] / pc[2] ** 2]]) @ Rcw  # fmt: skip
            C2 = J @ fp.cov_world @ J.T
            w, V = np.linalg.eigh(0.5 * (C2 + C2.T))
            axes = tuple(int(max(1, round(3.0 * ELLIPSE_GAIN * np.sqrt(max(x, 0.0))))) for x in w[::-1])
            angle = float(np.degrees(np.arctan2(V[1, -1], V[0, -1])))
            cv2.ellipse(out, _pt(uv[0]), axes, angle, 0, 360, ELLIPSE_COLOUR, 1, cv2.LINE_AA)
            cv2.circle(out, _pt(uv[0]), 1, FEATURE_COLOUR, -1)
        draw_axes(out, ov.estimate.pose, K, T, thickness=2)
    if ov.tracked_path is not None and len(ov.tracked_path) > 1:
        uv = _to_pixels(ov.tracked_path, K, T)
        if uv is not None:
            for a in uv[::2]:
                cv2.circle(out, _pt(a), 1, PATH_COLOUR, -1)
    if ov.planned_path is not None and len(ov.planned_path) > 1:
        uv = _to_pixels(ov.planned_path, K, T)
        if uv is not None:
            cv2.polylines(out, [np.round(uv).astype(np.int32)], False, PLANNED_COLOUR, 1, cv2.LINE_AA)
    if ov.tracked is not None:
        uv = _to_pixels(ov.tracked, K, T)
        if uv is not None:
            cv2.drawMarker(out, _pt(uv[0]), PATH_COLOUR, cv2.MARKER_CROSS, 10, 1, cv2.LINE_AA)
    for oid, top, target in ov.objects:  # each object of the world model, its id at its top
        uv = _to_pixels(top, K, T)
        if uv is not None:
            at, colour = _pt(uv[0] + [-4, -8]), PATH_COLOUR if target else ID_COLOUR
            label = f"#{oid}"
            cv2.putText(out, label, at, cv2.FONT_HERSHEY_SIMPLEX, 0.4, (0, 0, 0), 3, cv2.LINE_AA)  # (an outline)
            cv2.putText(out, label, at, cv2.FONT_HERSHEY_SIMPLEX, 0.4, colour, 1, cv2.LINE_AA)
    if ov.grasp is not None and ov.grasp_width_m > 0:
        half = ov.grasp_width_m / 2.0
        pads = ov.grasp.transform_points(np.array([[0.0, -half, 0.0], [0.0, half, 0.0]]))
        uv = _to_pixels(pads, K, T)
        if uv is not None:
            cv2.line(out, _pt(uv[0]), _pt(uv[1]), GRASP_COLOUR, 1, cv2.LINE_AA)
            for a in uv:
                cv2.circle(out, _pt(a), 3, GRASP_COLOUR, 1, cv2.LINE_AA)
    return out


def magnify(img: np.ndarray, K: Intrinsics, factor: int) -> tuple[np.ndarray, Intrinsics]:
    """An image enlarged ``factor`` times (each pixel a block, as perception saw it) and its intrinsics."""
    big = cv2.resize(img, (img.shape[1] * factor, img.shape[0] * factor), interpolation=cv2.INTER_NEAREST)
    # Pixel centres: u_big = factor * u + (factor - 1) / 2.
    off = (factor - 1) / 2.0
    Kb = Intrinsics(
        width=big.shape[1], height=big.shape[0], fx=K.fx * factor, fy=K.fy * factor,
        cx=K.cx * factor + off, cy=K.cy * factor + off,
    )  # fmt: skip
    return big, Kb


def legend_bar(width: int, height: int = LEGEND_BAR_PX) -> np.ndarray:
    """A strip naming each overlay's colour, drawn with the overlay's own marks."""
    bar = np.full((height, width, 3), 40, np.uint8)
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.36
    y = height // 2
    x = 8

    def text(label: str) -> None:
        nonlocal x
        cv2.putText(bar, label, (x, y + 4), font, scale, (225, 225, 225), 1, cv2.LINE_AA)
        x += cv2.getTextSize(label, font, scale, 1)[0][0] + 12

    for k, c in enumerate(AXIS_COLOURS):  # estimate axes: x, y, z
        cv2.line(bar, (x + 4 * k, y + 5), (x + 4 * k + 6, y - 5), c, 2, cv2.LINE_AA)
    x += 20
    text("estimate xyz")
    cv2.line(bar, (x, y + 5), (x + 10, y - 5), TRUTH_COLOUR, 1, cv2.LINE_AA)
    x += 14
    text("truth")
    cv2.ellipse(bar, (x + 6, y), (6, 4), 20, 0, 360, ELLIPSE_COLOUR, 2, cv2.LINE_AA)
    cv2.circle(bar, (x + 6, y), 1, FEATURE_COLOUR, -1)
    x += 16
    text("features, 3-sigma")
    for k in range(4):
        cv2.circle(bar, (x + 4 * k, y), 1, PATH_COLOUR, -1)
    cv2.drawMarker(bar, (x + 18, y), PATH_COLOUR, cv2.MARKER_CROSS, 9, 2, cv2.LINE_AA)
    x += 26
    text("tracker, path 1 s")
    cv2.line(bar, (x + 3, y), (x + 15, y), GRASP_COLOUR, 1, cv2.LINE_AA)
    for u in (x + 3, x + 15):
        cv2.circle(bar, (u, y), 3, GRASP_COLOUR, 2, cv2.LINE_AA)
    x += 22
    text("planned grasp")
    cv2.polylines(bar, [np.array([[x, y + 4], [x + 6, y - 4], [x + 14, y - 2]], np.int32)], False, PLANNED_COLOUR, 1)
    x += 18
    text("planned path")
    return bar


def compose(left: np.ndarray, right: np.ndarray, caption: str, *, legend: bool = True) -> np.ndarray:
    """Two views side by side (heights matched) above a caption bar and the overlays' legend; even
    width and height (H.264)."""
    h = max(left.shape[0], right.shape[0])

    def fit(img: np.ndarray) -> np.ndarray:
        if img.shape[0] == h:
            return img
        w = int(round(img.shape[1] * h / img.shape[0]))
        return cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)

    row = np.hstack([fit(left), fit(right)])
    bar = np.full((CAPTION_BAR_PX, row.shape[1], 3), 24, np.uint8)
    cv2.putText(bar, caption, (8, 19), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (240, 240, 240), 1, cv2.LINE_AA)
    frame = np.vstack([row, bar, legend_bar(row.shape[1])] if legend else [row, bar])
    return frame[: frame.shape[0] // 2 * 2, : frame.shape[1] // 2 * 2]


class VideoWriter:
    """Frames to an H.264 MP4 (yuv420p, plays in a browser) with PyAV."""

    def __init__(self, path: str | Path, fps: int) -> None:
        try:
            import av  # optional: pip install -c .ci/constraints.txt ".[video]" (in the checkout)
        except ImportError as exc:
            raise VideoUnavailable(
                'video needs PyAV: pip install -c .ci/constraints.txt ".[video]" (in the checkout)'
            ) from exc
        self._av = av
        self.path = Path(path)
        self.fps = fps
        self._container = None
        self._stream = None
        self.frames = 0

    def add(self, frame: np.ndarray) -> None:
        if self._container is None:
            self._container = self._av.open(str(self.path), mode="w")
            self._stream = self._container.add_stream("libx264", rate=self.fps)
            self._stream.width, self._stream.height = frame.shape[1], frame.shape[0]
            self._stream.pix_fmt = "yuv420p"
            self._stream.options = {"crf": "23", "preset": "veryfast", "movflags": "+faststart"}
        vf = self._av.VideoFrame.from_ndarray(np.ascontiguousarray(frame), format="rgb24")
        for packet in self._stream.encode(vf):
            self._container.mux(packet)
        self.frames += 1

    def close(self) -> None:
        if self._container is None:
            return
        for packet in self._stream.encode():
            self._container.mux(packet)
        self._container.close()
        self._container = None
