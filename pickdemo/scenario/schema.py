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

from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, field_validator, model_validator

from pickdemo.core.meshes import usable
from pickdemo.robot import DEFAULT_ROBOT, RobotDescription, RobotFileError, robot_named
from pickdemo.scenario.base import DRAWN_NAME, Angle, Model, Name, Scale, Vec2, printable
from pickdemo.scenario.belt import ConveyorSpec
from pickdemo.scenario.fixtures import FixtureSpec
from pickdemo.scenario.objects import ObjectSpec, PlaceSpec, TableSpec, resolve_path
from pickdemo.scenario.sensors import CameraSpec, WristCameraSpec
from pickdemo.scenario.tasks import TASK_RULES


class SuccessSpec(Model):
    lift_height: Annotated[float, Field(gt=0.0, le=1.0)] = 0.05  # m the target must rise
    place_tolerance: Annotated[float, Field(ge=0.001, le=1.0)] = 0.02  # m, horizontal distance to the place
    #: the target must end standing as it stood (a box or cylinder on a face of its height, a mesh with
    #: its body z within 10 deg of the vertical); default: a box's or cylinder's yes, a mesh's no
    upright: bool | None = None


class MotionSpec(Model):
    """Slower motion: pickdemo's Cartesian limits (near the object and in free space) scaled by these."""

    velocity_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    acceleration_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    jerk_scale: Annotated[float, Field(ge=0.05, le=1.0)] = 1.0
    #: "joint": transfers (home to above the target, to above the place, back home) in joint space to IK
    #: goals chosen well, straight lines only near the object; "cartesian": every move a straight line
    #: (as every move was before joint transfers; for comparison)
    transfers: Literal["cartesian", "joint"] = "joint"


class LayoutSpec(Model):
    clearance_m: Annotated[float, Field(ge=0.0, le=0.5)] = 0.01  # free space between objects' footprints


class ControlSpec(Model):
    """The closed loop: how often it looks, how late the estimates arrive, how often it may retry."""

    max_attempts: Annotated[int, Field(ge=1, le=10)] = 3  # grasp attempts before the episode fails
    perception_rate_hz: Annotated[float, Field(gt=0.0, le=60.0)] = 10.0  # frames per second while it looks
    perception_latency_s: Annotated[float, Field(ge=0.0, le=1.0)] = 0.05  # frame taken at t reaches control at t + this
    control_rate_hz: Annotated[float, Field(ge=30.0, le=240.0)] = 120.0  # control ticks per simulated second


Push = Annotated[float, Field(ge=-0.5, le=0.5)]  # m, how far a push moves the target along one axis


