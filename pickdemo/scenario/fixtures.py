"""The cell's fixtures (``[[fixtures]]`` in a scenario): a walled bin, built of boxes, fixed to the table.

A fixture is part of the task, as a real cell's bins are: the robot knows its pose and shape. What
the rest of pickdemo reads of one is its boxes (:meth:`FixtureSpec.boxes`): the simulator builds them,
perception leaves their points out of its cloud (as it does the robot's own links), the grasps keep
the hand clear of them, an object standing inside rests on its floor (:meth:`FixtureSpec.floor_z`),
and ``validate`` checks that it stands on the table, clear of the others and of the place.

Pure: no simulator.
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.scenario.base import RESERVED_NAMES, Angle, Model, Name, UnitFloat, Vec2

InnerSide = Annotated[float, Field(ge=0.05, le=1.5)]  # m, a bin's inside along one axis


class FixtureSpec(Model):
    """A walled bin: its inside ``inner_size`` (x, y, in its own frame) on a floor ``floor_thickness_m``
    thick, walls ``wall_thickness_m`` thick rising ``wall_height_m`` above the floor, its centre at
    ``position`` on the table, turned ``yaw_deg`` about the vertical."""

    kind: Literal["bin"]
    name: Name
    position: Vec2  # m, x, y of its centre on the table
    yaw_deg: Angle = 0.0
    inner_size: tuple[InnerSide, InnerSide]
    wall_height_m: Annotated[float, Field(ge=0.01, le=0.5)] = 0.08  # above the floor
    wall_thickness_m: Annotated[float, Field(ge=0.003, le=0.05)] = 0.01
    floor_thickness_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.01  # 0: no floor, it stands on the table
    color: tuple[UnitFloat, UnitFloat, UnitFloat] = (0.35, 0.45, 0.6)

    @field_validator("name")
    @classmethod
    def _not_reserved(cls, name: str) -> str:
        if name in RESERVED_NAMES:
            raise ValueError(f"{name!r} is the name of a body of the scene; choose another")
        return name

    @property
    def pose(self) -> Pose:
        """Its frame: the centre of its footprint on the table, turned by ``yaw_deg``."""
        return Pose.from_xyz_rpy(np.array([*self.position, 0.0]), yaw=float(np.radians(self.yaw_deg)))

    @property
    def floor_z(self) -> float:
        """The height above the table of what stands inside it (its floor's top)."""
        return self.floor_thickness_m

    @property
    def rim_z(self) -> float:
        """Its walls' top above the table."""
        return self.floor_thickness_m + self.wall_height_m

    @property
    def half_outer(self) -> tuple[float, float]:
        """Half its outer footprint (m, x and y in its own frame)."""
        return (self.inner_size[0] / 2.0 + self.wall_thickness_m, self.inner_size[1] / 2.0 + self.wall_thickness_m)

    def boxes(self, grown_m: float = 0.0) -> tuple[OrientedBox, ...]:
        """Its solid parts in the world: the floor (if it has one), then the walls at -x, +x, -y, +y;
        ``grown_m`` larger every way (what perception takes for the fixture: its surfaces seen with
        the sensor's noise)."""
        ix, iy = self.inner_size[0] / 2.0, self.inner_size[1] / 2.0
        ox, oy = self.half_outer
        top, f = self.rim_z, self.floor_thickness_m
        parts = [((-ox, -oy, 0.0), (ox, oy, f))] if f > 0.0 else []
        parts += [
            ((-ox, -oy, 0.0), (-ix, oy, top)),
            ((ix, -oy, 0.0), (ox, oy, top)),
            ((-ix, -oy, 0.0), (ix, -iy, top)),
            ((-ix, iy, 0.0), (ix, oy, top)),
        ]
        pose = self.pose
        g = np.full(3, grown_m)
        return tuple(OrientedBox(pose, np.asarray(lo, float) - g, np.asarray(hi, float) + g) for lo, hi in parts)

    def inside(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether (x, y) lies within its inner walls, ``margin`` from them."""
        local = (np.array([x, y, 0.0]) - self.pose.position) @ self.pose.rotation
        return bool(
            abs(local[0]) <= self.inner_size[0] / 2.0 - margin and abs(local[1]) <= self.inner_size[1] / 2.0 - margin
        )

    def footprint(self) -> np.ndarray:
        """Its outer footprint's corners on the table (4, 2), counter-clockwise."""
        ox, oy = self.half_outer
        local = np.array([[-ox, -oy, 0.0], [ox, -oy, 0.0], [ox, oy, 0.0], [-ox, oy, 0.0]])
        return self.pose.transform_points(local)[:, :2]


def fixture_boxes(fixtures: tuple[FixtureSpec, ...], grown_m: float = 0.0) -> tuple[OrientedBox, ...]:
    """Every fixture's solid parts in the world (``grown_m`` larger every way)."""
    return tuple(b for f in fixtures for b in f.boxes(grown_m))
