"""A clear round's tray, as the scenario file states it (its URDF, scale, position and turn): what the
robot knows of its cell's tray, and what the referee scores by. Pure: no simulator, nothing a seed
draws (so the controller may hold it: the import rule of ``tests/test_house.py`` allows this module)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.core.meshes import read_urdf
from pickdemo.scenario.schema import Scenario


@dataclass(frozen=True)
class Tray:
    """A clear round's tray, fixed to the table: what the robot knows of it (the cell's layout) and
    what the referee scores by. Its size is its URDF's collision geometry's bounding box at its scale."""

    urdf: str
    scale: float
    position: tuple[float, float]  # m, its centre on the table
    yaw_rad: float
    half_extents: tuple[float, float]  # m, of its footprint in its own frame
    rim_z: float  # m, its top edge above the table

    #: drop spots in the tray, as shares of its half extents: spread so that objects do not stack
    SPOTS = ((0.0, 0.0), (-0.4, -0.4), (0.4, 0.4), (-0.4, 0.4), (0.4, -0.4))

    @classmethod
    def of(cls, scenario: Scenario) -> Tray | None:
        """The scenario's tray (None without one); reads its URDF (a
        :class:`~pickdemo.core.meshes.MeshFileError` for a bad one)."""
        place = scenario.place
        if place.tray is None:
            return None

        v = read_urdf(place.tray).vertices * place.tray_scale
        lo, hi = v.min(axis=0), v.max(axis=0)
        assert place.position is not None  # the schema asks a tray for its position
        # its footprint about its origin (symmetric: a tray's origin is its middle)
        half = np.maximum(np.abs(lo[:2]), np.abs(hi[:2]))
        z0 = float(lo[2])  # the body frame sits on the table where its lowest point does
        return cls(place.tray, place.tray_scale, (float(place.position[0]), float(place.position[1])),
                   float(np.radians(place.yaw_deg)), (float(half[0]), float(half[1])), float(hi[2] - z0))  # fmt: skip

    @property
    def base_z(self) -> float:
        """Its body frame's height above the table (its lowest point on the table)."""
        return float(-read_urdf(self.urdf).vertices[:, 2].min() * self.scale)

    @property
    def pose(self) -> Pose:
        return Pose.from_xyz_rpy(np.array([*self.position, 0.0]), yaw=self.yaw_rad)

    def holds(self, xy: np.ndarray) -> bool:
        """Whether a point seen from above lies over its footprint."""
        dx, dy = float(xy[0]) - self.position[0], float(xy[1]) - self.position[1]
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)  # (into the tray's frame: the yaw's inverse)
        return abs(c * dx + s * dy) <= self.half_extents[0] and abs(-s * dx + c * dy) <= self.half_extents[1]

    def spot(self, k: int) -> tuple[float, float]:
        """Where the ``k``-th object is dropped (the spots in turn)."""
        sx, sy = self.SPOTS[k % len(self.SPOTS)]
        local = np.array([sx * self.half_extents[0], sy * self.half_extents[1]])
        xy = np.asarray(self.position) + self.pose.rotation[:2, :2] @ local
        return (float(xy[0]), float(xy[1]))

    def box(self, margin_m: float = 0.01, height_m: float = 1.0) -> OrientedBox:
        """Its footprint, ``margin_m`` wider, from just under the table to ``height_m`` above it: what
        lies there is the tray or in it (segmentation leaves it out, as it leaves out the robot)."""
        hx, hy = self.half_extents
        return OrientedBox(self.pose, np.array([-hx - margin_m, -hy - margin_m, -0.01]),
                           np.array([hx + margin_m, hy + margin_m, height_m]))  # fmt: skip
