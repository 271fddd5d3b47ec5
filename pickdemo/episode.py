"""One episode, wired: scenario -> scene -> the control loop -> metrics -> :class:`EpisodeResult`.

The control loop here (:meth:`_Episode.loop`) is the only place that advances simulated time, one
control tick at a time. Each tick: observe (joint states, finger opening, finger contacts), hand over
the estimates whose latency has passed, decide (:class:`pickdemo.pick.PickMachine`), command, take
a camera frame when one is due (rendering only the region perception asked for), then step the
physics. The step budget lives here: the scenario's simulated-time budget, counted in steps.

The controller acts only on the camera frames (RGB, depth, intrinsics, camera pose) and the joint
states. The simulator's true poses are read here for scoring and the trace only. Every random draw
comes from one generator per stage (:mod:`pickdemo.streams`), so one seed makes one episode, bit for
bit.
"""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from pickdemo.camera import calibration_error, look_at_pose, rendered_intrinsics
from pickdemo.geometry import Pose, wrap_angle
from pickdemo.kinematics import panda_kinematics
from pickdemo.layout import LayoutError, Placement, camera_position, sample_layout
from pickdemo.metrics import score_perception, score_place
from pickdemo.perception import PerceptionError, PerceptionParams, PoseEstimate, TargetModel, estimate_pose
from pickdemo.pick import TRACKING_STATES, CameraModel, FrameRequest, MachineParams, PickMachine, State
from pickdemo.result import (
    EpisodeFailure,
    EpisodeResult,
    EpisodeTrace,
    Failure,
    PerceptionScore,
    PhaseRecord,
    Stage,
    limit_exceedances,
)
from pickdemo.scenario import Scenario
from pickdemo.streams import spawn_rngs
from pickdemo.task import target_model

PhaseCallback = Callable[[PhaseRecord], None]  # each state entered (and each note), as it happens

SETTLE_MAX_S = 2.0  # the objects come to rest before the first look, within this
CARRY_STATES = frozenset({State.LIFT, State.TRANSPORT, State.LOWER})
#: The video's third-person view: from the front left, above the table, far enough back that the whole
#: arm stays in view (fitted to the link frames of several episodes, with 8 cm for the links' bulk).
THIRD_PERSON_POSE = look_at_pose(np.array([1.22, -0.92, 0.82]), np.array([0.2, 0.08, 0.26]))
THIRD_PERSON_K = rendered_intrinsics(256, 192, 60.0, 46.8)  # shown at 320x240: most of the cost is its rendering
VIDEO_CROP_PX = (160, 120)  # the camera's view in the video: this much around the target, shown twice the size


@dataclass(frozen=True)
class EpisodeOptions:
    gui: bool = False
    open_loop: bool = False  # look once and play the plan (no perception while moving)
    perception: PerceptionParams = PerceptionParams()
    perception_method: str = "paper"  # or "icp", "centroid", "pixel", "module:function" (pickdemo.estimators)
    machine: MachineParams = MachineParams()
    record_trace: bool = False  # keep the per-tick trace (EpisodeResult.trace)
    video_path: str | None = None  # write the episode's video here (needs PyAV: the video extra)
    video_fps: int = 10
    debug_draw: bool = False  # draw the overlays as debug lines (always with gui)


def run_episode(
    scenario: Scenario,
    seed: int,
    *,
    options: EpisodeOptions | None = None,
    open_loop: bool | None = None,
    on_phase: PhaseCallback | None = None,
) -> EpisodeResult:
    """Run one seeded episode of a scenario headless (or in the GUI) and score it.

    ``open_loop=True`` (or ``options.open_loop``) looks once and plays the plan, for comparison.
    Never raises for an episode that goes wrong: the result names the stage and the reason.
    """
    options = options or EpisodeOptions()
    if open_loop is not None:
        options = dataclasses.replace(options, open_loop=open_loop)
    return _Episode(scenario, seed, options, on_phase).run()


class _Timer:
    def __init__(self) -> None:
        self.times: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - t0


def yaw_symmetry(shape: str, size: tuple[float, ...]) -> float:
    """The turn (rad) after which the shape looks the same about its axis (0: any turn, a cylinder)."""
    if shape == "cylinder":
        return 0.0
    return np.pi / 2.0 if abs(size[0] - size[1]) < 1e-9 else np.pi


