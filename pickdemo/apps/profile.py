"""``pickdemo profile``: where a closed-loop episode's wall time goes, stage by stage, beside the
episode's own physics replayed in the same run.

Absolute figures travel badly between machines (the same episode ran 4.1x real time on one and 8.7x
on another), so every figure here comes with a reference measured in the same process. The first is
the episode's own physics, replayed right after it: the same scene and objects (built from the same
seed, settled the same way), the arm's and fingers' commands sent at the same physics steps as the
loop sent them, a push slid at the same times, a belt running; no camera, no perception, no control
decision. The loop's real-time factor over the replay's says how much of its own physics' speed the
loop keeps (1: the loop costs nothing but its physics); the replay is checked to end in the episode's
state bit for bit. The second, kept for comparison with older figures, is the bare physics: the cell's
robot and table (and belt) with no objects, the arm holding still.

The stages are timed by wrapping the episode's parts for its run (nothing in the loop knows): each
call is counted under one stage, its time exclusive of the wrapped calls it makes (a motion step's
IK counts as kinematics, not motion). What no wrapped call covers is ``loop`` (the episode's own
bookkeeping: frames in flight, the self-filter's boxes, the referee's truth). A wrapper costs about
a microsecond a call; the real-time factors here include it.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import pickdemo.runtime.episode as episode_module
from pickdemo.core.interfaces import Command
from pickdemo.runtime.episode import Episode, EpisodeOptions
from pickdemo.runtime.observers import Observer
from pickdemo.runtime.view import EpisodeView
from pickdemo.scenario.load import Scenario
from pickdemo.sim.disturb import Push, PushPlayer
from pickdemo.sim.scene import Scene

#: The stages, in the order they are printed, and what each covers.
STAGES: dict[str, str] = {
    "physics": "PyBullet's steps (and a push's slide)",
    "robot I/O": "joint states, contacts and the wrist's force read; the arm's command checked and sent",
    "render": "the cameras' frames (only the region perception asked for)",
    "perception": "the pose estimate of each frame",
    "world model": "each frame split into instances, matched to the objects with their ids",
    "tracker": "estimates gated and fused, the track predicted",
    "skill": "the pick's state machine, its plans and frame requests (the rest of the control decision)",
    "motion": "Ruckig: the hand's online trajectory and joint-space transfers",
    "planning": "coal and OMPL: straight motions checked against what is in the way, paths planned around it",
    "kinematics": "Pinocchio: IK along the hand's path, IK goals, forward kinematics",
    "observers": "trace, video, recordings",
    "loop": "the episode's own bookkeeping (what no stage above covers)",
}
_MISSING = object()
#: Physics steps of the bare reference (10 s at 240 Hz).
REFERENCE_STEPS = 2400


@dataclass
class StageTime:
    calls: int = 0
    seconds: float = 0.0  # exclusive of the wrapped calls it made
    samples: list[float] = field(default_factory=list, repr=False)  # each call's exclusive seconds

    @property
    def median_s(self) -> float | None:
        """A call's exclusive time, the median over the calls (None: not counted call by call)."""
        return statistics.median(self.samples) if self.samples else None


@dataclass
class Profiler:
    """Wraps callables on objects for a while; counts each call's exclusive wall time under a stage."""

    stages: dict[str, StageTime] = field(default_factory=dict)
    _stack: list[float] = field(default_factory=list)
    _undo: list[tuple[Any, str, Any]] = field(default_factory=list)

    def wrap(self, obj: Any, name: str, stage: str) -> None:
        """Time ``obj.name`` (a method or a callable attribute) under ``stage`` until :meth:`restore`."""
        if obj is None or not hasattr(obj, name):
            return
        fn: Callable[..., Any] = getattr(obj, name)
        if not callable(fn):
            return
        stat = self.stages.setdefault(stage, StageTime())
        stack = self._stack

        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            stack.append(0.0)
            try:
                return fn(*args, **kwargs)
            finally:
                dt = time.perf_counter() - t0
                inner = stack.pop()
                stat.calls += 1
                stat.seconds += dt - inner
                stat.samples.append(dt - inner)
                if stack:
                    stack[-1] += dt

        self._undo.append((obj, name, obj.__dict__.get(name, _MISSING) if hasattr(obj, "__dict__") else _MISSING))
        setattr(obj, name, timed)

    def restore(self) -> None:
        """Every wrapped attribute as it was (a shared object, the kinematics, is wrapped per episode)."""
        for obj, name, before in reversed(self._undo):
            if before is _MISSING:
                delattr(obj, name)
            else:
                setattr(obj, name, before)
        self._undo.clear()

    @contextmanager
    def wrapped(self) -> Iterator[Profiler]:
        try:
            yield self
        finally:
            self.restore()


