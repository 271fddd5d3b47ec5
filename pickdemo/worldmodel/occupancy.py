"""Free space as the robot has seen it: each point of the space above the table is occupied (within
an object's box, from the table to its top), free (a view saw past it: its depth reading there lies
farther), or never seen; never seen is kept apart from free (:class:`Occupancy`). The occupied cells
go to coal as an OctoMap octree (:meth:`Occupancy.octree`), which coal collides against the robot's
geometry (the next issue's planner).

Pure: views in, answers out; no simulator. A view is kept as it came (its strided depth, intrinsics
and pose): a point is classified when asked, by projecting it into the kept views, so taking a view
in costs nothing (a frame's free space carved voxel by voxel would cost more than its instances). A
camera keeps its :data:`VIEWS_PER_CAMERA` newest views from distinct poses (a hand camera moves).
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import OrientedBox
from pickdemo.worldmodel.instances import SceneView

UNKNOWN, FREE, OCCUPIED = 0, 1, 2
#: The octree's and the occupied test's cell (m).
RESOLUTION_M = 0.01
#: Views kept per camera (from distinct poses).
VIEWS_PER_CAMERA = 6
#: A camera moved less than this (m) since its last kept view replaces it.
SAME_POSE_M = 0.01
#: A view saw past a point when its reading there lies this much farther than the point (m).
PAST_M = 0.01


class Occupancy:
    """What the robot has seen of the space (see the module docstring)."""

    def __init__(self, resolution_m: float = RESOLUTION_M) -> None:
        self.resolution_m = resolution_m
        self.views: dict[str, list[SceneView]] = {}

    def add(self, view: SceneView) -> None:
        """Keep a view (a region's view too: what it saw of the space is as good)."""
        kept = self.views.setdefault(view.camera, [])
        at = view.T_world_cam.position
        # (a view from the same pose, of the same region, is replaced: it saw the same)
        kept[:] = [
            v
            for v in kept
            if np.linalg.norm(v.T_world_cam.position - at) >= SAME_POSE_M or v.depth_m.shape != view.depth_m.shape
        ]
        kept.append(view)
        del kept[:-VIEWS_PER_CAMERA]

    def seen_free(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: which points some kept view saw past."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        out = np.zeros(len(p), dtype=bool)
        for views in self.views.values():
            for view in views:
                out |= view.sees(p, margin_m=-PAST_M)
        return out

    def classify(self, points: np.ndarray, solids: list[OrientedBox]) -> np.ndarray:
        """(N,) int8: each point :data:`OCCUPIED` (in one of ``solids``, the objects' boxes as the world
        has them now: what the camera sees of an object from above is solid down to the table),
        :data:`FREE` (a view saw past it) or :data:`UNKNOWN`."""
        p = np.atleast_2d(np.asarray(points, dtype=float))
        out = np.where(self.seen_free(p), FREE, UNKNOWN).astype(np.int8)
        for box in solids:
            out[box.contains(p)] = OCCUPIED
        return out

    def octree(self, solids: list[OrientedBox]):  # noqa: ANN201 - a coal.OcTree
        """The objects' boxes as coal's OctoMap octree (``coal.makeOctree``, a point every cell of
        each); None: nothing occupied."""
        r = self.resolution_m
        cells = []
        for box in solids:
            axes = [
                np.arange(lo + r / 2.0, max(hi, lo + r / 2.0 + 1e-9), r) for lo, hi in zip(box.lo, box.hi, strict=True)
            ]
            grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
            cells.append(grid @ box.pose.rotation.T + box.pose.position)
        if not cells:
            return None
        import coal  # (installed with pin; imported when a planner asks)

        centres = np.unique(np.floor(np.vstack(cells) / r).astype(np.int64), axis=0) + 0.5
        return coal.makeOctree(centres * r, r)
