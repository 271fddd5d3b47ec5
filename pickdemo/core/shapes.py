"""The objects' shapes as types: a box and a cylinder, and everything that follows from a shape and its
size, each written once.

A scenario names an object's shape with a string (``"box"``, ``"cylinder"``: :data:`ShapeName`, the
same strings ``result.json`` and the TOML files use); those strings are written here only.
:func:`make_shape` turns a name and a size (in the scenario's order: a box's x, y, z extents, a
cylinder's diameter and height) into a :class:`Shape`, once per object and seed (where the layout
draws its size); the layout's placement and the robot's target model carry it, and every derivation
(height, footprint, yaw symmetry, resting height, the surface's closest points ...) is asked of it.

Sizes are in metres, in the object's body frame: its centre at the origin, its z axis up through its
top face (a cylinder's axis). Pure: numpy only.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import ClassVar, Literal, Protocol

import numpy as np

#: The names a scenario gives shapes (its ``shape`` key), as written in ``result.json``.
ShapeName = Literal["box", "cylinder", "mesh"]


#: A box whose top sides differ by less than this is square (for its symmetry).
SQUARE_TOLERANCE_M = 0.002


class Shape(Protocol):
    """What a shape of the task answers: its size and what follows from it."""

    kind: ClassVar[str]  # its :data:`ShapeName`
    n_sizes: ClassVar[int]  # how many numbers its size has
    size_text: ClassVar[str]  # what they are, for messages

    @property
    def size(self) -> tuple[float, ...]:
        """The size in the scenario's order (box: x, y, z; cylinder: diameter, height), m."""
        ...

    @property
    def height_m(self) -> float:
        """Extent along the body's z axis (standing upright, its height)."""
        ...

    @property
    def footprint_radius_m(self) -> float:
        """Radius of the circle that holds its footprint on the table, upright."""
        ...

    @property
    def bounding_radius_m(self) -> float:
        """Radius of the sphere about its centre that holds it, whatever its orientation."""
        ...

    @property
    def yaw_symmetry_rad(self) -> float:
        """The turn about its z axis after which it looks the same (0: any turn, no yaw at all)."""
        ...

    @property
    def grasp_width_m(self) -> float:
        """Its width across the narrower side of its top: what a top-down grasp closes on."""
        ...

    @property
    def top_extents_m(self) -> tuple[float, float]:
        """Extents of its top face, the larger first (a circle's: its diameter twice)."""
        ...

    def resting_height_m(self, rotation: np.ndarray) -> float:
        """Height of its centre above a plane its lowest point touches, turned by ``rotation``."""
        ...

    def resting_face(self, rotation: np.ndarray) -> tuple[float, float]:
        """The tilt (deg) of the body axis it stands on nearest the vertical, and its extent along it (m)."""
        ...

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Closest points on its surface to ``points`` (N, 3) and the outward normals there (body frame)."""
        ...

    def outline_residuals(self, xy: np.ndarray) -> np.ndarray:
        """Signed distance (m) of points of its top plane ((N, >=2), body x, y) from its top face's outline."""
        ...

    def outline_xy(self, yaw_rad: float) -> np.ndarray:
        """Its outline seen from above, upright and turned ``yaw_rad`` about z (m, a polygon about its centre)."""
        ...


