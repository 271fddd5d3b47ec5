"""The :class:`Controller` protocol: what the episode's loop asks of a skill once per control tick,
and what its observers may read of it. The pick skill (:class:`~pickdemo.skills.pick.PickMachine`)
and a clear round (:class:`~pickdemo.skills.clear.ClearSequencer`) are the two that ship."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from pickdemo.core.interfaces import Command, Observation
from pickdemo.core.result import AttemptRecord, Failure, Stage
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.motion.online import MotionSample
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.pick.params import Event, FrameRequest, State
from pickdemo.tracking.belief import Counters, Verdict
from pickdemo.tracking.tracker import TargetTracker
from pickdemo.worldmodel import SceneView


@runtime_checkable
class Controller(Protocol):
    """A skill in the loop: pure (no simulator), told only what a real robot's controller is told."""

    kin: Kinematics  # the robot's kinematics (where a camera on its hand is)
    failure: Failure | None
    events: list[Event]  # every state entered and every note, in order

    # ---- the loop's calls, once a tick
    def update(self, obs: Observation) -> Command:
        """One control tick: the command."""
        ...

    def views(self, now_s: float) -> list[FrameRequest]:
        """The frames its cameras should take now (asked when a frame is due)."""
        ...

    def on_estimate(
        self, result: PoseEstimate | PerceptionError | SceneView, frame_time_s: float, camera: str = "camera"
    ) -> Verdict:
        """A frame's estimate, or what it showed at the place (asked with ``FrameRequest.place``), as it
        arrives (after perception's latency)."""
        ...

    def abort(self, stage: Stage, reason: str) -> None:
        """End it from outside (the step budget is spent)."""
        ...

    # ---- what the loop, the referee and the observers read
    @property
    def finished(self) -> bool: ...

    @property
    def state(self) -> State: ...

    @property
    def model(self) -> TargetModel: ...

    @property
    def attempts(self) -> list[AttemptRecord]: ...

    @property
    def counters(self) -> Counters: ...

    @property
    def tracker(self) -> TargetTracker: ...

    @property
    def plan(self) -> GraspPlan | None: ...

    @property
    def last_sample(self) -> MotionSample | None: ...

    @property
    def progress(self) -> str:
        """Where it is, said for a viewer ("attempt 2", "pick 3")."""
        ...

    def cartesian_limits(self) -> tuple[list[float], list[float], list[float]]: ...
