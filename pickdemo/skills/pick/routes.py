"""How the arm gets around what is in the way (issue 59): the collision scene it plans in, built from
what the robot knows (the table and the fixtures from its task, the world model's objects as its
cameras saw them, grown by their uncertainty, and the held object's box in the hand), the check of a
straight motion (a joint transfer's line in joint space, the hand's Cartesian carry as the per-tick IK
follows it), and a joint path planned around the obstacles (:func:`~pickdemo.motion.planner.plan_joint_path`)
where that is not free.

A part of the pick skill: it answers with a :class:`Route`, never writes the machine's state. A
straight motion that is free stays straight; one whose ends are not free in this model (the model's
margins are wider than the hand's clearance the grasp chooser kept) is left to the straight motion,
and said (a planner asked for a path out of a wall would wait for ever).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, top_below
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.motion.ik_goals import along_line
from pickdemo.motion.planner import plan_joint_path
from pickdemo.robot.collision import TABLE, CollisionScene, Obstacle, robot_geometry
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.pick.upright import Upright, upright_carry
from pickdemo.worldmodel import WorldModel

#: An object's box is grown by this every way, beyond two of its standard deviations (m): the arm's
#: and the held object's clearance from what the cameras saw; a fixture's by this alone.
MARGIN_M = 0.01
#: The margin a motion is planned with when one of its ends is within the other (m): the hand at a
#: grasp beside a neighbour, the fixtures' own clearance.
TIGHT_MARGIN_M = 0.003
#: The held object's box is grown by this every way (m): it may turn a little in the fingers.
HELD_MARGIN_M = 0.01
#: A held object's box stood on a fixture whose top is this near its bottom (m): its box is grown by
#: :data:`HELD_MARGIN_M`, and a world model's box stands a little in or above what it rests on
FLOOR_M = 0.02
#: A straight Cartesian motion is checked every this far along it (m).
LINE_STEP_M = 0.02
#: A straight joint transfer is checked every this much of its largest joint's travel (rad).
JOINT_STEP_RAD = 0.02


@dataclass(frozen=True)
class Route:
    """How to get there: ``waypoints`` (K, dof) after the start, the last the goal (None: straight, the
    motion as asked); ``note`` says what was planned (or why not); ``failure`` what blocked a plan that
    failed; ``blocked`` what the straight motion would have met; the planner's effort."""

    waypoints: np.ndarray | None = None
    note: str | None = None
    failure: str | None = None
    checks: int = 0
    seconds: float = 0.0


STRAIGHT = Route()


def grown(box: OrientedBox, by_m: float | np.ndarray) -> OrientedBox:
    g = np.broadcast_to(np.asarray(by_m, dtype=float), (3,))
    return OrientedBox(box.pose, np.asarray(box.lo) - g, np.asarray(box.hi) + g)


