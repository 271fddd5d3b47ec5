"""Which object a clear round picks next: of every object a survey found, the one with the best
reachable grasp from above (its cloud's, clear of the others' points and of the cell's fixtures: the
fingers' top-down grasps, :func:`~pickdemo.grasping.cloud.sample_grasps`, or a suction cup's seals along
a face's normal, :func:`~pickdemo.grasping.suction.sample_suction`), an object a pick failed on since
the last that placed one after the others; for a suction cup where none has a seal seen all round, the
best glimpsed one (the survey's sparse points: its rim's short sectors counted unseen); where no object
has one, the best reachable grasp from any side (:func:`~pickdemo.grasping.antipodal.sample_antipodal`),
if the robot's hand takes them; for a suction cup with no seal glimpsed on any, the largest object not
tried since the last place, for the pick's closer look. A part of
:class:`~pickdemo.skills.clear.ClearSequencer`: it returns a choice, never writes the round's state."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.grasping.antipodal import sample_antipodal
from pickdemo.grasping.cloud import sample_grasps
from pickdemo.grasping.suction import BEST_SEALS, SuctionGrasp, SuctionParams, sample_suction, suction_plan
from pickdemo.grasping.top_down import GraspParams, top_down
from pickdemo.motion.ik_goals import GoalParams, line_followed
from pickdemo.perception.unknown import SeenObject, Survey
from pickdemo.robot.kinematics import IKParams, Kinematics

#: After a failed pick, an object seen within this of where it was tried (m) ...
TRIED_RADIUS_M = 0.03
#: ... comes after the others: its grasp's cost is raised by this
TRIED_PENALTY = 10.0
#: The cost of an object chosen for a closer look where the survey showed no seal on any
UNSEEN_SEAL_COST = 20.0
#: A fixture's points this near an object (m, horizontally) are obstacles to its grasps
FIXTURES_NEAR_M = 0.2
#: An object's best grasps from above tried for reach, best first, before it is passed over (a suction
#: cup's: as many as the pick is offered, :data:`~pickdemo.grasping.suction.BEST_SEALS`)
REACH_TRIES = 3


@dataclass(frozen=True)
class Choice:
    """The object a survey chose and its best grasp's cost."""

    seen: SeenObject
    cost: float


