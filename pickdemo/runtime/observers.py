"""Watching an episode's loop: the per-tick trace, the video and the GUI's debug drawing.

An :class:`Observer` is told what the loop does through one interface: each control ``tick`` (after
the command, before the physics steps), each camera ``frame`` with what perception made of it, each
``estimate`` handed to the controller, each ``phase`` entered, the loop's ``end``; ``close`` last,
always. Observers may read the simulator's truth (they are for viewers and scoring) but never change
the episode: no random draw, no render through the scene's camera's random stream, no command. The
episode shows them a view of itself (:class:`~pickdemo.runtime.view.EpisodeView`): its world, its controller, its clock.

The rerun recording is a fourth observer, in :mod:`pickdemo.runtime.recording`.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any

import numpy as np

from pickdemo.core.camera import RGBDFrame, look_at_pose, rendered_intrinsics
from pickdemo.core.result import EpisodeTrace, PhaseRecord
from pickdemo.perception import PerceptionError, PoseEstimate
from pickdemo.runtime.video import (
    GRASP_STATES,
    TRACKER_STATES,
    Overlay,
    VideoWriter,
    compose,
    draw_overlay,
    magnify,
    panel_centre,
)
from pickdemo.runtime.view import EpisodeView
from pickdemo.sim.debug import DebugDraw
from pickdemo.sim.render import render_rgb

Result = PoseEstimate | PerceptionError

#: The video's third-person view: from the front left, above the table, far enough back that the whole
#: arm stays in view (fitted to the link frames of several episodes, with 8 cm for the links' bulk).
THIRD_PERSON_POSE = look_at_pose(np.array([1.22, -0.92, 0.82]), np.array([0.2, 0.08, 0.26]))
THIRD_PERSON_K = rendered_intrinsics(256, 192, 60.0, 46.8)  # shown at 320x240: most of the cost is its rendering
VIDEO_CROP_PX = (160, 120)  # the camera's view in the video: this much around the target, shown twice the size


class Observer:
    """Watches the loop (every hook does nothing unless overridden). ``timer``: the name its wall
    time is counted under in ``stage_wall_times_s`` (``None``: not counted)."""

    timer: str | None = None

    def tick(self, ep: EpisodeView, now: float) -> None:
        """A control tick: the command is applied, the physics is about to step."""

    def frame(self, ep: EpisodeView, now: float, frame: RGBDFrame, result: Result) -> None:
        """A camera frame was taken and perceived (its result reaches the controller after the latency)."""

    def estimate(self, ep: EpisodeView, now: float, taken_s: float, result: Result, status: str) -> None:
        """A frame's result reached the controller (taken at ``taken_s``); ``status``: what it did with it."""

    def phase(self, ep: EpisodeView, record: PhaseRecord) -> None:
        """A state of the pick entered (or a note within one)."""

    def end(self, ep: EpisodeView, now: float) -> None:
        """The loop ended (done, failed or out of time), before the episode is scored."""

    def close(self) -> None:
        """The episode is over (also after an error): release what it holds."""


_HOOKS = ("tick", "frame", "estimate", "phase", "end")


def _overrides(observer: Observer, hook: str) -> bool:
    """Whether the observer does something on this hook (the others are not called at all)."""
    return getattr(type(observer), hook) is not getattr(Observer, hook)


class ObserverHub:
    """An episode's observers, in order: each hook calls those that override it (timed under the
    observer's ``timer`` name by ``timer``, a context manager factory), and ``close`` closes them all."""

    def __init__(self, observers: list[Observer], timer: Callable[[str], AbstractContextManager]) -> None:
        self.observers, self.timer = observers, timer
        self._hooks = {
            hook: [(ob.timer, getattr(ob, hook)) for ob in observers if _overrides(ob, hook)] for hook in _HOOKS
        }

    def notify(self, hook: str, view: EpisodeView, *args: Any) -> None:
        for timer, call in self._hooks.get(hook, ()):
            if timer is None:
                call(view, *args)
            else:
                with self.timer(timer):
                    call(view, *args)

    def close(self) -> None:
        """Close every observer (once: the hub is empty after)."""
        observers, self.observers, self._hooks = self.observers, [], {}
        for ob in observers:
            if ob.timer is None:
                ob.close()
            else:
                with self.timer(ob.timer):
                    ob.close()


