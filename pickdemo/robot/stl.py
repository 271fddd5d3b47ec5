"""Mesh files, as robot packages ship their collision meshes: a binary STL's triangles, and one
written as a Wavefront OBJ with each face's normal (some exporters leave an STL's normals zero, and a
renderer then shades the mesh black); the vertices of any collision mesh a URDF may name (STL,
binary or ASCII; OBJ; COLLADA), which the self-filter bounds. Pure: numpy and XML."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

_RECORD = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def stl_triangles(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """The normals (N, 3) and corners (N, 3, 3) of a binary STL file's triangles."""
    if len(data) < 84:
        raise ValueError("not a binary STL file (too short)")
    n = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0])
    if len(data) < 84 + 50 * n:
        raise ValueError("not a binary STL file (fewer triangles than its header says)")
    tri = np.frombuffer(data, dtype=_RECORD, count=n, offset=84)
    return tri["normal"].astype(float), tri["v"].astype(float)


def stl_vertices(data: bytes) -> np.ndarray:
    """The vertices (N, 3) of a binary STL file (its triangles' corners)."""
    return stl_triangles(data)[1].reshape(-1, 3)


def has_normals(path: Path) -> bool:
    """Whether every triangle of the STL file carries a normal."""
    normals, _ = stl_triangles(path.read_bytes())
    return bool(np.all(np.linalg.norm(normals, axis=1) > 0.5))


def write_obj_with_normals(stl: Path, out: Path) -> Path:
    """The STL's triangles as an OBJ whose faces carry the normals of their corners' winding."""
    _, v = stl_triangles(stl.read_bytes())
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    lines = [f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in v.reshape(-1, 3)]
    lines += [f"vn {x:.6g} {y:.6g} {z:.6g}" for x, y, z in n]
    lines += [f"f {3 * i + 1}//{i + 1} {3 * i + 2}//{i + 1} {3 * i + 3}//{i + 1}" for i in range(len(v))]
    out.write_text("\n".join(lines) + "\n")
    return out


#: The collision meshes' formats :func:`mesh_vertices` reads (by suffix, lower case).
MESH_SUFFIXES = (".stl", ".obj", ".dae")


def mesh_vertices(path: Path) -> np.ndarray:
    """The vertices (N, 3) of a mesh file, in metres as a simulator loads it (a COLLADA file's unit
    applied, and each node's own matrix; a parent node's is not). A ``ValueError`` for a file that
    is not one of :data:`MESH_SUFFIXES` or that has no vertices."""
    data, suffix = path.read_bytes(), path.suffix.lower()
    if suffix == ".stl":
        if data[:5].lower() == b"solid" and len(data) != 84 + 50 * int.from_bytes(data[80:84], "little"):
            words = data.decode("ascii", errors="replace").split()  # an ASCII STL: "vertex x y z" lines
            v = np.array([words[i + 1 : i + 4] for i, w in enumerate(words) if w == "vertex"], dtype=float)
        else:
            v = stl_vertices(data)
    elif suffix == ".obj":
        lines = data.decode("utf-8", errors="replace").splitlines()
        v = np.array([line.split()[1:4] for line in lines if line.startswith("v ")], dtype=float)
    elif suffix == ".dae":
        v = _collada_vertices(data)
    else:
        raise ValueError(f"{path.name}: a collision mesh is one of {', '.join(MESH_SUFFIXES)}")
    v = np.asarray(v, dtype=float).reshape(-1, 3)
    if len(v) == 0 or not np.all(np.isfinite(v)):
        raise ValueError(f"{path.name}: no vertices, or one that is not finite")
    return v


def _collada_vertices(data: bytes) -> np.ndarray:
    root = ET.fromstring(data)
    ns = root.tag[: root.tag.index("}") + 1] if root.tag.startswith("{") else ""
    unit = root.find(f"{ns}asset/{ns}unit")
    scale = float(unit.get("meter", "1")) if unit is not None else 1.0
    geometry = {}
    for geom in root.iter(f"{ns}geometry"):
        sources = {s.get("id"): s for s in geom.iter(f"{ns}source")}
        for inp in geom.iter(f"{ns}input"):
            source = sources.get(inp.get("source", "").lstrip("#"))
            if inp.get("semantic") == "POSITION" and source is not None:
                floats = source.find(f"{ns}float_array")
                text = floats.text if floats is not None and floats.text else ""
                geometry[geom.get("id")] = np.array(text.split(), dtype=float).reshape(-1, 3)
    placed = []
    for node in root.iter(f"{ns}node"):
        matrix = node.find(f"{ns}matrix")
        m = np.eye(4) if matrix is None or not matrix.text else np.array(matrix.text.split(), float).reshape(4, 4)
        for inst in node.findall(f"{ns}instance_geometry"):
            v = geometry.get(inst.get("url", "").lstrip("#"))
            if v is not None:
                placed.append(v @ m[:3, :3].T + m[:3, 3])
    return np.vstack(placed or list(geometry.values()) or [np.empty((0, 3))]) * scale
