"""Make the Unitree Z1 gripper's convex decompositions (``files/z1/*_vhacd.obj``), once.

PyBullet collides a link's mesh as its convex hull: the fixed jaw's link (the gripper's body and the
jaw under it) and the moving jaw's (bent) are far from convex, and their hulls filled the space
between the jaws. This writes each as PyBullet's V-HACD decomposition (100,000 voxels: 13 and 4
convex parts) from example-robot-data's collision STL. Run: ``python tests/robot/z1_decompose.py`` (a few seconds).
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.dirname(__file__))
from so101_hulls import read_stl  # noqa: E402 - (a script beside this one)

from pickdemo.robot.urdf_files import _erd_share_dirs  # noqa: E402

MESHES = {"z1_GripperStator.STL": "gripper_stator_vhacd.obj", "z1_GripperMover.STL": "gripper_mover_vhacd.obj"}
OUT = Path(__file__).resolve().parent / "files" / "z1"


def main() -> None:
    share = next(d for d in _erd_share_dirs() if (d / "robots/z1_description").is_dir())
    client = p.connect(p.DIRECT)
    with tempfile.TemporaryDirectory() as tmp:
        for stl, out in MESHES.items():
            points = read_stl(str(share / "robots/z1_description/meshes/collision" / stl))
            vertices, index = np.unique(points, axis=0, return_inverse=True)
            obj = os.path.join(tmp, stl.replace(".STL", ".obj"))  # (V-HACD reads OBJ)
            with open(obj, "w") as f:
                f.writelines(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in vertices)
                f.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in index.reshape(-1, 3))
            log = os.path.join(tmp, "vhacd.log")
            p.vhacd(obj, str(OUT / out), log, resolution=100_000, physicsClientId=client)
            print(f"{stl}: {len(vertices)} vertices -> {OUT / out}")
    p.disconnect(client)


if __name__ == "__main__":
    main()