def _wrap_episode(prof: Profiler, ep: Any) -> None:
    """The episode's parts, as :data:`STAGES` names them."""
    world, m = ep.world, ep.machine
    prof.wrap(world.scene, "step", "physics")
    prof.wrap(ep.robot, "observe", "robot I/O")
    prof.wrap(ep.robot, "apply", "robot I/O")
    for rig in world.cameras.values():
        prof.wrap(rig, "take", "render")
    prof.wrap(ep, "estimator", "perception")
    prof.wrap(episode_module, "split_view", "world model")
    prof.wrap(getattr(m, "world", None), "update", "world model")
    belief, arm = getattr(m, "belief", None), getattr(m, "arm", None)  # (a pick's: a clear round's own are not)
    for name in ("offer", "predict", "lost", "moving_velocity"):
        prof.wrap(belief, name, "tracker")
    for name in ("update", "on_estimate", "views"):
        prof.wrap(m, name, "skill")
    for name in ("step", "set_target", "time_to", "intercept", "reset_at"):
        prof.wrap(arm and arm.motion, name, "motion")
    for name in ("step", "start", "retarget", "brake"):
        prof.wrap(arm and arm.joints, name, "motion")
    for name in ("track", "solve", "forward", "manipulability", "limit_margin"):
        prof.wrap(m.kin, name, "kinematics")
    router = getattr(m, "router", None)
    for name in ("scene", "joint", "line_blocked", "accepting", "upright"):
        prof.wrap(router, name, "planning")


@dataclass(frozen=True)
class Reference:
    """The bare physics: the cell's robot and table, no objects, the arm holding still."""

    steps: int
    seconds: float
    time_step_s: float

    @property
    def us_per_step(self) -> float:
        return self.seconds / self.steps * 1e6

    @property
    def real_time_factor(self) -> float:
        return self.steps * self.time_step_s / self.seconds


def bare_physics(scenario: Scenario, steps: int = REFERENCE_STEPS) -> Reference:
    """Step the scenario's cell without its objects (the robot holding its home pose): the reference."""
    with Scene(scenario, ()) as scene:
        scene.step(10)  # (the first steps warm the solver's caches)
        t0 = time.perf_counter()
        scene.step(steps)
        seconds = time.perf_counter() - t0
        return Reference(steps=steps, seconds=seconds, time_step_s=scene.time_step_s)


@dataclass(eq=False)
class CommandLog(Observer):
    """What an episode's loop sent the simulator: each command with the physics step it was sent at,
    the pushes it played, the steps its loop spanned and the state it ended in (an observer of the
    episode, for its end)."""

    commands: list[tuple[int, Command]] = field(default_factory=list)
    pushes: list[Push] = field(default_factory=list)
    start_step: int = 0
    end_step: int = 0
    final_state: np.ndarray | None = None

    def watch(self, ep: Episode) -> None:
        """Log ``ep``'s commands as its robot sends them (a command the reflex refused was not sent)."""
        scene, robot = ep.world.scene, ep.robot
        self.start_step = self.end_step = scene.steps
        apply = robot.apply

        def logged(cmd: Command) -> None:
            apply(cmd)
            self.commands.append((scene.steps, cmd))

        robot.apply = logged

    def end(self, ep: EpisodeView, now: float) -> None:
        scene = ep.world.scene
        self.end_step, self.final_state = scene.steps, scene.state()


@dataclass(frozen=True)
class PhysicsReplay:
    """The episode's physics replayed: its wall time, and whether it ended in the episode's state."""

    steps: int
    seconds: float
    time_step_s: float
    same_state: bool | None  # None: the episode ended in an error, its state not taken

    @property
    def real_time_factor(self) -> float:
        return self.steps * self.time_step_s / max(self.seconds, 1e-12)


def replay_physics(
    scenario: Scenario, seed: int, log: CommandLog, options: EpisodeOptions | None = None
) -> PhysicsReplay:
    """The same seed's scene built and settled again, then stepped with ``log``'s commands and pushes,
    each at its step, and nothing else; timed from the loop's first step to its last."""
    ep = Episode(scenario, seed, options=options)
    try:
        ep.reset()
        scene, robot = ep.world.scene, ep.robot
        assert scene.steps == log.start_step, "the replay's scene did not settle as the episode's did"
        players = [PushPlayer(push, ep.target_name) for push in log.pushes]

        def advance(to: int) -> None:
            while scene.steps < to:
                for player in players:
                    player.step(scene)
                scene.step()

        t0 = time.perf_counter()
        for at, cmd in log.commands:
            advance(at)
            robot.send(cmd)
        advance(log.end_step)
        seconds = time.perf_counter() - t0
        same = None if log.final_state is None else bool(np.array_equal(scene.state(), log.final_state))
        return PhysicsReplay(
            steps=log.end_step - log.start_step, seconds=seconds, time_step_s=scene.time_step_s, same_state=same
        )
    finally:
        ep.close()


