"""The virtual RGB-D camera: renders a scene with PyBullet's TinyRenderer into an :class:`RGBDFrame`.

TinyRenderer (CPU) is used because it needs no GPU and is deterministic. Its optical axis lands at
pixel ``(W / 2, H / 2 - 1)`` for a symmetric frustum (measured, and checked by a test that projects
known points), so the intrinsics handed to perception say exactly that. Shadows are off (they
persist between calls and cost render time; evidence: docs/decisions.md#speed). Depth is converted
from the non-linear depth buffer to metric z-depth, then optionally corrupted with the paper's eq. (8)
noise from the camera's own RNG. A fixed camera's whole view (a dataset's image) renders the scene's
still boxes once and only what moves over them each time (:class:`Backdrop`).
"""

from __future__ import annotations

import numpy as np
import pybullet as p
from pybullet_utils.bullet_client import BulletClient

from pickdemo.core.camera import (
    Intrinsics,
    RGBDFrame,
    add_kinect_noise,
    crop_intrinsics,
    depth_from_buffer,
    depth_noise_coeff,
    look_at_pose,
    opengl_projection_matrix,
    opengl_view_matrix,
    project,
    rendered_intrinsics,
    sensor_faults,
)
from pickdemo.core.geometry import Pose
from pickdemo.scenario.load import CameraSpec, WristCameraSpec
from pickdemo.sim import quiet_c_stdout
from pickdemo.sim.scene import Scene, StillBox

LIGHT_DIRECTION = (0.4, -0.3, 1.0)  # world frame; mostly from above, so faces shade differently


def camera_intrinsics(spec: CameraSpec | WristCameraSpec) -> Intrinsics:
    """The intrinsics of the rendered images, with TinyRenderer's principal point."""
    return rendered_intrinsics(spec.width, spec.height, spec.fov_deg[0], spec.fov_deg[1])