class ObjectChooser:
    """The next object of a round, by its best reachable grasp (see the module docstring)."""

    def __init__(
        self,
        kin: Kinematics,
        rng: np.random.Generator,
        grasp: GraspParams,
        ik: IKParams,
        *,
        surface_z: Callable[[float, float], float] | None = None,
        fixture_points: np.ndarray | None = None,
        any_side: np.random.Generator | None = None,
        goals: GoalParams | None = None,
    ) -> None:
        """``rng``: the IK's restarts; ``grasp``: the pick's heights; ``ik``: the solver's settings;
        ``surface_z(x, y)``: what an object there rests on (None: the table); ``fixture_points``: points
        on the fixtures' faces, obstacles to every grasp; ``any_side``: the draw of grasps from any side
        (None: top-down only); ``goals``: a suction cup's descent must be followed as the pick will
        follow it (its straight line, at the near speed; None: not checked)."""
        self.kin, self.rng, self.grasp, self.ik, self.goals = kin, rng, grasp, ik, goals
        self.surface_z, self.fixture_points, self.any_side = surface_z, fixture_points, any_side

    def _surface(self, seen: SeenObject) -> float:
        return 0.0 if self.surface_z is None else self.surface_z(*(float(v) for v in seen.centre[:3]))

    def _cloud(self, seen: SeenObject):  # noqa: ANN202 - an ObjectCloud
        """The object's cloud with the fixtures' points near it among its obstacles."""
        pts = self.fixture_points
        if pts is None or len(pts) == 0:
            return seen.cloud
        near = pts[np.hypot(pts[:, 0] - seen.centre[0], pts[:, 1] - seen.centre[1]) <= FIXTURES_NEAR_M]
        if len(near) == 0:
            return seen.cloud
        return dataclasses.replace(seen.cloud, obstacles=np.vstack([seen.cloud.obstacles, near]))

    def choose(self, survey: Survey, tried: list[np.ndarray]) -> Choice | None:
        """The object with the best reachable grasp from above (a suction cup's: then the best glimpsed
        seal), else (none has one) with the best reachable grasp from any side (None: no object has one);
        ``tried``: where picks failed since the last that placed an object."""
        best = self._best(survey, tried)
        if best is None and self.kin.robot.gripper.suction:
            best = self._best(survey, tried, glimpsed=True)
        if best is None and self.any_side is not None:
            best = self._any_side(survey, tried)
        if best is None and self.kin.robot.gripper.suction:
            best = self._closer_look(survey, tried)
        return best

    def _closer_look(self, survey: Survey, tried: list[np.ndarray]) -> Choice | None:
        """Where no seal shows in the survey's sparse points, the largest object not tried since the last
        place, for the pick's closer look to judge (measured: ``suction_clear_tote`` seed 33 ended with 4
        parts of 30-67 points each, none with a seal glimpsed; a face a cup seals on is a few points
        across at the survey's stride). Its cost: :data:`UNSEEN_SEAL_COST`."""
        untried = [s for s in survey.objects if not _was_tried(s, tried)]
        if not untried:
            return None
        return Choice(max(untried, key=lambda s: s.n_px), UNSEEN_SEAL_COST)

    def _best(self, survey: Survey, tried: list[np.ndarray], *, glimpsed: bool = False) -> Choice | None:
        """The object with the best reachable grasp from above (None: none has one). ``glimpsed``: a
        suction cup's seal judged leniently, as the survey's sparse points allow (any of the rim's
        sectors short of the face counted as unseen): the pick looks closer and judges again."""
        best: Choice | None = None
        tries = BEST_SEALS if self.kin.robot.gripper.cup is not None else REACH_TRIES
        for seen in survey.objects:
            was_tried = _was_tried(seen, tried)
            # the best few: the first the arm reaches
            for g in self._grasps(seen, glimpsed)[:tries]:
                cost = g.cost + (TRIED_PENALTY if was_tried else 0.0)
                if best is not None and cost >= best.cost:
                    break
                if self._reaches(seen, g):
                    best = Choice(seen, cost)
                    break
        return best

    def _grasps(self, seen: SeenObject, glimpsed: bool = False) -> list:
        """An object's grasps from above, best first: the fingers' top-down ones (:func:`sample_grasps`) or
        a suction cup's seals (:func:`~pickdemo.grasping.suction.sample_suction`), as the robot's gripper is."""
        gripper, cloud = self.kin.robot.gripper, self._cloud(seen)
        if gripper.cup is not None:
            unknown = (lambda p: np.ones(len(p), dtype=bool)) if glimpsed else cloud.unknown
            return sample_suction(cloud.points, cloud.obstacles, self._surface(seen), gripper.cup, unknown=unknown)
        return sample_grasps(cloud, self._surface(seen), gripper, self.grasp)

    def _any_side(self, survey: Survey, tried: list[np.ndarray]) -> Choice | None:
        """The object with the best reachable grasp from any side."""
        best: Choice | None = None
        for seen in survey.objects:
            was_tried = _was_tried(seen, tried)
            cloud = self._cloud(seen)
            found = sample_antipodal(
                cloud.points, self._surface(seen), self.kin.robot.gripper, self.any_side, obstacles=cloud.obstacles,
                grasp=self.grasp,
            )  # fmt: skip
            for g in found[:3]:
                cost = g.cost + (TRIED_PENALTY if was_tried else 0.0)
                if best is not None and cost >= best.cost:
                    break
                grasp = Pose(g.position, g.rotation)
                pre = Pose(g.position - g.rotation[:, 2] * self.grasp.pregrasp_height_m, g.rotation)
                if all(self.kin.solve(p, self.kin.robot.home_q, self.rng, self.ik).success for p in (grasp, pre)):
                    best = Choice(seen, cost)
                    break
        return best

    def _reaches(self, seen: SeenObject, g) -> bool:  # noqa: ANN001 - a CloudGrasp or a SuctionGrasp
        """Whether the arm reaches a grasp and its pregrasp (a suction cup's: at any of four hand angles
        about a level cup's axis; a tilted one's as it comes along the face's normal)."""
        if not isinstance(g, SuctionGrasp):
            return self._reachable(g.position, g.hand_yaw_rad)
        for yaw in (0.0, np.pi / 2, np.pi, -np.pi / 2):
            plan = suction_plan(g, seen.centre, self._surface(seen), (0.0, 0.0), self.grasp, SuctionParams(), yaw)
            home = self.kin.robot.home_q
            at, above = (self.kin.solve(p, home, self.rng, self.ik) for p in (plan.grasp, plan.pregrasp))
            if at.success and above.success and self._descent_followed(at.q, plan):
                return True
            if g.tilt_rad > SuctionParams().level_rad:
                return False
        return False

    def _descent_followed(self, q_grasp: np.ndarray, plan) -> bool:  # noqa: ANN001 - a GraspPlan
        """Whether the per-tick IK follows the straight line between the pregrasp and the grasp fast enough
        (the pick's own test, :meth:`~pickdemo.skills.pick.chooser.GraspChooser.unreachable`)."""
        g = self.goals
        return g is None or line_followed(self.kin, q_grasp, plan.grasp, plan.pregrasp, g)

    def _reachable(self, position: np.ndarray, hand_yaw: float) -> bool:
        for yaw in (hand_yaw, hand_yaw + np.pi):
            for p in (position, position + np.array([0.0, 0.0, self.grasp.pregrasp_height_m])):
                res = self.kin.solve(top_down(p, yaw), self.kin.robot.home_q, self.rng, self.ik)
                if not res.success:
                    break
            else:
                return True
        return False


def _was_tried(seen: SeenObject, tried: list[np.ndarray]) -> bool:
    """Whether a pick failed where ``seen`` stands since the last that placed an object."""
    return any(np.linalg.norm(seen.centre[:2] - t) < TRIED_RADIUS_M for t in tried)