class DisturbanceSpec(Model):
    """The target (or the object named ``object``) is pushed across the table while the robot works (a
    slide of ``duration_s``).

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
    object: Name | None = None  # the object pushed (None: the target)

    @model_validator(mode="after")
    def _check(self) -> DisturbanceSpec:
        given = [x is not None for x in (self.offset_m, self.offset_range_m, self.distance_range_m)]
        if sum(given) != 1:
            raise ValueError("give exactly one of offset_m, offset_range_m, distance_range_m")
        for r in (*(self.offset_range_m or ()), self.distance_range_m, self.yaw_range_deg):
            if r is not None and r[0] > r[1]:
                raise ValueError("ranges must be [min, max]")
        return self


class ClearSpec(Model):
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
        return resolve_path(spec, info)  # type: ignore[return-value]

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


class SimSpec(Model):
    # 1/1000 s at the finest: a finer step multiplies the work and changes nothing a user would see.
    time_step_s: Annotated[float, Field(ge=1.0 / 1000.0, le=1.0 / 240.0)] = 1.0 / 240.0
    max_sim_time_s: Annotated[float, Field(gt=0.0, le=600.0)] = 60.0  # simulated-time budget of one episode


#: An object's lowest points may be seen this far below the top it stands on (depth noise): ``surface_z``.
SUPPORT_TOLERANCE_M = 0.005


class Scenario(Model):
    """A whole scenario file, validated."""

    name: Name
    description: Annotated[str, Field(max_length=300)] = ""
    #: the task as an instruction to a language-conditioned policy (a dataset's task string); "": made
    #: from the target and the place (:func:`pickdemo.scenario.instruction.instruction`)
    instruction: Annotated[str, Field(max_length=300)] = ""
    tags: tuple[Name, ...] = ()  # e.g. "suite": run by `pickdemo bench` when no scenario is named
    #: "perceive": for `pickdemo perceive` only (any number of targets); "clear": every object into the tray
    task: Literal["pick", "perceive", "clear"] = "pick"
    #: the robot that works the scene: a shipped one by name, or a robot file (``.toml``, a path
    #: relative to the scenario file)
    robot: Annotated[str, Field(min_length=1, max_length=300)] = DEFAULT_ROBOT
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
    fixtures: tuple[FixtureSpec, ...] = ()  # bins on the table, models (a shelf): known to the robot

    @field_validator("robot")
    @classmethod
    def _known_robot(cls, name: str, info: ValidationInfo) -> str:
        if name.endswith(".toml"):
            name = resolve_path(name, info)  # type: ignore[assignment]
        try:
            robot_named(name)
        except KeyError as exc:
            raise ValueError(exc.args[0]) from None
        except RobotFileError as exc:
            raise ValueError(f"bad robot file: {exc}") from None
        return name

    @property
    def robot_description(self) -> RobotDescription:
        """The robot this scenario runs (:attr:`robot` read)."""
        return robot_named(self.robot)

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
        for f in self.fixtures:
            if f.name in names:
                raise ValueError(f"fixtures.{f.name}: an object has that name; fixtures and objects are named apart")
            names.append(f.name)
        for i, d in enumerate(self.disturbances):
            if d.object is not None and d.object not in [o.name for o in self.objects]:
                raise ValueError(f"disturbances[{i}].object: {d.object!r} is not one of the objects")
        if not self.description.isprintable():
            raise ValueError("description: control characters are not allowed")
        self._place_beside()
        if self.wrist_camera is not None and self.wrist_camera.mount is not None:
            mounts = self.robot_description.camera_mounts  # the hand's links: they move rigidly with it
            if self.wrist_camera.mount not in mounts:
                raise ValueError(
                    f"wrist_camera.mount: {printable(self.wrist_camera.mount)!r} is not a link of the "
                    f"{self.robot_description.label}'s hand; one of {', '.join(mounts)}"
                )
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

    def _place_beside(self) -> None:
        """Each object ``beside`` another: the other named before it; where it may stand (its
        ``region_range``): the other's region grown by their footprints' radii and the gap."""
        before: dict[str, ObjectSpec] = {}
        for obj in self.objects:
            if obj.beside is not None:
                other = before.get(obj.beside.object)
                if other is None:
                    raise ValueError(
                        f"objects.{obj.name}.beside.object: {obj.beside.object!r} is not an object named before it"
                    )
                if "mesh" in (obj.shape, other.shape):  # (a mesh's size is its file's, read after validating)
                    raise ValueError(f"objects.{obj.name}.beside: for a box or a cylinder beside another, not a mesh")
                if obj.static or other.static:
                    raise ValueError(f"objects.{obj.name}.beside: not for a static object (it stands where it is put)")
                reach = obj.largest_shape.footprint_radius_m + other.largest_shape.footprint_radius_m
                reach += obj.beside.gap_m
                rng = other.region_range
                if rng is None:
                    x, y = other.position[:2]  # type: ignore[index]
                    rng = ((x, x), (y, y))
                (x0, x1), (y0, y1) = rng
                obj._beside_range = ((x0 - reach, x1 + reach), (y0 - reach, y1 + reach))
            before[obj.name] = obj

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

    def surface_z(self, x: float, y: float, z: float | None = None) -> float:
        """Height of what an object standing at (x, y) rests on: the belt's top, a bin's floor, or the
        table (0); for an object whose lowest points are at ``z`` (or whose centre is), the highest top of
        a fixture under it no higher than that (a shelf's board), else the table."""
        c = self.conveyor
        if c is not None and c.holds(x, y):
            return c.height_m
        if z is None:
            return next((f.floor_z for f in self.fixtures if f.kind == "bin" and f.inside(x, y)), 0.0)
        tops = [t for f in self.fixtures if (t := f.support_z(x, y, z + SUPPORT_TOLERANCE_M)) is not None]
        return max(tops, default=0.0)

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