# ============================================================================================ trace
@dataclass(frozen=True)
class TraceTick:
    """One control tick of the trace: the commanded Cartesian motion with the limits it was given,
    the joint command, the true TCP (truth: for plots) and the tracked target."""

    time_s: float
    state: str
    setpoint: np.ndarray  # (4,) x, y, z (m), yaw (rad)
    velocity: np.ndarray  # (4,)
    acceleration: np.ndarray  # (4,)
    jerk: np.ndarray  # (4,)
    max_velocity: Any  # (4,) the limits Ruckig had
    max_acceleration: Any
    max_jerk: Any
    retarget: bool  # Ruckig recomputed (a re-target or new limits)
    q: np.ndarray  # (7,) joint command
    tcp_true: np.ndarray  # (3,)
    tracked: np.ndarray | None  # (4,) the tracker's x, y, z, yaw now (None before it has one)


class TraceRecorder(Observer):
    """The per-tick trace (:class:`~pickdemo.core.result.EpisodeTrace`, for plots and tests)."""

    def __init__(self) -> None:
        self.ticks: list[TraceTick] = []

    def tick(self, ep: EpisodeView, now: float) -> None:
        m = ep.controller
        s = m.last_sample
        if s is None:  # (no motion yet: a clear round between its picks)
            return
        v, a, j = m.cartesian_limits()
        tracked = None
        if m.tracker.initialised:
            tp = m.tracker.predict(now)
            tracked = np.array([*tp.position, tp.yaw_rad])
        tcp = ep.world.scene.true_tcp_pose().position
        self.ticks.append(TraceTick(now, m.state.value, s.setpoint, s.velocity, s.acceleration, s.jerk, v, a, j,
                                    s.new_calculation, s.q, tcp, tracked))  # fmt: skip

    def freeze(self) -> EpisodeTrace:
        """The ticks as arrays."""
        ts = self.ticks
        nan4 = np.full(4, np.nan)

        def arr(name: str, width: int) -> np.ndarray:  # (no tick at all: an episode over before its first)
            return np.array([getattr(t, name) for t in ts], dtype=float).reshape(len(ts), width)

        return EpisodeTrace(
            time_s=np.array([t.time_s for t in ts], dtype=float),
            state=tuple(t.state for t in ts),
            setpoint=arr("setpoint", 4),
            velocity=arr("velocity", 4),
            acceleration=arr("acceleration", 4),
            jerk=arr("jerk", 4),
            max_velocity=arr("max_velocity", 4),
            max_acceleration=arr("max_acceleration", 4),
            max_jerk=arr("max_jerk", 4),
            retarget=np.array([t.retarget for t in ts], dtype=bool),
            q=arr("q", len(ts[0].q) if ts else 0),
            tcp_true=arr("tcp_true", 3),
            tracked=np.array([nan4 if t.tracked is None else t.tracked for t in ts], dtype=float).reshape(-1, 4),
        )