@dataclass
class _Record:
    """What the loop measures as it runs (typed; turned into the frozen result at the end)."""

    phases: list[PhaseRecord] = field(default_factory=list)
    frames: int = 0
    tracking_frames: int = 0  # frames taken while tracking (approach, descend, close, back off)
    tracking_ticks: int = 0
    tick_ms: list[float] = field(default_factory=list)
    perception: PerceptionScore | None = None  # the first estimate against the truth
    tracking_error_mm: float | None = None
    tracking_yaw_deg: float | None = None
    start_pose: Pose | None = None
    max_z_m: float | None = None  # highest the target got while carried
    place_error_mm: float | None = None
    wrong_estimates: int = 0  # estimates more than 5 mm off the truth that reached the controller
    wrong_estimates_accepted: int = 0  # of those, how many it acted on (fused into its belief)
    wrong_estimates_self_rejected: int = 0  # of those, how many perception's own fit check rejected
    off_table: bool | None = None  # the target ended off the table (fell, or was knocked off)
    trace_rows: list[tuple] = field(default_factory=list)
    commanded: list[tuple[float, np.ndarray]] = field(default_factory=list)  # (t, joint command) per tick


class _Episode:
    """One episode's world, controller and loop."""

    def __init__(self, scenario: Scenario, seed: int, options: EpisodeOptions, on_phase: PhaseCallback | None):
        self.scenario = scenario
        self.seed = seed
        self.options = options
        self.on_phase = on_phase
        self.rngs = spawn_rngs(seed)
        self.timer = _Timer()
        self.rec = _Record()
        self.scene = None
        self.machine: PickMachine | None = None
        self.pushes: list = []
        self._events_logged = 0
        self.video = None
        self.debug = None
        self.last_estimate: PoseEstimate | None = None
        self.last_estimate_s = -np.inf  # when the frame of the newest estimate was taken (the video's)

    # ========================================================================================= run
    def run(self) -> EpisodeResult:
        wall0 = time.perf_counter()
        failure: Failure | None = None
        try:
            self.build()
            self.loop()
            self.score()
        except EpisodeFailure as exc:
            failure = exc.failure
        except Exception as exc:  # noqa: BLE001 - one bad episode must not take a batch down
            failure = Failure(Stage.ERROR, f"{type(exc).__name__}: {exc}".splitlines()[0])
        finally:
            sim_time = self.scene.sim_time_s if self.scene is not None else 0.0
            if self.scene is not None and self.rec.start_pose is not None:
                self.rec.off_table = self._off_table()
            if self.video is not None:
                with self.timer("video"):
                    self.video.close()
            if self.scene is not None:
                self.scene.close()
        if failure is not None and not (self.rec.phases and self.rec.phases[-1].phase == State.FAILED.value):
            self._phase(PhaseRecord(State.FAILED.value, round(sim_time, 6), f"{failure.stage.value}: {failure.reason}"))
        return self.result(failure, sim_time, time.perf_counter() - wall0)

    # ======================================================================================= build
    def build(self) -> None:
        from pickdemo.sim.controller import RobotInterface  # simulator side, imported late
        from pickdemo.sim.render import Camera
        from pickdemo.sim.scene import Scene

        sc = self.scenario
        if len(sc.targets) != 1:
            raise EpisodeFailure(Stage.ERROR, f"a pick needs exactly one target; the scenario has {len(sc.targets)}")
        try:
            layout = sample_layout(sc, self.rngs["layout"])
        except LayoutError as exc:
            raise EpisodeFailure(Stage.ERROR, str(exc)) from None
        from pickdemo.estimators import EstimatorError, resolve_estimator

        method = self.options.perception_method
        if method == "paper":
            perception = self.options.perception
            self.estimate = lambda frame, model: estimate_pose(frame, model, perception)
        else:
            try:
                self.estimate = resolve_estimator(method)
            except EstimatorError as exc:
                raise EpisodeFailure(Stage.PERCEPTION, str(exc)) from None
        self.target_name = sc.target.name
        self.placement: Placement = next(p for p in layout if p.name == self.target_name)
        self.model: TargetModel = target_model(sc, self.placement)
        with self.timer("scene"):
            self.scene = Scene(sc, layout, gui=self.options.gui)
            where = camera_position(sc.camera, self.rngs["camera_pose"])
            error = calibration_error(*sc.camera.extrinsic_error, self.rngs["calibration"])
            self.camera = Camera(sc.camera, self.rngs["camera"], position=where, calibration_error=error)
            self.robot = RobotInterface(self.scene)
            kin = panda_kinematics()
        dt = self.scene.time_step_s
        self.substeps = max(1, round(1.0 / (sc.control.control_rate_hz * dt)))
        self.dt_ctl = self.substeps * dt
        self.max_steps = int(round(sc.sim.max_sim_time_s / dt))
        self.frame_ticks = max(1, round(1.0 / (sc.control.perception_rate_hz * self.dt_ctl)))
        self.video_ticks = max(1, round(1.0 / (self.options.video_fps * self.dt_ctl)))
        if self.options.gui or self.options.debug_draw:
            from pickdemo.sim.debug import DebugDraw

            self.debug = DebugDraw(self.scene)
        if self.options.video_path is not None:
            from pickdemo.video import VideoWriter

            self.video = VideoWriter(self.options.video_path, fps=round(1.0 / (self.video_ticks * self.dt_ctl)))
        with self.timer("settle"):
            self.scene.settle(int(SETTLE_MAX_S / dt))
        self.scene.start_belt()  # a conveyor runs from the robot's first tick
        self.rec.start_pose = self.scene.true_pose(self.target_name)  # truth: for scoring only
        self.rec.max_z_m = float(self.rec.start_pose.position[2])
        params = self.options.machine
        if sc.conveyor is not None:  # the cell has a belt: targets may move, at an unknown speed
            params = params.on_a_belt()
        m = sc.motion
        scales = (m.velocity_scale, m.acceleration_scale, m.jerk_scale)
        if scales != (1.0, 1.0, 1.0):
            params = dataclasses.replace(
                params, near=params.near.scaled_by(*scales), free=params.free.scaled_by(*scales)
            )
        self.machine = PickMachine(
            kin=kin,
            model=self.model,
            symmetry_rad=yaw_symmetry(self.model.shape, self.model.size),
            place_xy=sc.place.position,
            camera=CameraModel(self.camera.intrinsics, self.camera.T_world_cam),
            q0=self.robot.observe().arm_q,
            dt_s=self.dt_ctl,
            rng=self.rngs["ik"],
            max_attempts=sc.control.max_attempts,
            open_loop=self.options.open_loop,
            params=params,
            surface_z=sc.surface_z,
        )

    # ======================================================================================== loop
    def loop(self) -> None:
        """The control loop: one tick at a time until the machine is done, failed or out of time."""
        assert self.machine is not None and self.scene is not None
        machine, scene = self.machine, self.scene
        # (arrival, taken, result, its error against the truth then in mm: for scoring only)
        pending: deque[tuple[float, float, PoseEstimate | PerceptionError, float | None]] = deque()
        last_frame_tick = -(10**9)
        tick = 0
        while not machine.finished:
            if scene.steps + self.substeps > self.max_steps:
                budget = self.scenario.sim.max_sim_time_s
                machine.abort(Stage.TIMEOUT, f"simulated-time budget of {budget:.1f} s spent in {machine.state.value}")
                break
            now = scene.sim_time_s
            obs = self.robot.observe()
            while pending and pending[0][0] <= now + 1e-9:
                _, taken, result, error_mm = pending.popleft()
                status = machine.on_estimate(result, taken)
                if isinstance(result, PoseEstimate):
                    self.last_estimate, self.last_estimate_s = result, taken
                if error_mm is not None and error_mm > PERCEPTION_OFF_MM and status != "unused":
                    self.rec.wrong_estimates += 1
                    self.rec.wrong_estimates_accepted += status == "accepted"
                    self.rec.wrong_estimates_self_rejected += isinstance(result, PerceptionError)
            t0 = time.perf_counter()
            cmd = machine.update(obs)
            self.rec.tick_ms.append((time.perf_counter() - t0) * 1e3)
            self._log_events(now)
            if machine.finished:
                break
            self.robot.apply(cmd)
            self.rec.commanded.append((now, cmd.arm_q))  # always: result.json's limit_exceedances
            tracking = machine.state in TRACKING_STATES
            self.rec.tracking_ticks += tracking
            due = tick - last_frame_tick >= self.frame_ticks  # asked only then: a region costs a prediction
            request = machine.frame_request(now) if due else None
            if request is not None:
                last_frame_tick = tick
                result = self._look(request, now)
                error_mm = None
                # Truth: for scoring only (an estimate that perception's own checks rejected included).
                scored = result.estimate if isinstance(result, PerceptionError) else result
                if scored is not None:
                    truth = scene.true_pose(self.target_name).position
                    error_mm = float(np.linalg.norm(scored.pose.position - truth)) * 1e3
                pending.append((now + self.scenario.control.perception_latency_s, now, result, error_mm))
                self.rec.tracking_frames += tracking
            if self.options.record_trace:
                self._trace(now)
            if self.video is not None and tick % self.video_ticks == 0:
                with self.timer("video"):
                    self._video_frame(now)
            if self.debug is not None and tick % self.video_ticks == 0:
                self.debug.draw(self._overlay(now))
            with self.timer("physics"):
                for _ in range(self.substeps):
                    for push in self.pushes:
                        push.step(scene)
                    scene.step()
            if machine.state in CARRY_STATES:  # truth: how high it was carried, for scoring
                self.rec.max_z_m = max(self.rec.max_z_m, float(scene.true_pose(self.target_name).position[2]))
            tick += 1
        self._log_events(scene.sim_time_s)
        if self.video is not None:  # the last frame: how it ended (and what the verifying look saw)
            with self.timer("video"):
                self._video_frame(scene.sim_time_s)
        if machine.failure is not None:
            raise EpisodeFailure(machine.failure.stage, machine.failure.reason)

    def _look(self, request: FrameRequest, now: float) -> PoseEstimate | PerceptionError:
        """Render the requested frame and run perception on it (its result is delivered later)."""
        from pickdemo.sim.disturb import PushPlayer, draw_push

        with self.timer("render"):
            frame = self.camera.capture(self.scene, request.roi)
        with self.timer("perceive"):
            try:
                result: PoseEstimate | PerceptionError = self.estimate(frame, self.model)
                if not isinstance(result, PoseEstimate):
                    raise TypeError(f"the perception method returned {type(result).__name__}, not a PoseEstimate")
            except PerceptionError as exc:
                result = exc
        self.rec.frames += 1
        if self.rec.perception is None and isinstance(result, PoseEstimate):
            truth = self.scene.true_pose(self.target_name)  # truth: for scoring only
            self.rec.perception = score_perception(result, truth)
        if self.rec.frames == 1:  # the first look: disturbances are timed from here
            self.pushes = [
                PushPlayer(draw_push(d, now, self.rngs["disturbance"]), self.target_name)
                for d in self.scenario.disturbances
            ]
        return result

    def _log_events(self, now: float) -> None:
        assert self.machine is not None
        for ev in self.machine.events[self._events_logged :]:
            self._phase(PhaseRecord(ev.state.value, round(ev.time_s, 6), ev.message))
            if ev.state is State.CLOSE and not ev.note:  # committing: the tracker against the truth
                truth = self.scene.true_pose(self.target_name)
                tp = self.machine.tracker.predict(now)
                self.rec.tracking_error_mm = float(np.linalg.norm(tp.position - truth.position)) * 1e3
                if self.machine.symmetry > 0:
                    dyaw = wrap_angle(tp.yaw_rad - float(truth.rpy[2]), self.machine.symmetry)
                    self.rec.tracking_yaw_deg = float(abs(np.degrees(dyaw)))
        self._events_logged = len(self.machine.events)

    def _overlay(self, now: float):
        """What the video and the GUI draw now: the estimate of the newest frame (none once
        perception no longer looks), the truth (a label), the tracker's belief and path while it
        tracks, the chosen grasp until the gripper closes, and a caption."""
        from pickdemo.video import GRASP_STATES, TRACKER_STATES, Overlay

        m = self.machine
        tracked = path = None
        # An estimate is current until a frame after it is due (the frame period, plus its latency).
        max_age = self.scenario.control.perception_latency_s + 1.5 * self.frame_ticks * self.dt_ctl
        fresh = now - self.last_estimate_s <= max_age
        if m.tracker.initialised and m.state.value in TRACKER_STATES:
            tp = m.tracker.predict(now)
            tracked = tp.position
            path = tp.position + np.linspace(0.0, 1.0, 11)[:, None] * tp.velocity
        plan = m.plan
        overlay = Overlay(
            caption=f"{m.state.value}  |  t = {now:5.2f} s  |  attempt {m.attempt}"
            + ("  |  open loop" if self.options.open_loop else ""),
            estimate=self.last_estimate if fresh else None,
            truth=self.scene.true_pose(self.target_name),  # a label for the viewer
            tracked=tracked,
            tracked_path=path,
            grasp=None if plan is None or m.state.value not in GRASP_STATES else plan.grasp,
            grasp_width_m=0.0 if plan is None else plan.object_width_m,
        )
        return overlay

    def _video_frame(self, now: float) -> None:
        """One frame of the video: a third-person view beside the camera's, perception drawn on it."""
        from pickdemo.sim.render import render_rgb
        from pickdemo.video import compose, draw_overlay, magnify, panel_centre

        overlay = self._overlay(now)
        m = self.machine
        tracked = m.tracker.predict(now).position if m.tracker.initialised else None
        hand = None if m.last_sample is None else np.asarray(m.last_sample.setpoint[:3], dtype=float)
        place = np.array([*self.scenario.place.position, self.model.height_m / 2.0])
        centre = panel_centre(m.state.value, tracked=tracked, hand=hand, place=place)
        if centre is None:  # nothing to follow yet: the middle of the camera's image
            centre = np.full(3, np.nan)
        view, K = self.camera.preview_around(self.scene, centre, VIDEO_CROP_PX)
        view, K = magnify(view, K, 2)
        right = draw_overlay(view, K, self.camera.T_world_cam, overlay)
        left = render_rgb(self.scene, THIRD_PERSON_POSE, THIRD_PERSON_K)
        self.video.add(compose(left, right, overlay.caption))

    def _phase(self, record: PhaseRecord) -> None:
        self.rec.phases.append(record)
        if self.on_phase is not None:
            self.on_phase(record)

    def _trace(self, now: float) -> None:
        m = self.machine
        s = m.last_sample
        v, a, j = m.motion.limits.arrays()
        tracked = None
        if m.tracker.initialised:
            tp = m.tracker.predict(now)
            tracked = np.array([*tp.position, tp.yaw_rad])
        tcp = self.scene.true_tcp_pose().position
        self.rec.trace_rows.append(
            (now, m.state.value, s.setpoint, s.velocity, s.acceleration, s.jerk, v, a, j, s.new_calculation, s.q,
             tcp, tracked)
        )  # fmt: skip

    # ===================================================================================== scoring
    def _off_table(self) -> bool:
        """Whether the target ended off the table: below its top, or beyond its edges (the truth)."""
        final = self.scene.true_pose(self.target_name)
        x, y, z = final.position
        return bool(z < -0.005 or not self.scenario.table.holds(float(x), float(y)))

    def score(self) -> None:
        """Success, scored on the truth: lifted high enough, put down where asked, upright and at rest."""
        sc = self.scenario
        final = self.scene.true_pose(self.target_name)  # truth: for scoring only
        outcome = score_place(
            start=self.rec.start_pose,
            max_z_m=self.rec.max_z_m,
            final=final,
            final_speed_m_s=self.scene.true_speed(self.target_name),
            place_xy=sc.place.position,
            shape=self.placement.shape,
            size=self.placement.size,
            lift_height_m=sc.success.lift_height,
            place_tolerance_m=sc.success.place_tolerance,
        )
        self.rec.place_error_mm = outcome.place_error_m * 1e3
        if not outcome.success:
            stage = Stage.LIFT if outcome.lifted_m < sc.success.lift_height else Stage.PLACE
            raise EpisodeFailure(stage, outcome.reason)

    def result(self, failure: Failure | None, sim_time_s: float, wall_time_s: float) -> EpisodeResult:
        rec, m = self.rec, self.machine
        ticks = np.array(rec.tick_ms) if rec.tick_ms else np.zeros(1)
        lifted = None
        if m is not None and m.attempts and rec.start_pose is not None:
            lifted = (rec.max_z_m - float(rec.start_pose.position[2])) * 1e3
        return EpisodeResult(
            scenario=self.scenario.name,
            seed=self.seed,
            success=failure is None,
            failure=failure,
            perception=rec.perception,
            place_error_mm=rec.place_error_mm,
            lift_height_mm=lifted,
            grasp_width_mm=None if m is None or m.grasp_width_m is None else m.grasp_width_m * 1e3,
            sim_time_s=sim_time_s,
            wall_time_s=wall_time_s,
            stage_wall_times_s={k: round(v, 6) for k, v in self.timer.times.items()},
            phases=tuple(rec.phases),
            open_loop=self.options.open_loop,
            attempts=tuple(m.attempts) if m is not None else (),
            perception_frames=rec.frames,
            perception_rate_hz=rec.tracking_frames / (rec.tracking_ticks * self.dt_ctl) if rec.tracking_ticks else None,
            estimates_rejected=m.counters.rejected if m is not None else 0,
            perception_failures=m.counters.perception_errors if m is not None else 0,
            target_moves_detected=m.counters.jumps if m is not None else 0,
            retargets=m.counters.retargets if m is not None else 0,
            tracking_error_mm=rec.tracking_error_mm,
            tracking_yaw_error_deg=rec.tracking_yaw_deg,
            diagnosis=diagnose(failure, rec.tracking_error_mm),
            estimates_off=rec.wrong_estimates,
            estimates_off_accepted=rec.wrong_estimates_accepted,
            estimates_off_fit_rejected=rec.wrong_estimates_self_rejected,
            target_off_table=rec.off_table,
            perception_method=self.options.perception_method,
            disturbances=tuple(p.push.to_dict() for p in self.pushes),
            control_tick_wall_ms={
                "median": float(np.median(ticks)),
                "p95": float(np.percentile(ticks, 95)),
                "ticks": len(rec.tick_ms),
            },
            limit_exceedances=tuple(e.to_dict() for e in _exceedances(rec.commanded)),
            trace=_freeze_trace(rec.trace_rows) if self.options.record_trace else None,
        )


