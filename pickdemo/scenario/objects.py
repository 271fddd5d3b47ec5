"""The scenario's table, objects and place: shapes, sizes, colours, meshes by file or glob, where
they stand (fixed or drawn per seed), and where the target goes (a spot, a region, a tray)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, PrivateAttr, ValidationInfo, field_validator, model_validator

from pickdemo.core.meshes import PYBULLET_DATA, read_urdf, usable
from pickdemo.core.shapes import SHAPES, Mesh, Shape, ShapeName, make_shape
from pickdemo.scenario.base import (
    RESERVED_NAMES,
    Angle,
    Coord,
    Extent,
    Friction,
    Model,
    Name,
    Scale,
    UnitFloat,
    Vec2,
)

#: The table's slab, below its top (m).
TABLE_THICKNESS_M = 0.05


class TableSpec(Model):
    """The table; its top surface is the world plane z = 0 and the robot stands on it at the origin."""

    size: tuple[Annotated[float, Field(ge=0.3, le=5.0)], Annotated[float, Field(ge=0.3, le=5.0)]] = (1.4, 1.2)  # m
    center: Vec2 = (0.45, 0.0)  # m, x, y of the table's centre
    color: tuple[UnitFloat, UnitFloat, UnitFloat] = (0.55, 0.42, 0.30)
    friction: Friction = 0.8

    def holds(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether the point (x, y) lies on the table top, ``margin`` inside its edges."""
        hx, hy = self.size[0] / 2.0 - margin, self.size[1] / 2.0 - margin
        return abs(x - self.center[0]) <= hx and abs(y - self.center[1]) <= hy


class ReferenceSpec(Model):
    """Published figures to show beside ours (for example a row of the paper's Tables 1 and 2)."""

    label: Annotated[str, Field(max_length=80)] = ""
    position_error_mm: Annotated[float, Field(ge=0.0)]
    yaw_error_deg: Annotated[float, Field(ge=0.0)]
    pitch_error_deg: Annotated[float, Field(ge=0.0)] = 0.0
    roll_error_deg: Annotated[float, Field(ge=0.0)] = 0.0


def resolve_path(spec: str | None, info: ValidationInfo) -> str | None:
    """A path relative to the scenario file made absolute (``pybullet_data:`` ones are kept: another
    machine finds its own copy)."""
    if spec is None or spec.startswith(PYBULLET_DATA):
        return spec
    if not spec.isprintable():
        raise ValueError("a path of printable characters")
    base = (info.context or {}).get("base_dir")
    path = Path(spec).expanduser()
    return str(path if path.is_absolute() or base is None else Path(base) / path)


#: The sides of an object another may stand beside: along its own x or y axis, either way.
Side = Literal["+x", "-x", "+y", "-y"]


class BesideSpec(Model):
    """Where an object stands against another one (the scenes users set up: a cube flush against a
    carton): beside ``object`` (named before it), on one of ``sides`` of it (its own axes; one drawn
    per seed), ``gap_m`` from it (0: touching), turned as it is (plus the object's own yaw)."""

    object: Name
    gap_m: Annotated[float, Field(ge=0.0, le=0.2)] = 0.0
    sides: Annotated[tuple[Side, ...], Field(min_length=1)] = ("+x", "-x", "+y", "-y")


