"""Which grasp: the selector's grasps of the target as tracked, and which of a grasp's equivalent hand
angles the arm takes, by IK (joint-limit margin, a carry the joints can follow, then joint travel; no
rule of a particular joint). A part of the pick skill: it returns a plan or a failure, never writes
the machine's state."""

from __future__ import annotations

import dataclasses

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, wrap_angle
from pickdemo.core.result import Failure, Stage
from pickdemo.grasping.clearance import near as boxes_near
from pickdemo.grasping.selection import GraspRequest, GraspSelector
from pickdemo.grasping.side_plans import LEAST_LIFT_M
from pickdemo.grasping.top_down import GraspPlan, GraspPlanningError
from pickdemo.motion.ik_goals import along_line, goal_candidates, line_followed, line_reach, line_speed_scale
from pickdemo.motion.lines import rise_followed
from pickdemo.motion.online import pose_to_x4
from pickdemo.perception import ObjectCloud, TargetModel
from pickdemo.perception.neighbours import NEIGHBOURHOOD_M, OWN_MARGIN_M
from pickdemo.robot.collision import CollisionScene, Obstacle, robot_geometry
from pickdemo.robot.kinematics import IKParams, Kinematics
from pickdemo.skills.pick.arm import ArmDriver
from pickdemo.skills.pick.intercept import Interceptor, leaves_reach
from pickdemo.skills.pick.params import MachineParams
from pickdemo.skills.pick.plans import turned_plan
from pickdemo.tracking.belief import TargetBelief
from pickdemo.worldmodel import WorldModel

DESCENT_OUT_OF_REACH = "the straight descent onto the grasp is out of reach"
WAY_OUT_NOT_FOLLOWED = "the arm cannot follow the lift from among the fixtures"
SEEN_IN_PART = "something seen in part"
#: A fixture's boxes this near the target are the grasps' concern (m): the open hand about it, from its pregrasp
SOLIDS_NEAR_M = 0.5
#: ... and the world's objects, beside a target nobody described (m)
CLOUD_NEAR_M = 0.25
#: ... and the arm's (m): its links from the hand to the elbow
ARM_NEAR_M = 0.8


