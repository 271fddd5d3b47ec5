"""Scenario files: the TOML schema, its validation, and how names resolve to files.

A scenario describes a scene (camera, table, objects), the task (which object to pick, where to
place it) and the success criteria. It is validated when loaded; a bad file raises
:class:`ScenarioError` whose message is one line naming the file and the offending key.
"""

from __future__ import annotations

import sys
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, ValidationInfo, field_validator, model_validator

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

PositiveFloat = Annotated[float, Field(gt=0.0)]
UnitFloat = Annotated[float, Field(ge=0.0, le=1.0)]
Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


class ScenarioError(ValueError):
    """A scenario that cannot be used; the message is one line naming the file and key."""


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class CameraSpec(_Model):
    """A fixed RGB-D camera. Defaults match the paper's Xtion Pro Live (57 x 43 deg, 640x480)."""

    position: Vec3 = (1.1, 0.0, 0.75)  # m, world frame
    look_at: Vec3 = (0.5, 0.0, 0.0)  # m, world frame
    width: Annotated[int, Field(ge=16, le=4096)] = 640  # px
    height: Annotated[int, Field(ge=16, le=4096)] = 480  # px
    fov_deg: tuple[Annotated[float, Field(gt=1.0, lt=170.0)], Annotated[float, Field(gt=1.0, lt=170.0)]] = (
        57.0,
        43.0,
    )  # horizontal, vertical
    depth_noise: Literal["none", "kinect"] = "kinect"
    # Instead of a fixed position: sampled around look_at per seed (all three, or none).
    distance_range_m: tuple[PositiveFloat, PositiveFloat] | None = None
    elevation_range_deg: tuple[float, float] | None = None  # above the table plane
    azimuth_range_deg: tuple[float, float] | None = None  # about world z, 0 = from +x
    near_m: PositiveFloat = 0.1
    far_m: PositiveFloat = 3.0

    @model_validator(mode="after")
    def _check(self) -> CameraSpec:
        if sum((a - b) ** 2 for a, b in zip(self.position, self.look_at, strict=True)) < 1e-6:
            raise ValueError("look_at must differ from position")
        if self.far_m <= self.near_m:
            raise ValueError("far_m must exceed near_m")
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


class TableSpec(_Model):
    """The table; its top surface is the world plane z = 0 and the robot stands on it at the origin."""

    size: tuple[PositiveFloat, PositiveFloat] = (1.4, 1.2)  # m, x and y extents
    center: Vec2 = (0.45, 0.0)  # m, x, y of the table's centre
    color: tuple[UnitFloat, UnitFloat, UnitFloat] = (0.55, 0.42, 0.30)
    friction: Annotated[float, Field(ge=0.0)] = 0.8


class ReferenceSpec(_Model):
    """Published figures to show beside ours (for example a row of the paper's Tables 1 and 2)."""

    label: str = ""
    position_error_mm: Annotated[float, Field(ge=0.0)]
    yaw_error_deg: Annotated[float, Field(ge=0.0)]
    pitch_error_deg: Annotated[float, Field(ge=0.0)] = 0.0
    roll_error_deg: Annotated[float, Field(ge=0.0)] = 0.0


