"""A rerun recording of an episode (``run ... --rerun FILE.rrd``; open it with ``rerun FILE.rrd``).

An observer (:class:`~pickdemo.runtime.observers.Observer`) that logs to its own ``rerun.RecordingStream``
(never the global one), saved to a file, on one simulated-time timeline ``sim``:

- ``world/camera``: the camera's pose (the one the robot is told) and its pinhole; under it
  ``image/rgb`` and ``image/depth`` (metres): the frames perception got, as it got them (a region of
  the image when it asked for one), never rendered again;
- ``world/target/points``: the target's pixels as perception's segmentation finds them, in 3-D;
- ``world/target/features``: the Shi-Tomasi features with their covariance (3-sigma ellipsoids);
- ``world/estimate`` (``world/estimate/rejected``: one perception's own checks rejected) and
  ``world/tracker``: the estimate's and the tracker's poses, with the target's shape;
- ``world/truth``: the target's true pose (for the viewer: the controller never reads it);
- ``world/tcp``: the TCP's true position each tick, and its path at the end; ``tcp/setpoint/*``,
  ``tcp/true/*`` and ``joints/command/q1..q7``: time series; ``phases``: the pick's states as text.

rerun-sdk is an optional extra (the ``rerun`` extra: ``pip install -c .ci/constraints.txt ".[rerun]"`` in
the checkout), imported only when recording.
Recording never changes the episode: no random draw, no render, nothing the controller reads.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import Pose
from pickdemo.core.result import PhaseRecord
from pickdemo.core.shapes import Box, Cylinder
from pickdemo.perception import PerceptionError, PoseEstimate
from pickdemo.perception.segmentation import segment_target, world_heights, world_points
from pickdemo.runtime.observers import Observer
from pickdemo.runtime.view import EpisodeView
from pickdemo.worldmodel import UNKNOWN, SceneView

APP_ID = "pickdemo"
TIMELINE = "sim"
FEATURE_SIGMAS = 3.0  # the features' ellipsoids: this many standard deviations
#: The entities a recording of a pick holds (a test reads them back).
ENTITIES = (
    "/world/camera",
    "/world/camera/image",
    "/world/camera/image/rgb",
    "/world/camera/image/depth",
    "/world/target/points",
    "/world/target/features",
    "/world/estimate",
    "/world/tracker",
    "/world/truth",
    "/world/tcp",
    "/world/tcp/path",
    "/tcp/setpoint/x",
    "/tcp/true/x",
    "/joints/command/q1",
    "/phases",
)
_JOINTS = tuple(f"q{i}" for i in range(1, 8))  # (at most 7: a robot's own arm has as many as it has)


class RecordingUnavailable(RuntimeError):
    """rerun-sdk is not installed."""


def import_rerun() -> Any:
    try:
        import rerun  # optional: pip install -c .ci/constraints.txt ".[rerun]" (in the checkout)
    except ImportError as exc:
        raise RecordingUnavailable(
            'a rerun recording needs rerun-sdk: pip install -c .ci/constraints.txt ".[rerun]" (in the checkout)'
        ) from exc
    return rerun


class RerunRecorder(Observer):
    """Logs the episode to a rerun file as it runs (see the module docstring for what)."""

    timer = "rerun"

    def __init__(self, ep: EpisodeView, path: str | Path) -> None:
        rr = import_rerun()
        self.rr = rr
        self.path = Path(path)
        self.rec = rr.RecordingStream(APP_ID, recording_id=f"{ep.scenario.name}-seed{ep.seed}")
        self.rec.save(str(self.path))
        self.rec.set_log_time_enabled(False)  # one timeline: simulated time
        self.rec.set_log_tick_enabled(False)
        # Per tick, sent as columns when the episode closes (one call per entity, not one per tick).
        self.ticks: list[float] = []
        self.tcp: list[np.ndarray] = []
        self.truth: list[Pose] = []
        self.setpoints: list[tuple[float, np.ndarray]] = []
        self.commands: list[tuple[float, np.ndarray]] = []
        self.tracked: list[tuple[float, Pose]] = []
        self._planned: np.ndarray | None = None  # the planned path last drawn
        model = ep.model
        g = model.geometry
        shapes: tuple = ()  # an object nobody described: its axes only (its shape is what the camera sees)
        if isinstance(g, Box):
            shapes = (rr.Boxes3D(half_sizes=[np.asarray(g.size_m, dtype=float) / 2.0]),)
        elif isinstance(g, Cylinder):
            shapes = (rr.Cylinders3D(lengths=[g.height_m], radii=[g.diameter_m / 2.0]),)
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        for entity in ("world/truth", "world/tracker", "world/estimate", "world/estimate/rejected"):
            self.rec.log(entity, *shapes, rr.TransformAxes3D(0.05), static=True)
        self.rec.log("world/camera", rr.TransformAxes3D(0.05), static=True)
        place = [*ep.world.place_xy, 0.0]
        self.rec.log("world/place", rr.Points3D([place], radii=0.01, labels=["place"]), static=True)

    # ------------------------------------------------------------------------------------- helpers
    def _time(self, t: float) -> None:
        self.rec.set_time(TIMELINE, duration=float(t))

    def _pose(self, entity: str, pose: Pose) -> None:
        self.rec.log(entity, self.rr.Transform3D(translation=pose.position, mat3x3=pose.rotation))

    # --------------------------------------------------------------------------------------- hooks
    def tick(self, ep: EpisodeView, now: float) -> None:

        m = ep.controller
        self.ticks.append(now)
        self.tcp.append(np.array(ep.world.scene.true_tcp_pose().position, dtype=float))
        self.truth.append(ep.world.true_pose(ep.truth_name))  # for the viewer only
        if m.last_sample is not None:
            self.setpoints.append((now, np.array(m.last_sample.setpoint, dtype=float)))
        if ep.last_command is not None:  # this tick's joint command
            self.commands.append((now, np.array(ep.last_command, dtype=float)))
        if m.tracker.initialised:
            tp = m.tracker.predict(now)
            self.tracked.append((now, Pose.from_xyz_rpy(tp.position, yaw=tp.yaw_rad)))
        planned = getattr(m, "planned_path", None)  # a path planned around something, while the arm is on it
        if (planned is None) != (self._planned is None) or (planned is not None and planned is not self._planned):
            self._time(now)
            if planned is None:
                self.rec.log("world/planned_path", self.rr.Clear(recursive=False))
            else:
                self.rec.log("world/planned_path", self.rr.LineStrips3D([planned], radii=0.003, colors=[[80, 255, 80]]))
            self._planned = planned

    def frame(self, ep: EpisodeView, now: float, frame: RGBDFrame, result: PoseEstimate | PerceptionError) -> None:
        rr = self.rr
        self._time(frame.time_s)
        T, K = frame.T_world_cam, frame.intrinsics
        cam = f"world/{frame.camera}"
        self._pose(cam, T)
        self.rec.log(
            f"{cam}/image",
            rr.Pinhole(
                image_from_camera=[[K.fx, 0.0, K.cx], [0.0, K.fy, K.cy], [0.0, 0.0, 1.0]],
                resolution=[K.width, K.height],
                image_plane_distance=0.1,
            ),
        )
        self.rec.log(f"{cam}/image/rgb", rr.Image(np.ascontiguousarray(frame.rgb)))
        depth = np.where(np.isfinite(frame.depth_m), frame.depth_m, 0.0).astype(np.float32)  # 0: no return
        self.rec.log(f"{cam}/image/depth", rr.DepthImage(depth, meter=1.0))
        self.rec.log("world/target/points", rr.Points3D(_target_points(ep, frame, result), radii=0.001))
        self._world(ep)
        estimate = result if isinstance(result, PoseEstimate) else getattr(result, "estimate", None)
        if estimate is None:
            self.rec.log("world/target/features", rr.Clear(recursive=False))
            return
        self._features(estimate)
        entity = "world/estimate" if isinstance(result, PoseEstimate) else "world/estimate/rejected"
        self._pose(entity, estimate.pose)

    def _world(self, ep: EpisodeView) -> None:
        """The controller's world model as it is now: its objects' boxes, labelled with their ids (the
        target's marked), and their points."""
        world = getattr(ep.controller, "world", None)
        if world is None:
            return
        rr = self.rr
        objs = list(world.objects.values())
        if not objs:
            self.rec.log("world/objects", rr.Clear(recursive=True))
            return
        boxes = [o.box for o in objs]
        self.rec.log(
            "world/objects/boxes",
            rr.Boxes3D(
                centers=[b.pose.position for b in boxes],
                half_sizes=[b.hi for b in boxes],
                quaternions=[_quaternion_xyzw(b.pose.rotation) for b in boxes],
                labels=[f"{o.id}{' target' if o.is_target else ''}" for o in objs],
            ),
        )
        pts = [o.points for o in objs if len(o.points)]
        if pts:
            self.rec.log("world/objects/points", rr.Points3D(np.vstack(pts), radii=0.001))
        # the occupancy map on the table: what no view has seen yet (the rest was seen free, or is an object's)
        never = TABLE_GRID[world.classify(TABLE_GRID) == UNKNOWN]
        self.rec.log("world/never_seen", rr.Points3D(never, radii=0.004, colors=[[120, 120, 120]]))

    def _features(self, est: PoseEstimate) -> None:
        rr = self.rr
        if not est.features:
            self.rec.log("world/target/features", rr.Clear(recursive=False))
            return
        centres, halves, quats = [], [], []
        for fp in est.features:
            w, V = np.linalg.eigh(0.5 * (fp.cov_world + fp.cov_world.T))
            if np.linalg.det(V) < 0:
                V[:, 0] = -V[:, 0]
            centres.append(fp.mean_world)
            halves.append(FEATURE_SIGMAS * np.sqrt(np.maximum(w, 0.0)))
            quats.append(_quaternion_xyzw(V))
        self.rec.log("world/target/features", rr.Ellipsoids3D(centers=centres, half_sizes=halves, quaternions=quats))

    def estimate(self, ep: EpisodeView, now: float, taken_s: float, result, status: str) -> None:
        self._time(now)
        what = "estimate" if isinstance(result, PoseEstimate) else f"perception error ({result})"
        self.rec.log("estimates", self.rr.TextLog(f"{what} of the frame at {taken_s:.3f} s: {status}"))

    def phase(self, ep: EpisodeView, record: PhaseRecord) -> None:
        self._time(record.sim_time_s)
        self.rec.log("phases", self.rr.TextLog(f"{record.phase}: {record.message}"))

    def close(self) -> None:
        try:
            self._send_series()
        finally:
            self.rec.flush()
            self.rec.disconnect()

    def _send_series(self) -> None:
        rr, rec = self.rr, self.rec

        def send(entity: str, times: list[float], columns) -> None:
            if times:
                rec.send_columns(entity, indexes=[rr.TimeColumn(TIMELINE, duration=times)], columns=columns)

        def series(prefix: str, names: tuple[str, ...], rows: list[tuple[float, np.ndarray]]) -> None:
            if rows:
                times, values = [t for t, _ in rows], np.array([v for _, v in rows])
                for i, name in enumerate(names):
                    send(f"{prefix}/{name}", times, rr.Scalars.columns(scalars=values[:, i]))

        def poses(entity: str, rows: list[tuple[float, Pose]]) -> None:
            if rows:
                send(entity, [t for t, _ in rows], rr.Transform3D.columns(
                    translation=np.array([p.position for _, p in rows]),
                    mat3x3=np.array([p.rotation for _, p in rows]),
                ))  # fmt: skip

        tcp = np.array(self.tcp).reshape(-1, 3)
        series("tcp/true", ("x", "y", "z"), list(zip(self.ticks, tcp, strict=True)))
        send("world/tcp", self.ticks, rr.Points3D.columns(positions=tcp, radii=np.full(len(tcp), 0.004)))
        if len(tcp) > 1:
            rec.set_time(TIMELINE, duration=float(self.ticks[-1]))
            rec.log("world/tcp/path", rr.LineStrips3D([tcp], radii=0.002))
        series("tcp/setpoint", ("x", "y", "z", "yaw"), self.setpoints)
        dof = len(self.commands[0][1]) if self.commands else 0  # (the robot's own arm: 7, 6 or 5 joints)
        series("joints/command", _JOINTS[:dof], self.commands)
        poses("world/truth", list(zip(self.ticks, self.truth, strict=True)))
        poses("world/tracker", self.tracked)


#: The table's cells the recording shows as never seen (x, y every 2 cm within reach, 1 cm up).
TABLE_GRID = np.array([[x, y, 0.01] for x in np.arange(0.2, 0.81, 0.02) for y in np.arange(-0.45, 0.451, 0.02)])


def _target_points(ep: EpisodeView, frame: RGBDFrame, result: object = None) -> np.ndarray:
    """The target's pixels in 3-D, as perception's segmentation finds them (none: an empty set); of an
    object nobody described, its cloud; of a clear round's survey, every object's it showed."""

    none = np.zeros((0, 3))
    if isinstance(result, SceneView):  # a clear round's survey: every object it showed
        return np.vstack([i.points for i in result.instances]) if result.instances else none
    estimate = result if isinstance(result, PoseEstimate) else getattr(result, "estimate", None)
    if estimate is not None and estimate.cloud is not None:
        return estimate.cloud.points
    model = ep.controller.model if ep.controller is not None else ep.model
    if model.color is None:
        return none
    try:
        mask = segment_target(frame, model, ep.perception, world_heights(frame))
    except PerceptionError:
        return np.zeros((0, 3))
    pts = world_points(frame)[mask]
    return pts[np.all(np.isfinite(pts), axis=1)]


def _quaternion_xyzw(R: np.ndarray) -> np.ndarray:
    """A rotation matrix's unit quaternion (x, y, z, w)."""

    return np.asarray(Pose(np.zeros(3), R).quaternion_xyzw, dtype=float)
