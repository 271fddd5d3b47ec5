"""Scenario files' schema: what a scenario holds, validated; the types the rest of pickdemo reads.

A scenario describes a scene (camera, table, objects), the task (which object to pick, where to
place it) and the success criteria. :func:`parse_scenario` validates one given as a parsed TOML
table; a bad one raises :class:`ScenarioError` whose message is one line naming the file and the
offending key. (Finding and reading the files, and checking what needs geometry, is
:mod:`pickdemo.scenario.load`'s.)

The schema is strict: every number is finite and within physical bounds, nothing is coerced (a
string or a boolean is never a number, a number never a boolean), names are printable and not
reserved, and an unknown key names itself and the closest valid key. What needs geometry (is the
object on the table, in reach, in view?) is checked by :mod:`pickdemo.scenario.checks`.

Pure: no simulator. Files are read only when a mesh's files or shape are asked for
(:attr:`ObjectSpec.urdf_files`, :attr:`ObjectSpec.largest_shape`), never while validating.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator, model_validator

from pickdemo.core.meshes import PYBULLET_DATA, read_urdf, usable
from pickdemo.core.shapes import SHAPES, Mesh, Shape, ShapeName, make_shape
from pickdemo.robot import robot_named
from pickdemo.scenario.tasks import TASK_RULES

PositiveFloat = Annotated[float, Field(gt=0.0)]
UnitFloat = Annotated[float, Field(ge=0.0, le=1.0)]
Coord = Annotated[float, Field(ge=-10.0, le=10.0)]  # m, a place in the world
Angle = Annotated[float, Field(ge=-720.0, le=720.0)]  # deg
Extent = Annotated[float, Field(ge=0.001, le=0.5)]  # m, an object's size: 1 mm to 50 cm
Friction = Annotated[float, Field(ge=0.0, le=5.0)]
Scale = Annotated[float, Field(gt=0.0, le=100.0)]  # a mesh's scale: positive and finite
Vec2 = tuple[Coord, Coord]
Vec3 = tuple[Coord, Coord, Coord]
#: Names: printable, no spaces or control characters (they end up in terminals, files and JUnit XML).
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}$"
Name = Annotated[str, Field(pattern=NAME_PATTERN)]
#: Bodies of the scene that an object may not be named after.
RESERVED_NAMES = frozenset({"robot", "table", "world", "camera", "conveyor", "tray"})
#: The names a clear round gives the objects it draws (``drawn_1``, ...): a listed object may not take one.
DRAWN_NAME = "drawn_{}"
MAX_NESTING = 16


class ScenarioError(ValueError):
    """A scenario that cannot be used; the message is one line naming the file and key."""


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", strict=True, allow_inf_nan=False)


#: Realistic sensor faults at once (``[camera] sensor = "..."``); the file's own keys take precedence.
SENSOR_PRESETS: dict[str, dict[str, object]] = {
    "realsense_d435": {"depth_noise": "d435", "depth_holes": 0.02, "depth_edge_dropout": 0.2, "depth_invalid": 0.0,
                       "depth_quantum_m": 0.001, "rgb_noise_sigma": 5.0, "extrinsic_error": (1.0, 0.1)},
    "realsense_d415": {"depth_noise": "d415", "depth_holes": 0.01, "depth_edge_dropout": 0.1, "depth_invalid": 0.0,
                       "depth_quantum_m": 0.001, "rgb_noise_sigma": 4.0, "extrinsic_error": (1.0, 0.1)},
    "kinect": {"depth_noise": "kinect", "depth_holes": 0.01, "depth_edge_dropout": 0.1, "depth_invalid": 0.0,
               "depth_quantum_m": 0.001, "rgb_noise_sigma": 3.0, "extrinsic_error": (2.0, 0.2)},
}  # fmt: skip


class _SensorSpec(_Model):
    """What an RGB-D sensor gives: its image, its field of view, its depth range and its faults."""

    width: Annotated[int, Field(ge=16, le=4096)] = 640  # px
    height: Annotated[int, Field(ge=16, le=4096)] = 480  # px
    fov_deg: tuple[Annotated[float, Field(gt=1.0, lt=170.0)], Annotated[float, Field(gt=1.0, lt=170.0)]] = (
        57.0,
        43.0,
    )  # horizontal, vertical
    depth_noise: Literal["none", "kinect", "d415", "d435"] = "kinect"
    # A real sensor's faults (all off by default; `sensor = "realsense_d435"` sets them all at once).
    depth_holes: Annotated[float, Field(ge=0.0, le=0.5)] = 0.0  # fraction of pixels with no return, at random
    depth_edge_dropout: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0  # fraction of pixels at depth edges dropped
    depth_invalid: Literal[0.0, "nan"] = 0.0  # what a hole reads as: 0.0 (like real drivers) or "nan"
    depth_quantum_m: Annotated[float, Field(ge=0.0, le=0.01)] = 0.0  # depth reported in steps of this (0: none)
    rgb_noise_sigma: Annotated[float, Field(ge=0.0, le=50.0)] = 0.0  # 8-bit units
    sensor: Literal["realsense_d435", "realsense_d415", "kinect"] | None = None  # a preset for the keys above
    near_m: Annotated[float, Field(ge=0.01, le=1.0)] = 0.1
    far_m: Annotated[float, Field(gt=0.1, le=20.0)] = 3.0

    #: the key a preset's calibration error goes to
    calibration_key: ClassVar[str] = "extrinsic_error"

    @model_validator(mode="before")
    @classmethod
    def _preset(cls, data: object) -> object:
        """A sensor preset fills the fault keys the file does not give itself."""
        if isinstance(data, dict) and isinstance(data.get("sensor"), str) and data["sensor"] in SENSOR_PRESETS:
            preset = dict(SENSOR_PRESETS[data["sensor"]])
            preset[cls.calibration_key] = preset.pop("extrinsic_error")
            return {**preset, **data}
        return data

    @model_validator(mode="after")
    def _placed(self) -> _SensorSpec:
        """Every sensor has a depth range and looks from its ``position`` at its ``look_at`` (its class's)."""
        if self.far_m <= self.near_m:
            raise ValueError("far_m must exceed near_m")
        if sum((a - b) ** 2 for a, b in zip(self.position, self.look_at, strict=True)) < 1e-6:  # type: ignore[attr-defined]
            raise ValueError("look_at must differ from position")
        return self

    @property
    def extrinsic_sigma(self) -> tuple[float, float]:
        """How far the pose the robot is told may be off (mm, deg)."""
        return getattr(self, self.calibration_key)


class CameraSpec(_SensorSpec):
    """A fixed RGB-D camera. Defaults match the paper's Xtion Pro Live (57 x 43 deg, 640x480)."""

    position: Vec3 = (1.1, 0.0, 0.75)  # m, world frame
    look_at: Vec3 = (0.5, 0.0, 0.0)  # m, world frame
    extrinsic_error: tuple[Annotated[float, Field(ge=0.0, le=50.0)], Annotated[float, Field(ge=0.0, le=5.0)]] = (
        0.0,
        0.0,
    )  # mm, deg: the true camera pose differs from the one the robot is told, drawn per seed
    # Instead of a fixed position: sampled around look_at per seed (all three, or none).
    distance_range_m: tuple[Annotated[float, Field(ge=0.2, le=5.0)], Annotated[float, Field(ge=0.2, le=5.0)]] | None = (
        None
    )
    elevation_range_deg: tuple[Angle, Angle] | None = None  # above the table plane
    azimuth_range_deg: tuple[Angle, Angle] | None = None  # about world z, 0 = from +x

    @model_validator(mode="after")
    def _check(self) -> CameraSpec:
        ranges = (self.distance_range_m, self.elevation_range_deg, self.azimuth_range_deg)
        if any(r is not None for r in ranges) and any(r is None for r in ranges):
            raise ValueError("give all of distance_range_m, elevation_range_deg, azimuth_range_deg, or none")
        for r in ranges:
            if r is not None and r[0] > r[1]:
                raise ValueError("camera ranges must be [min, max]")
        if self.elevation_range_deg is not None and not (
            0 < self.elevation_range_deg[0] and self.elevation_range_deg[1] < 90
        ):
            raise ValueError("elevation_range_deg must lie in (0, 90)")
        return self

    @property
    def sampled(self) -> bool:
        return self.distance_range_m is not None


#: The robot whose hand a wrist camera is mounted on (a scenario does not choose its robot yet)
_ROBOT = robot_named()
HandCoord = Annotated[float, Field(ge=-0.5, le=0.5)]  # m, in the mount link's frame


class WristCameraSpec(_SensorSpec):
    """An RGB-D camera on the hand (``[wrist_camera]``), as real pick cells mount a small one on the
    Franka hand. Defaults: a RealSense D405-like camera (87 x 58 deg, 424x240, from 5 cm) 9 cm beside the
    hand, looking down past the fingertips; the hand-eye calibration exact."""

    mount: str = _ROBOT.hand_frame  # a link of the hand (the frame ``position`` and ``look_at`` are in)
    #: m, in the mount's frame (the hand's z points from the flange to the fingertips)
    position: tuple[HandCoord, HandCoord, HandCoord] = (0.09, 0.0, 0.04)
    look_at: tuple[HandCoord, HandCoord, HandCoord] = (0.0, 0.0, 0.16)
    width: Annotated[int, Field(ge=16, le=4096)] = 424
    height: Annotated[int, Field(ge=16, le=4096)] = 240
    fov_deg: tuple[Annotated[float, Field(gt=1.0, lt=170.0)], Annotated[float, Field(gt=1.0, lt=170.0)]] = (
        87.0,
        58.0,
    )
    depth_noise: Literal["none", "kinect", "d415", "d435"] = "d415"
    near_m: Annotated[float, Field(ge=0.01, le=1.0)] = 0.05
    far_m: Annotated[float, Field(gt=0.1, le=20.0)] = 1.0
    #: mm, deg: the true pose of the camera on the hand differs from the one the robot is told (drawn per seed)
    hand_eye_error: tuple[Annotated[float, Field(ge=0.0, le=50.0)], Annotated[float, Field(ge=0.0, le=5.0)]] = (
        0.0,
        0.0,
    )

    calibration_key: ClassVar[str] = "hand_eye_error"

    @field_validator("mount")
    @classmethod
    def _on_the_hand(cls, mount: str) -> str:
        mounts = _ROBOT.camera_mounts  # the hand's links: they move rigidly with it (the fingers do not)
        if mount not in mounts:
            raise ValueError(f"{printable(mount)!r} is not a link of the hand; one of {', '.join(mounts)}")
        return mount


class TableSpec(_Model):
    """The table; its top surface is the world plane z = 0 and the robot stands on it at the origin."""

    size: tuple[Annotated[float, Field(ge=0.3, le=5.0)], Annotated[float, Field(ge=0.3, le=5.0)]] = (1.4, 1.2)  # m
    center: Vec2 = (0.45, 0.0)  # m, x, y of the table's centre
    color: tuple[UnitFloat, UnitFloat, UnitFloat] = (0.55, 0.42, 0.30)
    friction: Friction = 0.8

    def holds(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether the point (x, y) lies on the table top, ``margin`` inside its edges."""
        hx, hy = self.size[0] / 2.0 - margin, self.size[1] / 2.0 - margin
        return abs(x - self.center[0]) <= hx and abs(y - self.center[1]) <= hy


class ReferenceSpec(_Model):
    """Published figures to show beside ours (for example a row of the paper's Tables 1 and 2)."""

    label: Annotated[str, Field(max_length=80)] = ""
    position_error_mm: Annotated[float, Field(ge=0.0)]
    yaw_error_deg: Annotated[float, Field(ge=0.0)]
    pitch_error_deg: Annotated[float, Field(ge=0.0)] = 0.0
    roll_error_deg: Annotated[float, Field(ge=0.0)] = 0.0


def _resolve_path(spec: str | None, info: ValidationInfo) -> str | None:
    """A path relative to the scenario file made absolute (``pybullet_data:`` ones are kept: another
    machine finds its own copy)."""
    if spec is None or spec.startswith(PYBULLET_DATA):
        return spec
    if not spec.isprintable():
        raise ValueError("a path of printable characters")
    base = (info.context or {}).get("base_dir")
    path = Path(spec).expanduser()
    return str(path if path.is_absolute() or base is None else Path(base) / path)


class ObjectSpec(_Model):
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
    yaw_deg: Angle | None = None
    yaw_range_deg: tuple[Angle, Angle] | None = None
    pitch_deg: Angle | None = None
    pitch_range_deg: tuple[Angle, Angle] | None = None
    roll_deg: Angle | None = None
    roll_range_deg: tuple[Angle, Angle] | None = None
    static: bool = False  # held where it is placed (no gravity): for tilted objects in perception tests
    target: bool = False
    reference: ReferenceSpec | None = None  # published errors for this object, shown by `perceive`

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
        return _resolve_path(spec, info)

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
        if (self.position is None) == (self.position_range is None):
            raise ValueError("give exactly one of position, position_range")
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
        if tilted and not self.static:
            raise ValueError("a tilted object needs static = true (it would fall over)")
        if self.position_range is not None:
            for lo, hi in self.position_range:
                if lo > hi:
                    raise ValueError("position_range bounds must be [min, max]")
        return self

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


class PlaceSpec(_Model):
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
        return _resolve_path(spec, info)

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


class SuccessSpec(_Model):
    lift_height: Annotated[float, Field(gt=0.0, le=1.0)] = 0.05  # m the target must rise
    place_tolerance: Annotated[float, Field(ge=0.001, le=1.0)] = 0.02  # m, horizontal distance to the place
    #: the target must end standing as it stood (a box or cylinder on a face of its height, a mesh with
    #: its body z within 10 deg of the vertical); default: a box's or cylinder's yes, a mesh's no
    upright: bool | None = None


class MotionSpec(_Model):
    """Slower motion: pickdemo's Cartesian limits (near the object and in free space) scaled by these."""

    velocity_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    acceleration_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    jerk_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    #: "joint": transfers (home to above the target, to above the place, back home) in joint space to IK
    #: goals chosen well, straight lines only near the object; "cartesian": every move a straight line
    #: (as every move was before joint transfers; for comparison)
    transfers: Literal["cartesian", "joint"] = "joint"


class LayoutSpec(_Model):
    clearance_m: Annotated[float, Field(ge=0.0, le=0.5)] = 0.01  # free space between objects' footprints


class ControlSpec(_Model):
    """The closed loop: how often it looks, how late the estimates arrive, how often it may retry."""

    max_attempts: Annotated[int, Field(ge=1, le=10)] = 3  # grasp attempts before the episode fails
    perception_rate_hz: Annotated[float, Field(gt=0.0, le=60.0)] = 10.0  # frames per second while it looks
    perception_latency_s: Annotated[float, Field(ge=0.0, le=1.0)] = 0.05  # frame taken at t reaches control at t + this
    control_rate_hz: Annotated[float, Field(ge=30.0, le=240.0)] = 120.0  # control ticks per simulated second


Push = Annotated[float, Field(ge=-0.5, le=0.5)]  # m, how far a push moves the target along one axis


class DisturbanceSpec(_Model):
    """The target is pushed across the table while the robot works (a slide of ``duration_s``).

    The offset is fixed (``offset_m``), drawn per axis (``offset_range_m``) or drawn as a distance in
    a random direction (``distance_range_m``); the turn is fixed or drawn, either way when
    ``yaw_either_way`` is set.
    """

    at_time_s: Annotated[float, Field(ge=0.0, le=600.0)]  # simulated time after the first look
    offset_m: tuple[Push, Push] | None = None
    offset_range_m: tuple[tuple[Push, Push], tuple[Push, Push]] | None = None  # ((x_min, x_max), (y_min, y_max))
    distance_range_m: tuple[Annotated[float, Field(ge=0.0, le=0.5)], Annotated[float, Field(ge=0.0, le=0.5)]] | None = (
        None
    )
    yaw_deg: Angle = 0.0
    yaw_range_deg: tuple[Angle, Angle] | None = None
    yaw_either_way: bool = False
    duration_s: Annotated[float, Field(gt=0.0, le=2.0)] = 0.3

    @model_validator(mode="after")
    def _check(self) -> DisturbanceSpec:
        given = [x is not None for x in (self.offset_m, self.offset_range_m, self.distance_range_m)]
        if sum(given) != 1:
            raise ValueError("give exactly one of offset_m, offset_range_m, distance_range_m")
        for r in (*(self.offset_range_m or ()), self.distance_range_m, self.yaw_range_deg):
            if r is not None and r[0] > r[1]:
                raise ValueError("ranges must be [min, max]")
        return self


Speed = Annotated[float, Field(ge=0.0, le=0.5)]  # m/s, a belt's speed
#: How fast a belt changes speed (m/s^2): a change of 0.05 m/s takes 0.1 s.
BELT_ACCELERATION_M_S2 = 0.5
#: How far the belt's slab travels before it is slid back (m); the slab is this much longer than
#: its strip along the belt's direction (see :mod:`pickdemo.sim.conveyor`).
BELT_REWIND_M = 0.2
#: The longest physics step a scenario may have (s): the slab overruns its travel by at most one.
MAX_TIME_STEP_S = 1.0 / 240.0


@dataclass(frozen=True)
class BeltSlab:
    """The belt's body: a slab (a box) that slides along the belt's direction on a prismatic joint.

    One pure description, used by the simulator to build it and by :mod:`pickdemo.scenario.checks` to keep
    things off where it goes, so that the two cannot disagree. Positions are in the table's frame (m).
    """

    centre: tuple[float, float, float]  # of the slab at joint position 0: the strip's centre, half its height up
    half_extents: tuple[float, float, float]  # the strip's, lengthened by half the rewind along the direction
    direction: tuple[float, float]  # unit vector of its travel (+y for a belt that never moves)
    travel_m: tuple[float, float]  # the joint positions it takes: it starts at the first, is slid back past the second
    rewind_m: float

    def corners_at(self, q: float) -> list[tuple[float, float]]:
        """The slab's outline seen from above (4 corners, counter-clockwise) at joint position ``q``."""
        cx, cy = self.centre[0] + q * self.direction[0], self.centre[1] + q * self.direction[1]
        hx, hy = self.half_extents[0], self.half_extents[1]
        return [(cx - hx, cy - hy), (cx + hx, cy - hy), (cx + hx, cy + hy), (cx - hx, cy + hy)]

    def swept_corners(self) -> list[tuple[float, float]]:
        """The corners of the slab at both ends of its travel: the convex hull of these 8 points is
        the whole footprint it sweeps on the table (the strip, plus the overhang and its travel)."""
        return self.corners_at(self.travel_m[0]) + self.corners_at(self.travel_m[1])


class ConveyorSpec(_Model):
    """A belt across the table that carries what rests on it (by friction, as a real belt does).

    The robot knows where the belt is (the cell's layout), never how fast it runs: that it measures.
    Its clock starts with the robot's (the first control tick): ``speed_changes`` are timed from then.
    """

    velocity_m_s: tuple[Annotated[float, Field(ge=-0.5, le=0.5)], Annotated[float, Field(ge=-0.5, le=0.5)]]  # x, y
    x_range_m: tuple[Coord, Coord]  # the belt's strip on the table
    y_range_m: tuple[Coord, Coord]
    speed_changes: tuple[tuple[Annotated[float, Field(ge=0.0, le=600.0)], Speed], ...] = ()  # (time s, speed m/s)
    height_m: Annotated[float, Field(ge=0.002, le=0.1)] = 0.01  # its top surface above the table
    color: tuple[UnitFloat, UnitFloat, UnitFloat] = (0.16, 0.17, 0.19)
    friction: Friction = 0.9

    @model_validator(mode="after")
    def _check(self) -> ConveyorSpec:
        for key in ("x_range_m", "y_range_m"):
            lo, hi = getattr(self, key)
            if hi - lo < 0.05:
                raise ValueError(f"{key} must be [min, max] and at least 0.05 m wide")
        if sum(v * v for v in self.velocity_m_s) ** 0.5 > 0.5:
            raise ValueError("velocity_m_s: at most 0.5 m/s")
        times = [t for t, _ in self.speed_changes]
        if times != sorted(times) or len(set(times)) != len(times):
            raise ValueError("speed_changes must be in increasing time order")
        if self.speed_changes and self.speed == 0.0:
            raise ValueError("speed_changes need a non-zero velocity_m_s (it gives the belt's direction)")
        return self

    @property
    def speed(self) -> float:
        return float(sum(v * v for v in self.velocity_m_s) ** 0.5)

    def speed_at(self, t_s: float) -> float:
        """The belt's speed ``t_s`` after it started: its speed, then each change, ramped at
        :data:`BELT_ACCELERATION_M_S2`."""
        speed = self.speed
        for at, new in self.speed_changes:
            if t_s <= at:
                break
            ramp = (t_s - at) * BELT_ACCELERATION_M_S2
            speed = new if abs(new - speed) <= ramp else speed + (ramp if new > speed else -ramp)
        return float(speed)

    @property
    def top_speed(self) -> float:
        """The fastest the belt ever runs (m/s)."""
        return max([self.speed, *(s for _, s in self.speed_changes)])

    def slab(self) -> BeltSlab:
        """The belt's body and where it goes (:class:`BeltSlab`).

        The slab is the strip lengthened by :data:`BELT_REWIND_M` along the belt's direction (half
        at each end: on a diagonal belt, its x and y extents grow by their share of it), starts at
        joint position ``-rewind/2`` and is slid back by ``rewind`` once it is past ``+rewind/2`` (at
        most one physics step past). A belt that never moves stays where it starts.
        """
        (x0, x1), (y0, y1) = self.x_range_m, self.y_range_m
        speed = self.speed
        dx, dy = (self.velocity_m_s[0] / speed, self.velocity_m_s[1] / speed) if speed > 0 else (0.0, 1.0)
        r = BELT_REWIND_M
        start = -r / 2.0
        end = r / 2.0 + self.top_speed * MAX_TIME_STEP_S if self.top_speed > 0 else start
        return BeltSlab(
            centre=((x0 + x1) / 2.0, (y0 + y1) / 2.0, self.height_m / 2.0),
            half_extents=(
                (x1 - x0) / 2.0 + abs(dx) * r / 2.0,
                (y1 - y0) / 2.0 + abs(dy) * r / 2.0,
                self.height_m / 2.0,
            ),
            direction=(dx, dy),
            travel_m=(start, end),
            rewind_m=r,
        )

    def holds(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether (x, y) lies on the belt, ``margin`` inside its edges."""
        (x0, x1), (y0, y1) = self.x_range_m, self.y_range_m
        return x0 + margin <= x <= x1 - margin and y0 + margin <= y <= y1 - margin

    def touches(self, x: float, y: float, radius: float) -> bool:
        """Whether a footprint of ``radius`` about (x, y) reaches onto the belt."""
        (x0, x1), (y0, y1) = self.x_range_m, self.y_range_m
        return x0 - radius < x < x1 + radius and y0 - radius < y < y1 + radius


class ClearSpec(_Model):
    """A clear round (``task = "clear"``): ``count`` objects drawn per seed from ``objects_from`` (a glob,
    as ``urdf_choice``) at a scale from ``scale_range``, laid out in ``region`` as a ``pile`` (dropped in
    a heap) or ``packed`` (standing side by side), join the ``[[objects]]`` listed; the robot puts them
    all into the tray. The round ends when the table is clear, when no grasp is found, or after
    ``max_consecutive_failures`` failed attempts in a row (VGN's clutter-removal protocol)."""

    layout: Literal["pile", "packed"] = "packed"
    region: tuple[Vec2, Vec2]  # ((x_min, x_max), (y_min, y_max)) in m: where the round is laid out
    count: Annotated[int, Field(ge=1, le=20)] = 5  # objects drawn a round
    objects_from: Annotated[str, Field(min_length=1, max_length=500)]
    scale_range: tuple[Scale, Scale] = (1.0, 1.0)
    max_consecutive_failures: Annotated[int, Field(ge=1, le=10)] = 2
    #: a pile: each object is dropped from this far above what is under it
    drop_height_m: Annotated[float, Field(ge=0.0, le=0.3)] = 0.02

    @field_validator("objects_from")
    @classmethod
    def _resolve_glob(cls, spec: str, info: ValidationInfo) -> str:
        return _resolve_path(spec, info)  # type: ignore[return-value]

    @model_validator(mode="after")
    def _check(self) -> ClearSpec:
        if any(lo > hi for lo, hi in self.region):
            raise ValueError("region bounds must be [min, max]")
        if self.scale_range[0] > self.scale_range[1]:
            raise ValueError("scale_range must be [min, max]")
        return self

    @property
    def files(self) -> tuple[str, ...]:
        """The files ``objects_from`` matches that can be read (reads the disk)."""
        return usable(self.objects_from)


class SimSpec(_Model):
    # 1/1000 s at the finest: a finer step multiplies the work and changes nothing a user would see.
    time_step_s: Annotated[float, Field(ge=1.0 / 1000.0, le=1.0 / 240.0)] = 1.0 / 240.0
    max_sim_time_s: Annotated[float, Field(gt=0.0, le=600.0)] = 60.0  # simulated-time budget of one episode


class Scenario(_Model):
    """A whole scenario file, validated."""

    name: Name
    description: Annotated[str, Field(max_length=300)] = ""
    tags: tuple[Name, ...] = ()  # e.g. "suite": run by `pickdemo bench` when no scenario is named
    #: "perceive": for `pickdemo perceive` only (any number of targets); "clear": every object into the tray
    task: Literal["pick", "perceive", "clear"] = "pick"
    camera: CameraSpec = CameraSpec()
    wrist_camera: WristCameraSpec | None = None  # a second camera, on the hand
    table: TableSpec = TableSpec()
    objects: tuple[ObjectSpec, ...] = ()
    place: PlaceSpec
    success: SuccessSpec = SuccessSpec()
    layout: LayoutSpec = LayoutSpec()
    motion: MotionSpec = MotionSpec()
    sim: SimSpec = SimSpec()
    control: ControlSpec = ControlSpec()
    disturbances: tuple[DisturbanceSpec, ...] = ()
    conveyor: ConveyorSpec | None = None
    clear: ClearSpec | None = None  # a clear round's objects (task = "clear")

    @model_validator(mode="after")
    def _check(self) -> Scenario:
        rules = TASK_RULES[self.task]
        if rules.draws_round:
            self._check_clear()
        elif not self.objects:
            raise ValueError("at least one object is needed")
        targets = [o for o in self.objects if o.target]
        if not targets and not rules.picks_every_object:
            raise ValueError("one object must have target = true")
        names = [o.name for o in self.objects]
        if len(set(names)) != len(names):
            raise ValueError("object names must be unique")
        if not self.description.isprintable():
            raise ValueError("description: control characters are not allowed")
        if rules.one_target:
            if len(targets) != 1:
                names_t = ", ".join(o.name for o in targets)
                raise ValueError(
                    f"objects: a pick needs exactly one object with target = true; {len(targets)} have it ({names_t})"
                )
            if targets[0].static:
                raise ValueError(
                    f"objects.{targets[0].name}: the target of a pick cannot be static (it could never be lifted)"
                )
        return self

    def _check_clear(self) -> None:
        if self.clear is None:
            raise ValueError('clear: a clear round (task = "clear") needs a [clear] table')
        if self.place.tray is None:
            raise ValueError('place.tray: a clear round (task = "clear") puts its objects into a tray: give one')
        if self.conveyor is not None:
            raise ValueError('conveyor: a clear round (task = "clear") is laid out on the table, not on a belt')
        if any(o.target for o in self.objects):
            raise ValueError('objects: target = true is for a pick; a clear round (task = "clear") clears every object')
        taken = {DRAWN_NAME.format(i + 1) for i in range(self.clear.count)} & {o.name for o in self.objects}
        if taken:
            raise ValueError(f"objects.{sorted(taken)[0]}: the name of an object the clear round draws; choose another")
        if any(o.static for o in self.objects):
            raise ValueError('objects: a clear round (task = "clear") clears every object: none can be static')

    def surface_z(self, x: float, y: float) -> float:
        """Height of what an object standing at (x, y) rests on: the belt's top, or the table (0)."""
        c = self.conveyor
        return c.height_m if c is not None and c.holds(x, y) else 0.0

    @property
    def target(self) -> ObjectSpec:
        """The target of a pick (the first object marked as one)."""
        return next(o for o in self.objects if o.target)

    @property
    def targets(self) -> tuple[ObjectSpec, ...]:
        """Every object marked as a target (perception evaluates them all; a pick needs exactly one; a
        clear round's are all its listed objects)."""
        if TASK_RULES[self.task].picks_every_object:
            return self.objects
        return tuple(o for o in self.objects if o.target)


_NAME_RE = re.compile(NAME_PATTERN)


def _item_name(items: object, index: int) -> str | None:
    """The name of ``items[index]`` when it names the item on its own: a valid, unreserved name that
    no other item of the list has."""
    if not isinstance(items, (list, tuple)) or not 0 <= index < len(items) or not isinstance(items[index], dict):
        return None
    name = items[index].get("name")
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name) or name.lower() in RESERVED_NAMES:
        return None
    if sum(1 for it in items if isinstance(it, dict) and it.get("name") == name) != 1:
        return None
    return name


def _format_loc(loc: tuple[int | str, ...], data: object) -> str:
    """A key's path as every scenario error writes it: ``objects.cube.color``, the way the checks of
    :mod:`pickdemo.scenario.checks` name it too (an object by its name; by its index, ``objects[0]``, only
    when it has no name of its own), and ``position_range[0][1]`` inside arrays."""
    parts: list[str] = []
    node = data
    for item in loc:
        if isinstance(item, int):
            name = _item_name(node, item)
            if name is not None and parts:
                parts.append(name)
            else:
                parts[-1:] = [f"{parts[-1]}[{item}]" if parts else f"[{item}]"]
            node = node[item] if isinstance(node, (list, tuple)) and 0 <= item < len(node) else None
        else:
            parts.append(printable(str(item)))
            node = node.get(item) if isinstance(node, dict) else None
    return ".".join(parts) or "(top level)"


def printable(text: str, limit: int = 60) -> str:
    """Text safe for one line of a terminal: control characters escaped, long text cut."""
    out = text if text.isprintable() else text.encode("unicode_escape").decode("ascii")
    return out if len(out) <= limit else out[: limit - 3] + "..."


def _model_at(loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """The schema model that the location ``loc`` (without its last key) points into."""
    model: type[BaseModel] | None = Scenario
    for item in loc[:-1]:
        if isinstance(item, int) or model is None:
            continue
        field = model.model_fields.get(str(item))
        if field is None:
            return None
        model = next((t for t in _types_in(field.annotation) if isinstance(t, type) and issubclass(t, BaseModel)), None)
    return model


def _types_in(annotation: object) -> list[object]:
    args = getattr(annotation, "__args__", None)
    if not args:
        return [annotation]
    return [t for a in args for t in _types_in(a)]


def _tuples(value: object, depth: int = 0) -> object:
    """TOML arrays as tuples (the strict schema takes tuples), and a bound on nesting."""
    if depth > MAX_NESTING:
        raise ScenarioError(f"nested more than {MAX_NESTING} levels deep")
    if isinstance(value, list):
        return tuple(_tuples(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return {k: _tuples(v, depth + 1) for k, v in value.items()}
    return value


def _data_loc(loc: tuple, data: object) -> tuple[int | str, ...]:
    """Pydantic's error location less the parts it adds (union branches, validator names): only keys
    and indices that exist in the document are kept, plus a last key that is missing or unknown."""
    out: list[int | str] = []
    node = data
    for i, item in enumerate(loc):
        if isinstance(node, dict) and isinstance(item, str) and item in node:
            out.append(item)
            node = node[item]
        elif isinstance(node, (list, tuple)) and isinstance(item, int) and 0 <= item < len(node):
            out.append(item)
            node = node[item]
        elif i == len(loc) - 1 and isinstance(item, str) and isinstance(node, dict):
            out.append(item)  # a missing key (or an unknown one) at the end
    return tuple(out)


def _close_key(loc: tuple[int | str, ...]) -> str | None:
    """The valid key an unknown key at ``loc`` most likely meant (None if none is close)."""
    model = _model_at(loc)
    valid = sorted(model.model_fields) if model is not None else []
    close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.6)
    return close[0] if close else None


def _message(err: dict, data: object, listed: set[tuple[int | str, ...]] | None = None) -> str:
    """One problem as ``path: what``. ``listed``: where the valid keys were listed already (a second
    unknown key there does not list them again)."""
    loc = _data_loc(err["loc"], data)
    where = _format_loc(loc, data)
    if err["type"] == "extra_forbidden" and loc:
        model = _model_at(loc)
        valid = sorted(model.model_fields) if model is not None else []
        close = _close_key(loc)
        if close:
            return f"{where}: unknown key (did you mean {close!r}?)"
        if not valid or (listed is not None and loc[:-1] in listed):
            return f"{where}: unknown key"
        if listed is not None:
            listed.add(loc[:-1])
        return f"{where}: unknown key (valid keys: {', '.join(valid)})"
    msg = err["msg"].removeprefix("Value error, ")
    if not loc:
        return msg
    if err["type"] in ("float_type", "int_type", "bool_type", "string_type", "tuple_type"):
        got = err.get("input")
        shown = printable(repr(got), 40)
        hint = ' (values are not converted: write 0.1, not "0.1")' if isinstance(got, str) else ""
        if err["type"] == "int_type" and isinstance(got, float):
            hint = " (a whole number: write 640, not 640.5)"
        msg = f"{msg}, got {type(got).__name__} {shown}{hint}"
    return f"{where}: {msg}"


#: Problems of one file spelt out in its error line; any more are named by their keys only.
SHOWN_PROBLEMS = 3


def _problems(exc: ValidationError, data: object) -> str:
    """Every problem pydantic found, on one line: unknown keys first, then the rest in file order; a
    key reported missing only because a misspelling of it is there (``colour`` for ``color``) is left
    out, the misspelling's "did you mean" says it. Past :data:`SHOWN_PROBLEMS`, the others are named."""
    errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
    meant = set()
    for e in errors:
        loc = _data_loc(e["loc"], data)
        if e["type"] == "extra_forbidden" and loc:
            close = _close_key(loc)
            if close is not None:
                meant.add((*loc[:-1], close))
    kept = [e for e in errors if not (e["type"] == "missing" and _data_loc(e["loc"], data) in meant)] or errors[:1]
    listed: set[tuple[int | str, ...]] = set()
    messages = list(dict.fromkeys(_message(e, data, listed) for e in kept))
    text = "; ".join(messages[:SHOWN_PROBLEMS])
    rest = messages[SHOWN_PROBLEMS:]
    if rest:
        where = [m.split(": ", 1)[0] for m in rest]
        text += f"; {len(rest)} more at {printable(', '.join(where), 120)}"
    return text


def parse_scenario(data: dict, *, source: str = "<scenario>", default_task: str = "pick") -> Scenario:
    """Validate a scenario given as a parsed TOML table. ``default_task``: the task of a file without a
    ``task`` key ("pick"; ``pickdemo perceive`` reads such a file as "perceive")."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: a scenario is a TOML table, got {type(data).__name__}")
    try:
        tupled = _tuples(data)
    except ScenarioError as exc:
        raise ScenarioError(f"{source}: {exc}") from None
    if "task" not in tupled:
        tupled["task"] = default_task
    base_dir = Path(source).parent if source and not source.startswith("<") else None
    try:
        return Scenario.model_validate(tupled, context={"base_dir": base_dir})
    except ValidationError as exc:
        raise ScenarioError(f"{source}: {_problems(exc, data)}") from None