class ObjectSpec(_Model):
    """One object on the table: a box or a cylinder (upright unless tilted)."""

    name: Annotated[str, Field(min_length=1)]
    shape: Literal["box", "cylinder"]
    size: tuple[PositiveFloat, ...] | None = None  # box: x, y, z extents; cylinder: diameter, height (m)
    size_range: tuple[tuple[PositiveFloat, PositiveFloat], ...] | None = None  # per dimension: [min, max]
    color: tuple[UnitFloat, UnitFloat, UnitFloat]
    mass: PositiveFloat = 0.1  # kg
    friction: Annotated[float, Field(ge=0.0)] = 0.9
    position: tuple[float, float] | tuple[float, float, float] | None = None  # m: x, y (and centre z)
    position_range: tuple[Vec2, Vec2] | None = None  # ((x_min, x_max), (y_min, y_max)) in m
    yaw_deg: float | None = None
    yaw_range_deg: Vec2 | None = None
    pitch_deg: float | None = None
    pitch_range_deg: Vec2 | None = None
    roll_deg: float | None = None
    roll_range_deg: Vec2 | None = None
    static: bool = False  # held where it is placed (no gravity): for tilted objects in perception tests
    target: bool = False
    reference: ReferenceSpec | None = None  # published errors for this object, shown by `perceive`

    @field_validator("size", "size_range")
    @classmethod
    def _check_size(cls, size: tuple | None, info: ValidationInfo) -> tuple | None:
        if size is None:
            return size
        shape = info.data.get("shape")
        expected = {"box": 3, "cylinder": 2}.get(shape or "", len(size))
        if len(size) != expected:
            what = "x, y, z extents" if shape == "box" else "diameter, height"
            raise ValueError(f"a {shape} needs {expected} values ({what}), got {len(size)}")
        if info.field_name == "size_range" and any(lo > hi for lo, hi in size):
            raise ValueError("each size_range entry must be [min, max]")
        return size

    @model_validator(mode="after")
    def _check(self) -> ObjectSpec:
        if (self.size is None) == (self.size_range is None):
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


class PlaceSpec(_Model):
    position: Vec2  # m, x, y on the table where the target is to be put down


class SuccessSpec(_Model):
    lift_height: PositiveFloat = 0.05  # m the target must rise
    place_tolerance: PositiveFloat = 0.02  # m, horizontal distance to the place position


class MotionSpec(_Model):
    """Slower motion: pickdemo's Cartesian limits (near the object and in free space) scaled by these."""

    velocity_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    acceleration_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    jerk_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0


class LayoutSpec(_Model):
    clearance_m: Annotated[float, Field(ge=0.0)] = 0.01  # free space between objects' footprints


class ControlSpec(_Model):
    """The closed loop: how often it looks, how late the estimates arrive, how often it may retry."""

    max_attempts: Annotated[int, Field(ge=1, le=10)] = 3  # grasp attempts before the episode fails
    perception_rate_hz: Annotated[float, Field(gt=0.0, le=60.0)] = 10.0  # frames per second while it looks
    perception_latency_s: Annotated[float, Field(ge=0.0, le=1.0)] = 0.05  # frame taken at t reaches control at t + this
    control_rate_hz: Annotated[float, Field(ge=30.0, le=240.0)] = 120.0  # control ticks per simulated second


class DisturbanceSpec(_Model):
    """The target is pushed across the table while the robot works (a slide of ``duration_s``).

    The offset is fixed (``offset_m``), drawn per axis (``offset_range_m``) or drawn as a distance in
    a random direction (``distance_range_m``); the turn is fixed or drawn, either way when
    ``yaw_either_way`` is set.
    """

    at_time_s: Annotated[float, Field(ge=0.0)]  # simulated time after the first look
    offset_m: Vec2 | None = None
    offset_range_m: tuple[Vec2, Vec2] | None = None  # ((x_min, x_max), (y_min, y_max))
    distance_range_m: tuple[Annotated[float, Field(ge=0.0)], Annotated[float, Field(ge=0.0)]] | None = None
    yaw_deg: float = 0.0
    yaw_range_deg: Vec2 | None = None
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


class SimSpec(_Model):
    time_step_s: Annotated[float, Field(gt=0.0, le=1.0 / 240.0)] = 1.0 / 240.0
    max_sim_time_s: PositiveFloat = 60.0  # simulated-time budget of one episode