class ObjectSpec(Model):
    """One object on the table: a box or a cylinder (upright unless tilted), or a mesh from a URDF file
    (as the file stands it, turned about z)."""

    name: Name
    shape: ShapeName
    size: tuple[Extent, ...] | None = None  # box: x, y, z extents; cylinder: diameter, height (m)
    size_range: tuple[tuple[Extent, Extent], ...] | None = None  # per dimension: [min, max]
    color: tuple[UnitFloat, UnitFloat, UnitFloat] | None = None  # a box's or cylinder's; a mesh has its file's
    #: a mesh: "pybullet_data:duck_vhacd.urdf" (the pybullet wheel's data folder), else a path relative
    #: to the scenario file; or ``urdf_choice``, a glob of either kind: one of its sorted matches a seed
    urdf: Annotated[str, Field(min_length=1, max_length=500)] | None = None
    urdf_choice: Annotated[str, Field(min_length=1, max_length=500)] | None = None
    scale: Scale | None = None  # a mesh: times the URDF's own mesh scale (default 1)
    scale_range: tuple[Scale, Scale] | None = None  # ... or drawn per seed from [min, max]
    mass: Annotated[float, Field(ge=0.001, le=20.0)] = 0.1  # kg: 1 g to 20 kg (a mesh: its file's unless given)
    friction: Friction = 0.9  # (a mesh: its file's unless given)
    position: tuple[Coord, Coord] | tuple[Coord, Coord, Coord] | None = None  # m: x, y (and centre z)
    position_range: tuple[Vec2, Vec2] | None = None  # ((x_min, x_max), (y_min, y_max)) in m
    #: it stands on the highest top of a fixture under it at most this high (m above the table's top: a
    #: shelf's board); None: on the table, a belt or a bin's floor
    level_m: Coord | None = None
    beside: BesideSpec | None = None  # ... or against another object
    yaw_deg: Angle | None = None
    yaw_range_deg: tuple[Angle, Angle] | None = None
    pitch_deg: Angle | None = None
    pitch_range_deg: tuple[Angle, Angle] | None = None
    roll_deg: Angle | None = None
    roll_range_deg: tuple[Angle, Angle] | None = None
    static: bool = False  # held where it is placed (no gravity): for tilted objects in perception tests
    #: air passes through it (foam, fabric, a mesh bag): a suction cup on it never seals (the simulator's
    #: truth; the robot does not know it)
    porous: bool = False
    target: bool = False
    #: what a pick order tells the robot of a target it is otherwise told nothing of (a mesh, a cylinder
    #: lying): its height and its footprint's longer and shorter side as it rests (m), the same every
    #: seed; None: nothing (it is then the only object the robot may take for it)
    rough_size_m: tuple[Extent, Extent, Extent] | None = None
    reference: ReferenceSpec | None = None  # published errors for this object, shown by `perceive`
    #: an object ``beside`` another: where its centre may be (the scenario sets it from the other's)
    _beside_range: tuple[Vec2, Vec2] | None = PrivateAttr(default=None)

    @field_validator("name")
    @classmethod
    def _not_reserved(cls, name: str) -> str:
        if name.lower() in RESERVED_NAMES:
            raise ValueError(f"{name!r} is reserved (a body of the scene: {', '.join(sorted(RESERVED_NAMES))})")
        return name

    @field_validator("size", "size_range")
    @classmethod
    def _check_size(cls, size: tuple | None, info: ValidationInfo) -> tuple | None:
        if size is None:
            return size
        shape = info.data.get("shape")
        kind = SHAPES.get(shape or "")
        expected = len(size) if kind is None else kind.n_sizes
        if len(size) != expected:
            raise ValueError(f"a {shape} needs {expected} values ({kind.size_text}), got {len(size)}")  # type: ignore[union-attr]
        if info.field_name == "size_range" and any(lo > hi for lo, hi in size):
            raise ValueError("each size_range entry must be [min, max]")
        return size

    @field_validator("urdf", "urdf_choice")
    @classmethod
    def _resolve(cls, spec: str | None, info: ValidationInfo) -> str | None:
        return resolve_path(spec, info)

    @model_validator(mode="after")
    def _check(self) -> ObjectSpec:
        if self.shape == "mesh":
            self._check_mesh()
        else:
            for key in ("urdf", "urdf_choice", "scale", "scale_range"):
                if getattr(self, key) is not None:
                    raise ValueError(f'{key} is for a mesh (shape = "mesh"), not a {self.shape}')
            if self.color is None:
                raise ValueError(f"a {self.shape} needs a color ([r, g, b], each 0-1)")
        if self.shape != "mesh" and (self.size is None) == (self.size_range is None):
            raise ValueError("give exactly one of size, size_range")
        if sum(v is not None for v in (self.position, self.position_range, self.beside)) != 1:
            raise ValueError("give exactly one of position, position_range, beside")
        for fixed, rng, name in (
            (self.yaw_deg, self.yaw_range_deg, "yaw"),
            (self.pitch_deg, self.pitch_range_deg, "pitch"),
            (self.roll_deg, self.roll_range_deg, "roll"),
        ):
            if fixed is not None and rng is not None:
                raise ValueError(f"give at most one of {name}_deg, {name}_range_deg")
            if rng is not None and rng[0] > rng[1]:
                raise ValueError(f"{name}_range_deg must be [min, max]")
        tilted = any(v for v in (self.pitch_deg, self.roll_deg, self.pitch_range_deg, self.roll_range_deg))
        if tilted and not self.static and not self.lying:
            raise ValueError(
                "a tilted object needs static = true (it would fall over); a cylinder may lie on its side "
                "(roll_deg or pitch_deg = 90)"
            )
        if self.position_range is not None:
            for lo, hi in self.position_range:
                if lo > hi:
                    raise ValueError("position_range bounds must be [min, max]")
        if self.rough_size_m is not None:
            self._check_rough_size()
        return self

    def _check_rough_size(self) -> None:
        if self.shape != "mesh" and not self.lying:
            raise ValueError(
                f"rough_size_m is for a target nobody described (a mesh, a cylinder lying): a {self.shape}'s "
                "shape, size and colour are told in full"
            )
        if not self.target:
            raise ValueError("rough_size_m is what the robot is told of its target: this object is not the target")
        if self.rough_size_m[1] < self.rough_size_m[2]:  # type: ignore[index]
            raise ValueError("rough_size_m is [height, longer side, shorter side]: the longer side first")

    @property
    def told_nothing(self) -> bool:
        """An object nobody described (a mesh, a cylinder lying on its side): the robot is told at most
        its :attr:`rough_size_m`."""
        return self.shape == "mesh" or self.lying

    @property
    def lying(self) -> bool:
        """A cylinder on its side (a roll or a pitch of a quarter turn, the other none): it rests stably."""
        if self.shape != "cylinder" or self.pitch_range_deg is not None or self.roll_range_deg is not None:
            return False
        turns = sorted(abs(v or 0.0) for v in (self.pitch_deg, self.roll_deg))
        return turns == [0.0, 90.0]

    def rough_size(self, shape: Shape) -> tuple[float, float, float]:
        """Its height and its footprint's longer and shorter side as it stands, at this shape (m): what
        ``validate`` holds a stated :attr:`rough_size_m` and a look-alike against (a cylinder on its side:
        its diameter high, its length and its diameter across). Never told to the robot: a seed's draw."""
        if self.lying:
            d, length = shape.size
            return d, max(d, length), min(d, length)
        wide, narrow = sorted(shape.top_extents_m, reverse=True)
        return shape.height_m, wide, narrow

    def _check_mesh(self) -> None:
        if self.size is not None or self.size_range is not None:
            raise ValueError("a mesh's size is its file's: give scale or scale_range, not size")
        if (self.urdf is None) == (self.urdf_choice is None):
            raise ValueError("a mesh needs exactly one of urdf, urdf_choice")
        if self.scale is not None and self.scale_range is not None:
            raise ValueError("give at most one of scale, scale_range")
        if self.scale_range is not None and self.scale_range[0] > self.scale_range[1]:
            raise ValueError("scale_range must be [min, max]")
        if self.color is not None:
            raise ValueError("a mesh has its file's colours: no color")

    @property
    def region_range(self) -> tuple[Vec2, Vec2] | None:
        """Where its centre may be, as ((x_min, x_max), (y_min, y_max)): its ``position_range``, or
        for an object ``beside`` another the other's region grown by how far apart their centres stand
        (None: a fixed position)."""
        return self.position_range if self.beside is None else self._beside_range

    def shape_of_size(self, size: tuple[float, ...]) -> Shape:
        """Its :class:`~pickdemo.core.shapes.Shape` at this size (its own, or one drawn from ``size_range``)."""
        return make_shape(self.shape, size)

    @property
    def urdf_files(self) -> tuple[str, ...]:
        """A mesh's files: its ``urdf``, or every readable match of its ``urdf_choice`` (sorted; reads
        the disk: :func:`pickdemo.core.meshes.usable`)."""
        return (self.urdf,) if self.urdf is not None else usable(self.urdf_choice or "")

    @property
    def scales(self) -> tuple[float, float]:
        """A mesh's smallest and largest scale."""
        if self.scale_range is not None:
            return self.scale_range
        return (self.scale or 1.0, self.scale or 1.0)

    def mesh_shape(self, urdf: str, scale: float) -> Shape:
        """Its mesh from one of its files at a scale (reads the file: a
        :class:`~pickdemo.core.meshes.MeshFileError` for a bad one)."""
        return Mesh(urdf, scale, read_urdf(urdf).vertices * scale)

    @property
    def largest_size(self) -> tuple[float, ...]:
        """The largest size it may have: its size, or the top of each size range (a mesh: its
        bounding box at its largest scale, over all its files)."""
        if self.shape == "mesh":
            return self.largest_shape.size
        if self.size is not None:
            return tuple(self.size)
        return tuple(hi for _, hi in self.size_range)  # type: ignore[union-attr]

    @property
    def largest_shape(self) -> Shape:
        """Its shape at :attr:`largest_size` (what the checks hold against the table, the belt and the
        camera). A mesh: every vertex of all its files at its largest scale, as one (it reads them)."""
        if self.shape == "mesh":
            import numpy as np

            files = self.urdf_files
            big = self.scales[1]
            return Mesh(files[0] if len(files) == 1 else f"{len(files)} files", big,
                        np.vstack([read_urdf(f).vertices for f in files]) * big)  # fmt: skip
        return self.shape_of_size(self.largest_size)