class Camera:
    """A fixed RGB-D camera placed by the scenario."""

    def __init__(
        self,
        spec: CameraSpec,
        rng: np.random.Generator,
        *,
        position: np.ndarray | None = None,
        calibration_error: Pose | None = None,
    ) -> None:
        """``position`` overrides the scenario's (for a camera placement sampled per seed).

        ``calibration_error``: the pose the robot is told is off the true one by this (in the
        camera frame); frames report the told pose, the renderer uses the true one.
        """
        self.spec = spec
        self.intrinsics = camera_intrinsics(spec)
        where = np.array(spec.position) if position is None else np.asarray(position, dtype=float)
        self.T_world_cam_true: Pose = look_at_pose(where, np.array(spec.look_at))
        self.T_world_cam: Pose = (
            self.T_world_cam_true if calibration_error is None else self.T_world_cam_true @ calibration_error
        )  # what the robot is told
        err_mm, err_deg = spec.extrinsic_sigma
        self.calibration_sigma = (err_mm * 1e-3, float(np.radians(err_deg)))
        self.noise_coeff = depth_noise_coeff(spec.depth_noise, self.intrinsics.fx)
        self._view = opengl_view_matrix(self.T_world_cam_true)
        self._proj = opengl_projection_matrix(self.intrinsics, spec.near_m, spec.far_m)
        self._rng = rng
        self._backdrops: dict[tuple[int, int], Backdrop] = {}  # (width, height) -> of _backdrop_scene
        self._backdrop_scene: Scene | None = None

    def _render(
        self, scene: Scene, roi: tuple[int, int, int, int] | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if roi is None:
            w, h, proj = self.spec.width, self.spec.height, self._proj
        else:
            w, h = roi[2] - roi[0], roi[3] - roi[1]
            proj = opengl_projection_matrix(self.intrinsics, self.spec.near_m, self.spec.far_m, roi)
        _, _, rgba, zbuf, seg = scene.client.getCameraImage(
            w,
            h,
            viewMatrix=self._view,
            projectionMatrix=proj,
            shadow=0,
            lightDirection=list(LIGHT_DIRECTION),
            renderer=p.ER_TINY_RENDERER,
        )
        rgb = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3].copy()
        depth = depth_from_buffer(np.asarray(zbuf).reshape(h, w), self.spec.near_m, self.spec.far_m)
        depth[depth >= self.spec.far_m * 0.999] = np.inf  # no return
        return rgb, depth, np.asarray(seg).reshape(h, w)

    on_hand = False  # a camera fixed in the world

    def take(self, scene: Scene, roi: tuple[int, int, int, int] | None, T_world_tcp: Pose | None) -> RGBDFrame:
        """A frame of the region ``roi`` (None: the whole image); a fixed camera ignores the hand's pose."""
        return self.capture(scene, roi)

    def capture(self, scene: Scene, roi: tuple[int, int, int, int] | None = None) -> RGBDFrame:
        """An RGB-D frame as a real sensor would give it (noisy depth if the scenario says so).

        With ``roi = (x0, y0, x1, y1)`` only that region of the image is rendered (at the full
        frame's pixel density, so it holds exactly the pixels ``[y0:y1, x0:x1]`` of the whole frame):
        a 120x120 crop costs about a sixteenth of a 640x480 frame.
        """
        rgb, depth, _ = self._render(scene, roi)
        sp = self.spec
        faults = (sp.depth_holes, sp.depth_edge_dropout, sp.depth_quantum_m, sp.rgb_noise_sigma)
        if sp.depth_noise == "kinect" and not any(faults):  # the original draw order: episodes unchanged
            finite = np.isfinite(depth)
            noisy = depth.copy()
            noisy[finite] = add_kinect_noise(depth[finite], self._rng)
            depth = noisy
        elif sp.depth_noise != "none" or any(faults):
            rgb, depth = sensor_faults(
                rgb,
                depth,
                self._rng,
                noise_coeff=self.noise_coeff if sp.depth_noise != "none" else 0.0,
                holes=sp.depth_holes,
                edge_dropout=sp.depth_edge_dropout,
                invalid=0.0 if sp.depth_invalid == 0.0 else np.nan,
                quantum_m=sp.depth_quantum_m,
                rgb_sigma=sp.rgb_noise_sigma,
            )
        rgb.setflags(write=False)
        depth.setflags(write=False)
        K = self.intrinsics if roi is None else crop_intrinsics(self.intrinsics, roi)
        return RGBDFrame(
            rgb=rgb,
            depth_m=depth,
            intrinsics=K,
            T_world_cam=self.T_world_cam,
            time_s=scene.sim_time_s,
            roi=roi,
            depth_noise_coeff=self.noise_coeff,
            depth_quantum_m=sp.depth_quantum_m,
            calibration_sigma=self.calibration_sigma,
            rgb_noise_sigma=sp.rgb_noise_sigma,
            depth_edge_dropout=sp.depth_edge_dropout,
        )

    def preview_around(
        self, scene: Scene, centre_world: np.ndarray, size_px: tuple[int, int]
    ) -> tuple[np.ndarray, Intrinsics]:
        """The camera's view for a video: a ``size_px`` region at full resolution around a world
        point (clamped to the image), RGB and its intrinsics. No noise: the random stream is untouched."""
        K = self.intrinsics
        w, h = min(size_px[0], K.width), min(size_px[1], K.height)
        uv = project(self.T_world_cam.inverse().transform_points(np.atleast_2d(centre_world)), K)[0]
        x0 = int(np.clip(round(uv[0] - w / 2), 0, K.width - w)) if np.all(np.isfinite(uv)) else (K.width - w) // 2
        y0 = int(np.clip(round(uv[1] - h / 2), 0, K.height - h)) if np.all(np.isfinite(uv)) else (K.height - h) // 2
        roi = (x0, y0, x0 + w, y0 + h)
        rgb, _, _ = self._render(scene, roi)
        return rgb, crop_intrinsics(K, roi)

    def snapshot(
        self, scene: Scene, width: int, height: int, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        """The whole view in ``width`` x ``height`` pixels (a dataset's image; the same field of view), from
        where the camera truly is now: RGB and depth (m; 0 where there is no return), the depth with the
        sensor's noise drawn from ``rng`` (the camera's own random stream, and perception's frames, untouched)."""
        sp = self.spec
        rgb, zbuf = self.whole_view(scene, width, height)
        depth = depth_from_buffer(zbuf, sp.near_m, sp.far_m)
        seen = depth < sp.far_m * 0.999
        if sp.depth_noise != "none":
            depth[seen] = add_kinect_noise(depth[seen], rng)
        depth[~seen] = 0.0
        return rgb, depth.astype(np.float32)

    def whole_view(
        self, scene: Scene, width: int, height: int, *, backdrop: bool = True
    ) -> tuple[np.ndarray, np.ndarray]:
        """The whole view from where the camera truly is, ``width`` x ``height``: RGB and the depth buffer.
        A fixed camera renders the scene's still boxes once (``backdrop``) and what moves each time."""
        sp = self.spec
        K = rendered_intrinsics(width, height, sp.fov_deg[0], sp.fov_deg[1])
        T = scene.true_tcp_pose() @ self.T_tcp_cam_true if self.on_hand else self.T_world_cam_true
        view, proj = opengl_view_matrix(T), opengl_projection_matrix(K, sp.near_m, sp.far_m)
        if self.on_hand or not backdrop or not scene.still_boxes:
            return _tiny_render(scene.client, width, height, view, proj)
        drop = self._backdrops.get((width, height)) if self._backdrop_scene is scene else None
        if drop is None:
            if self._backdrop_scene is not scene:
                self._backdrops, self._backdrop_scene = {}, scene
            drop = self._backdrops[width, height] = Backdrop(scene.still_boxes, width, height, view, proj)
        return drop.under(scene, view, proj)

    def capture_labels(self, scene: Scene) -> tuple[RGBDFrame, np.ndarray]:
        """A noise-free frame and its segmentation (body ids): for tests and labels, never for control."""
        rgb, depth, seg = self._render(scene)
        frame = RGBDFrame(
            rgb=rgb, depth_m=depth, intrinsics=self.intrinsics, T_world_cam=self.T_world_cam, time_s=scene.sim_time_s
        )
        return frame, seg


class WristCamera(Camera):
    """An RGB-D camera on the hand: rendered from the hand's true pose when a frame is taken; each frame
    says the pose the robot knows it by (its kinematics at the joint states then, and its hand-eye
    calibration, off the true mount by the error drawn for the seed)."""

    def __init__(self, spec: WristCameraSpec, rng: np.random.Generator, T_tcp_cam: Pose, hand_eye_error: Pose | None):
        self.spec = spec  # type: ignore[assignment]
        self.intrinsics = camera_intrinsics(spec)
        self.T_tcp_cam_true = T_tcp_cam
        self.T_tcp_cam = T_tcp_cam if hand_eye_error is None else T_tcp_cam @ hand_eye_error  # what the robot is told
        err_mm, err_deg = spec.extrinsic_sigma
        self.calibration_sigma = (err_mm * 1e-3, float(np.radians(err_deg)))
        self.noise_coeff = depth_noise_coeff(spec.depth_noise, self.intrinsics.fx)
        self._proj = opengl_projection_matrix(self.intrinsics, spec.near_m, spec.far_m)
        self._rng = rng
        self.T_world_cam_true = self.T_world_cam = Pose.identity()
        self._view = opengl_view_matrix(self.T_world_cam_true)

    on_hand = True

    def take(self, scene: Scene, roi: tuple[int, int, int, int] | None, T_world_tcp: Pose | None) -> RGBDFrame:
        """A frame of the region ``roi`` with the hand at ``T_world_tcp`` (where the arm's joints put it)."""
        assert T_world_tcp is not None, "a camera on the hand needs the hand's pose"
        return self.capture_from(scene, T_world_tcp, roi)

    def capture_from(self, scene: Scene, T_world_tcp: Pose, roi: tuple[int, int, int, int] | None = None) -> RGBDFrame:
        """A frame from where the hand truly is, told as seen from ``T_world_tcp`` (the robot's
        kinematics at the joint states it reads)."""
        self.T_world_cam_true = scene.true_tcp_pose() @ self.T_tcp_cam_true
        self._view = opengl_view_matrix(self.T_world_cam_true)
        self.T_world_cam = T_world_tcp @ self.T_tcp_cam
        return self.capture(scene, roi)


def _tiny_render(client, width: int, height: int, view: list, proj: list) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """TinyRenderer's RGB (H, W, 3) and depth buffer (H, W, float32 in [0, 1]) of a whole view."""
    _, _, rgba, zbuf, _ = client.getCameraImage(
        width, height, viewMatrix=view, projectionMatrix=proj, shadow=0, lightDirection=list(LIGHT_DIRECTION),
        renderer=p.ER_TINY_RENDERER,
    )  # fmt: skip
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy(), np.asarray(zbuf).reshape(
        height, width
    )


class Backdrop:
    """What a fixed camera sees of the scene's parts that never move (:attr:`Scene.still_boxes`: the table,
    a bin's walls), rendered once, in a world of their own; :meth:`under` renders the rest of the scene
    with them hidden and keeps, pixel by pixel, the nearer of the two.

    TinyRenderer keeps each pixel's nearest surface (on a tie, the body drawn later: the merge gives it to
    what moves) and casts no shadow here, so the two merged are the whole render, pixel for pixel (a
    test checks). The table covers most of a view and costs most of its render: a 224 px frame
    over it costs about 3.7 ms instead of 9.3 (evidence: docs/decisions.md#speed).
    """

    def __init__(self, boxes: list[StillBox], width: int, height: int, view: list, proj: list) -> None:
        self.boxes = boxes
        with quiet_c_stdout():
            own = BulletClient(connection_mode=p.DIRECT)
        try:
            for b in boxes:
                vis = own.createVisualShape(p.GEOM_BOX, halfExtents=list(b.half_extents), rgbaColor=list(b.rgba))
                own.createMultiBody(
                    0.0, -1, vis, basePosition=list(b.position), baseOrientation=list(b.orientation_xyzw)
                )
            self.rgb, self.zbuf = _tiny_render(own, width, height, view, proj)
        finally:
            own.disconnect()

    def under(self, scene: Scene, view: list, proj: list) -> tuple[np.ndarray, np.ndarray]:
        """The whole view: RGB and depth buffer, as :func:`_tiny_render` gives them."""
        h, w = self.zbuf.shape
        c = scene.client
        for b in self.boxes:  # hidden: TinyRenderer skips a body whose alpha is 0
            c.changeVisualShape(b.body, -1, rgbaColor=[*b.rgba[:3], 0.0])
        try:
            rgb, zbuf = _tiny_render(c, w, h, view, proj)
        finally:
            for b in self.boxes:
                c.changeVisualShape(b.body, -1, rgbaColor=list(b.rgba))
        mover = zbuf <= self.zbuf
        return np.where(mover[:, :, None], rgb, self.rgb), np.where(mover, zbuf, self.zbuf)


def render_rgb(scene: Scene, T_world_cam: Pose, K: Intrinsics, near_m: float = 0.05, far_m: float = 5.0) -> np.ndarray:
    """An RGB image of the scene from any pose (a third-person view for a video)."""
    view, proj = opengl_view_matrix(T_world_cam), opengl_projection_matrix(K, near_m, far_m)
    return _tiny_render(scene.client, K.width, K.height, view, proj)[0]
