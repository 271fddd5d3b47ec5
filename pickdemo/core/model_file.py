"""A fixture's model file (URDF or SDF): the boxes of its collision geometry, in the model's frame.

Pure: the standard library and numpy (no simulator). What the robot knows of a model fixture (a shelf)
is read from the same file the simulator loads: the collision geometries of its one link (boxes; a
cylinder or a sphere bounded by a box), each posed in the model's frame and scaled, and the link's
inertial frame there (PyBullet places a body by its inertial frame). The model's frame is its root
link's: for an SDF, the link's pose in the model; the model's own ``<pose>``, which places it in a
world, is the scenario's to give. A collision mesh is refused: the robot would not know its shape.

Its XML is read the one way :mod:`pickdemo.core.meshes` reads an object's URDF (its ``read_xml``, and
the ``floats``, ``urdf_origin`` and ``rpy_matrix`` beside it). Every problem with a file is a
:class:`~pickdemo.core.meshes.MeshFileError` whose message is one line naming the file.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.core.meshes import MeshFileError, floats, read_xml, rpy_matrix, urdf_origin


@dataclass(frozen=True)
class ModelFile:
    """The collision boxes of a model file's one link, in its frame at scale 1, and the link's
    inertial frame there."""

    path: Path
    format: str  # "urdf" or "sdf"
    boxes: tuple[OrientedBox, ...]
    inertial: Pose

    def scaled(self, scale: float) -> tuple[tuple[OrientedBox, ...], Pose]:
        """Its boxes and inertial frame as the simulator loads it at ``scale`` (``globalScaling``)."""
        boxes = tuple(
            OrientedBox(Pose(b.pose.position * scale, b.pose.rotation), b.lo * scale, b.hi * scale) for b in self.boxes
        )
        return boxes, Pose(self.inertial.position * scale, self.inertial.rotation)


def _box_of(geometry: ET.Element | None, path: Path, size_key: str) -> tuple[np.ndarray, np.ndarray]:
    """A collision geometry's bounding box in its own frame (lo, hi): a box; a cylinder along its z; a
    sphere. ``size_key``: how the format names a box's size and a radius's (URDF attributes, SDF elements)."""
    shape = geometry[0] if geometry is not None and len(geometry) else None
    if shape is None:
        raise MeshFileError(f"{path}: a collision with no geometry")

    def value(name: str, n: int) -> np.ndarray:
        text = shape.get(name) if size_key == "attr" else (shape.findtext(name) or None)
        return floats(text, n, np.nan, f"{shape.tag} {name}", path)

    if shape.tag == "box":
        half = value("size", 3) / 2.0
    elif shape.tag == "cylinder":
        r, h = float(value("radius", 1)[0]), float(value("length", 1)[0])
        half = np.array([r, r, h / 2.0])
    elif shape.tag == "sphere":
        half = np.full(3, float(value("radius", 1)[0]))
    else:
        raise MeshFileError(
            f"{path}: a <{shape.tag}> collision geometry; a model fixture is read as boxes, cylinders and spheres "
            "(the robot must know its shape)"
        )
    if not np.all(np.isfinite(half)) or np.any(half <= 0.0):
        raise MeshFileError(f"{path}: a {shape.tag} whose size is missing or not positive")
    return -half, half


def _sdf_pose(element: ET.Element | None, path: Path) -> Pose:
    """An SDF ``<pose>`` (x y z roll pitch yaw; identity if absent)."""
    text = element.findtext("pose") if element is not None else None
    v = floats(text, 6, 0.0, "pose", path)
    return Pose(v[:3], rpy_matrix(v[3:]))


def _read_urdf(root: ET.Element, path: Path) -> tuple[list[tuple[Pose, ET.Element | None]], Pose]:
    links = root.findall("link")
    if not links:
        raise MeshFileError(f"{path}: a URDF with no <link>")
    if len(links) > 1:
        raise MeshFileError(f"{path}: {len(links)} links; a model fixture is one rigid body (one link)")
    link = links[0]
    cols = []
    for col in link.findall("collision"):
        R, t = urdf_origin(col, path)
        cols.append((Pose(t, R), col.find("geometry")))
    R_in, t_in = urdf_origin(link.find("inertial"), path)
    return cols, Pose(t_in, R_in)


def _read_sdf(root: ET.Element, path: Path) -> tuple[list[tuple[Pose, ET.Element | None]], Pose]:
    model = root.find("model")
    if model is None:
        model = root.find("world/model")
    if model is None:
        raise MeshFileError(f"{path}: an SDF with no <model>")
    links = model.findall("link")
    if len(links) != 1:
        raise MeshFileError(f"{path}: {len(links)} links; a model fixture is one rigid body (one link)")
    link = links[0]
    at = _sdf_pose(link, path)  # the link in the model's frame
    cols = [(at @ _sdf_pose(col, path), col.find("geometry")) for col in link.findall("collision")]
    return cols, at @ _sdf_pose(link.find("inertial"), path)


def _parse(path: Path) -> ModelFile:
    root = read_xml(path, "a URDF or SDF file")
    if root.tag == "robot":
        fmt, (cols, inertial) = "urdf", _read_urdf(root, path)
        key = "attr"
    elif root.tag == "sdf":
        fmt, (cols, inertial) = "sdf", _read_sdf(root, path)
        key = "element"
    else:
        raise MeshFileError(f"{path}: not a URDF or SDF file (its root element is <{root.tag}>)")
    boxes = []
    for pose, geometry in cols:
        lo, hi = _box_of(geometry, path, key)
        boxes.append(OrientedBox(pose, lo, hi))
    if not boxes:
        raise MeshFileError(f"{path}: its link has no collision geometry")
    return ModelFile(path, fmt, tuple(boxes), inertial)


@functools.lru_cache(maxsize=64)
def _parse_cached(path: str) -> ModelFile:
    return _parse(Path(path))


def read_model(path: Path) -> ModelFile:
    """The model file at ``path`` (read once per file and process)."""
    return _parse_cached(str(Path(path).resolve()))
