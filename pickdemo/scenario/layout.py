"""Where each object of a scenario starts, its size, and where the camera stands: sampled from the
scenario's ranges with the scene's RNG.

Pure: no simulator. Objects are placed in file order; an object that would overlap one already
placed is re-drawn (a bounded number of times), so a seed always gives the same layout. A draw is
made only for what the scenario leaves open, so adding a range to one key does not change the other
keys' draws of a scenario that does not use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.meshes import MeshFileError, read_urdf
from pickdemo.core.shapes import Mesh, Shape
from pickdemo.scenario.base import DRAWN_NAME
from pickdemo.scenario.objects import ObjectSpec
from pickdemo.scenario.schema import Scenario
from pickdemo.scenario.sensors import CameraSpec

MAX_DRAWS = 200


class LayoutError(ValueError):
    """The scenario's ranges leave no room to place its objects apart."""


@dataclass(frozen=True)
class Placement:
    """Where one object starts, and its shape at the size drawn for this seed."""

    name: str
    pose: Pose  # world pose of the object's centre
    geometry: Shape

    @property
    def size(self) -> tuple[float, ...]:
        """The size in the scenario's order (box: x, y, z; cylinder: diameter, height; mesh: its bounding box), m."""
        return self.geometry.size

    @property
    def shape(self) -> str:
        """The shape's name (``"box"``, ``"cylinder"``), as in the scenario file."""
        return self.geometry.kind

    @property
    def height_m(self) -> float:
        return self.geometry.height_m


def _angle(fixed: float | None, rng_range: tuple[float, float] | None, rng: np.random.Generator) -> float:
    if fixed is not None:
        return float(np.radians(fixed))
    if rng_range is not None:
        return float(np.radians(rng.uniform(*rng_range)))
    return 0.0


def _size(obj: ObjectSpec, rng: np.random.Generator) -> tuple[float, ...]:
    if obj.size is not None:
        return tuple(obj.size)
    return tuple(float(rng.uniform(lo, hi)) for lo, hi in obj.size_range)  # type: ignore[union-attr]


def _draw(obj: ObjectSpec, rng: np.random.Generator) -> tuple[np.ndarray, float, float, float]:
    if obj.position is not None:
        xy = np.array(obj.position[:2], dtype=float)
    else:
        (x0, x1), (y0, y1) = obj.position_range  # type: ignore[misc]
        xy = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
    yaw = _angle(obj.yaw_deg, obj.yaw_range_deg, rng)
    pitch = _angle(obj.pitch_deg, obj.pitch_range_deg, rng)
    roll = _angle(obj.roll_deg, obj.roll_range_deg, rng)
    return xy, yaw, pitch, roll


#: A side of an object (its own axes) as a unit vector.
SIDE_AXES = {"+x": (1.0, 0.0), "-x": (-1.0, 0.0), "+y": (0.0, 1.0), "-y": (0.0, -1.0)}


def _half_width(shape: Shape, yaw_rad: float, direction: np.ndarray) -> float:
    """How far a footprint reaches from its centre along a unit ``direction`` (m): a box's rectangle,
    turned by its yaw; any other shape's circle."""
    if shape.kind != "box":
        return shape.footprint_radius_m
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    sx, sy = shape.size[0], shape.size[1]
    return float(abs(direction @ [c, s]) * sx / 2.0 + abs(direction @ [-s, c]) * sy / 2.0)