@dataclass(frozen=True)
class Box:
    """A box: its x, y, z extents (m)."""

    size_m: tuple[float, float, float]
    kind: ClassVar[ShapeName] = "box"
    n_sizes: ClassVar[int] = 3
    size_text: ClassVar[str] = "x, y, z extents"

    @property
    def size(self) -> tuple[float, ...]:
        return self.size_m

    @property
    def height_m(self) -> float:
        return self.size_m[2]

    @property
    def footprint_radius_m(self) -> float:
        return 0.5 * float(np.hypot(self.size_m[0], self.size_m[1]))

    @property
    def bounding_radius_m(self) -> float:
        return 0.5 * float(np.linalg.norm(self.size_m))

    @property
    def yaw_symmetry_rad(self) -> float:
        """A quarter turn for a square top, else a half turn. Sides within :data:`SQUARE_TOLERANCE_M`
        of each other make a square top: no camera tells them apart, and either pair fits the fingers
        (taken as a half turn, a nearly square box's yaw can flip by a quarter turn in the tracker;
        evidence: docs/decisions.md#the-loop-and-the-tracker)."""
        return np.pi / 2.0 if abs(self.size_m[0] - self.size_m[1]) < SQUARE_TOLERANCE_M else np.pi

    @property
    def grasp_width_m(self) -> float:
        return min(self.size_m[0], self.size_m[1])

    @property
    def top_extents_m(self) -> tuple[float, float]:
        a, b = sorted(self.size_m[:2], reverse=True)
        return a, b

    def resting_height_m(self, rotation: np.ndarray) -> float:
        return 0.5 * float(np.abs(rotation[2]) @ np.asarray(self.size_m))

    def resting_face(self, rotation: np.ndarray) -> tuple[float, float]:
        """A box rests on any face: the body axis with the largest world-z component."""
        axis = int(np.argmax(np.abs(rotation[2])))
        tilt = float(np.degrees(np.arccos(np.clip(abs(rotation[2, axis]), -1.0, 1.0))))
        return tilt, float(self.size_m[axis])

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        h = np.array(self.size_m) / 2.0
        inside = np.all(np.abs(points) <= h, axis=1)
        q = np.clip(points, -h, h)
        # Points inside the box go to their nearest face.
        gap = h - np.abs(points)
        axis_in = np.argmin(gap, axis=1)
        idx = np.nonzero(inside)[0]
        q[idx, axis_in[idx]] = np.sign(points[idx, axis_in[idx]] + 1e-15) * h[axis_in[idx]]
        # The normal of the face the closest point lies on (the axis where it sits on the boundary,
        # preferring the one the point is furthest out along).
        out = np.abs(points) - h
        out[inside] = -gap[inside]
        axis = np.argmax(out, axis=1)
        n = np.zeros_like(points)
        n[np.arange(len(points)), axis] = np.sign(points[np.arange(len(points)), axis] + 1e-15)
        return q, n

    def ray_entry(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where rays from outside first meet the box (the slab method), the outward normal there,
        and which rays meet it at all (body frame, centred)."""
        h = np.array(self.size_m) / 2.0
        d = np.where(np.abs(directions) < 1e-12, 1e-12, directions)
        t1, t2 = (-h - origins) / d, (h - origins) / d
        near, far = np.minimum(t1, t2), np.maximum(t1, t2)
        axis = np.argmax(near, axis=1)
        rows = np.arange(len(origins))
        enter = near[rows, axis]
        exit_ = np.minimum(np.minimum(far[:, 0], far[:, 1]), far[:, 2])  # far.min(axis=1), a third of the cost
        hit = (enter <= exit_) & (enter > 0.0)
        n = np.zeros_like(origins)
        n[rows, axis] = -np.sign(d[rows, axis])
        return origins + enter[:, None] * directions, n, hit

    def outline_residuals(self, xy: np.ndarray) -> np.ndarray:
        """To the nearer pair of sides."""
        hx, hy = self.size_m[0] / 2.0, self.size_m[1] / 2.0
        on_x = np.abs(np.abs(xy[:, 0]) - hx) < np.abs(np.abs(xy[:, 1]) - hy)
        return np.where(on_x, np.abs(xy[:, 0]) - hx, np.abs(xy[:, 1]) - hy)

    def outline_xy(self, yaw_rad: float) -> np.ndarray:
        """Its four corners."""
        corners = ((-1, -1), (1, -1), (1, 1), (-1, 1))
        local = np.array([[sx * self.size_m[0], sy * self.size_m[1]] for sx, sy in corners]) / 2.0
        rot = np.array([[np.cos(yaw_rad), -np.sin(yaw_rad)], [np.sin(yaw_rad), np.cos(yaw_rad)]])
        return local @ rot.T

    def surface_points(self, spacing_m: float = 0.004) -> np.ndarray:
        """Points (N, 3) on its six faces, a grid about ``spacing_m`` apart, in its frame."""
        half = np.asarray(self.size_m, dtype=float) / 2.0
        out = []
        for axis in range(3):
            u, v = [a for a in range(3) if a != axis]
            n = [max(int(np.ceil(2.0 * half[a] / spacing_m)), 1) + 1 for a in (u, v)]
            mu, mv = np.meshgrid(np.linspace(-half[u], half[u], n[0]), np.linspace(-half[v], half[v], n[1]))
            for side in (-half[axis], half[axis]):
                local = np.empty((mu.size, 3))
                local[:, u], local[:, v], local[:, axis] = mu.ravel(), mv.ravel(), side
                out.append(local)
        return np.vstack(out)


@dataclass(frozen=True)
class Cylinder:
    """An upright cylinder (its axis the body's z): diameter and height (m)."""

    diameter_m: float
    height_m: float
    kind: ClassVar[ShapeName] = "cylinder"
    n_sizes: ClassVar[int] = 2
    size_text: ClassVar[str] = "diameter, height"

    @property
    def size(self) -> tuple[float, ...]:
        return (self.diameter_m, self.height_m)

    @property
    def footprint_radius_m(self) -> float:
        return 0.5 * self.diameter_m

    @property
    def bounding_radius_m(self) -> float:
        return 0.5 * float(np.linalg.norm(self.size))

    @property
    def yaw_symmetry_rad(self) -> float:
        """Any turn: a cylinder has no yaw."""
        return 0.0

    @property
    def grasp_width_m(self) -> float:
        return self.diameter_m

    @property
    def top_extents_m(self) -> tuple[float, float]:
        return self.diameter_m, self.diameter_m

    def resting_height_m(self, rotation: np.ndarray) -> float:
        axis_z = abs(float(rotation[2, 2]))
        return 0.5 * (self.height_m * axis_z + self.diameter_m * float(np.sqrt(max(1.0 - axis_z**2, 0.0))))

    def resting_face(self, rotation: np.ndarray) -> tuple[float, float]:
        """A cylinder stands only on a cap: its axis is its body z."""
        tilt = float(np.degrees(np.arccos(np.clip(abs(rotation[2, 2]), -1.0, 1.0))))
        return tilt, float(self.height_m)

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r, hh = self.diameter_m / 2.0, self.height_m / 2.0
        rho = np.hypot(points[:, 0], points[:, 1])
        radial = np.column_stack([points[:, 0], points[:, 1]]) / np.maximum(rho, 1e-12)[:, None]
        d_side = np.where(np.abs(points[:, 2]) <= hh, np.abs(rho - r), np.inf)
        d_cap = np.where(rho <= r, np.abs(np.abs(points[:, 2]) - hh), np.inf)
        on_side = d_side <= d_cap
        q = points.copy()
        n = np.zeros_like(points)
        q[on_side, :2] = radial[on_side] * r
        q[on_side, 2] = np.clip(points[on_side, 2], -hh, hh)
        n[on_side, :2] = radial[on_side]
        caps = ~on_side
        clip_rho = np.minimum(rho[caps], r)
        q[caps, :2] = radial[caps] * clip_rho[:, None]
        q[caps, 2] = np.sign(points[caps, 2] + 1e-15) * hh
        n[caps, 2] = np.sign(points[caps, 2] + 1e-15)
        return q, n

    def ray_entry(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where rays from outside first meet the cylinder (its side or a cap), the outward normal
        there, and which rays meet it at all (body frame, centred)."""
        r, hh = self.diameter_m / 2.0, self.height_m / 2.0
        o, d = origins, directions
        a = np.maximum(d[:, 0] ** 2 + d[:, 1] ** 2, 1e-24)
        b = 2.0 * (o[:, 0] * d[:, 0] + o[:, 1] * d[:, 1])
        c = o[:, 0] ** 2 + o[:, 1] ** 2 - r * r
        disc = b * b - 4.0 * a * c
        t_side = np.where(disc >= 0.0, (-b - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * a), np.inf)
        z_side = o[:, 2] + t_side * d[:, 2]
        t_side = np.where((np.abs(z_side) <= hh) & (t_side > 0.0), t_side, np.inf)
        dz = np.where(np.abs(d[:, 2]) < 1e-12, 1e-12, d[:, 2])
        t_cap = np.minimum((hh - o[:, 2]) / dz, (-hh - o[:, 2]) / dz)  # the cap faced first
        cap_xy = o[:, :2] + t_cap[:, None] * d[:, :2]
        t_cap = np.where((np.hypot(cap_xy[:, 0], cap_xy[:, 1]) <= r) & (t_cap > 0.0), t_cap, np.inf)
        on_side = t_side <= t_cap
        t = np.minimum(t_side, t_cap)
        hit = np.isfinite(t)
        q = o + np.where(hit, t, 0.0)[:, None] * d
        n = np.zeros_like(o)
        rho = np.maximum(np.hypot(q[:, 0], q[:, 1]), 1e-12)
        n[on_side, 0] = q[on_side, 0] / rho[on_side]
        n[on_side, 1] = q[on_side, 1] / rho[on_side]
        n[~on_side, 2] = -np.sign(dz[~on_side])
        return q, n, hit

    def outline_residuals(self, xy: np.ndarray) -> np.ndarray:
        return np.hypot(xy[:, 0], xy[:, 1]) - self.diameter_m / 2.0

    def outline_xy(self, yaw_rad: float) -> np.ndarray:
        """A 24-gon on its circle (the same whatever the yaw)."""
        a = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
        return self.diameter_m / 2.0 * np.column_stack([np.cos(a), np.sin(a)])

    def surface_points(self, spacing_m: float = 0.004) -> np.ndarray:
        """Points (N, 3) on its side and its top and bottom discs, about ``spacing_m`` apart, in its frame."""
        r, h = self.diameter_m / 2.0, self.height_m
        a = np.linspace(0.0, 2.0 * np.pi, max(12, int(2.0 * np.pi * r / spacing_m)), endpoint=False)
        z = np.linspace(-h / 2.0, h / 2.0, max(2, int(h / spacing_m) + 1))
        side = np.stack([np.repeat(r * np.cos(a)[None], len(z), 0), np.repeat(r * np.sin(a)[None], len(z), 0),
                         np.repeat(z[:, None], len(a), 1)], axis=-1).reshape(-1, 3)  # fmt: skip
        rings = [rr * np.column_stack([np.cos(a), np.sin(a)]) for rr in np.arange(spacing_m, r, spacing_m)]
        disc = np.vstack([np.zeros((1, 2)), *rings]) if rings else np.zeros((1, 2))
        caps = [np.column_stack([disc, np.full(len(disc), zz)]) for zz in (-h / 2.0, h / 2.0)]
        return np.vstack([side, *caps])


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """The convex hull of (N, 2) points, counter-clockwise (Andrew's monotone chain)."""
    pts = np.unique(np.round(np.asarray(points, dtype=float), 9), axis=0)
    if len(pts) < 3:
        return pts

    def half(seq: np.ndarray) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2:
                a, b = out[-2], out[-1]
                if (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) > 0:
                    break
                out.pop()
            out.append(p)
        return out

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def caliper_widths(points_xy: np.ndarray) -> tuple[float, float, float]:
    """Of a planar point set: its narrowest width, the direction (rad) across which it is that narrow,
    and its widest extent (the widths across each edge's normal of the convex hull: the narrowest is
    one of them)."""
    hull = convex_hull_2d(points_xy)
    if len(hull) < 3:
        span = float(np.ptp(hull, axis=0).max()) if len(hull) else 0.0
        return 0.0, 0.0, span
    edges = np.roll(hull, -1, axis=0) - hull
    normals = np.column_stack([-edges[:, 1], edges[:, 0]]) / np.linalg.norm(edges, axis=1)[:, None]
    proj = hull @ normals.T
    widths = proj.max(axis=0) - proj.min(axis=0)
    k = int(np.argmin(widths))
    widest = float(np.max(np.linalg.norm(hull[:, None, :] - hull[None, :, :], axis=2)))
    return float(widths[k]), float(np.arctan2(normals[k, 1], normals[k, 0])), widest


@dataclass(frozen=True)
class Mesh:
    """An object of any shape, from a URDF file: its collision meshes' vertices (m, in its body frame:
    PyBullet's base frame, at its centre of mass), at the scale it is loaded with.

    Its size is its bounding box's extents; it is known to the robot only as what the camera sees of
    it (no model to fit). Upright means as the file stands it, body z up. Two meshes are equal when
    they come from the same file at the same scale."""

    urdf: str  # the scenario's name for the file ("pybullet_data:..." or an absolute path)
    scale: float  # times the URDF's own mesh scale (PyBullet's ``globalScaling``)
    vertices: np.ndarray = field(compare=False, repr=False)
    kind: ClassVar[ShapeName] = "mesh"
    n_sizes: ClassVar[int] = 3
    size_text: ClassVar[str] = "bounding box x, y, z extents"

    @property
    def size(self) -> tuple[float, ...]:
        lo, hi = self.vertices.min(axis=0), self.vertices.max(axis=0)
        return tuple(float(v) for v in hi - lo)

    @property
    def height_m(self) -> float:
        return float(np.ptp(self.vertices[:, 2]))

    @property
    def box_centre(self) -> np.ndarray:
        """Its centre in its body frame (m), standing upright: :meth:`centre_turned` with no turn."""
        return self.centre_turned(np.eye(3))

    def centre_turned(self, rotation: np.ndarray) -> np.ndarray:
        """Its centre in its body frame (m) when the body is turned by ``rotation``: the middle of its
        footprint along its principal axes seen from above, at half its height. Where a place puts "it",
        and what an object nobody described is seen by (its file's origin and its centre of mass may lie
        anywhere). It turns with the object about the vertical; an object resting on an edge is seen,
        and scored, by the middle of what it covers as it rests, not of what it would cover upright."""
        R = np.asarray(rotation, dtype=float)
        v = self.vertices @ R.T
        xy = v[:, :2] - v[:, :2].mean(axis=0)
        _, axes = np.linalg.eigh(np.cov(xy.T))
        along = xy @ axes
        mid = axes @ (0.5 * (along.min(axis=0) + along.max(axis=0))) + v[:, :2].mean(axis=0)
        return R.T @ np.array([mid[0], mid[1], 0.5 * (v[:, 2].min() + v[:, 2].max())])

    @property
    def footprint_radius_m(self) -> float:
        return float(np.max(np.hypot(self.vertices[:, 0], self.vertices[:, 1])))

    @property
    def bounding_radius_m(self) -> float:
        return float(np.max(np.linalg.norm(self.vertices, axis=1)))

    @property
    def yaw_symmetry_rad(self) -> float:
        """None known: a whole turn."""
        return 2.0 * np.pi

    @property
    def grasp_width_m(self) -> float:
        """The narrowest width of its footprint (what a top-down grasp across it closes on)."""
        return caliper_widths(self.vertices[:, :2])[0]

    @property
    def top_extents_m(self) -> tuple[float, float]:
        narrow, _, wide = caliper_widths(self.vertices[:, :2])
        return wide, narrow

    @property
    def min_width_m(self) -> float:
        """Its narrowest width in any direction (a parallel gripper closing across it at its best): the
        least over 2000 directions, its body axes and its principal axes, and exact across the horizontal
        (an upper bound on the true least within the directions' 2.5 deg)."""
        v = self.vertices
        _, axes = np.linalg.eigh(np.cov((v - v.mean(axis=0)).T))  # its principal axes: a box's face normals
        proj = v @ np.vstack([_DIRECTIONS, np.eye(3), axes.T]).T
        return min(float(np.min(proj.max(axis=0) - proj.min(axis=0))), self.grasp_width_m)

    def top_down_width_m(self, levels: int = 12, min_pad_z_m: float = 0.003, pad_height_m: float = 0.0185) -> float:
        """The narrowest width a top-down grasp of it standing upright could close across: of the part
        above each height of the pads' lower edge (from ``min_pad_z_m`` over its base to a pad's height
        below its top: the pads close on it, not on its tip), the narrowest caliper width of its
        footprint (the fingers pass everything above the pads on their way down)."""
        v = self.vertices
        z = v[:, 2] - v[:, 2].min()
        best = np.inf
        for h in np.linspace(min_pad_z_m, max(float(z.max()) - pad_height_m, min_pad_z_m), levels):
            above = v[z >= h, :2]
            if len(above) >= 3:
                best = min(best, caliper_widths(above)[0])
        return float(best) if np.isfinite(best) else self.grasp_width_m

    def resting_height_m(self, rotation: np.ndarray) -> float:
        return float(-np.min(self.vertices @ np.asarray(rotation)[2]))

    def resting_face(self, rotation: np.ndarray) -> tuple[float, float]:
        """Its body z from the vertical, and its extent along body z."""
        tilt = float(np.degrees(np.arccos(np.clip(abs(rotation[2, 2]), -1.0, 1.0))))
        return tilt, self.height_m

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Its nearest vertices, with the direction from its centre as the normal (a coarse model:
        a mesh is perceived as an unknown object, not fitted)."""
        d = np.linalg.norm(points[:, None, :] - self.vertices[None, :, :], axis=2)
        q = self.vertices[np.argmin(d, axis=1)]
        return q.copy(), q / np.maximum(np.linalg.norm(q, axis=1), 1e-12)[:, None]

    def outline_residuals(self, xy: np.ndarray) -> np.ndarray:
        raise NotImplementedError("a mesh has no top face to fit: it is perceived as an unknown object")

    def outline_xy(self, yaw_rad: float) -> np.ndarray:
        """The convex hull of its footprint, turned ``yaw_rad``."""
        hull = convex_hull_2d(self.vertices[:, :2])
        rot = np.array([[np.cos(yaw_rad), -np.sin(yaw_rad)], [np.sin(yaw_rad), np.cos(yaw_rad)]])
        return hull @ rot.T


@dataclass(frozen=True)
class Unknown:
    """What the robot is told of an object nobody described: nothing of its shape, only a bound on its
    size (the task's: the largest object it expects, m), which sizes the regions it looks at, and
    perhaps its rough size as a cue among other objects (a pick order's "the 3 cm brick"). Its
    extents, its yaw and its grasps are what the camera sees of it (:mod:`pickdemo.perception.unknown`).

    Its pose is its features' mean and the principal axes of their spread, as the paper describes;
    the principal axes look the same after a half turn. The robot's model only: a scenario's object
    is a box, a cylinder or a mesh."""

    max_extent_m: float = 0.15
    #: a size the task names, as a cue to tell it from other objects (not a model to fit): its height,
    #: its footprint's longer and shorter side (m); None: not named
    size_cue_m: tuple[float, float, float] | None = None
    #: objects may touch one another (a heap on a table being cleared): told apart where the depth or the
    #: colour steps
    heap: bool = False
    kind: ClassVar[str] = "unknown"
    n_sizes: ClassVar[int] = 0
    size_text: ClassVar[str] = "nothing (its size is seen)"

    @property
    def size(self) -> tuple[float, ...]:
        return ()

    @property
    def height_m(self) -> float:
        return self.max_extent_m

    @property
    def footprint_radius_m(self) -> float:
        return self.max_extent_m / 2.0

    @property
    def bounding_radius_m(self) -> float:
        return self.max_extent_m / 2.0

    @property
    def yaw_symmetry_rad(self) -> float:
        """Its principal axes: a half turn."""
        return np.pi

    @property
    def grasp_width_m(self) -> float:
        raise NotImplementedError("an unknown object's width is seen, not told")

    @property
    def top_extents_m(self) -> tuple[float, float]:
        raise NotImplementedError("an unknown object's extents are seen, not told")

    def resting_height_m(self, rotation: np.ndarray) -> float:
        raise NotImplementedError("an unknown object's height is seen, not told")

    def resting_face(self, rotation: np.ndarray) -> tuple[float, float]:
        raise NotImplementedError("an unknown object has no known faces")

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError("an unknown object has no model to fit")

    def outline_residuals(self, xy: np.ndarray) -> np.ndarray:
        raise NotImplementedError("an unknown object has no model to fit")

    def outline_xy(self, yaw_rad: float) -> np.ndarray:
        """A square of its size bound (for pictures only)."""
        return Box((self.max_extent_m, self.max_extent_m, self.max_extent_m)).outline_xy(yaw_rad)


def _hemisphere(n: int) -> np.ndarray:
    """``n`` unit vectors spread evenly over the upper hemisphere (a Fibonacci lattice)."""
    k = np.arange(n) + 0.5
    z = 1.0 - k / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (3.0 - np.sqrt(5.0)) * k
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


#: Directions across which a mesh's narrowest width is sought (about 2.5 deg apart).
_DIRECTIONS = _hemisphere(2000)


#: Each shape's class by its name.
SHAPES: dict[str, type[Box] | type[Cylinder] | type[Mesh]] = {cls.kind: cls for cls in (Box, Cylinder, Mesh)}


def make_shape(kind: str, size: Sequence[float]) -> Box | Cylinder:
    """The shape named ``kind`` of this size (the scenario's order: box x, y, z; cylinder diameter, height).
    A :class:`Mesh` is made from its file (:func:`pickdemo.core.meshes.read_urdf`), not from a size."""
    if kind == Box.kind:
        x, y, z = size
        return Box((x, y, z))
    if kind == Cylinder.kind:
        d, h = size
        return Cylinder(d, h)
    if kind == Mesh.kind:
        raise ValueError("a mesh is made from its file (ObjectSpec.mesh_shape), not from a size")
    raise ValueError(f"unknown shape {kind!r} (known: {', '.join(SHAPES)})")