class Scenario(_Model):
    """A whole scenario file, validated."""

    name: Annotated[str, Field(min_length=1)]
    description: str = ""
    tags: tuple[str, ...] = ()  # e.g. "suite": run by `pickdemo bench` when no scenario is named
    camera: CameraSpec = CameraSpec()
    table: TableSpec = TableSpec()
    objects: tuple[ObjectSpec, ...]
    place: PlaceSpec
    success: SuccessSpec = SuccessSpec()
    layout: LayoutSpec = LayoutSpec()
    motion: MotionSpec = MotionSpec()
    sim: SimSpec = SimSpec()
    control: ControlSpec = ControlSpec()
    disturbances: tuple[DisturbanceSpec, ...] = ()

    @model_validator(mode="after")
    def _check(self) -> Scenario:
        if not self.objects:
            raise ValueError("at least one object is needed")
        targets = [o for o in self.objects if o.target]
        if not targets:
            raise ValueError("one object must have target = true")
        names = [o.name for o in self.objects]
        if len(set(names)) != len(names):
            raise ValueError("object names must be unique")
        return self

    @property
    def target(self) -> ObjectSpec:
        """The target of a pick (the first object marked as one)."""
        return next(o for o in self.objects if o.target)

    @property
    def targets(self) -> tuple[ObjectSpec, ...]:
        """Every object marked as a target (perception evaluates them all; a pick needs exactly one)."""
        return tuple(o for o in self.objects if o.target)


def _format_loc(loc: tuple[int | str, ...], data: object) -> str:
    parts: list[str] = []
    node = data
    for item in loc:
        if isinstance(item, int):
            name = None
            if isinstance(node, list) and 0 <= item < len(node) and isinstance(node[item], dict):
                name = node[item].get("name")
            parts[-1] = f"{parts[-1]}[{item}]" + (f"({name})" if name else "") if parts else f"[{item}]"
            node = node[item] if isinstance(node, list) and 0 <= item < len(node) else None
        else:
            parts.append(str(item))
            node = node.get(item) if isinstance(node, dict) else None
    return ".".join(parts) or "(top level)"


def parse_scenario(data: dict, *, source: str = "<scenario>") -> Scenario:
    """Validate a scenario given as a parsed TOML table."""
    try:
        return Scenario.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        loc = tuple(x for x in err["loc"] if not (isinstance(x, str) and x.startswith("function-")))
        msg = err["msg"].removeprefix("Value error, ")
        extra = f" (and {exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
        raise ScenarioError(f"{source}: {_format_loc(loc, data)}: {msg}{extra}") from None


def builtin_scenario_dirs() -> list[Path]:
    """Where scenario names are looked up: the installed package first, then a source checkout."""
    dirs = []
    try:
        packaged = resources.files("pickdemo") / "scenarios"
        dirs.append(Path(str(packaged)))
    except (ModuleNotFoundError, TypeError):  # pragma: no cover
        pass
    dirs.append(Path(__file__).resolve().parent.parent / "scenarios")
    return [d for d in dirs if d.is_dir()]


def list_scenarios() -> list[str]:
    names: set[str] = set()
    for d in builtin_scenario_dirs():
        names.update(p.stem for p in d.glob("*.toml"))
    return sorted(names)


def suite_scenarios() -> list[str]:
    """Names of the shipped scenarios tagged ``suite`` (what ``pickdemo bench`` runs by default)."""
    out = []
    for name in list_scenarios():
        try:
            if "suite" in load_scenario(name).tags:
                out.append(name)
        except ScenarioError:
            continue
    return out


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """A path to a file, or the name of a shipped scenario (``pick_cube``)."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists() or len(path.parts) > 1:
        if not path.is_file():
            raise ScenarioError(f"{path}: no such scenario file")
        return path
    for d in builtin_scenario_dirs():
        candidate = d / f"{path.name}.toml"
        if candidate.is_file():
            return candidate
    known = ", ".join(list_scenarios()) or "none found"
    raise ScenarioError(f"{name_or_path}: unknown scenario (known: {known})")


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario by name or path; raises :class:`ScenarioError` on bad input."""
    path = resolve_scenario_path(name_or_path)
    try:
        with path.open("rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: invalid TOML: {exc}") from None
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read: {exc.strerror}") from None
    return parse_scenario(data, source=str(path))