def _beside(obj: ObjectSpec, shape: Shape, other: Placement, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    """Where an object ``beside`` another stands, and its yaw: against one of the other's sides (drawn
    when there are several), turned as the other is plus its own yaw, ``gap_m`` from it."""
    spec = obj.beside
    assert spec is not None
    side = spec.sides[int(rng.integers(len(spec.sides)))] if len(spec.sides) > 1 else spec.sides[0]
    other_yaw = float(other.pose.rpy[2])
    yaw = other_yaw + _angle(obj.yaw_deg, obj.yaw_range_deg, rng)
    c, s = np.cos(other_yaw), np.sin(other_yaw)
    u = np.array([[c, -s], [s, c]]) @ np.array(SIDE_AXES[side])
    d = _half_width(other.geometry, other_yaw, u) + _half_width(shape, yaw, u) + spec.gap_m
    return other.pose.position[:2] + d * u, yaw


def _overlap(shape: Shape, xy: np.ndarray, yaw: float, other: Placement) -> bool:
    """Whether a footprint at ``xy`` turned ``yaw`` overlaps another object's (their outlines, seen
    from above; touching is not overlapping)."""
    a = (shape.outline_xy(yaw) + xy).astype(np.float32)
    b = (other.geometry.outline_xy(float(other.pose.rpy[2])) + other.pose.position[:2]).astype(np.float32)
    area, _ = cv2.intersectConvexConvex(a * 1e3, b * 1e3)  # (mm: its area in mm^2)
    return area > 1.0


def _mesh(obj: ObjectSpec, rng: np.random.Generator) -> Shape:
    """A mesh object's file (one of its ``urdf_choice`` matches) and scale for this seed, drawn from
    the seed's ``objects`` stream (so that the layout's own draws stay as they were)."""
    files = obj.urdf_files
    if not files:
        raise LayoutError(f"objects.{obj.name}.urdf_choice: {obj.urdf_choice!r} matches no file")
    urdf = files[int(rng.integers(len(files)))] if len(files) > 1 else files[0]
    lo, hi = obj.scales
    scale = float(rng.uniform(lo, hi)) if hi > lo else lo
    try:
        return obj.mesh_shape(urdf, scale)
    except MeshFileError as exc:
        raise LayoutError(f"objects.{obj.name}: {exc}") from None


def sample_layout(
    scenario: Scenario, rng: np.random.Generator, objects_rng: np.random.Generator | None = None
) -> tuple[Placement, ...]:
    """Start poses and sizes of all objects, resting on the table (or the belt) unless a centre height
    is given. ``objects_rng``: the stream a mesh's file and scale are drawn from (a scenario with no
    mesh never asks it)."""
    placed: list[tuple[np.ndarray, float]] = []
    out: list[Placement] = []
    for obj in scenario.objects:
        if obj.shape == "mesh":
            if objects_rng is None:
                raise ValueError("a mesh's file and scale are drawn from the seed's objects stream: pass objects_rng")
            shape = _mesh(obj, objects_rng)
        else:
            shape = obj.shape_of_size(_size(obj, rng))
        r = shape.footprint_radius_m
        against = None if obj.beside is None else next(p for p in out if p.name == obj.beside.object)
        for _ in range(MAX_DRAWS):
            if against is not None:  # against it, its footprint overlapping no other's
                xy, yaw = _beside(obj, shape, against, rng)
                pitch = roll = 0.0
                if not any(_overlap(shape, xy, yaw, p) for p in out):
                    break
                continue
            xy, yaw, pitch, roll = _draw(obj, rng)
            if obj.position is not None:  # a fixed spot: the scenario's author answers for the spacing
                break
            if all(np.linalg.norm(xy - q) >= r + rq + scenario.layout.clearance_m for q, rq in placed):
                break
        else:
            raise LayoutError(f"objects.{obj.name}: no free spot found in {MAX_DRAWS} draws")
        placed.append((xy, r))
        pose = Pose.from_xyz_rpy(np.array([xy[0], xy[1], 0.0]), roll=roll, pitch=pitch, yaw=yaw)
        z = obj.position[2] if obj.position is not None and len(obj.position) == 3 else None
        if z is None:  # resting on the table, or on the belt where there is one
            z = shape.resting_height_m(pose.rotation) + scenario.surface_z(float(xy[0]), float(xy[1]), obj.level_m)
        out.append(Placement(obj.name, Pose(np.array([xy[0], xy[1], z]), pose.rotation), shape))
    return tuple(out)


def sample_place(
    scenario: Scenario, layout: tuple[Placement, ...] | list[Placement], rng: np.random.Generator
) -> tuple[float, float]:
    """Where the target is to be put down: the scenario's spot, or one drawn from its region clear of
    where every object starts, the target included (by the layout's clearance and the target's own
    footprint): somewhere else."""
    place = scenario.place
    if place.position is not None:
        return (float(place.position[0]), float(place.position[1]))
    (x0, x1), (y0, y1) = place.position_range  # type: ignore[misc]
    targets = [p for p in layout if p.name in {t.name for t in scenario.targets}]
    r = max((p.geometry.footprint_radius_m for p in targets), default=0.0)
    for _ in range(MAX_DRAWS):
        xy = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
        clear = all(
            np.linalg.norm(xy - p.pose.position[:2]) >= r + p.geometry.footprint_radius_m + scenario.layout.clearance_m
            for p in layout
        )
        if clear:
            return (float(xy[0]), float(xy[1]))
    raise LayoutError(f"place.position_range: no spot clear of the other objects in {MAX_DRAWS} draws")


def camera_position(spec: CameraSpec, rng: np.random.Generator) -> np.ndarray:
    """Where the camera stands: the scenario's position, or one drawn around ``look_at``."""
    if not spec.sampled:
        return np.array(spec.position, dtype=float)
    d = rng.uniform(*spec.distance_range_m)  # type: ignore[misc]
    el = np.radians(rng.uniform(*spec.elevation_range_deg))  # type: ignore[misc]
    az = np.radians(rng.uniform(*spec.azimuth_range_deg))  # type: ignore[misc]
    offset = d * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return np.asarray(spec.look_at, dtype=float) + offset


def sample_round(
    scenario: Scenario, rng: np.random.Generator, placed: tuple[Placement, ...] | list[Placement] = ()
) -> tuple[Placement, ...]:
    """A clear round's drawn objects (``[clear]``), from the seed's ``clear`` stream: ``count`` files of
    ``objects_from`` (without repeats while there are enough), each at a scale from ``scale_range`` and
    a yaw drawn in full, standing as its file stands it.

    ``packed``: side by side in the region, apart by the layout's clearance (and clear of the objects
    ``placed`` already). ``pile``: anywhere in the region, each above what it would fall on (the
    footprints drawn before it that it overlaps), ``drop_height_m`` higher: the scene lets them fall
    into a heap before the robot's first look."""
    spec = scenario.clear
    assert spec is not None
    files = spec.files
    if not files:
        raise LayoutError(f"clear.objects_from: {spec.objects_from!r} matches no file")
    picks = rng.choice(len(files), size=spec.count, replace=spec.count > len(files))
    lo, hi = spec.scale_range
    (x0, x1), (y0, y1) = spec.region
    taken: list[tuple[np.ndarray, float, float]] = [  # (xy, footprint radius, top z)
        (p.pose.position[:2], p.geometry.footprint_radius_m, float(p.pose.position[2] + p.height_m / 2.0))
        for p in placed
    ]
    out: list[Placement] = []
    for i, k in enumerate(picks):
        name = DRAWN_NAME.format(i + 1)
        scale = float(rng.uniform(lo, hi)) if hi > lo else lo
        try:
            shape = Mesh(files[int(k)], scale, read_urdf(files[int(k)]).vertices * scale)
        except MeshFileError as exc:
            raise LayoutError(f"clear.objects_from: {exc}") from None
        r = shape.footprint_radius_m
        yaw = float(rng.uniform(-np.pi, np.pi))
        rotation = Pose.from_xyz_rpy(np.zeros(3), yaw=yaw).rotation
        rest = shape.resting_height_m(rotation)
        for _ in range(MAX_DRAWS):
            xy = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
            under = [top for q, rq, top in taken if np.linalg.norm(xy - q) < r + rq]
            if spec.layout == "pile":
                break
            if not under and all(np.linalg.norm(xy - q) >= r + rq + scenario.layout.clearance_m for q, rq, _ in taken):
                break
        else:
            raise LayoutError(
                f"clear.region: no room for {spec.count} objects packed "
                f"{scenario.layout.clearance_m * 1e3:.0f} mm apart "
                f"({name} found no free spot in {MAX_DRAWS} draws): a larger region or fewer objects"
            )
        # (at least on what stands there: a bin's floor; on the table's top, a part drawn first sat 1 cm
        # into the floor, and a plate pushed through it fell into the table: 4 parts in 150 rounds)
        ground = scenario.surface_z(float(xy[0]), float(xy[1]))
        base = max([ground, *under]) + (spec.drop_height_m if under else 0.0)
        z = base + rest
        taken.append((xy, r, z + shape.height_m - rest))
        out.append(Placement(name, Pose(np.array([xy[0], xy[1], z]), rotation), shape))
    return tuple(out)