class GraspChooser:
    """Grasp plans for the target where the belief says it is, each checked against the arm by IK."""

    def __init__(
        self,
        kin: Kinematics,
        rng: np.random.Generator,
        params: MachineParams,
        model: TargetModel,
        place_xy: tuple[float, float],
        selector: GraspSelector,
        belief: TargetBelief,
        arm: ArmDriver,
        intercept: Interceptor,
        fixture_points: np.ndarray | None = None,
        solids: tuple[OrientedBox, ...] = (),
        world: WorldModel | None = None,
    ) -> None:
        """``fixture_points``: points on the cell's fixtures' faces (a bin's walls), known from the task:
        the hand keeps out of them as it does out of what the camera sees beside the target; ``solids``:
        every fixture's boxes (a shelf's too), which the open hand and the arm keep out of; ``world``:
        the robot's world model, whose objects but the target the hand keeps out of."""
        self.world = world
        self.kin, self.rng, self.p, self.model, self.place_xy = kin, rng, params, model, place_xy
        self.fixture_points, self.solids = fixture_points, solids
        #: this target's grasps that held nothing or let it slip: the selector's grasps from any side
        #: come first after one (:class:`~pickdemo.grasping.selection.TopDownFirst`)
        self.misses = 0
        self.still = True  # the target stood still at the last plan (a grasp from the side is for one that does)
        self.selector, self.belief, self.arm, self.intercept = selector, belief, arm, intercept
        self.plan_id = 0  # counts first plans (the grasp selector's plan_id)
        self._room_checked: tuple[np.ndarray, bool] | None = None  # a re-plan's last check of joint room
        #: this attempt's pregrasp, lowered this far (m) to where the arm follows the descent (:meth:`lowered`)
        self.descent_drop_m = 0.0

    def request(self, pose: Pose, hand_yaws: tuple[float | None, ...]) -> GraspRequest:
        """What the selector is asked: the target at ``pose`` (and, seen as a cloud, its newest view)."""
        surface = self.belief.surface_z(*(float(v) for v in pose.position))
        cloud, obstacles = self.belief.cloud, self._obstacles(pose)
        # beside one nobody described, the world's other objects; in a heap (objects touching), what its
        # own view split off around it (measured: clearing piles lost 5 of 50 objects with the world's)
        heap = bool(getattr(self.model.geometry, "heap", False))
        if cloud is not None and self.world is not None and self.world.objects and not heap:
            cloud = dataclasses.replace(
                cloud, obstacles=self.world.obstacles(pose.position, CLOUD_NEAR_M, seen=cloud.points)
            )
        if cloud is None and not self.belief.unknown:  # a described target: its known surface where it is
            cloud = ObjectCloud(pose.transform_points(self.model.geometry.surface_points()), np.zeros((0, 3)), 0.0)
        near = self._fixtures_near(pose)
        if near is not None:
            obstacles = near if obstacles is None else np.vstack([obstacles, near])
            if cloud is not None:
                cloud = dataclasses.replace(cloud, obstacles=np.vstack([cloud.obstacles, near]))
        return GraspRequest(
            pose,
            self.model,
            self.place_xy,
            hand_yaws,
            cloud=cloud,
            surface_z=surface,
            plan_id=self.plan_id,
            obstacles=obstacles,
            gripper=self.kin.robot.gripper,
            misses=self.misses,
            still=self.still,
            fixtures=boxes_near(self.solids, pose.position, SOLIDS_NEAR_M) if self.solids else (),
        )

    def _obstacles(self, pose: Pose) -> np.ndarray | None:
        """What stands around a described target, from the world model: every object but the target
        within the hand's reach (an estimator's own neighbours where the world has no object at all;
        None for a target nobody described: its cloud says what stands beside it)."""
        if self.world is None or not self.world.objects:
            return self.belief.neighbours
        if self.belief.unknown:  # (its cloud's obstacles say it)
            return None
        shape = self.model.geometry
        own = (shape.footprint_radius_m + OWN_MARGIN_M, float(pose.position[2]) + shape.height_m / 2.0 + OWN_MARGIN_M)
        return self.world.obstacles(pose.position, NEIGHBOURHOOD_M, own)

    def _fixtures_near(self, pose: Pose) -> np.ndarray | None:
        """The fixtures' points within the open hand's reach of the target (None: none)."""
        pts = self.fixture_points
        if pts is None or len(pts) == 0:
            return None
        g = self.kin.robot.gripper
        # the open hand about the target, its palm, and how far a grasp may be from the target's centre
        reach = g.finger_max_m + g.finger_thickness_m + max(g.palm_half_length_m, g.palm_half_width_m) + 0.1
        near = pts[np.hypot(pts[:, 0] - pose.position[0], pts[:, 1] - pose.position[1]) <= reach]
        return near if len(near) else None

    def grasp(self, pose: Pose, near: float | None) -> GraspPlan:
        """The selector's best grasp for the target at ``pose`` with the hand angle nearest ``near`` (its
        pregrasp as low as this attempt's first plan had it)."""
        plan = next(iter(self.selector.candidates(self.request(pose, (near,)))))
        return lower_pregrasp(plan, self.descent_drop_m) if self.descent_drop_m else plan

    def best_ik(self, pose: Pose, seeds: list[np.ndarray]) -> np.ndarray | None:
        """Of the IK solutions of ``pose`` from each of ``seeds``, the one with the most joint-limit
        margin; None if none converged."""
        best = None
        for seed in seeds:
            res = self.kin.solve(pose, seed, self.rng, self.p.goals.ik)
            if res.success and (best is None or self.kin.limit_margin(res.q) > self.kin.limit_margin(best)):
                best = res.q
        return best

    def room_kept(self, plan: GraspPlan) -> bool:
        """Whether the arm, on the branch it is on, still holds this plan's pregrasp with every joint
        ``min_margin_rad`` from its limits (a re-plan's check; re-used while the pose moves less than
        a millimetre and a half-degree: the tracker moves it that much a frame)."""
        x4 = pose_to_x4(plan.pregrasp)
        last = self._room_checked
        if last is not None and np.all(np.abs(x4 - last[0]) < np.array([1e-3, 1e-3, 1e-3, np.radians(0.5)])):
            return last[1]
        q = self.best_ik(plan.pregrasp, [self.arm.q])  # on the branch the arm is on
        kept = q is not None and self.kin.limit_margin(q) >= self.p.goals.min_margin_rad
        self._room_checked = (x4, kept)
        return kept

    def hand_angle_score(self, plan: GraspPlan, held: np.ndarray | None) -> tuple[bool, bool, float]:
        """How the arm would do this plan's pick and place with its hand angle, by IK: whether the
        grasp (where it will be held, for a moving target) has a solution; whether the hand can then
        go straight to the place with the joints following continuously (the carry: the angle's
        joint 7 turns with the arm's bearing, and past its stop the carry cannot follow) and every
        joint ``min_margin_rad`` clear of its limits at both ends; and the joint travel (s at the
        speed limits) from here to the grasp and on to the place."""
        q_now = self.arm.q
        grasp = plan.grasp if held is None else Pose(np.array([*held, plan.grasp.position[2]]), plan.grasp.rotation)
        home, v_max = self.kin.robot.home_q, self.kin.robot.limits.max_velocity_rad_s
        best = self.best_ik(grasp, [q_now] if np.array_equal(q_now, home) else [q_now, home])
        if best is None:
            return False, False, 0.0
        g = dataclasses.replace(self.p.goals, line_steps=self.p.goals.line_steps // 2)
        q_end = best
        for q_k in along_line(self.kin, best, grasp, plan.place, g.line_steps):
            if q_k is None:
                q_end = None
                break
            q_end = q_k
        travel = float(np.max(np.abs(best - q_now) / v_max))
        if q_end is None:
            return True, False, travel
        travel += float(np.max(np.abs(q_end - best) / v_max))
        margin = min(self.kin.limit_margin(best), self.kin.limit_margin(q_end))
        return True, margin >= g.min_margin_rad, travel

    def ranked_hand_yaws(self, pose: Pose, held: np.ndarray | None, other_faces_than: tuple[float, ...]) -> list[float]:
        """The target's equivalent hand angles (the selector's ``hand_yaws``), best
        first by IK (:meth:`hand_angle_score`): those whose grasp has a solution; of them those from
        which the carry to the place can be followed with room at both ends; then the least joint
        travel, or for a moving target the least turn of the hand from where it is (turning the
        wrist while chasing a target across the table drifts the arm's redundancy towards a
        singularity, measured). ``other_faces_than``: hand angles that missed the target, or whose
        finger touched something beside it: the other faces first (a cube's other pair; the hand
        turned half a turn is the same grasp)."""
        scored = []
        try:
            yaws = self.selector.hand_yaws(self.request(pose, (None,)))
        except GraspPlanningError:
            return []
        for yaw in yaws:
            try:
                plan = self.grasp(pose, yaw)
            except GraspPlanningError:
                return []
            feasible, carries, travel = self.hand_angle_score(plan, held)
            same_faces = any(abs(float(wrap_angle(yaw - bad, np.pi))) < np.pi / 4 for bad in other_faces_than)
            turn = abs(float(wrap_angle(yaw - float(self.arm.motion.setpoint[3]))))
            scored.append(((not feasible, same_faces, not carries, turn if held is not None else travel), yaw))
        return [yaw for _, yaw in sorted(scored, key=lambda kv: kv[0])]

    def replan(
        self, pose: Pose, v: np.ndarray | None, current: GraspPlan | None, *, hand_over_target: bool,
        approaching: bool, now_s: float,
    ) -> GraspPlan | Failure:  # fmt: skip
        """A re-plan for the target at ``pose``: it keeps the hand's angle, unless IK says the arm would
        then be left without room at the grasp (and the hand is not yet going down over the target);
        ``approaching`` a moving target: still in reach where it will be met?"""
        held = None if v is None else pose.position[:2] + v * self.p.grasp_time_s
        self.still = v is None
        near = None if current is None else current.hand_yaw_rad
        try:
            plan = self.grasp(pose, near)
            if not self.room_kept(plan):  # this hand angle is running out of room: choose again
                ranked = self.ranked_hand_yaws(pose, held, ())
                # ... but not with the hand going down over the target (the room was judged before
                # it went down; another angle there reads as the target turning, and backed the
                # hand off again and again)
                other = ranked and abs(float(wrap_angle(ranked[0] - plan.hand_yaw_rad))) > 1e-6
                if other and not hand_over_target:
                    plan = self.grasp(pose, ranked[0])
        except GraspPlanningError as exc:
            return Failure(Stage.GRASP_PLANNING, str(exc))
        if approaching and v is not None:  # still in reach?
            reason = self.intercept.out_of_reach(plan, now_s)
            if reason:
                return Failure(Stage.IK, reason)
        return plan

    def first_plan(
        self, pose: Pose, v: np.ndarray | None, avoid: tuple[float, ...], now_s: float
    ) -> GraspPlan | Failure:
        """An attempt's first plan: the best of the equivalent hand angles by IK
        (:meth:`ranked_hand_yaws`) that the whole pick and place can reach; the other faces before
        those of the angles in ``avoid`` (it missed there, or a finger touched something beside it).
        After a miss, when the grasps the selector puts first then (from any side) give no plan the arm
        can do, the plan is asked for again as before any miss (from above, another angle): a grasp
        that may hold before a failure that is certain."""
        plan = self._first_plan(pose, v, avoid, now_s)
        if isinstance(plan, Failure) and self.misses and plan.stage in (Stage.IK, Stage.GRASP_PLANNING):
            misses, self.misses = self.misses, 0
            try:
                again = self._first_plan(pose, v, avoid, now_s)
            finally:
                self.misses = misses
            if not isinstance(again, Failure):
                return again
        return plan

    def _first_plan(
        self, pose: Pose, v: np.ndarray | None, avoid: tuple[float, ...], now_s: float
    ) -> GraspPlan | Failure:
        held = None if v is None else pose.position[:2] + v * self.p.grasp_time_s
        self.still = v is None
        self.plan_id += 1  # a first plan: the selector plans afresh
        self.descent_drop_m = 0.0
        try:
            hand_yaws = self.ranked_hand_yaws(pose, held, avoid) or [None]
            candidates = iter(self.selector.candidates(self.request(pose, tuple(hand_yaws))))
        except GraspPlanningError as exc:
            return Failure(Stage.GRASP_PLANNING, str(exc))
        first_reason = ""  # the best-ranked hand angle's reason, if no angle will do
        steep: list[GraspPlan] = []  # plans whose descent alone the arm cannot follow from the full height
        unsure: list[GraspPlan] = []  # plans whose arm meets only what was seen in part (its extent a guess)
        for _ in hand_yaws:
            try:
                plan = next(candidates)
            except GraspPlanningError as exc:
                return Failure(Stage.GRASP_PLANNING, str(exc))
            reason = self.unreachable(plan, now_s)
            if isinstance(reason, Failure):
                return reason
            if not reason:
                return plan
            first_reason = first_reason or reason
            if reason == DESCENT_OUT_OF_REACH:
                steep.append(plan)
            if SEEN_IN_PART in reason:
                unsure.append(plan)
        for plan in steep:  # (only when no angle will do from the full height: the others' plans are as before)
            lowered = self.lowered(plan, now_s)
            if lowered is not None:
                return lowered
        if unsure:  # (never refused on a guess: the routes and the path watch go around what it is)
            return unsure[0]
        return Failure(Stage.IK, first_reason)

    def lowered(self, plan: GraspPlan, now_s: float) -> GraspPlan | None:
        """The plan with its pregrasp lowered to where the arm follows the descent from the grasp's IK
        solution up (:func:`~pickdemo.motion.ik_goals.line_reach`), no lower than ``min_descent_share``
        of the pregrasp's height; None if that will not do. Sets :attr:`descent_drop_m` for the attempt's
        re-plans."""
        height = float(plan.pregrasp.position[2] - plan.grasp.position[2])
        res = self.kin.solve(plan.grasp, self.arm.motion.q, self.rng, IKParams())
        if not res.success or height <= 0.0:
            return None
        steps = self.p.goals.line_steps
        reached = round(line_reach(self.kin, res.q, plan.grasp, plan.pregrasp, self.p.goals) * steps)
        for k in range(reached, 0, -1):  # the highest start whose whole plan the arm can do
            if k / steps < self.p.min_descent_share:
                break
            drop = height * (1.0 - k / steps)
            low = lower_pregrasp(plan, drop)
            if not self.unreachable(low, now_s):
                self.descent_drop_m = drop
                return low
        return None

    def _solids_near(self, at: np.ndarray) -> list[Obstacle]:
        """The fixtures' boxes near ``at``, and what the world model's newest views showed there in part."""
        near = [Obstacle("a fixture", b) for b in boxes_near(self.solids, at, ARM_NEAR_M)]
        pieces = () if self.world is None else tuple(self.world.seen_in_part())
        return near + [Obstacle(SEEN_IN_PART, b) for b in boxes_near(pieces, at, ARM_NEAR_M)]

    def arm_meets_fixture(self, plan: GraspPlan, q_grasp: np.ndarray) -> str:
        """Where the arm (its links' collision geometry, the fingers open as the plan opens them) would
        meet a fixture (or something seen in part) on this plan's way in and out: at the grasp (its IK
        solution ``q_grasp``), the pregrasp, and where it takes the target out to ("" if nowhere)."""
        solids = self._solids_near(plan.grasp.position)
        if not solids:
            return ""
        poses = [("pregrasp", plan.pregrasp)] + ([("way out", plan.withdraw)] if plan.withdraw is not None else [])
        scene = CollisionScene(robot_geometry(self.kin.robot), solids)
        fingers = plan.open_m or self.kin.robot.gripper.finger_max_m
        hit = scene.contact(q_grasp, fingers)
        if hit is not None:
            # the arm's other postures at the grasp (a 7-joint arm's elbow has room to move) before refusing
            others = goal_candidates(self.kin, [plan.grasp], q_grasp, self.rng, self.p.goals)
            free = [c.q for c in others if scene.free(c.q, fingers)]
            if not free:
                return f"the arm would meet {hit[1]} at the grasp"
            q_grasp = free[0]
        for name, pose in poses:
            res = self.kin.solve(pose, q_grasp, self.rng, IKParams())
            hit = scene.contact(res.q, fingers) if res.success else None
            if hit is not None:
                return f"the arm would meet {hit[1]} at the {name}"
        return ""

    def takes_out(self, plan: GraspPlan, q_grasp: np.ndarray) -> bool:
        """Whether the arm, at the grasp as ``q_grasp`` or in another of its postures there, can follow
        the plan's lift from among the fixtures as a straight line (run as a joint path:
        :func:`~pickdemo.motion.lines.line_in_joints`) at least :data:`LEAST_LIFT_M`, over a shelf's
        lip (the lift goes as high as the arm follows it, the way out level from there as far as it
        follows that, and the carry's plan from there: a Panda's level hand reaches 5-20 cm over the
        table 55 cm out, `tests/hand_reach.py`)."""

        def lifts(q: np.ndarray) -> bool:
            return rise_followed(self.kin, q, plan.lift, self.rng, self.p.goals.ik) >= LEAST_LIFT_M - 1e-3

        if lifts(q_grasp):
            return True
        return any(lifts(c.q) for c in goal_candidates(self.kin, [plan.grasp], q_grasp, self.rng, self.p.goals))

    def _descent_followed(self, plan: GraspPlan, q_grasp: np.ndarray) -> bool:
        """Whether the per-tick IK follows the descent from the grasp's IK solution ``q_grasp`` up, or from
        the one found from home (the approach chooses its goal among several, ``ArmDriver.goal``: the
        arm's branch where it happens to be may pass a singular posture that another does not)."""
        g = self.p.goals
        if line_followed(self.kin, q_grasp, plan.grasp, plan.pregrasp, g):
            return True
        res = self.kin.solve(plan.grasp, self.kin.robot.home_q, self.rng, IKParams())
        return res.success and line_followed(self.kin, res.q, plan.grasp, plan.pregrasp, g)

    def unreachable(self, plan: GraspPlan, now_s: float) -> str | Failure:
        """Why the arm cannot do this plan's pick and place ("" if it can; a failure to end the episode
        at once: a moving target that cannot be met at all)."""
        reach = self.intercept.reach_targets(plan, now_s)
        if isinstance(reach, str):
            return Failure(Stage.IK, reach)
        q = self.arm.motion.q
        floor = self.p.goals.min_line_speed_scale
        for name, target in (*reach, ("place", plan.place)):
            res = self.kin.solve(target, q, self.rng, IKParams())
            if not res.success:
                if name not in ("grasp", "place"):  # a moving target's
                    return leaves_reach(name)
                return f"{name} pose out of reach: {res.reason}"
            if name == "grasp":
                meets = self.arm_meets_fixture(plan, res.q)
                if meets:
                    return meets
                if plan.withdraw is not None and not self.takes_out(plan, res.q):
                    return WAY_OUT_NOT_FOLLOWED
            if name == "grasp" and not self._descent_followed(plan, res.q):
                # The descent follows the vertical line from the pregrasp (a small arm's hand points down
                # only low near its base, and a jaw's TCP is beside the object, on the side its angle
                # puts it); the lift goes up it as far as the arm follows (:meth:`ArmDriver.lift_in_reach`).
                return DESCENT_OUT_OF_REACH
        # Above the place, some IK solution from which the lowering can be followed: with joint
        # transfers the carry may go in joint space to any of them, the hand turned half a turn or not.
        lines = [(plan.place_above, plan.place)]
        if self.p.joint_transfers:
            turned = turned_plan(plan, pick=False, place=True)
            lines.append((turned.place_above, turned.place))
            found = goal_candidates(self.kin, [a for a, _ in lines], q, self.rng, self.p.goals)
            above = [(g.q, *lines[g.index]) for g in found]
        else:
            res = self.kin.solve(plan.place_above, q, self.rng, IKParams())
            above = [(res.q, *lines[0])] if res.success else []
        if not above:
            return "the pose above the place is out of reach"
        if all(line_speed_scale(self.kin, q, start, end, self.p.goals) < floor for q, start, end in above):
            return "the straight lowering onto the place passes too near a singular posture"
        return ""


def lower_pregrasp(plan: GraspPlan, drop_m: float) -> GraspPlan:
    """The plan with its pregrasp ``drop_m`` lower (the descent onto the grasp starts there)."""
    pre = Pose(plan.pregrasp.position - np.array([0.0, 0.0, drop_m]), plan.pregrasp.rotation)
    return dataclasses.replace(plan, pregrasp=pre)
