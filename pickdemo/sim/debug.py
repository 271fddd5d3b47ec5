"""The same overlays as the video's, drawn in the PyBullet window (``run --gui``) as debug lines.

Each item keeps its id and is replaced in place (``replaceItemUniqueId``), so the window shows the
newest estimate, the tracker's path and the chosen grasp without piling lines up.
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.runtime.video import Overlay
from pickdemo.sim.scene import Scene

AXIS_M = 0.08  # longer than the video's: the window is seen from farther away

_RGB = ((0.9, 0.15, 0.15), (0.15, 0.8, 0.15), (0.25, 0.35, 0.95))


class DebugDraw:
    """Draws an :class:`~pickdemo.runtime.video.Overlay` into the scene's debug visualiser."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self._ids: dict[str, int] = {}

    def _line(self, key: str, a: np.ndarray, b: np.ndarray, rgb: tuple[float, float, float], width: float) -> None:
        self._ids[key] = self.scene.client.addUserDebugLine(
            [float(v) for v in a], [float(v) for v in b], list(rgb), lineWidth=width,
            replaceItemUniqueId=self._ids.get(key, -1),
        )  # fmt: skip

    def _axes(self, key: str, pose: Pose, width: float, rgb=None) -> None:
        ends = pose.transform_points(np.vstack([np.zeros(3), np.eye(3) * AXIS_M]))
        for k in range(3):
            self._line(f"{key}{k}", ends[0], ends[k + 1], rgb or _RGB[k], width)

    def draw(self, ov: Overlay) -> None:
        if ov.estimate is not None:
            self._axes("estimate", ov.estimate.pose, 3.0)
        if ov.truth is not None:
            self._axes("truth", ov.truth, 1.0, (1.0, 1.0, 1.0))
        if ov.tracked_path is not None and len(ov.tracked_path) > 1:
            path = ov.tracked_path + np.array([0.0, 0.0, 0.002])
            for i in range(min(len(path) - 1, 10)):
                self._line(f"path{i}", path[i], path[i + 1], (1.0, 0.0, 1.0), 2.0)
        if ov.grasp is not None and ov.grasp_width_m > 0:
            half = ov.grasp_width_m / 2.0
            pads = ov.grasp.transform_points(np.array([[0.0, -half, 0.0], [0.0, half, 0.0]]))
            self._line("grasp", pads[0], pads[1], (1.0, 0.55, 0.0), 3.0)
        self._ids["caption"] = self.scene.client.addUserDebugText(
            ov.caption,
            [0.2, -0.45, 0.45],
            [0.1, 0.1, 0.1],
            textSize=1.3,
            replaceItemUniqueId=self._ids.get("caption", -1),
        )
