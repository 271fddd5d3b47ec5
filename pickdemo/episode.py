"""One episode, wired: scenario -> scene -> the control loop -> metrics -> :class:`EpisodeResult`.

The control loop here is the only place that advances simulated time, one control tick at a time.
Each tick: observe (joint states, finger opening, finger contacts), hand over the estimates whose
latency has passed, decide (:class:`pickdemo.pick.PickMachine`), command, take a camera frame when
one is due (rendering only the region perception asked for), then step the physics. The step budget
lives here: the scenario's simulated-time budget, counted in ticks.

The controller acts only on the camera frames (RGB, depth, intrinsics, camera pose) and the joint
states. The simulator's true poses are read here for scoring and the trace only. Every random draw
comes from one generator per stage (:mod:`pickdemo.streams`), so one seed makes one episode, bit for
bit.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from pickdemo.geometry import wrap_angle
from pickdemo.kinematics import panda_kinematics
from pickdemo.layout import LayoutError, camera_position, sample_layout
from pickdemo.metrics import score_perception, score_place
from pickdemo.perception import PerceptionError, PerceptionParams, PoseEstimate, estimate_pose
from pickdemo.pick import TRACKING_STATES, CameraModel, MachineParams, PickMachine, State
from pickdemo.result import EpisodeResult, EpisodeTrace, Failure, PerceptionScore, PhaseRecord, Stage
from pickdemo.scenario import Scenario
from pickdemo.streams import spawn_rngs
from pickdemo.task import target_model

PhaseCallback = Callable[[PhaseRecord], None]  # each state entered (and each note), as it happens

SETTLE_MAX_S = 2.0  # the objects come to rest before the first look, within this


@dataclass(frozen=True)
class EpisodeOptions:
    gui: bool = False
    open_loop: bool = False  # look once and play the plan (no perception while moving)
    perception: PerceptionParams = PerceptionParams()
    machine: MachineParams = MachineParams()
    record_trace: bool = False  # keep the per-tick trace (EpisodeResult.trace)


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


def _symmetry(shape: str, size: tuple[float, ...]) -> float:
    if shape == "cylinder":
        return 0.0
    return np.pi / 2.0 if abs(size[0] - size[1]) < 1e-9 else np.pi


@dataclass
class _TraceRows:
    """Rows of the trace, appended per tick (turned into arrays once at the end)."""

    rows: list[tuple] = field(default_factory=list)

    def freeze(self) -> EpisodeTrace:
        nan4 = np.full(4, np.nan)
        cols = list(zip(*self.rows, strict=True)) if self.rows else [()] * 13

        def arr(i: int, width: int) -> np.ndarray:
            return np.array(cols[i], dtype=float).reshape(-1, width) if cols[i] else np.zeros((0, width))

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
    from pickdemo.sim.controller import RobotInterface  # simulator side, imported late
    from pickdemo.sim.disturb import PushPlayer, draw_push
    from pickdemo.sim.render import Camera
    from pickdemo.sim.scene import Scene

    options = options or EpisodeOptions()
    if open_loop is not None:
        options = EpisodeOptions(**{**options.__dict__, "open_loop": open_loop})
    timer = _Timer()
    wall0 = time.perf_counter()
    rngs = spawn_rngs(seed)
    phases: list[PhaseRecord] = []
    failure: Failure | None = None
    scene = None
    machine: PickMachine | None = None
    perception: PerceptionScore | None = None
    place_error_mm = lift_height_mm = grasp_width_mm = None
    tracking_error_mm = tracking_yaw_deg = None
    pushes: list[PushPlayer] = []
    frames = 0
    tracking_frames = 0
    tracking_ticks = 0
    tick_ms: list[float] = []
    trace = _TraceRows() if options.record_trace else None
    dt_ctl = 1.0 / scenario.control.control_rate_hz

    def phase(name: str, msg: str, t: float) -> None:
        phases.append(PhaseRecord(name, round(t, 6), msg))
        if on_phase is not None:
            on_phase(phases[-1])

    try:
        if len(scenario.targets) != 1:
            raise _End(Stage.ERROR, f"a pick needs exactly one target; the scenario has {len(scenario.targets)}")
        try:
            layout = sample_layout(scenario, rngs["layout"])
        except LayoutError as exc:
            raise _End(Stage.ERROR, str(exc)) from None
        target_name = scenario.target.name
        placement = next(p for p in layout if p.name == target_name)
        model = target_model(scenario, placement)
        with timer("scene"):
            scene = Scene(scenario, layout, gui=options.gui)
            camera = Camera(
                scenario.camera, rngs["camera"], position=camera_position(scenario.camera, rngs["camera_pose"])
            )
            robot = RobotInterface(scene)
            kin = panda_kinematics()
        dt = scene.time_step_s
        substeps = max(1, round(dt_ctl / dt))
        dt_ctl = substeps * dt
        max_steps = int(round(scenario.sim.max_sim_time_s / dt))
        frame_ticks = max(1, round(1.0 / (scenario.control.perception_rate_hz * dt_ctl)))
        latency_s = scenario.control.perception_latency_s

        with timer("settle"):
            scene.settle(int(SETTLE_MAX_S / dt))
        start_pose = scene.true_pose(target_name)  # truth: for scoring only
        machine = PickMachine(
            kin=kin,
            model=model,
            symmetry_rad=_symmetry(model.shape, model.size),
            place_xy=scenario.place.position,
            camera=CameraModel(camera.intrinsics, camera.T_world_cam),
            q0=robot.observe().arm_q,
            dt_s=dt_ctl,
            rng=rngs["ik"],
            max_attempts=scenario.control.max_attempts,
            open_loop=options.open_loop,
            params=options.machine,
        )
        pending: deque[tuple[float, float, PoseEstimate | PerceptionError]] = deque()
        last_frame_tick = -(10**9)
        max_z = float(start_pose.position[2])
        n_events = 0
        first_look_s: float | None = None
        tick = 0
        while not machine.finished:
            if scene.steps + substeps > max_steps:
                budget = scenario.sim.max_sim_time_s
                machine.abort(Stage.TIMEOUT, f"simulated-time budget of {budget:.1f} s spent in {machine.state.value}")
                break
            now = scene.sim_time_s
            obs = robot.observe()
            while pending and pending[0][0] <= now + 1e-9:
                _, t_frame, result = pending.popleft()
                machine.on_estimate(result, t_frame)
            t0 = time.perf_counter()
            cmd = machine.update(obs)
            tick_ms.append((time.perf_counter() - t0) * 1e3)
            for ev in machine.events[n_events:]:
                phase(ev.state.value, ev.message, ev.time_s)
                if ev.state is State.CLOSE and not ev.note:  # commit: how far the tracker is from the truth (scoring)
                    truth = scene.true_pose(target_name)
                    tp = machine.tracker.predict(now)
                    tracking_error_mm = float(np.linalg.norm(tp.position - truth.position)) * 1e3
                    if machine.symmetry > 0:
                        dyaw = wrap_angle(tp.yaw_rad - float(truth.rpy[2]), machine.symmetry)
                        tracking_yaw_deg = float(abs(np.degrees(dyaw)))
            n_events = len(machine.events)
            if machine.finished:
                break
            robot.apply(cmd)
            if machine.state in TRACKING_STATES:
                tracking_ticks += 1
            request = machine.frame_request(now)
            if request is not None and tick - last_frame_tick >= frame_ticks:
                last_frame_tick = tick
                with timer("render"):
                    frame = camera.capture(scene, request.roi)
                with timer("perceive"):
                    try:
                        result: PoseEstimate | PerceptionError = estimate_pose(frame, model, options.perception)
                    except PerceptionError as exc:
                        result = exc
                frames += 1
                if machine.state in TRACKING_STATES:
                    tracking_frames += 1
                if perception is None and isinstance(result, PoseEstimate):
                    perception = score_perception(result, scene.true_pose(target_name))  # truth: scoring
                if first_look_s is None:
                    first_look_s = now
                    pushes = [
                        PushPlayer(draw_push(d, now, rngs["disturbance"]), target_name) for d in scenario.disturbances
                    ]
                pending.append((now + latency_s, now, result))
            if trace is not None:
                s = machine.last_sample
                lim = machine.motion.limits
                v, a, j = lim.arrays()
                tracked = None
                if machine.tracker.initialised:
                    tp = machine.tracker.predict(now)
                    tracked = np.array([*tp.position, tp.yaw_rad])
                trace.rows.append(
                    (now, machine.state.value, s.setpoint, s.velocity, s.acceleration, s.jerk, v, a, j,
                     s.new_calculation, s.q, scene.true_tcp_pose().position, tracked)
                )  # fmt: skip
            with timer("physics"):
                for _ in range(substeps):
                    for push in pushes:
                        push.step(scene)
                    scene.step()
            if machine.state in (State.LIFT, State.TRANSPORT, State.LOWER):
                max_z = max(max_z, float(scene.true_pose(target_name).position[2]))
            tick += 1
        if machine.failure is not None:
            raise _End(machine.failure.stage, machine.failure.reason)
        # ---------------------------------------------------------------------------- scoring
        final = scene.true_pose(target_name)  # truth: for scoring only
        outcome = score_place(
            start=start_pose,
            max_z_m=max_z,
            final=final,
            final_speed_m_s=scene.true_speed(target_name),
            place_xy=scenario.place.position,
            height_m=placement.height_m,
            lift_height_m=scenario.success.lift_height,
            place_tolerance_m=scenario.success.place_tolerance,
        )
        place_error_mm = outcome.place_error_m * 1e3
        if not outcome.success:
            stage = Stage.LIFT if outcome.lifted_m < scenario.success.lift_height else Stage.PLACE
            raise _End(stage, outcome.reason)
    except _End as exc:
        failure = exc.failure
    except Exception as exc:  # noqa: BLE001 - one bad episode must not take a batch down
        failure = Failure(Stage.ERROR, f"{type(exc).__name__}: {exc}".splitlines()[0])
    finally:
        sim_time = scene.sim_time_s if scene is not None else 0.0
        if scene is not None and machine is not None and machine.attempts:
            lift_height_mm = (max_z - float(start_pose.position[2])) * 1e3
        if scene is not None:
            scene.close()
    attempts = tuple(machine.attempts) if machine is not None else ()
    counters = machine.counters if machine is not None else None
    if machine is not None and machine.grasp_width_m is not None:
        grasp_width_mm = machine.grasp_width_m * 1e3
    if failure is not None:
        phases.append(PhaseRecord("failed", round(sim_time, 6), f"{failure.stage.value}: {failure.reason}"))
    tick_arr = np.array(tick_ms) if tick_ms else np.zeros(1)
    return EpisodeResult(
        scenario=scenario.name,
        seed=seed,
        success=failure is None,
        failure=failure,
        perception=perception,
        place_error_mm=place_error_mm,
        lift_height_mm=lift_height_mm,
        grasp_width_mm=grasp_width_mm,
        sim_time_s=sim_time,
        wall_time_s=time.perf_counter() - wall0,
        stage_wall_times_s={k: round(v, 6) for k, v in timer.times.items()},
        phases=tuple(phases),
        open_loop=options.open_loop,
        attempts=attempts,
        perception_frames=frames,
        perception_rate_hz=(tracking_frames / (tracking_ticks * dt_ctl)) if tracking_ticks else None,
        estimates_rejected=counters.rejected if counters else 0,
        perception_failures=counters.perception_errors if counters else 0,
        target_moves_detected=counters.jumps if counters else 0,
        retargets=counters.retargets if counters else 0,
        tracking_error_mm=tracking_error_mm,
        tracking_yaw_error_deg=tracking_yaw_deg,
        disturbances=tuple(p.push.to_dict() for p in pushes),
        control_tick_wall_ms={
            "median": float(np.median(tick_arr)),
            "p95": float(np.percentile(tick_arr, 95)),
            "ticks": len(tick_ms),
        },
        trace=trace.freeze() if trace is not None else None,
    )


class _End(Exception):
    """Ends an episode in a named stage."""

    def __init__(self, stage: Stage, reason: str) -> None:
        super().__init__(f"{stage.value}: {reason}")
        self.failure = Failure(stage, reason)
