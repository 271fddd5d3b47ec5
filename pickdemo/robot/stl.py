"""Binary STL files, as robot packages ship their collision meshes: read their triangles, and write
one as a Wavefront OBJ with each face's normal (some exporters leave an STL's normals zero, and a
renderer then shades the mesh black). Pure: numpy."""

from __future__ import annotations

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