class PlaceSpec(Model):
    """Where the target is to be put down: a fixed spot, or one drawn per seed from a region (the
    seed's ``place`` stream), clear of where the objects start. A clear round (``task = "clear"``)
    puts its objects into a ``tray`` (a URDF, fixed to the table at ``position``, turned by ``yaw_deg``)."""

    position: Vec2 | None = None  # m, x, y on the table
    position_range: tuple[Vec2, Vec2] | None = None  # ((x_min, x_max), (y_min, y_max)) in m
    #: a tray's URDF ("pybullet_data:tray/traybox.urdf", or a path relative to the scenario file)
    tray: Annotated[str, Field(min_length=1, max_length=500)] | None = None
    tray_scale: Scale = 0.5  # times the URDF's own size (pybullet_data's traybox is 0.6 m square at 1)
    yaw_deg: Angle = 0.0  # the tray's turn about z

    @field_validator("tray")
    @classmethod
    def _resolve_tray(cls, spec: str | None, info: ValidationInfo) -> str | None:
        return resolve_path(spec, info)

    @model_validator(mode="after")
    def _one_of(self) -> PlaceSpec:
        if (self.position is None) == (self.position_range is None):
            raise ValueError("give exactly one of position, position_range")
        if self.position_range is not None and any(lo > hi for lo, hi in self.position_range):
            raise ValueError("position_range bounds must be [min, max]")
        if self.tray is not None and self.position is None:
            raise ValueError("a tray stands at a position: give position, not position_range")
        return self

    @property
    def key(self) -> str:
        return "place.position" if self.position is not None else "place.position_range"

    @property
    def spots(self) -> tuple[tuple[float, float], ...]:
        """The spot, or the region's corners and centre: what must be reachable and on the table."""
        if self.position is not None:
            return (tuple(self.position),)
        (x0, x1), (y0, y1) = self.position_range  # type: ignore[misc]
        return ((x0, y0), (x0, y1), (x1, y0), (x1, y1), (0.5 * (x0 + x1), 0.5 * (y0 + y1)))
