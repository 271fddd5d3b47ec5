"""Measurement (not a test): where on a bin's floor the robot's hand can grasp a box of a given size,
top-down or from any side, with the bin's walls known (no simulator: the grasp samplers on a box's
seen faces, the walls' faces as obstacles, as a clear round asks them).

    python tests/bin_reach.py [--scenario clear_bin] [--size 0.05,0.045,0.016] [--robot panda]

Prints a map of the floor, 2 cm a cell (rows: y, high first; columns: x, low first; the walls' 3 cm
left out): ``T`` a top-down grasp fits, ``A`` only one from any side, ``.`` none; and the share of
cells with a grasp. The hand's body (the Panda's: 21 cm along its closing axis, its palm 3.4 cm above
the pads' middle) must pass above the walls or between them.
"""

from __future__ import annotations

import argparse

import numpy as np

from pickdemo.core.geometry import Pose, box_surface_points
from pickdemo.grasping.antipodal import sample_antipodal
from pickdemo.grasping.cloud import sample_grasps
from pickdemo.grasping.top_down import GraspParams
from pickdemo.perception import ObjectCloud
from pickdemo.robot import robot_named
from pickdemo.scenario.fixtures import fixture_boxes
from pickdemo.scenario.load import load_scenario

#: the walls' faces this near the object (m) are obstacles, as a clear round takes them
NEAR_M = 0.2


def box_faces(size: np.ndarray, centre: np.ndarray, yaw_rad: float) -> np.ndarray:
    """Points 2 mm apart on a box's faces but its bottom, standing at ``centre`` (x, y, floor z)."""
    faces = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        gu, gv = np.meshgrid(*(np.arange(-size[a] / 2.0, size[a] / 2.0 + 1e-9, 0.002) for a in (u, v)))
        for side in (-size[axis] / 2.0, size[axis] / 2.0):
            if axis == 2 and side < 0:
                continue
            face = np.zeros((gu.size, 3))
            face[:, u], face[:, v], face[:, axis] = gu.ravel(), gv.ravel(), side
            faces.append(face)
    pose = Pose.from_xyz_rpy(centre + np.array([0.0, 0.0, size[2] / 2.0]), yaw=yaw_rad)
    return pose.transform_points(np.vstack(faces))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="clear_bin")
    ap.add_argument("--size", default="0.05,0.045,0.016", help="the box's x, y, z extents (m)")
    ap.add_argument("--yaw-deg", type=float, default=15.0)
    ap.add_argument("--robot", default=None, help="a shipped robot or a robot file (default: the scenario's)")
    args = ap.parse_args()
    sc = load_scenario(args.scenario)
    bins = [f for f in sc.fixtures if f.kind == "bin"]
    if not bins:
        raise SystemExit(f"bin_reach: {args.scenario} has no bin")
    b = bins[0]
    walls = box_surface_points(fixture_boxes(tuple(sc.fixtures)))
    gripper = robot_named(args.robot or sc.robot).gripper
    size = np.array([float(v) for v in args.size.split(",")])
    floor = sc.surface_z(b.position[0], b.position[1])
    ix, iy = b.inner_size[0] / 2.0 - 0.03, b.inner_size[1] / 2.0 - 0.03
    yaw = np.radians(b.yaw_deg)
    rows, fits = [], 0
    for dy in np.arange(-iy, iy + 1e-9, 0.02):
        row = ""
        for dx in np.arange(-ix, ix + 1e-9, 0.02):
            at = np.array([*Pose.from_xyz_rpy(np.zeros(3), yaw=yaw).transform_points(np.array([[dx, dy, 0.0]]))[0]])
            centre = np.array([b.position[0] + at[0], b.position[1] + at[1], floor])
            pts = box_faces(size, centre, np.radians(args.yaw_deg) + yaw)
            near = walls[np.hypot(walls[:, 0] - centre[0], walls[:, 1] - centre[1]) < NEAR_M]
            if sample_grasps(ObjectCloud(pts, near, 0.0), floor, gripper, GraspParams()):
                row += "T"
            elif sample_antipodal(pts, floor, gripper, np.random.default_rng(0), obstacles=near, grasp=GraspParams()):
                row += "A"
            else:
                row += "."
        fits += sum(c != "." for c in row)
        rows.append(row)
    cells = sum(len(r) for r in rows)
    print(f"{sc.name}: a {' x '.join(f'{v * 100:.1f}' for v in size)} cm box on the bin's floor, 2 cm a cell")
    for r in rows[::-1]:
        print("  " + r)
    print(f"a grasp fits in {fits} of {cells} cells ({100.0 * fits / cells:.0f} %)")


if __name__ == "__main__":
    main()
