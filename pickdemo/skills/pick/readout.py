"""What the loop, the referee and the observers read of the pick's machine (the
:class:`~pickdemo.skills.controller.Controller` protocol's read side): whether it is finished and at
rest, its tracker, its progress, its last motion sample and command, its Cartesian limits. Reads
only: it writes nothing of the machine's state."""

from __future__ import annotations

import numpy as np

from pickdemo.motion.online import MotionSample
from pickdemo.skills.pick.params import State
from pickdemo.tracking.tracker import TargetTracker


class MachineReadout:
    """The read side of :class:`~pickdemo.skills.pick.machine.PickMachine` (its base)."""

    @property
    def finished(self) -> bool:
        return self.state in (State.DONE, State.FAILED)

    @property
    def at_rest(self) -> bool:
        """Finished, and the arm at rest (with ``end_at_rest`` a failure brakes it first): the joint commands
        sent have caught up with where the motion ended (a line the rate limiter held back goes on being
        sent after it; the next controller starts from rest where they stopped)."""
        caught_up = not np.any(self.arm.limiter.dq)
        if self.state is State.DONE:
            return caught_up
        return self.state is State.FAILED and (self.arm.braked or not self.p.end_at_rest) and caught_up

    @property
    def tracker(self) -> TargetTracker:
        """The belief's tracker (read by observers: the video, the trace, the scoring)."""
        return self.belief.tracker

    @property
    def progress(self) -> str:
        """Where it is, said for a viewer: the attempt under way."""
        return f"attempt {self.attempt}"

    @property
    def last_sample(self) -> MotionSample | None:
        return self.arm.sample

    @property
    def commanded_q(self) -> np.ndarray:
        """The joint command last sent (where the next controller takes over)."""
        return self.arm.limiter.q.copy()

    @property
    def planned_path(self) -> np.ndarray | None:
        """(N, 3) where the TCP goes on the path planned around something, while the arm is on it
        (None: no such path under way), for the video and the recording to draw."""
        under_way = bool(self.arm.legs) or (self.arm.joint and not self.arm.joints.finished)
        return self.router.path if under_way else None

    def cartesian_limits(self) -> tuple[list[float], list[float], list[float]]:
        return self.arm.cartesian_limits()
