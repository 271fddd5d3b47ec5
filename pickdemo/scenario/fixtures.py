"""The cell's fixtures (``[[fixtures]]`` in a scenario): a walled bin built of boxes on the table
(:class:`BinSpec`), or a rigid model from a URDF or SDF file (:class:`ModelSpec`: a shelf).

A fixture is part of the task, as a real cell's bins and shelves are: the robot knows its pose and
shape. What the rest of pickdemo reads of one is its boxes (``boxes()``): perception leaves their
points out of its cloud (as it does the robot's own links), the grasps and the arm keep clear of them,
and an object stands on the highest of their tops under it (``support_z``: a bin's floor, a shelf's
board); the simulator builds a bin's boxes and loads a model's file. ``validate`` checks that each
stands clear of the robot, the table's slab, the others and the place.

Pure: no simulator.
"""

from __future__ import annotations

import functools
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, ValidationInfo, field_validator

from pickdemo.core.geometry import OrientedBox, Pose, top_below
from pickdemo.core.meshes import MeshFileError, resolve
from pickdemo.core.model_file import read_model
from pickdemo.scenario.base import RESERVED_NAMES, Angle, Model, Name, Scale, UnitFloat, Vec2, Vec3
from pickdemo.scenario.objects import resolve_path

InnerSide = Annotated[float, Field(ge=0.05, le=1.5)]  # m, a bin's inside along one axis


class _Fixture(Model):
    """What every fixture has: a name (not a body of the scene's), solid parts (``boxes``, given by
    each kind), and the tops of those an object stands on (``support_z``)."""

    name: Name

    @field_validator("name")
    @classmethod
    def _not_reserved(cls, name: str) -> str:
        if name in RESERVED_NAMES:
            raise ValueError(f"{name!r} is the name of a body of the scene; choose another")
        return name

    def boxes(self, grown_m: float = 0.0) -> tuple[OrientedBox, ...]:
        raise NotImplementedError

    @functools.cached_property
    def _solid(self) -> tuple[OrientedBox, ...]:
        return self.boxes()

    def support_z(self, x: float, y: float, z: float) -> float | None:
        """The highest top of its solid parts under (x, y) at or below ``z`` (a bin's floor inside it,
        a shelf's board), or None."""
        return top_below(self._solid, x, y, z)


class BinSpec(_Fixture):
    """A walled bin: its inside ``inner_size`` (x, y, in its own frame) on a floor ``floor_thickness_m``
    thick, walls ``wall_thickness_m`` thick rising ``wall_height_m`` above the floor, its centre at
    ``position`` on the table, turned ``yaw_deg`` about the vertical."""

    kind: Literal["bin"]
    position: Vec2  # m, x, y of its centre on the table
    yaw_deg: Angle = 0.0
    inner_size: tuple[InnerSide, InnerSide]
    wall_height_m: Annotated[float, Field(ge=0.01, le=0.5)] = 0.08  # above the floor
    wall_thickness_m: Annotated[float, Field(ge=0.003, le=0.05)] = 0.01
    floor_thickness_m: Annotated[float, Field(ge=0.0, le=0.05)] = 0.01  # 0: no floor, it stands on the table
    color: tuple[UnitFloat, UnitFloat, UnitFloat] = (0.35, 0.45, 0.6)

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


class ModelSpec(_Fixture):
    """A rigid model fixed in the cell, from a URDF or SDF file (``pybullet_data:kiva_shelf/model.sdf``,
    or a path relative to the scenario file): its frame (the root link's) at ``position`` (x, y, and z
    above the table's top: a shelf standing on the floor beside the table has it below 0), turned
    ``yaw_deg`` about the vertical, at ``scale``. Its collision geometry is read as boxes
    (:mod:`pickdemo.core.model_file`)."""

    kind: Literal["model"]
    file: Annotated[str, Field(min_length=1, max_length=500)]
    position: Vec3
    yaw_deg: Angle = 0.0
    scale: Scale = 1.0
    color: tuple[UnitFloat, UnitFloat, UnitFloat] | None = None  # None: the file's own
    #: how far the surfaces the camera sees (its visual mesh) may stand off its collision boxes (m): what
    #: perception leaves out around them (the kiva shelf's mesh: up to 23 mm, measured)
    visual_margin_m: Annotated[float, Field(ge=0.0, le=0.1)] = 0.0

    @field_validator("file")
    @classmethod
    def _readable(cls, spec: str, info: ValidationInfo) -> str:
        path = resolve_path(spec, info)
        assert path is not None
        try:
            read_model(resolve(path, None))
        except MeshFileError as exc:
            raise ValueError(str(exc)) from None
        return path

    @property
    def pose(self) -> Pose:
        """Its frame in the world."""
        return Pose.from_xyz_rpy(np.array(self.position, dtype=float), yaw=float(np.radians(self.yaw_deg)))

    def _local(self) -> tuple[tuple[OrientedBox, ...], Pose]:
        return read_model(resolve(self.file, None)).scaled(self.scale)

    @property
    def inertial_pose(self) -> Pose:
        """Its root link's inertial frame in the world (where PyBullet puts its base)."""
        return self.pose @ self._local()[1]

    def boxes(self, grown_m: float = 0.0) -> tuple[OrientedBox, ...]:
        """Its collision boxes in the world, ``grown_m`` larger every way."""
        g = np.full(3, grown_m)
        at = self.pose
        return tuple(OrientedBox(at @ b.pose, b.lo - g, b.hi + g) for b in self._local()[0])

    def footprint(self) -> np.ndarray:
        """The corners of its boxes' bounding rectangle in its own frame, on the table (4, 2)."""
        corners = np.vstack([b.corners() for b in self._local()[0]])
        (x0, y0), (x1, y1) = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
        local = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
        return self.pose.transform_points(local)[:, :2]


#: A fixture of any kind (``kind`` says which).
FixtureSpec = Annotated[Union[BinSpec, ModelSpec], Field(discriminator="kind")]  # noqa: UP007 - a pydantic union


def fixture_boxes(fixtures: tuple[BinSpec | ModelSpec, ...], grown_m: float = 0.0) -> tuple[OrientedBox, ...]:
    """Every fixture's solid parts in the world (``grown_m`` larger every way)."""
    return tuple(b for f in fixtures for b in f.boxes(grown_m))


def seen_boxes(fixtures: tuple[BinSpec | ModelSpec, ...]) -> tuple[OrientedBox, ...]:
    """Every fixture's parts as the camera may see them: a model's grown by its ``visual_margin_m``."""
    return tuple(b for f in fixtures for b in f.boxes(getattr(f, "visual_margin_m", 0.0)))