@dataclass(frozen=True)
class EpisodeProfile:
    seed: int
    success: bool
    failure: str | None
    sim_time_s: float
    build_s: float  # the scene built, the objects settled (before the first tick)
    loop_s: float  # the control loop's wall time
    loop_sim_s: float  # the simulated time the loop spanned (the settling before it not included)
    stages: dict[str, StageTime]
    control_decision_ms: float  # the machine's update, a tick (median)
    replay: PhysicsReplay | None  # None: the episode ended before its loop began

    @property
    def real_time_factor(self) -> float:
        """The loop's: simulated time over its wall time."""
        return self.loop_sim_s / max(self.loop_s, 1e-12)

    @property
    def share_of_replay(self) -> float | None:
        """The loop's real-time factor over its own physics replay's (the same simulated span)."""
        return None if self.replay is None else self.replay.seconds / max(self.loop_s, 1e-12)


def profile_episode(scenario: Scenario, seed: int, options: EpisodeOptions | None = None) -> EpisodeProfile:
    """One episode, its loop timed stage by stage."""
    prof = Profiler()
    log = CommandLog()
    ep = Episode(scenario, seed, options=options, observers=(log,))
    t0 = time.perf_counter()
    started = ep.reset() is not None
    build_s = time.perf_counter() - t0
    loop_s = 0.0
    with prof.wrapped():
        if started:
            log.watch(ep)  # (under the profiler's wrapper: a command's logging counts as robot I/O)
            _wrap_episode(prof, ep)
            t0 = time.perf_counter()
            while not ep.step():
                pass
            loop_s = time.perf_counter() - t0
    log.pushes = [player.push for player in ep.pushes]
    result = ep.result()
    ep.close()
    replay = replay_physics(scenario, seed, log, options) if started and log.end_step > log.start_step else None
    times = result.stage_wall_times_s
    known = {"scene", "settle", "render", "render wrist", "perceive", "perceive wrist", "world", "physics"}
    observers = sum(v for k, v in times.items() if k not in known)
    stages = {name: prof.stages.get(name, StageTime()) for name in STAGES if name not in ("observers", "loop")}
    stages["observers"] = StageTime(calls=0, seconds=observers)
    covered = sum(s.seconds for s in stages.values())
    stages["loop"] = StageTime(calls=0, seconds=max(loop_s - covered, 0.0))
    failure = None if result.failure is None else f"{result.failure.stage.value}: {result.failure.reason}"
    return EpisodeProfile(
        seed=seed,
        success=result.success,
        failure=failure,
        sim_time_s=result.sim_time_s,
        build_s=build_s,
        loop_s=loop_s,
        loop_sim_s=(log.end_step - log.start_step) * scenario.sim.time_step_s,
        stages=stages,
        control_decision_ms=float(result.control_tick_wall_ms.get("median", 0.0)),
        replay=replay,
    )


