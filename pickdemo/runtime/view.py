"""What observers see of a running episode: :class:`EpisodeView`, never the episode itself.

An observer (:mod:`pickdemo.runtime.observers`) is given the view on every call: the scenario and
seed, the world (its truth is for viewers), the controller's read-only side (its state, its
tracker, its plan, its last motion sample, what it has done), the task's target model and the
loop's clock and last joint command. The episode fills it in as it builds and updates it each
tick; an observer has nothing on it to step, command or draw a random number with.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pickdemo.perception import PerceptionParams, TargetModel
from pickdemo.runtime.world import World
from pickdemo.scenario.load import Scenario
from pickdemo.skills.controller import Controller


@dataclass
class EpisodeView:
    """A running episode as observers see it (read it; the episode writes it)."""

    scenario: Scenario
    seed: int
    open_loop: bool
    perception: PerceptionParams  # the perception's parameters (a viewer segments the frames as it did)
    world: World | None = None
    controller: Controller | None = None  # its read side: state, tracker, plan, last_sample, ...
    model: TargetModel | None = None  # what the robot is told of its target
    target_name: str = ""  # "" in a clear round
    dt_ctl: float = 0.0  # one control tick (s)
    frame_ticks: int = 1  # control ticks between camera frames
    tick: int = 0  # the control tick now
    last_command: np.ndarray | None = field(default=None, repr=False)  # this tick's joint command

    @property
    def truth_name(self) -> str:
        """The object the viewers label with its true pose: the target, or in a clear round the object
        nearest where the pick under way looks (truth: for viewers only, never for control)."""
        if self.target_name or self.world is None:
            return self.target_name
        at = getattr(self.controller, "look_at", None)
        names = [p.name for p in self.world.layout]
        if at is None:
            return names[0]
        return min(names, key=lambda n: float(np.linalg.norm(self.world.true_pose(n).position[:2] - at[:2])))
