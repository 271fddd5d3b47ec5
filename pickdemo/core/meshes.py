"""Mesh objects from URDF files: where a file is, what its collision mesh is, and its vertices.

Pure: the standard library and numpy (no simulator). A scenario names a URDF as
``"pybullet_data:duck_vhacd.urdf"`` (the data folder the pybullet wheel ships, found by the tiny
``pybullet_data`` package, which imports nothing of pybullet) or as a path relative to the scenario
file; ``urdf_choice`` is a glob of either kind. What the robot's model of an object needs of a URDF is
read here once per file: its first link's collision meshes (Wavefront OBJ, each with its origin and
scale) and its inertial frame. PyBullet reports a body's pose at its inertial frame (the centre of
mass), so the vertices are given in that frame, scaled as the scene loads them (``globalScaling``
times the URDF's own mesh scale). A dynamic body collides with the convex hull of each OBJ object,
so the vertices hold every point it can touch the table or the fingers with.

It also owns the reading of a description file's XML that :mod:`pickdemo.core.model_file` (a fixture's
URDF or SDF) shares with it, one way for both: :func:`read_xml` (the guarded read: size, existence,
well-formed), :func:`floats` (a list of numbers in an attribute), :func:`urdf_origin` and
:func:`rpy_matrix`.

Every problem with a file is a :class:`MeshFileError` whose message is one line naming the file.
"""

from __future__ import annotations

import functools
import glob
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: The prefix of a path inside the pybullet wheel's data folder.
PYBULLET_DATA = "pybullet_data:"
#: At most this many bytes of a URDF or SDF file are read (a URDF of an object is a few kB).
MAX_URDF_BYTES = 1 << 20
#: At most this many bytes of an OBJ file are read.
MAX_OBJ_BYTES = 64 << 20


class MeshFileError(ValueError):
    """A URDF or mesh file that cannot be used; the message is one line naming the file."""


def pybullet_data_dir() -> Path:
    import pybullet_data  # a data package: getDataPath() only, no simulator

    return Path(pybullet_data.getDataPath())


def resolve(spec: str, base_dir: Path | None) -> Path:
    """The file a scenario's ``urdf`` names (``pybullet_data:...``, or relative to ``base_dir``)."""
    if spec.startswith(PYBULLET_DATA):
        return pybullet_data_dir() / spec[len(PYBULLET_DATA) :]
    path = Path(spec).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = base_dir / path
    return path


def expand(pattern: str, base_dir: Path | None) -> tuple[str, ...]:
    """The files a scenario's ``urdf_choice`` glob matches, sorted (as absolute paths, or kept
    ``pybullet_data:``-relative so that another machine finds its own copy)."""
    if pattern.startswith(PYBULLET_DATA):
        root = pybullet_data_dir()
        hits = sorted(glob.glob(str(root / pattern[len(PYBULLET_DATA) :])))
        return tuple(PYBULLET_DATA + str(Path(h).relative_to(root)) for h in hits if Path(h).is_file())
    path = resolve(pattern, base_dir)
    return tuple(h for h in sorted(glob.glob(str(path))) if Path(h).is_file())


@functools.lru_cache(maxsize=64)
def usable(pattern: str) -> tuple[str, ...]:
    """The matches of a ``urdf_choice`` glob (:func:`expand`) that can be read: a broken file in a
    large set (``random_urdfs/168`` has only NaN vertices) is left out of the choice rather than
    making the whole set unusable. A ``urdf`` naming one such file is still an error."""
    out = []
    for f in expand(pattern, None):
        try:
            read_urdf(f)
        except MeshFileError:
            continue
        out.append(f)
    return tuple(out)


# ------------------------------------------------------------- a description file's XML (shared)
def read_xml(path: Path, kind: str) -> ET.Element:
    """The root element of the XML file at ``path``, read at most :data:`MAX_URDF_BYTES` long; a
    :class:`MeshFileError` (``not {kind}``, e.g. ``a URDF``) for a directory, a missing, unreadable,
    too large or malformed file."""
    try:
        if path.is_dir():
            raise MeshFileError(f"{path}: is a directory, not {kind}")
        if path.stat().st_size > MAX_URDF_BYTES:
            raise MeshFileError(f"{path}: {path.stat().st_size} bytes; {kind} is at most {MAX_URDF_BYTES}")
        return ET.fromstring(path.read_bytes())
    except FileNotFoundError:
        raise MeshFileError(f"{path}: no such file") from None
    except OSError as exc:
        raise MeshFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except ET.ParseError as exc:
        raise MeshFileError(f"{path}: not {kind} (not XML: {exc})") from None


def floats(text: str | None, n: int, default: float, what: str, where: Path) -> np.ndarray:
    """``n`` finite numbers from an attribute's (or an element's) text, space-separated; ``default``
    each if ``text`` is None; a :class:`MeshFileError` naming ``what`` and the file ``where`` else."""
    if text is None:
        return np.full(n, default)
    try:
        values = np.array([float(v) for v in text.split()])
    except ValueError:
        raise MeshFileError(f"{where}: {what} {text!r} is not {n} numbers") from None
    if values.size != n or not np.all(np.isfinite(values)):
        raise MeshFileError(f"{where}: {what} {text!r} is not {n} finite numbers")
    return values


def rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """The rotation matrix of roll, pitch, yaw (rad) about fixed x, y, z, as URDF and SDF give them."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    return np.array(
        [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
         [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
         [-sp, cp * sr, cp * cr]]
    )  # fmt: skip


def urdf_origin(element: ET.Element | None, where: Path) -> tuple[np.ndarray, np.ndarray]:
    """(rotation, translation) of the URDF ``<origin>`` in ``element`` (identity if absent)."""
    o = element.find("origin") if element is not None else None
    if o is None:
        return np.eye(3), np.zeros(3)
    xyz = floats(o.get("xyz"), 3, 0.0, "origin xyz", where)
    rpy = floats(o.get("rpy"), 3, 0.0, "origin rpy", where)
    return rpy_matrix(rpy), xyz


# --------------------------------------------------------------------------------- an object's URDF
def obj_vertices(path: Path) -> np.ndarray:
    """The vertices (N, 3) of a Wavefront OBJ file (its ``v`` lines), in the file's units."""
    try:
        if path.stat().st_size > MAX_OBJ_BYTES:
            raise MeshFileError(f"{path}: {path.stat().st_size} bytes; a mesh file is at most {MAX_OBJ_BYTES}")
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise MeshFileError(f"{path}: cannot read the mesh: {exc.strerror or exc}") from None
    rows = []
    for line in text.splitlines():
        if line.startswith("v "):
            parts = line.split()
            try:
                rows.append((float(parts[1]), float(parts[2]), float(parts[3])))
            except (IndexError, ValueError):
                raise MeshFileError(f"{path}: a vertex line that is not three numbers: {line[:60]!r}") from None
    if len(rows) < 4:
        raise MeshFileError(f"{path}: not a Wavefront OBJ mesh with a solid's vertices ({len(rows)} found)")
    v = np.array(rows)
    if not np.all(np.isfinite(v)):
        raise MeshFileError(f"{path}: a vertex that is not finite")
    return v


def _geometry_vertices(geometry: ET.Element | None, path: Path) -> np.ndarray:
    """Points whose convex hull is a URDF collision geometry (a mesh's vertices; a box's corners; a
    cylinder's or sphere's points 5 deg apart), in the geometry's frame."""
    shape = geometry[0] if geometry is not None and len(geometry) else None
    if shape is None:
        raise MeshFileError(f"{path}: a collision with no geometry")
    if shape.tag == "mesh":
        filename = shape.get("filename") or ""
        mesh_path = (path.parent / filename.removeprefix("package://")).resolve()
        if mesh_path.suffix.lower() != ".obj":
            raise MeshFileError(f"{path}: collision mesh {filename!r} is not a Wavefront .obj file")
        scale = floats(shape.get("scale"), 3, 1.0, "mesh scale", path)
        if np.any(scale <= 0.0):
            raise MeshFileError(f"{path}: mesh scale {shape.get('scale')!r} is not positive")
        return obj_vertices(mesh_path) * scale
    a = np.radians(np.arange(0.0, 360.0, 5.0))
    if shape.tag == "box":
        half = floats(shape.get("size"), 3, 0.0, "box size", path) / 2.0
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    if shape.tag == "cylinder":
        r = float(floats(shape.get("radius"), 1, 0.0, "cylinder radius", path)[0])
        h = float(floats(shape.get("length"), 1, 0.0, "cylinder length", path)[0])
        ring = np.column_stack([r * np.cos(a), r * np.sin(a)])
        return np.vstack([np.column_stack([ring, np.full(len(a), z)]) for z in (-h / 2.0, h / 2.0)])
    if shape.tag == "sphere":
        r = float(floats(shape.get("radius"), 1, 0.0, "sphere radius", path)[0])
        el = np.radians(np.arange(-90.0, 90.1, 5.0))
        return r * np.array([[np.cos(e) * np.cos(b), np.cos(e) * np.sin(b), np.sin(e)] for e in el for b in a])
    raise MeshFileError(f"{path}: a collision geometry pickdemo cannot read: <{shape.tag}>")


@dataclass(frozen=True)
class UrdfObject:
    """What pickdemo reads of an object's URDF (first link only)."""

    path: Path
    vertices: np.ndarray  # (N, 3) m: every collision mesh's vertices, in the inertial (body) frame, at scale 1
    mass_kg: float
    color: tuple[float, float, float] | None  # its visual's material colour, if it names one


def _parse(path: Path) -> UrdfObject:
    root = read_xml(path, "a URDF")
    if root.tag != "robot":
        raise MeshFileError(f"{path}: not a URDF (its root element is <{root.tag}>, not <robot>)")
    link = root.find("link")
    if link is None:
        raise MeshFileError(f"{path}: a URDF with no <link>")
    R_in, t_in = urdf_origin(link.find("inertial"), path)
    mass_el = link.find("inertial/mass")
    mass = 0.0 if mass_el is None else float(floats(mass_el.get("value"), 1, 0.0, "mass", path)[0])
    parts = []
    for col in link.findall("collision"):
        R, t = urdf_origin(col, path)
        parts.append(_geometry_vertices(col.find("geometry"), path) @ R.T + t)  # in the link frame
    if not parts:
        raise MeshFileError(f"{path}: a URDF whose first link has no collision mesh")
    v_link = np.vstack(parts)
    vertices = (v_link - t_in) @ R_in  # in the inertial frame: PyBullet's base frame
    rgba = link.find("visual/material/color")
    color = None
    if rgba is not None and rgba.get("rgba"):
        c = floats(rgba.get("rgba"), 4, 1.0, "material rgba", path)
        color = (float(c[0]), float(c[1]), float(c[2]))
    vertices.setflags(write=False)
    return UrdfObject(path, vertices, mass, color)


@functools.lru_cache(maxsize=4096)
def _parse_cached(path: str) -> UrdfObject:
    return _parse(Path(path))


def read_urdf(spec: str, base_dir: Path | None = None) -> UrdfObject:
    """The object a scenario's ``urdf`` names (read once per file and process)."""
    return _parse_cached(str(resolve(spec, base_dir).resolve()))