@dataclass(frozen=True)
class ProfileReport:
    scenario: str
    reference: Reference
    episodes: tuple[EpisodeProfile, ...]

    def totals(self) -> dict[str, StageTime]:
        out = {name: StageTime() for name in STAGES}
        for e in self.episodes:
            for name, s in e.stages.items():
                out[name].calls += s.calls
                out[name].seconds += s.seconds
                out[name].samples.extend(s.samples)
        return out

    @property
    def sim_time_s(self) -> float:
        return sum(e.sim_time_s for e in self.episodes)

    @property
    def loop_s(self) -> float:
        return sum(e.loop_s for e in self.episodes)

    @property
    def loop_sim_s(self) -> float:
        return sum(e.loop_sim_s for e in self.episodes)

    @property
    def real_time_factor(self) -> float:
        """The loops': the simulated time they spanned over their wall time."""
        return self.loop_sim_s / max(self.loop_s, 1e-12)

    @property
    def replays(self) -> list[PhysicsReplay]:
        return [e.replay for e in self.episodes if e.replay is not None]

    @property
    def replay_real_time_factor(self) -> float:
        """The episodes' physics replays': the same simulated time over their wall time."""
        rs = self.replays
        return sum(r.steps * r.time_step_s for r in rs) / max(sum(r.seconds for r in rs), 1e-12)

    @property
    def share_of_replay(self) -> float:
        """The loops' real-time factor over their physics replays' (1: the loop costs nothing but its
        physics); over the episodes that have a replay."""
        timed = [e for e in self.episodes if e.replay is not None]
        return sum(e.replay.seconds for e in timed) / max(sum(e.loop_s for e in timed), 1e-12)  # type: ignore[union-attr]

    @property
    def ratio(self) -> float:
        """The loop's real-time factor over the bare physics'."""
        return self.real_time_factor / self.reference.real_time_factor

    def to_dict(self) -> dict[str, Any]:
        totals = self.totals()
        return {
            "scenario": self.scenario,
            "reference": {
                "steps": self.reference.steps,
                "seconds": self.reference.seconds,
                "us_per_step": self.reference.us_per_step,
                "real_time_factor": self.reference.real_time_factor,
            },
            "episodes": [
                {
                    "seed": e.seed,
                    "success": e.success,
                    "failure": e.failure,
                    "sim_time_s": e.sim_time_s,
                    "build_s": e.build_s,
                    "loop_s": e.loop_s,
                    "loop_sim_s": e.loop_sim_s,
                    "real_time_factor": e.real_time_factor,
                    "replay": None
                    if e.replay is None
                    else {
                        "seconds": e.replay.seconds,
                        "real_time_factor": e.replay.real_time_factor,
                        "same_state": e.replay.same_state,
                    },
                    "share_of_replay": e.share_of_replay,
                    "control_decision_ms": e.control_decision_ms,
                    "stages": {k: {"calls": s.calls, "seconds": s.seconds} for k, s in e.stages.items()},
                }
                for e in self.episodes
            ],
            "sim_time_s": self.sim_time_s,
            "loop_s": self.loop_s,
            "loop_sim_s": self.loop_sim_s,
            "real_time_factor": self.real_time_factor,
            "replay_real_time_factor": self.replay_real_time_factor,
            "share_of_replay": self.share_of_replay,
            "ratio_to_reference": self.ratio,
            "control_decision_ms_median": self.control_decision_ms,
            "stages": {
                k: {
                    "calls": s.calls,
                    "seconds": s.seconds,
                    "share": s.seconds / max(self.loop_s, 1e-12),
                    "us_per_call": (s.seconds / s.calls * 1e6) if s.calls else None,
                    "median_us_per_call": None if s.median_s is None else s.median_s * 1e6,
                }
                for k, s in totals.items()
            },
        }

    @property
    def control_decision_ms(self) -> float:
        return statistics.median(e.control_decision_ms for e in self.episodes) if self.episodes else 0.0

    def format(self) -> str:
        ref, totals = self.reference, self.totals()
        ok = sum(e.success for e in self.episodes)
        rs = self.replays
        same = sum(r.same_state is True for r in rs)
        lines = [
            f"episodes: {len(self.episodes)} ({ok} succeeded), {self.loop_sim_s:.1f} s simulated in "
            f"{self.loop_s:.2f} s of loop: {self.real_time_factor:.1f}x real time",
            f"their physics replayed (same scene, same commands at the same steps; no camera, perception or "
            f"decision): {sum(r.seconds for r in rs):.2f} s, {self.replay_real_time_factor:.1f}x real time; "
            f"{same} of {len(rs)} ended in the episode's state bit for bit",
            f"the loop: {self.share_of_replay:.3f} of its physics replay's real-time factor",
            f"bare physics (the cell's robot and table, no objects, the arm still): {ref.steps} steps, "
            f"{ref.us_per_step:.0f} us a step, {ref.real_time_factor:.1f}x real time; the loop {self.ratio:.3f} of it",
            f"control decision: {self.control_decision_ms:.3f} ms a tick (median of the episodes' medians)",
            "",
            f"{'stage':<11} {'share':>6} {'wall s':>8} {'calls':>8} {'per call':>10} {'median':>10}  what",
        ]
        for name, s in totals.items():
            share = 100.0 * s.seconds / max(self.loop_s, 1e-12)
            per, med = _per_call(s), _duration(s.median_s)
            lines.append(
                f"{name:<11} {share:5.1f}% {s.seconds:8.3f} {s.calls or '':>8} {per:>10} {med:>10}  {STAGES[name]}"
            )
        for e in self.episodes:
            if not e.success:
                lines.append(f"seed {e.seed} failed: {e.failure}")
        return "\n".join(lines)


def _per_call(s: StageTime) -> str:
    return _duration(s.seconds / s.calls) if s.calls else ""


def _duration(seconds: float | None) -> str:
    if seconds is None:
        return ""
    us = seconds * 1e6
    return f"{us / 1e3:.2f} ms" if us >= 1000.0 else f"{us:.0f} us"


def profile(
    scenario: Scenario,
    seeds: list[int],
    on_episode: Callable[[EpisodeProfile], None] | None = None,
    *,
    open_loop: bool = False,
) -> ProfileReport:
    """The bare physics of the scenario's cell, then its episodes (each with its physics replayed),
    one after another in this process; ``open_loop``: looking once (the loop without its frames)."""
    reference = bare_physics(scenario)
    options = EpisodeOptions(open_loop=open_loop)
    episodes = []
    for seed in seeds:
        e = profile_episode(scenario, seed, options)
        episodes.append(e)
        if on_episode is not None:
            on_episode(e)
    return ProfileReport(scenario=scenario.name, reference=reference, episodes=tuple(episodes))
