"""One episode, wired: scenario -> world -> the control loop -> the referee -> :class:`EpisodeResult`.

:class:`Episode` is one seeded episode that can be stepped from outside: :meth:`Episode.reset` builds
the world (:mod:`pickdemo.runtime.world`) and the controller and returns the first observation,
:meth:`Episode.step` advances one control tick and says when the episode is over, and
:meth:`Episode.result` scores it. :func:`run_episode` is that loop.

The control loop is the only place that advances simulated time, one control tick at a time. Each
tick: observe (joint states, finger opening, finger contacts), hand over the estimates whose latency
has passed, decide (:class:`pickdemo.skills.pick.PickMachine`), command, take a camera frame when one is due
(rendering only the region perception asked for), then step the physics. The step budget lives here:
the scenario's simulated-time budget, counted in steps.

The controller acts only on the camera frames (RGB, depth, intrinsics, camera pose) and the joint
states. The simulator's true poses are read by the referee (:mod:`pickdemo.runtime.referee`, for scoring) and
the observers (:mod:`pickdemo.runtime.observers`: the trace, the video, the debug drawing, the rerun
recording; for viewers) only. Every random draw comes from one generator per stage
(:mod:`pickdemo.core.streams`), so one seed makes one episode, bit for bit, observed or not.
"""

from __future__ import annotations

import dataclasses
import time
import traceback
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from pickdemo.core.interfaces import Observation
from pickdemo.core.result import (
    EpisodeFailure,
    EpisodeResult,
    Failure,
    PhaseRecord,
    Stage,
)
from pickdemo.perception import (
    PerceptionParams,
    PoseEstimate,
    TargetModel,
)
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.robot.rate_limit import ReflexError
from pickdemo.runtime.frames import InFlight, Timer, estimate, take_frame
from pickdemo.runtime.honest import check_honest
from pickdemo.runtime.observers import (
    THIRD_PERSON_K,
    THIRD_PERSON_POSE,
    VIDEO_CROP_PX,
    DebugDrawer,
    Observer,
    ObserverHub,
    TraceRecorder,
    VideoRecorder,
)
from pickdemo.runtime.recording import RerunRecorder
from pickdemo.runtime.referee import PERCEPTION_OFF_MM, Referee, diagnose
from pickdemo.runtime.results import LoopCounts, episode_result
from pickdemo.runtime.tasks import cell_obstacles, episode_task, machine_params
from pickdemo.runtime.view import EpisodeView
from pickdemo.runtime.world import World
from pickdemo.scenario.layout import LayoutError
from pickdemo.scenario.load import Scenario
from pickdemo.sim.controller import RobotInterface
from pickdemo.sim.disturb import PushPlayer, draw_push
from pickdemo.skills.controller import Controller
from pickdemo.skills.pick import HELD_STATES, TRACKING_STATES, CameraModel, FrameRequest, MachineParams, State
from pickdemo.worldmodel import SceneView, split_view

__all__ = [
    "PERCEPTION_OFF_MM",
    "THIRD_PERSON_K",
    "THIRD_PERSON_POSE",
    "VIDEO_CROP_PX",
    "Episode",
    "EpisodeOptions",
    "diagnose",
    "run_episode",
]

PhaseCallback = Callable[[PhaseRecord], None]  # each state entered (and each note), as it happens
#: (the task's controller, what it was told) -> the controller the loop drives: an agent's, which may
#: keep the task's to look for it (:mod:`pickdemo.envs`)
ControllerWrap = Callable[[Controller, dict], Controller]


@dataclass(frozen=True)
class EpisodeOptions:
    gui: bool = False
    open_loop: bool = False  # look once and play the plan (no perception while moving)
    perception: PerceptionParams = PerceptionParams()
    perception_method: str = "paper"  # or "icp", "centroid", "pixel", "module:function" (perception.estimators)
    machine: MachineParams = MachineParams()
    record_trace: bool = False  # keep the per-tick trace (EpisodeResult.trace)
    video_path: str | None = None  # write the episode's video here (needs PyAV: the video extra)
    video_fps: int = 10
    debug_draw: bool = False  # draw the overlays as debug lines (always with gui)
    rerun_path: str | None = None  # write a rerun recording (.rrd) here (needs rerun-sdk: the rerun extra)


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
    episode = Episode(scenario, seed, options, on_phase=on_phase)
    episode.reset()
    while not episode.step():
        pass
    return episode.result()


