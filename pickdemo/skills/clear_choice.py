"""Which object a clear round picks next: of every object a survey found, the one with the best
reachable top-down grasp (its cloud's, clear of the others' points:
:func:`~pickdemo.grasping.cloud.sample_grasps`), an object a pick failed on since the last that placed one
after the others. A part of :class:`~pickdemo.skills.clear.ClearSequencer`: it returns a choice, never
writes the round's state."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.grasping.cloud import sample_grasps
from pickdemo.grasping.top_down import GraspParams, top_down
from pickdemo.perception.unknown import SeenObject, Survey
from pickdemo.robot.kinematics import IKParams, Kinematics

#: After a failed pick, an object seen within this of where it was tried (m) ...
TRIED_RADIUS_M = 0.03
#: ... comes after the others: its grasp's cost is raised by this
TRIED_PENALTY = 10.0


@dataclass(frozen=True)
class Choice:
    """The object a survey chose and its best grasp's cost."""

    seen: SeenObject
    cost: float


class ObjectChooser:
    """The next object of a round, by its best reachable grasp (see the module docstring)."""

    def __init__(self, kin: Kinematics, rng: np.random.Generator, grasp: GraspParams, ik: IKParams) -> None:
        """``rng``: the IK's restarts; ``grasp``: the pick's heights; ``ik``: the solver's settings."""
        self.kin, self.rng, self.grasp, self.ik = kin, rng, grasp, ik

    def choose(self, survey: Survey, tried: list[np.ndarray]) -> Choice | None:
        """The object with the best reachable top-down grasp (None: no object has one); ``tried``: where
        picks failed since the last that placed an object."""
        best: Choice | None = None
        params = self.grasp
        for seen in survey.objects:
            was_tried = any(np.linalg.norm(seen.centre[:2] - t) < TRIED_RADIUS_M for t in tried)
            # the best few: the first that IK reaches
            for g in sample_grasps(seen.cloud, 0.0, self.kin.robot.gripper, params)[:3]:
                cost = g.cost + (TRIED_PENALTY if was_tried else 0.0)
                if best is not None and cost >= best.cost:
                    break
                if self._reachable(g.position, g.hand_yaw_rad):
                    best = Choice(seen, cost)
                    break
        return best

    def _reachable(self, position: np.ndarray, hand_yaw: float) -> bool:
        for yaw in (hand_yaw, hand_yaw + np.pi):
            for p in (position, position + np.array([0.0, 0.0, self.grasp.pregrasp_height_m])):
                res = self.kin.solve(top_down(p, yaw), self.kin.robot.home_q, self.rng, self.ik)
                if not res.success:
                    break
            else:
                return True
        return False