#: Above this, the tracker's belief was off when the robot committed to the grasp (scored on the truth).
PERCEPTION_OFF_MM = 5.0


def diagnose(failure: Failure | None, tracking_error_mm: float | None) -> str | None:
    """For a failed episode, from the truth (for reading, never for control): was perception off
    when the robot committed to the grasp? ``perception_off``, ``perception_ok`` (the failure lies
    elsewhere), or ``not_committed`` (it never closed the gripper)."""
    if failure is None:
        return None
    if tracking_error_mm is None:
        return "not_committed"
    return "perception_off" if tracking_error_mm > PERCEPTION_OFF_MM else "perception_ok"


def _exceedances(commanded: list[tuple[float, np.ndarray]]):
    """The joint command's excursions beyond the datasheet limits (as the motion plot marks them)."""
    if len(commanded) < 4:
        return []
    t, q = zip(*commanded, strict=True)
    return limit_exceedances(np.array(t, dtype=float), np.array(q, dtype=float).reshape(-1, 7))


def _freeze_trace(rows: list[tuple]) -> EpisodeTrace:
    """The per-tick rows as arrays."""
    nan4 = np.full(4, np.nan)
    cols = list(zip(*rows, strict=True)) if rows else [()] * 13

    def arr(i: int, width: int) -> np.ndarray:
        return np.array(cols[i], dtype=float).reshape(-1, width)

    return EpisodeTrace(
        time_s=np.array(cols[0], dtype=float),
        state=tuple(cols[1]),
        setpoint=arr(2, 4),
        velocity=arr(3, 4),
        acceleration=arr(4, 4),
        jerk=arr(5, 4),
        max_velocity=arr(6, 4),
        max_acceleration=arr(7, 4),
        max_jerk=arr(8, 4),
        retarget=np.array(cols[9], dtype=bool),
        q=arr(10, 7),
        tcp_true=arr(11, 3),
        tracked=np.array([nan4 if t is None else t for t in cols[12]], dtype=float).reshape(-1, 4),
    )