def _guarded(part: Callable[[], bool]) -> tuple[Failure | None, bool]:
    """Run a part of the episode: (None, whether it ended the episode), or a failure that ends it
    (a typed one, or any error as ``error``: one bad episode must not take a batch down)."""
    try:
        return None, part()
    except EpisodeFailure as exc:
        return exc.failure, True
    except Exception as exc:  # noqa: BLE001 - a bug: in error, with where it was raised
        reason = f"{type(exc).__name__}: {exc}".splitlines()[0]
        return Failure(Stage.ERROR, reason, traceback="".join(traceback.format_exception(exc))), True


class Episode:
    """One seeded episode of a scenario, stepped one control tick at a time::

        episode = Episode(load_scenario("pick_cube"), seed=0)
        obs = episode.reset()  # the world built, the objects at rest: the robot's first observation
        while not episode.step():  # one control tick
            ...  # episode.time_s, episode.state, episode.observation, episode.machine ...
        result = episode.result()  # the same EpisodeResult as run_episode's

    ``reset`` returns ``None`` when the episode ends before its first tick (a scenario it cannot
    build, an unknown perception method); ``step`` returns True from then on and ``result`` says why.
    Never raises for an episode that goes wrong. ``observers``: more :class:`~pickdemo.runtime.observers.Observer`
    to watch the loop (after the ones the options ask for); ``wrap_controller``: the controller in the
    loop made from the task's (an agent's: :mod:`pickdemo.envs`).
    """

    def __init__(
        self,
        scenario: Scenario,
        seed: int,
        options: EpisodeOptions | None = None,
        *,
        on_phase: PhaseCallback | None = None,
        observers: tuple[Observer, ...] = (),
        wrap_controller: ControllerWrap | None = None,
    ) -> None:
        self.scenario = scenario
        self.seed = seed
        self.options = options or EpisodeOptions()
        self.on_phase = on_phase
        self.extra_observers = tuple(observers)
        self.wrap_controller = wrap_controller
        self._clear()

    def _clear(self) -> None:
        self.timer = Timer()
        self.world: World | None = None
        self.robot: RobotInterface | None = None
        self.machine: Controller | None = None  # the controller in the loop (the task's, or an agent's)
        self.task_controller: Controller | None = None  # the task's (a pick, a clear round)
        self.model: TargetModel | None = None
        self.target_name: str = ""
        self.estimator: Callable[..., PoseEstimate] | None = None
        self.referee: Referee | None = None
        self.hub = ObserverHub([], self.timer)  # the observers, called on their hooks
        self.trace = TraceRecorder() if self.options.record_trace else None  # (an empty trace if it never ran)
        self.pushes: list = []  # the disturbances, drawn at the first look
        self.counts = LoopCounts()
        self.substeps = 1  # physics steps per control tick
        self.dt_ctl = 0.0  # one control tick (s)
        self.max_steps = 0  # the simulated-time budget, in physics steps
        self.frame_ticks = 1  # control ticks between frames
        self.video_ticks = 1  # control ticks between video frames (and debug drawings)
        self.tick = 0  # the control tick now (counted from 0)
        self.observation: Observation | None = None  # the robot's newest observation
        self._pending: deque[InFlight] = deque()
        self._last_frame_tick = -(10**9)
        self._events_logged = 0
        self._started = False
        self._done = False
        self._failure: Failure | None = None
        self._sim_time_s = 0.0
        self._wall_s = 0.0
        self._result: EpisodeResult | None = None
        self._round_score: dict | None = None  # a clear round's figures, read before the scene closes
        opts = self.options
        self.view = EpisodeView(self.scenario, self.seed, opts.open_loop, opts.perception)  # what observers see

    # ================================================================================ stepping
    @property
    def done(self) -> bool:
        return self._done

    @property
    def time_s(self) -> float:
        """Simulated time now."""
        return self._sim_time_s if self._done else (self.world.sim_time_s if self.world is not None else 0.0)

    @property
    def state(self) -> State | None:
        """The pick's state (``None`` before the controller exists)."""
        return self.machine.state if self.machine is not None else None

    def reset(self) -> Observation | None:
        """Build the world and the controller (again, from the seed, if it was stepped before) and
        let the objects come to rest; the robot's first observation (``None``: it ended already)."""
        if self._started:
            self._close()
            self._clear()
        self._started = True
        t0 = time.perf_counter()

        def build() -> bool:
            self._build()
            return False

        failure, over = _guarded(build)
        if over:
            self._finish(failure)
        self._wall_s += time.perf_counter() - t0
        if over:
            return None
        self.observation = self.robot.observe()
        return self.observation

    def step(self) -> bool:
        """One control tick; True when the episode is over (then :meth:`result` has it)."""
        if not self._started:
            raise RuntimeError("Episode.step() before reset()")
        if self._done:
            return True
        t0 = time.perf_counter()

        def tick() -> bool:
            if self._tick():
                return False
            self._end_loop()
            self.referee.score()
            return True

        failure, over = _guarded(tick)
        if over:
            self._finish(failure)
        self._wall_s += time.perf_counter() - t0
        return self._done

    def result(self) -> EpisodeResult:
        """The scored episode (once :meth:`step` has said it is over)."""
        if not self._done:
            raise RuntimeError("the episode is not over: step() until it returns True")
        if self._result is None:
            self._result = self._make_result()
        return self._result

    def close(self) -> None:
        """Stop an episode before its end: release the simulator and the observers' files."""
        self._close()

    def __enter__(self) -> Episode:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # =================================================================================== build
    def _build(self) -> None:
        sc = self.scenario
        task = episode_task(sc.task)
        task.check(sc)
        try:
            world = World(sc, self.seed)  # the layout
        except LayoutError as exc:
            raise EpisodeFailure(Stage.ERROR, str(exc)) from None
        self.world = world
        opts = self.options
        told = task.told(sc, world, opts.perception_method, opts.perception, opts.open_loop)
        self.target_name, self.model, self.estimator = told.target_name, told.model, told.estimator
        with self.timer("scene"):
            world.open(gui=opts.gui)
            kin = kinematics_of(world.robot)
        scene = world.scene
        dt = scene.time_step_s
        self.substeps = max(1, round(1.0 / (sc.control.control_rate_hz * dt)))
        self.dt_ctl = self.substeps * dt
        self.robot = RobotInterface(scene, self.dt_ctl)
        self.max_steps = int(round(sc.sim.max_sim_time_s / dt))
        self.frame_ticks = max(1, round(1.0 / (sc.control.perception_rate_hz * self.dt_ctl)))
        self.video_ticks = max(1, round(1.0 / (opts.video_fps * self.dt_ctl)))
        self.referee = task.referee(sc, world, told)
        view = self.view
        view.world, view.model, view.target_name = world, told.model, told.target_name
        view.dt_ctl, view.frame_ticks = self.dt_ctl, self.frame_ticks
        self._add_observers()
        with self.timer("settle"):
            settling = scene.settle(int(task.settle_max_s / dt))
        if settling.note is not None:  # the first look sees them move: said in the result, not hidden
            self._phase(PhaseRecord("settle", round(scene.sim_time_s, 6), settling.note))
        task.settled(world)
        scene.start_belt()  # a conveyor runs from the robot's first tick
        self.referee.started()  # truth: for scoring only
        cameras = [  # what the robot is told of its cameras: intrinsics, poses (as calibrated), depth ranges
            CameraModel(rig.intrinsics, rig.T_tcp_cam, name, on_hand=True, near_m=rig.spec.near_m, far_m=rig.spec.far_m)
            if rig.on_hand
            else CameraModel(rig.intrinsics, rig.T_world_cam, name)
            for name, rig in world.cameras.items()
        ]
        common = dict(  # what the controller is told of its cell and its arm, for any task
            kin=kin,
            cameras=cameras,
            q0=self.robot.observe().arm_q,
            dt_s=self.dt_ctl,
            rng=world.rngs["ik"],
            grasp_rng=world.rngs["grasps"],
            plan_rng=world.rngs["planning"],
            cell=cell_obstacles(sc),
            params=machine_params(sc, opts.machine),
        )
        controller = task.controller(sc, world, told, self.referee, opts.open_loop, common)
        check_honest(controller)  # nothing of the simulator or the scoring handed to it (a bug: TruthLeak)
        self.task_controller = controller
        if self.wrap_controller is not None:
            controller = self.wrap_controller(controller, common)
        self.machine = self.view.controller = controller

    def _add_observers(self) -> None:
        """The observers the options ask for, in this order: the trace, the video, the debug
        drawing, the rerun recording; then the caller's."""
        opts = self.options
        observers: list[Observer] = [] if self.trace is None else [self.trace]
        if opts.video_path is not None:
            fps = round(1.0 / (self.video_ticks * self.dt_ctl))
            observers.append(VideoRecorder(opts.video_path, self.video_ticks, fps))
        if opts.gui or opts.debug_draw:
            observers.append(DebugDrawer(self.view, self.video_ticks))
        if opts.rerun_path is not None:
            observers.append(RerunRecorder(self.view, opts.rerun_path))
        self.hub = ObserverHub([*observers, *self.extra_observers], self.timer)

    def _notify(self, hook: str, *args) -> None:
        self.hub.notify(hook, self.view, *args)

    # ==================================================================================== loop
    def _tick(self) -> bool:
        """One control tick; False (nothing done) once the machine is done, failed or out of time."""
        machine, scene, counts = self.machine, self.world.scene, self.counts
        if machine.finished:
            return False
        if scene.steps + self.substeps > self.max_steps:
            budget = self.scenario.sim.max_sim_time_s
            said = f"{budget:.1f}" if budget >= 0.1 else f"{budget:.2g}"  # (a tiny budget is not 0.0 s)
            self._abort(Stage.TIMEOUT, f"simulated-time budget of {said} s spent in {machine.state.value}")
            return False
        now = scene.sim_time_s
        obs = self.observation = self.robot.observe()
        self.deliver()
        t0 = time.perf_counter()
        cmd = machine.update(obs)
        counts.tick_ms.append((time.perf_counter() - t0) * 1e3)
        self.referee.decided(machine)  # truth: for scoring only
        self._log_events(now)
        if machine.finished:
            return False
        try:
            self.robot.apply(cmd)
        except ReflexError as exc:  # the robot stopped: nothing was sent
            self._abort(Stage.REFLEX, str(exc))
            self._log_events(now)
            return False
        counts.commanded.append((now, cmd.arm_q))  # always: result.json's limit_exceedances
        self.view.last_command = cmd.arm_q
        tracking = machine.state in TRACKING_STATES
        counts.tracking_ticks += tracking
        due = self.tick - self._last_frame_tick >= self.frame_ticks  # asked only then: a region costs a prediction
        for request in machine.views(now) if due else ():  # each camera its frame, each frame its estimate
            self._last_frame_tick = self.tick
            self._look(request, now)
            counts.tracking_frames += tracking and not self.world.cameras[request.camera].on_hand
        self._notify("tick", now)
        with self.timer("physics"):
            for _ in range(self.substeps):
                for push in self.pushes:
                    push.step(scene)
                scene.step()
        # truth: how high it was carried, what came into a tray: for scoring only
        self.referee.tick(carrying=machine.carrying if self.wrap_controller else machine.state in HELD_STATES)
        self.tick += 1
        self.view.tick = self.tick
        return True

    def _abort(self, stage: Stage, reason: str) -> None:
        """Stop the controller from outside, and let the referee read what it recorded then."""
        self.machine.abort(stage, reason)
        self.referee.decided(self.machine)

    def observe(self) -> Observation:
        """The robot's observation now, between ticks (the next tick reads the same)."""
        self.observation = self.robot.observe()
        return self.observation

    def deliver(self) -> None:
        """Hand the controller the estimates whose latency has passed by now (each tick does, first)."""
        now = self.world.scene.sim_time_s
        while self._pending and self._pending[0].arrival_s <= now + 1e-9:
            f = self._pending.popleft()
            if isinstance(f.result, SceneView):  # the frame's instances: into the robot's world model
                with self.timer("world"):
                    self.machine.on_estimate(f.result, f.taken_s, f.camera)
                self.referee.world_seen(self.machine, f.result)  # truth: for scoring only
                continue
            check_honest(f.result)  # an estimator's (a user's too) carries nothing of the simulator
            status = self.machine.on_estimate(f.result, f.taken_s, f.camera)
            self.referee.delivered(f.result, f.error_mm, status)
            self._notify("estimate", now, f.taken_s, f.result, status)

    def _end_loop(self) -> None:
        """After the last tick: the last events, the observers' end; the machine's failure raised."""
        now = self.world.scene.sim_time_s
        self._log_events(now)
        self._notify("end", now)
        check_honest((self.task_controller, self.observation))  # nor kept since, nor in what it observed
        if self.machine.failure is not None:
            raise EpisodeFailure(self.machine.failure.stage, self.machine.failure.reason)

    def _look(self, request: FrameRequest, now: float) -> None:
        """Render the requested frame and run perception on it (its result is delivered later)."""
        world = self.world
        rig = world.cameras[request.camera]
        with self.timer("render wrist" if rig.on_hand else "render"):
            frame = take_frame(world, self.scenario, request, self.observation, self.machine.kin)
        latency = self.scenario.control.perception_latency_s
        with self.timer("world"):  # every frame's instances, from every camera (the robot's world model)
            view = split_view(frame, self.options.perception)
        self._pending.append(InFlight(now + latency, now, view, None, frame.camera))
        if request.survey:  # a clear round's look at the whole table: its world model's objects, no pose
            self.counts.frames += 1
            self._notify("frame", now, frame, view)
            return
        with self.timer("perceive wrist" if rig.on_hand else "perceive"):
            result = estimate(self.estimator, frame, self.machine.model, self.options.perception)
        self.counts.frames += 1
        self.referee.first_estimate(result)  # truth: for scoring only
        if self.counts.frames == 1:  # the first look: disturbances are timed from here
            self.pushes = [
                PushPlayer(draw_push(d, now, world.rngs["disturbance"]), d.object or self.target_name)
                for d in self.scenario.disturbances
            ]
        # Truth: for scoring only (an estimate that perception's own checks rejected included).
        error_mm = self.referee.error_mm(result)
        self._pending.append(InFlight(now + latency, now, result, error_mm, frame.camera))
        self._notify("frame", now, frame, result)

    def _log_events(self, now: float) -> None:
        m = self.machine
        for ev in m.events[self._events_logged :]:
            self._phase(PhaseRecord(ev.state.value, round(ev.time_s, 6), ev.message))
            if ev.state is State.CLOSE and not ev.note:  # committing: the tracker against the truth
                self.referee.committed(m.tracker.predict(now), m.symmetry)
        self._events_logged = len(m.events)

    def _phase(self, record: PhaseRecord) -> None:
        self.counts.phases.append(record)
        if self.on_phase is not None:
            self.on_phase(record)
        self._notify("phase", record)

    # ==================================================================================== end
    def _finish(self, failure: Failure | None) -> None:
        """The episode is over: where the target ended, the failure as the last phase, all closed."""
        self._sim_time_s = self.world.sim_time_s if self.world is not None else 0.0
        try:
            if self.referee is not None:
                self.referee.ended()
                self.referee.judge(failure)  # (a refusal, on the truth: before the scene closes)
                failure = self.referee.named_moves(failure)
                self._round_score = self.referee.round_score(self.machine)  # (truth: read before the scene closes)
            phases = self.counts.phases
            if failure is not None and not (phases and phases[-1].phase == State.FAILED.value):
                reason = f"{failure.stage.value}: {failure.reason}"
                self._phase(PhaseRecord(State.FAILED.value, round(self._sim_time_s, 6), reason))
        finally:
            self._failure = failure
            self._done = True
            self._close()

    def _close(self) -> None:
        try:
            self.hub.close()
        finally:
            if self.world is not None:
                self.world.close()

    def _make_result(self) -> EpisodeResult:
        return episode_result(
            scenario=self.scenario,
            seed=self.seed,
            options=self.options,
            failure=self._failure,
            counts=self.counts,
            referee=self.referee,
            controller=self.machine,
            world=self.world,
            sim_time_s=self._sim_time_s,
            wall_s=self._wall_s,
            stage_wall_times_s=self.timer.times,
            dt_ctl=self.dt_ctl,
            pushes=self.pushes,
            round_score=self._round_score,
            trace=self.trace,
        )
