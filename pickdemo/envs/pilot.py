"""The controller in the episode's loop when an agent acts (:class:`Pilot`), and the eye that looks
for it (:class:`Watcher`). A part of the Gymnasium environments: no Gymnasium here.

The pilot turns the agent's latest action into each control tick's command (through the control
mode, :mod:`pickdemo.envs.control`) and hands the loop's camera requests and estimates to its eye.
The eye decides where the cameras look and keeps the target's track, which the state observation
reports. By default it is a :class:`Watcher`; the expert policy (:mod:`pickdemo.envs.expert`) puts
pickdemo's own skill there, so that it looks as it does in ``bench``.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from pickdemo.core.interfaces import Command, Observation
from pickdemo.core.result import AttemptRecord, Failure, Stage
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.pick import HELD_STATES, CameraModel, FrameRequest, MachineParams, State
from pickdemo.skills.pick.views import ViewPlanner
from pickdemo.skills.pick.watch import MoveWatch
from pickdemo.tracking.belief import Counters, TargetBelief, Verdict
from pickdemo.tracking.tracker import TargetTracker
from pickdemo.worldmodel import SceneView


class Eye(Protocol):
    """What looks for the agent: the frames to take, the estimates they give, the target's track."""

    kin: Kinematics
    failure: Failure | None

    def views(self, now_s: float) -> list[FrameRequest]: ...

    def on_estimate(
        self, result: PoseEstimate | PerceptionError | SceneView, frame_time_s: float, camera: str = "camera"
    ) -> Verdict: ...

    @property
    def finished(self) -> bool: ...

    @property
    def state(self) -> State: ...

    @property
    def tracker(self) -> TargetTracker: ...


class Watcher:
    """An eye that only watches the target: the fixed camera's whole view until it is seen, then the
    region about its track; a camera on the hand whenever the track lies wholly in its view (then not
    the fixed one, which sees the hand over it). Its track is the skill's
    (:class:`~pickdemo.tracking.belief.TargetBelief`: the same gate and filter); it never rejects a
    view as partial under the hand, having no grasp in mind."""

    def __init__(
        self,
        kin: Kinematics,
        cameras: list[CameraModel],
        model: TargetModel,
        params: MachineParams,
        place_xy: tuple[float, float],
        q0: np.ndarray,
        surface_z: Any = None,  # Callable[..., float] | None: what the target rests on (the table: 0)
        *,
        looking: bool = True,
    ) -> None:
        """``looking`` False: no frames at all (a replay, an agent on the truth alone): the track stays empty."""
        self.kin, self.model = kin, model
        self.symmetry = model.geometry.yaw_symmetry_rad
        self.counters = Counters()
        self.belief = TargetBelief(
            model,
            self.symmetry,
            params.tracker,
            params.gate,
            surface_z=surface_z or (lambda x, y, z=None: 0.0),
            counters=self.counters,
        )
        hand = frozenset(c.name for c in cameras if c.on_hand)
        watch = MoveWatch(kin, params, model, self.belief, hand, open_loop=False)
        self.planner = ViewPlanner(
            kin, params, model, self.belief, watch, cameras, place_xy, look_at=None, open_loop=False
        )
        self.arm_q = np.asarray(q0, dtype=float)
        self.looking = looking
        self.failure: Failure | None = None
        self.events: list = []
        self.attempts: list[AttemptRecord] = []
        self.picks: list = []  # (a clear round's records: none)
        self.plan = None
        self.last_sample = None
        self.grasp_width_m = None
        self.progress = "watching"

    def see_joints(self, obs: Observation) -> None:
        """The joint states now (where a camera on the hand is)."""
        self.arm_q = obs.arm_q

    def views(self, now_s: float) -> list[FrameRequest]:
        if not self.looking:
            return []
        # LOOK: the whole view, then about the track; DESCEND: a hand camera when the track is in its view
        state = State.DESCEND if self.belief.initialised else State.LOOK
        return self.planner.requests(
            now_s, state, ready=True, since_s=0.0, verify_asked=False, plan=None, arm_q=self.arm_q
        )

    def on_estimate(
        self, result: PoseEstimate | PerceptionError | SceneView, frame_time_s: float, camera: str = "camera"
    ) -> Verdict:
        if isinstance(result, SceneView):  # (the agent keeps no world model)
            return Verdict.UNUSED
        return self.belief.offer(result, frame_time_s, hand_over_target=False, camera=camera).verdict

    @property
    def finished(self) -> bool:
        return False

    @property
    def state(self) -> State:
        return State.LOOK

    @property
    def tracker(self) -> TargetTracker:
        return self.belief.tracker

    def cartesian_limits(self) -> tuple[list[float], list[float], list[float]]:
        return [], [], []


class Pilot:
    """The loop's controller while an agent acts: :meth:`update` sends the command ``command(obs)``
    makes of the agent's latest action; views and estimates go to the ``eye``; everything else the
    loop, the referee and the result read of a controller is the eye's."""

    def __init__(self, eye: Eye, command: Any) -> None:  # command: Callable[[Observation], Command]
        self.eye, self.command = eye, command
        self.kin = eye.kin
        self._failure: Failure | None = None
        self._stopped = False

    def update(self, obs: Observation) -> Command:
        see = getattr(self.eye, "see_joints", None)
        if see is not None:
            see(obs)
        return self.command(obs)

    def views(self, now_s: float) -> list[FrameRequest]:
        return self.eye.views(now_s)

    def on_estimate(
        self, result: PoseEstimate | PerceptionError | SceneView, frame_time_s: float, camera: str = "camera"
    ) -> Verdict:
        return self.eye.on_estimate(result, frame_time_s, camera)

    def abort(self, stage: Stage, reason: str) -> None:
        if self._failure is None:
            self._failure = Failure(stage, reason)

    def stop(self) -> None:
        """The environment ends the episode here (its task done): the loop scores it."""
        self._stopped = True

    @property
    def failure(self) -> Failure | None:
        return self._failure or self.eye.failure

    @property
    def finished(self) -> bool:
        return self._stopped or self._failure is not None or self.eye.finished

    @property
    def state(self) -> State:
        return self.eye.state

    @property
    def carrying(self) -> bool:
        """Whether the referee measures how high the target got now: always for an agent (it may lift
        it at any time), in the skill's carrying states for the skill."""
        return isinstance(self.eye, Watcher) or self.eye.state in HELD_STATES

    def __getattr__(self, name: str) -> Any:  # the rest of a controller's face: the eye's
        return getattr(self.eye, name)
