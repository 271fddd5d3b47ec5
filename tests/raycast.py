"""Frames ray-cast here, no simulator: boxes standing on the table (z = 0) and the table, seen by one
camera (shared by the perception and clearing tests)."""

from __future__ import annotations

import dataclasses

import numpy as np

from pickdemo.core.camera import Intrinsics, RGBDFrame, look_at_pose
from pickdemo.core.geometry import Pose

K = Intrinsics.from_fov(320, 240, 57.0, 43.0)
T_CAM = look_at_pose(np.array([1.0, 0.0, 0.7]), np.array([0.5, 0.0, 0.0]))


@dataclasses.dataclass(frozen=True)
class Block:
    centre_xy: tuple[float, float]
    size: tuple[float, float, float]
    yaw_deg: float = 0.0
    rgb: tuple[int, int, int] = (200, 180, 40)


def render(blocks: list[Block], *, T: Pose = T_CAM, noise: float = 0.0, seed: int = 0) -> RGBDFrame:
    """Ray-cast boxes standing on the table (z = 0) and the table itself: RGB and z-depth."""
    v, u = np.mgrid[0 : K.height, 0 : K.width].astype(float)
    dirs_cam = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u)], axis=-1)
    dirs = dirs_cam @ T.rotation.T
    o = T.position
    t_best = np.where(dirs[..., 2] < 0, -o[2] / np.minimum(dirs[..., 2], -1e-12), np.inf)
    rgb = np.zeros((*u.shape, 3), dtype=np.uint8)
    rgb[...] = (140, 100, 70)
    for b in blocks:
        c, s = np.cos(np.radians(b.yaw_deg)), np.sin(np.radians(b.yaw_deg))
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        centre = np.array([*b.centre_xy, b.size[2] / 2.0])
        ol = R.T @ (o - centre)
        dl = dirs @ R  # each ray in the box's frame
        half = np.array(b.size) / 2.0
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-half - ol) / dl
            t2 = (half - ol) / dl
        t_near = np.max(np.minimum(t1, t2), axis=-1)
        t_far = np.min(np.maximum(t1, t2), axis=-1)
        hit = (t_near <= t_far) & (t_near > 0) & (t_near < t_best)
        t_best = np.where(hit, t_near, t_best)
        rgb[hit] = b.rgb
    depth = t_best * dirs_cam[..., 2]  # z-depth
    if noise > 0:
        depth = depth + np.random.default_rng(seed).normal(0.0, noise * depth**2)
    return RGBDFrame(rgb=rgb, depth_m=depth, intrinsics=K, T_world_cam=T, time_s=0.0)