# ========================================================================================= overlays
class _OverlayObserver(Observer):
    """Draws the overlays (:class:`~pickdemo.runtime.video.Overlay`) every ``every`` ticks: keeps the newest
    estimate that reached the controller, and when its frame was taken."""

    def __init__(self, every: int) -> None:
        self.every = every
        self.last_estimate: PoseEstimate | None = None
        self.last_estimate_s = -np.inf

    def estimate(self, ep: EpisodeView, now: float, taken_s: float, result: Result, status: str) -> None:
        if isinstance(result, PoseEstimate):
            self.last_estimate, self.last_estimate_s = result, taken_s

    def overlay(self, ep: EpisodeView, now: float) -> Overlay:
        """What the video and the GUI draw now: the estimate of the newest frame (none once
        perception no longer looks), the truth (a label), the tracker's belief and path while it
        tracks, the chosen grasp until the gripper closes, and a caption."""

        m = ep.controller
        tracked = path = None
        # An estimate is current until a frame after it is due (the frame period, plus its latency).
        max_age = ep.scenario.control.perception_latency_s + 1.5 * ep.frame_ticks * ep.dt_ctl
        fresh = now - self.last_estimate_s <= max_age
        if m.tracker.initialised and m.state.value in TRACKER_STATES:
            tp = m.tracker.predict(now)
            tracked = tp.position
            path = tp.position + np.linspace(0.0, 1.0, 11)[:, None] * tp.velocity
        plan = m.plan
        return Overlay(
            caption=f"{m.state.value}  |  t = {now:5.2f} s  |  "
            + m.progress
            + ("  |  open loop" if ep.open_loop else ""),
            estimate=self.last_estimate if fresh else None,
            truth=ep.world.true_pose(ep.truth_name),  # a label for the viewer
            tracked=tracked,
            tracked_path=path,
            grasp=None if plan is None or m.state.value not in GRASP_STATES else plan.grasp,
            grasp_width_m=0.0 if plan is None else plan.object_width_m,
            objects=_world_labels(m),
            planned_path=getattr(m, "planned_path", None),
        )


class VideoRecorder(_OverlayObserver):
    """The episode's video (:mod:`pickdemo.runtime.video`): a third-person view beside the camera's, perception
    drawn on it, every ``every`` ticks and once more at the end (how it ended)."""

    timer = "video"

    def __init__(self, path: str, every: int, fps: int) -> None:

        super().__init__(every)
        self.writer = VideoWriter(path, fps=fps)

    def tick(self, ep: EpisodeView, now: float) -> None:
        if ep.tick % self.every == 0:
            self._frame(ep, now)

    def end(self, ep: EpisodeView, now: float) -> None:
        self._frame(ep, now)  # the last frame: how it ended (and what the verifying look saw)

    def _frame(self, ep: EpisodeView, now: float) -> None:

        overlay = self.overlay(ep, now)
        m = ep.controller
        tracked = m.tracker.predict(now).position if m.tracker.initialised else None
        hand = None if m.last_sample is None else np.asarray(m.last_sample.setpoint[:3], dtype=float)
        place = np.array([*ep.world.place_xy, ep.model.height_m / 2.0])
        centre = panel_centre(m.state.value, tracked=tracked, hand=hand, place=place)
        if centre is None:  # nothing to follow yet: the middle of the camera's image
            centre = np.full(3, np.nan)
        camera, scene = ep.world.camera, ep.world.scene
        view, K = camera.preview_around(scene, centre, VIDEO_CROP_PX)  # no noise: no random draw
        view, K = magnify(view, K, 2)
        right = draw_overlay(view, K, camera.T_world_cam, overlay)
        left = render_rgb(scene, THIRD_PERSON_POSE, THIRD_PERSON_K)
        self.writer.add(compose(left, right, overlay.caption))

    def close(self) -> None:
        self.writer.close()


class DebugDrawer(_OverlayObserver):
    """The same overlays as the video's, as debug lines in the PyBullet window (``--gui``)."""

    def __init__(self, ep: EpisodeView, every: int) -> None:

        super().__init__(every)
        self.draw = DebugDraw(ep.world.scene)

    def tick(self, ep: EpisodeView, now: float) -> None:
        if ep.tick % self.every == 0:
            self.draw.draw(self.overlay(ep, now))


def _world_labels(controller: object) -> tuple[tuple[int, np.ndarray, bool], ...]:
    """The controller's world model's objects, for the video's labels (none: it keeps no world model)."""
    world = getattr(controller, "world", None)
    if world is None:
        return ()
    return tuple((o.id, np.array([o.centre[0], o.centre[1], o.top_m]), o.is_target) for o in world.objects.values())
