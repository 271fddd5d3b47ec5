"""Make the SO-101's collision hulls (``pickdemo/robot/robots/so101/collision/``), once.

PyBullet collides a moving link's mesh as its convex hull and computes it at every load, from every
vertex of the mesh: 0.34 s an episode for the SO-101's full meshes. This writes each mesh's hull as a
small binary STL from the mesh's own float32 vertices, so PyBullet builds the same hull from far
fewer points. The jaws keep their V-HACD decompositions (``so101.toml``).

Needs SciPy (not a pickdemo dependency): ``pip install scipy``, then
``python tests/robot/so101_hulls.py SO101_MESH_DIR pickdemo/robot/robots/so101/collision``, with
SO101_MESH_DIR example-robot-data's ``so_arm_description/meshes/so101``. Check the episodes are
unchanged with ``tests/same_episodes.py`` or two ``bench`` runs of the SO-101's scenarios.
"""

from __future__ import annotations

import glob
import os
import struct
import sys

import numpy as np

TRIANGLE = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
JAWS = ("moving_jaw_so101_v1.stl", "wrist_roll_follower_so101_v1.stl")  # V-HACD, not hulls


def read_stl(path: str) -> np.ndarray:
    """An STL's vertices (binary or ASCII), float64 holding their float32 values exactly."""
    b = open(path, "rb").read()
    n = struct.unpack("<I", b[80:84])[0]
    if len(b) == 84 + 50 * n:
        return np.frombuffer(b[84:], dtype=TRIANGLE, count=n)["v"].reshape(-1, 3).astype(np.float64)
    rows = [line.split()[1:4] for line in b.decode().splitlines() if line.strip().startswith("vertex")]
    return np.array(rows, dtype=np.float32).astype(np.float64)


def write_stl(path: str, vertices: np.ndarray, faces: np.ndarray) -> None:
    out = np.zeros(len(faces), dtype=TRIANGLE)
    tri = vertices[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    out["n"] = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    out["v"] = tri
    with open(path, "wb") as f:
        f.write(b"convex hull".ljust(80, b"\0") + struct.pack("<I", len(faces)) + out.tobytes())


def main(src: str, dst: str) -> None:
    from scipy.spatial import ConvexHull

    os.makedirs(dst, exist_ok=True)
    for path in sorted(glob.glob(os.path.join(src, "*.stl"))):
        name = os.path.basename(path)
        if name in JAWS:
            continue
        points = read_stl(path)
        hull = ConvexHull(points)
        write_stl(os.path.join(dst, name), points, hull.simplices)
        print(f"{name}: {len(points)} vertices -> {len(hull.vertices)} on the hull, {len(hull.simplices)} triangles")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