def nearest_turn(q: np.ndarray, q_from: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """``q`` with each joint a whole turn nearer ``q_from`` where its limits allow: the same posture,
    the shorter way (an IK solution of a UR5's joints, free through two turns, can be a turn off)."""
    out = np.array(q, dtype=float)
    for i in range(len(out)):
        k = np.round((q_from[i] - out[i]) / (2.0 * np.pi))
        moved = out[i] + 2.0 * np.pi * k
        if k != 0 and lower[i] <= moved <= upper[i]:
            out[i] = moved
    return out


def held_box(world: WorldModel, tcp: Pose, solids: Sequence[OrientedBox] = ()) -> OrientedBox | None:
    """The held object's box in the TCP's frame (its world-model box where it stood, as the hand holds it
    now at ``tcp``), grown by :data:`HELD_MARGIN_M`; None: the world holds nothing for it. A world
    model's box stands on the table; one that stood on a fixture's top (a shelf's board, a bin's floor:
    the highest of ``solids``' tops under its middle) begins there, or its box held would be as tall
    again as it is, and could not be taken out between a shelf's boards."""
    target = world.target
    if target is None:
        return None
    box = target.box
    x, y, top = box.pose.position[0], box.pose.position[1], target.top_m
    floor = top_below(list(solids), float(x), float(y), top) if solids else None
    if floor is not None and 0.0 < floor < top:
        half = np.array([box.hi[0], box.hi[1], (top - floor) / 2.0])
        box = OrientedBox(Pose(np.array([x, y, (top + floor) / 2.0]), box.pose.rotation), -half, half)
    box = grown(box, HELD_MARGIN_M)
    return OrientedBox(tcp.inverse() @ box.pose, box.lo, box.hi)


def rise_over(held: OrientedBox, fixtures: Sequence[Obstacle], reach_m: float) -> float:
    """How far the held object's box ``held`` (in the world, as it is now) must rise for its bottom to clear,
    by :data:`MARGIN_M`, the fixture it was taken from: the walls within ``reach_m`` of it across of the
    fixture whose box it stood on (a bin's or a tote's floor: carried off lower, a part was dragged
    across a wall's top and knocked off). 0 if it stood on none (a wall beside a part on the table is
    the routes' to go around) or none stands above its bottom there."""
    c = held.corners()
    lo, hi, bottom = c[:, :2].min(0) - reach_m, c[:, :2].max(0) + reach_m, float(c[:, 2].min())
    x, y = (float(v) for v in held.pose.position[:2])
    names = set()  # the fixtures it stood on: one of their boxes' tops just under its bottom
    for o in fixtures:
        top = None if o.name == TABLE else top_below([o.box], x, y, bottom + FLOOR_M)
        if top is not None and top >= bottom - FLOOR_M:
            names.add(o.name)
    need = 0.0
    for o in fixtures:
        b = o.box.corners()
        if o.name in names and np.all(b[:, :2].max(0) >= lo) and np.all(b[:, :2].min(0) <= hi):
            need = max(need, float(b[:, 2].max()) + MARGIN_M - bottom)
    return need


class Router:
    """The collision scenes and routes of one pick (see the module docstring)."""

    def __init__(
        self, kin: Kinematics, fixtures: Sequence[Obstacle], rng: np.random.Generator, *, max_checks: int
    ) -> None:
        self.kin = kin
        #: the fixtures' solid parts as they are (what a held object stood on: :func:`held_box`)
        self.solids = tuple(o.box for o in fixtures if o.name != TABLE)
        self.named = tuple(fixtures)  # (each box by its fixture's name: a bin's floor and walls are one)
        # (the fixtures grown by the margin: the arm follows its commands to within millimetres)
        self.fixtures = tuple(o if o.name == TABLE else Obstacle(o.name, grown(o.box, MARGIN_M)) for o in fixtures)
        self.rng = rng  # the planner's seeds, one per plan
        self.max_checks = max_checks
        self.plans = 0
        self.seconds: list[float] = []  # each plan's wall time (the profile's and the bench's)
        self.checks: list[int] = []  # the states each plan checked (none found: its budget)
        self.path: np.ndarray | None = None  # (N, 3) the TCP along the last path planned, for drawing

    def scene(
        self,
        world: WorldModel,
        *,
        held: OrientedBox | None = None,
        held_at: tuple[np.ndarray, float] | None = None,
        margin_m: float = MARGIN_M,
    ) -> CollisionScene:
        """The robot among the fixtures and the world's objects but the target (the hand goes to it,
        or holds it: then ``held``, its box in the TCP's frame, taken with the arm ``held_at``), each grown
        by ``margin_m`` (an object's by two of its standard deviations besides). Its ``tighter``: the same
        at :data:`TIGHT_MARGIN_M`."""
        grow = margin_m - MARGIN_M
        obstacles = [o if o.name == TABLE else Obstacle(o.name, grown(o.box, grow)) for o in self.fixtures]
        for obj in world.objects.values():
            if obj.is_target or len(obj.by_camera) == 0:
                continue
            sigma = np.sqrt(np.clip(np.diag(obj.cov), 0.0, None))
            obstacles.append(Obstacle(f"object {obj.id}", grown(obj.box, margin_m + 2.0 * sigma)))
        for box in world.seen_in_part():  # (the newest view showed it only in part: not an object yet)
            obstacles.append(Obstacle("something seen in part", grown(box, margin_m)))
        scene = CollisionScene(robot_geometry(self.kin.robot), obstacles, held, held_at)
        tighter = margin_m > TIGHT_MARGIN_M
        tight = TIGHT_MARGIN_M
        scene.tighter = (lambda: self.scene(world, held=held, held_at=held_at, margin_m=tight)) if tighter else None
        return scene

    def joint(self, scene: CollisionScene, q_from: np.ndarray, q_goal: np.ndarray, fingers_m: float) -> Route:
        """A transfer in joint space to ``q_goal`` (each joint a whole turn nearer where it can be): straight
        if its line is free, else a planned path."""
        self.path = None  # (a new motion: the last path drawn no more)
        near = nearest_turn(q_goal, q_from, self.kin.lower, self.kin.upper)  # (the same posture, the shorter way)
        if not scene.model.collisionPairs or scene.segment_free(q_from, near, fingers_m, JOINT_STEP_RAD):
            return STRAIGHT if np.array_equal(near, q_goal) else Route(waypoints=near[None, :])
        return self._plan(
            scene, q_from, near, fingers_m, scene.segment_contact(q_from, near, fingers_m, JOINT_STEP_RAD)
        )

    def straight_free(self, scene: CollisionScene, q_from: np.ndarray, q_goal: np.ndarray, fingers_m: float) -> bool:
        """Whether the straight joint transfer to ``q_goal`` (the shorter way, as :meth:`joint` goes) is free."""
        near = nearest_turn(q_goal, q_from, self.kin.lower, self.kin.upper)
        return not scene.model.collisionPairs or scene.segment_free(q_from, near, fingers_m, JOINT_STEP_RAD)

    def path_contact(
        self, scene: CollisionScene, q_from: np.ndarray, waypoints: Sequence[np.ndarray], fingers_m: float
    ) -> tuple[str, str] | None:
        """What the straight joint path from ``q_from`` through ``waypoints`` would meet first (as
        :meth:`~pickdemo.robot.collision.CollisionScene.contact`), or None; None too where its start
        meets something already (the arm leaving it: a motion taken straight knowingly, as :meth:`joint` does)."""
        if not scene.model.collisionPairs or not waypoints or scene.contact(q_from, fingers_m) is not None:
            return None
        q = q_from
        for w in waypoints:
            hit = scene.segment_contact(q, w, fingers_m, JOINT_STEP_RAD)
            if hit is not None:
                return hit
            q = w
        return None

    def line_blocked(
        self,
        scene: CollisionScene,
        q_from: np.ndarray,
        ends: Sequence[Pose],
        fingers_m: float,
        posture: np.ndarray | None = None,
        *,
        untracked: bool = False,
    ) -> tuple[str, str] | None:
        """What the hand's straight Cartesian motion through ``ends`` (one line after another) from the
        arm at ``q_from`` would meet first, as the per-tick IK follows it (held to ``posture``, the Cartesian
        motion's, if given; the link, what it meets), or None."""
        if not scene.model.collisionPairs:
            return None
        q, start = q_from, self.kin.forward(q_from)
        for end in ends:
            n = max(2, int(np.ceil(float(np.linalg.norm(end.position - start.position)) / LINE_STEP_M)))
            for q_k in along_line(self.kin, q, start, end, n, posture):
                if q_k is None:  # (not followed to its end: the caller's checks say so, or it is said)
                    return ("the hand's line", "the arm's reach") if untracked else None
                hit = scene.contact(q_k, fingers_m)
                if hit is not None:
                    return hit
                q = q_k
            start = end
        return None

    def clearance(self, scene: CollisionScene, fingers_m: float) -> Callable[[np.ndarray, np.ndarray], bool]:
        """``clear(q_a, q_b)``: whether the straight joint path between two configurations keeps clear
        (for the legs of a way over the top, :meth:`~pickdemo.skills.pick.arm.ArmDriver.over_the_top`)."""
        return lambda qa, qb: scene.segment_free(qa, qb, fingers_m, JOINT_STEP_RAD)

    def accepting(
        self, scene: CollisionScene, ends: Sequence[Pose], fingers_m: float
    ) -> Callable[[np.ndarray, int], bool]:
        """``accept(q, i)`` for :meth:`~pickdemo.skills.pick.arm.ArmDriver.goal`: whether the arm at ``q``,
        and the straight line from the hand's pose there to ``ends[i]`` (a descent to the grasp, a lowering
        to the place), keep clear (what the hand touches at its end is allowed: the target is no obstacle,
        and the held object is not checked against the table)."""

        def accept(q: np.ndarray, i: int) -> bool:
            return scene.contact(q, fingers_m) is None and self.line_blocked(scene, q, [ends[i]], fingers_m) is None

        return accept

    def accepting_near(
        self, scene: CollisionScene, ends: Sequence[Pose], fingers_m: float
    ) -> Callable[[np.ndarray, int], bool] | None:
        """:meth:`accepting` within the scene's tight margins (its ``tighter``, made when first asked;
        None: it has none, or the task has no fixtures: the tight margins are for known geometry, a
        shelf's boards; among seen objects only, whose margins carry their uncertainty, a goal whose
        line can be followed is taken as before, and a packed table's rounds cleared fewer objects)."""
        if scene.tighter is None or not self.solids:
            return None
        make = scene.tighter
        tight: list[CollisionScene] = []

        def near(q: np.ndarray, i: int) -> bool:
            if not tight:
                tight.append(make())
            return self.accepting(tight[0], ends, fingers_m)(q, i)

        return near

    def accepting_fixed(
        self, ends: Sequence[Pose], fingers_m: float, followed: Callable[[np.ndarray, int], bool]
    ) -> Callable[[np.ndarray, int], bool] | None:
        """:meth:`accepting` among the fixtures alone, as they are (the world's objects aside; as the grasp
        chooser checks a plan, ``arm_meets_fixture``: a cup's tube passes a bin's wall within millimetres),
        where ``followed(q, i)`` says the arm follows the line to ``ends[i]`` as it will make it (a check of
        a line not followed would pass it): where no goal keeps clear of everything, one whose posture and
        line keep off a bin's walls before one that does not (in a heap, no goal of a cup's tilted way in
        kept clear of the neighbours, and the goal taken then ended its descent with the upper arm on the
        bin's wall, 16 mm short of the face: 8 of 8 cups that met nothing in ``suction_clear_bin`` and
        ``_tote``, measured). None: the task has no fixtures."""
        if not self.solids:
            return None
        clear = self.accepting(CollisionScene(robot_geometry(self.kin.robot), list(self.named)), ends, fingers_m)
        return lambda q, i: followed(q, i) and clear(q, i)

    def free_share(
        self, scene: CollisionScene, q_from: np.ndarray, end: Pose, fingers_m: float, posture: np.ndarray | None = None
    ) -> float:
        """How much of the hand's straight Cartesian motion to ``end`` from the arm at ``q_from`` keeps
        clear, as a share of its length (1.0: all of it; a lift stops below what it would meet)."""
        if not scene.free(q_from, fingers_m):
            return 1.0  # (it starts within a margin, beside its neighbour: the margin says nothing of the way up)
        start = self.kin.forward(q_from)
        n = max(2, int(np.ceil(float(np.linalg.norm(end.position - start.position)) / LINE_STEP_M)))
        for k, q_k in enumerate(along_line(self.kin, q_from, start, end, n, posture), start=1):
            if q_k is None:
                return 1.0  # (not followed to its end: the caller's checks say so)
            if not scene.free(q_k, fingers_m):
                return (k - 1) / n
        return 1.0

    def upright(
        self,
        scene: CollisionScene,
        q: np.ndarray,
        plan: GraspPlan,
        fingers_m: float,
        goal: Callable[[GraspPlan, np.ndarray], np.ndarray | None],
    ) -> Upright | None:
        """An item held from the side carried upright, clear in ``scene``
        (:func:`~pickdemo.skills.pick.upright.upright_carry`): a plan of its own, its time and the
        states it checked kept with the planner's."""
        t0, checked = time.perf_counter(), scene.checks
        carry = upright_carry(self.kin, q, plan, lambda q_k: scene.free(q_k, fingers_m), goal)
        self.plans += 1
        self.seconds.append(time.perf_counter() - t0)
        self.checks.append(scene.checks - checked)
        return carry

    def _tcp_along(self, waypoints: np.ndarray, per_leg: int = 12) -> np.ndarray:
        """The TCP's positions along a joint path (each leg a straight line in joint space)."""
        legs = [a + (b - a) * t for a, b in zip(waypoints[:-1], waypoints[1:], strict=True)
                for t in np.linspace(0.0, 1.0, per_leg, endpoint=False)]  # fmt: skip
        return np.array([self.kin.forward(q).position for q in [*legs, waypoints[-1]]])

    def _plan(
        self,
        scene: CollisionScene,
        q_from: np.ndarray,
        q_goal: np.ndarray,
        fingers_m: float,
        hit: tuple[str, str] | None,
    ) -> Route:
        said = "" if hit is None else f"{hit[0]} would meet {hit[1]}"
        for end, q in (("start", q_from), ("goal", q_goal)):
            at = scene.contact(q, fingers_m)
            if at is not None and scene.tighter is not None:  # (a hand beside its target is within a margin)
                return self._plan(scene.tighter(), q_from, q_goal, fingers_m, hit)
            if at is not None:  # (within even the tight margin: straight, as before)
                within = f"{at[0]} within {TIGHT_MARGIN_M * 1e3:.0f} mm of {at[1]}"
                return Route(note=f"{said} on the straight way, but the {end} is not free ({within}): going straight")
        t0 = time.perf_counter()
        seed = int(self.rng.integers(2**31 - 1))
        path = plan_joint_path(
            q_from, q_goal, self.kin.lower, self.kin.upper, lambda q: scene.free(q, fingers_m), seed,
            max_checks=self.max_checks,
        )  # fmt: skip
        seconds = time.perf_counter() - t0
        self.plans += 1
        self.seconds.append(seconds)
        self.checks.append(self.max_checks if path is None else path.checks)
        if path is None:
            return Route(failure=f"no path found in {self.max_checks} states checked: {said}", seconds=seconds)
        waypoints = path.waypoints[1:]
        self.path = self._tcp_along(path.waypoints)
        note = f"planned around: {said} on the straight way, so by {len(waypoints) - 1} waypoint(s)"
        return Route(waypoints=waypoints, note=note, checks=path.checks, seconds=seconds)
