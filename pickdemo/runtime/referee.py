"""Scoring an episode against the simulator's truth, as it runs and at its end.

The referee reads the truth (the target's true pose and speed) and nothing it measures ever reaches
the controller: how far each estimate was off when its frame was taken (and whether the controller
acted on the wrong ones), the first estimate's error, the tracker's error when the robot committed to
the grasp, how high the target was carried, where it ended, and whether the pick succeeded.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pickdemo.core.geometry import Pose, wrap_angle
from pickdemo.core.result import EpisodeFailure, Failure, PerceptionScore, Stage
from pickdemo.core.shapes import Mesh
from pickdemo.grasping.top_down import GraspParams
from pickdemo.perception import PerceptionError, PoseEstimate
from pickdemo.runtime.collisions import CollisionTally
from pickdemo.runtime.grasp_truth import grasp_exists, true_box
from pickdemo.runtime.metrics import score_perception, score_place, seen_truth
from pickdemo.runtime.world import World
from pickdemo.runtime.world_score import WorldScore
from pickdemo.scenario.fixtures import seen_boxes
from pickdemo.scenario.load import Scenario
from pickdemo.sim.contacts import log_contacts
from pickdemo.worldmodel import SceneView, WorldModel

#: Above this, the tracker's belief was off when the robot committed to the grasp (scored on the truth).
PERCEPTION_OFF_MM = 5.0


def diagnose(failure: Failure | None, tracking_error_mm: float | None, fits_hand: bool | None = None) -> str | None:
    """For a failed episode, from the truth (for reading, never for control): was perception off
    when the robot committed to the grasp? ``perception_off``, ``perception_ok`` (the failure lies
    elsewhere), or ``not_committed`` (it never closed the gripper). A pick the grasp planner refused
    is checked against the truth (``fits_hand``: a grasp the hand can make exists among the true
    objects and fixtures, :meth:`Referee.grasp_exists`): ``refused_fits_hand`` (one exists: the
    refusal was the robot's mistake) or ``refused_too_wide`` (none does)."""
    if failure is None:
        return None
    if failure.stage is Stage.GRASP_PLANNING and fits_hand is not None:
        return "refused_fits_hand" if fits_hand else "refused_too_wide"
    if tracking_error_mm is None:
        return "not_committed"
    return "perception_off" if tracking_error_mm > PERCEPTION_OFF_MM else "perception_ok"


#: Another object that ended this far (mm) from where it started was moved by the robot (a nudge of a
#: few millimetres while the hand goes down beside it is not counted).
OTHER_MOVED_MM = 10.0
#: The target is held off the table (its contacts then the robot's doing) once this far above its start (m).
HELD_ABOVE_M = 0.01


class _WorldScoring:
    """The referee's scoring of the robot's world model (:mod:`pickdemo.runtime.world_score`), a pick's
    and a round's alike: its ``world_score`` and ``world`` (the simulator's)."""

    def world_seen(self, controller: object, view: SceneView) -> None:
        """The controller took a view's instances into its world model (``controller.world``, if it
        keeps one): scored against the truth now."""
        world_model = getattr(controller, "world", None)
        if isinstance(world_model, WorldModel):
            self.world_score.view(world_model, view, self.world)

    def log_collisions(self, target: str | None, place_xy: tuple[float, float] | None, objects=frozenset()) -> None:  # noqa: ANN001
        """From now on, the robot's contacts (and the target's) are judged as collisions or not
        (:mod:`pickdemo.runtime.collisions`)."""
        self._contacts = log_contacts(self.world.scene)
        self._contacts.watch(target)
        self.collisions = CollisionTally(target, place_xy, frozenset(objects))

    def judge_contacts(self, held: bool) -> None:
        """A tick: the contacts that began during it, judged (``held``: the target off the table in the hand)."""
        tally = getattr(self, "collisions", None)
        if tally is not None:
            tally.judge(self._contacts.take(), held)

    def collision_summary(self) -> dict | None:
        """``result.json``'s ``collisions`` (None: the episode never started)."""
        tally = getattr(self, "collisions", None)
        return None if tally is None else tally.summary()

    def world_summary(self, controller: object) -> dict | None:
        """``result.json``'s ``world`` (None: the controller keeps no world model)."""
        world_model = getattr(controller, "world", None)
        return self.world_score.summary(world_model) if isinstance(world_model, WorldModel) else None


@dataclass
class Referee(_WorldScoring):
    """The truth's view of one episode (filled in as it runs; read into the result at its end)."""

    scenario: Scenario
    world: World
    target: str
    perception: PerceptionScore | None = None  # the first estimate against the truth
    tracking_error_mm: float | None = None
    tracking_yaw_deg: float | None = None
    start_pose: Pose | None = None
    max_z_m: float | None = None  # highest the target got while carried
    place_error_mm: float | None = None
    wrong_estimates: int = 0  # estimates more than 5 mm off the truth that reached the controller
    wrong_estimates_accepted: int = 0  # of those, how many it acted on (fused into its belief)
    wrong_estimates_self_rejected: int = 0  # of those, how many perception's own fit check rejected
    off_table: bool | None = None  # the target ended off the table (fell, or was knocked off)
    #: the other objects that ended this far (mm) or more from where they started: {name: mm}
    others_moved_mm: dict[str, float] | None = None
    _others_at_start: dict[str, np.ndarray] = field(default_factory=dict)  # where they stood once settled
    world_score: WorldScore = field(default_factory=WorldScore)  # the robot's world model against the truth
    #: a refusal in grasp_planning judged on the truth (:meth:`judge`): a grasp the hand can make existed
    grasp_existed: bool | None = None

    def _truth(self) -> Pose:
        return self.world.true_pose(self.target)

    @property
    def _mesh(self) -> Mesh | None:
        geometry = self.world.placement(self.target).geometry
        return geometry if isinstance(geometry, Mesh) else None

    def _seen_truth(self) -> Pose:
        return seen_truth(self._truth(), self.world.placement(self.target).geometry)

    def started(self) -> None:
        """The objects are at rest and the robot is about to move: where the target starts."""
        self.start_pose = self._truth()
        self.max_z_m = float(self.start_pose.position[2])
        self.log_collisions(self.target, self.world.place_xy)
        self._others_at_start = {
            p.name: self.world.true_pose(p.name).position.copy() for p in self.world.layout if p.name != self.target
        }

    def first_estimate(self, result: PoseEstimate | PerceptionError) -> None:
        """A frame's result: the first estimate is scored in full."""
        if self.perception is None and isinstance(result, PoseEstimate):
            self.perception = score_perception(result, self._seen_truth(), oriented=self._mesh is None)

    def error_mm(self, result: PoseEstimate | PerceptionError) -> float | None:
        """How far the result (or the estimate perception's own checks rejected) is off the truth now."""
        scored = result.estimate if isinstance(result, PerceptionError) else result
        if scored is None:
            return None
        return float(np.linalg.norm(scored.pose.position - self._seen_truth().position)) * 1e3

    def delivered(self, result: PoseEstimate | PerceptionError, error_mm: float | None, status: str) -> None:
        """A result reached the controller: count it if it was off and the controller saw it."""
        if error_mm is not None and error_mm > PERCEPTION_OFF_MM and status != "unused":
            self.wrong_estimates += 1
            self.wrong_estimates_accepted += status == "accepted"
            self.wrong_estimates_self_rejected += isinstance(result, PerceptionError)

    def committed(self, predicted, symmetry_rad: float) -> None:
        """The robot commits to the grasp: the tracker's belief now (``predicted``) against the truth."""
        truth = self._seen_truth()
        self.tracking_error_mm = float(np.linalg.norm(predicted.position - truth.position)) * 1e3
        if symmetry_rad > 0 and self._mesh is None:
            dyaw = wrap_angle(predicted.yaw_rad - float(truth.rpy[2]), symmetry_rad)
            self.tracking_yaw_deg = float(abs(np.degrees(dyaw)))

    def carried(self) -> None:
        """A tick while the target should be in the hand: how high it got."""
        self.max_z_m = max(self.max_z_m, float(self._truth().position[2]))

    def decided(self, controller: object) -> None:
        """The controller has just decided (or been stopped), before the physics step: a pick has nothing
        to read of it here."""

    def tick(self, carrying: bool) -> None:
        """After a control tick's physics: how high the target got while it should be in the hand."""
        held = False
        if carrying:
            self.carried()
            assert self.start_pose is not None
            held = float(self._truth().position[2]) > float(self.start_pose.position[2]) + HELD_ABOVE_M
        self.judge_contacts(held)

    def round_score(self, controller: object) -> None:
        """A clear round's figures (a pick has none)."""
        return None

    def ended(self) -> None:
        """The episode is over: whether the target ended off the table (below its top, beyond its
        edges), and which other objects it moved (:data:`OTHER_MOVED_MM`)."""
        if self.start_pose is None:
            return
        x, y, z = self._truth().position
        self.off_table = bool(z < -0.005 or not self.scenario.table.holds(float(x), float(y)))
        belt = self.scenario.conveyor is not None  # (a belt moves them all)
        moved = {}
        for name, start in ({} if belt else self._others_at_start).items():
            d = float(np.linalg.norm(self.world.true_pose(name).position - start)) * 1e3
            if d >= OTHER_MOVED_MM:
                moved[name] = round(d, 1)
        self.others_moved_mm = moved

    def named_moves(self, failure: Failure | None) -> Failure | None:
        """A failure that moved another object says so first: the robot may have carried it instead."""
        if failure is None or not self.others_moved_mm:
            return failure
        moved = ", ".join(f"objects.{n} {mm:.0f} mm" for n, mm in self.others_moved_mm.items())
        return Failure(failure.stage, f"another object moved from where it stood ({moved}); {failure.reason}")

    def score(self) -> None:
        """Success: lifted high enough, put down where asked, upright and at rest (raises the failure)."""
        sc = self.scenario
        placement = self.world.placement(self.target)
        outcome = score_place(
            start=self.start_pose,
            max_z_m=self.max_z_m,
            final=self._truth(),
            final_speed_m_s=self.world.scene.true_speed(self.target),
            place_xy=self.world.place_xy,
            shape=placement.geometry,
            lift_height_m=sc.success.lift_height,
            place_tolerance_m=sc.success.place_tolerance,
            upright_required=sc.success.upright
            if sc.success.upright is not None
            else placement.geometry.kind != "mesh",
        )
        self.place_error_mm = outcome.place_error_m * 1e3
        if not outcome.success:
            stage = Stage.LIFT if outcome.lifted_m < sc.success.lift_height else Stage.PLACE
            raise EpisodeFailure(stage, outcome.reason)

    def fits_hand(self) -> bool:
        """Whether the target, as this seed drew it, fits the open hand with the grasp's clearance across
        its narrowest width (any direction, for a mesh): a refusal of it is then not the object's. The
        truth, for scoring a refusal only."""
        shape = self.world.placement(self.target).geometry
        width = shape.min_width_m if isinstance(shape, Mesh) else shape.grasp_width_m
        cup = self.world.robot.gripper.cup
        if cup is not None:  # a suction cup: a face at least as wide as it (a mesh's faces not judged here)
            return isinstance(shape, Mesh) or width >= cup.diameter_m
        return width <= self.world.robot.gripper.max_opening_m - GraspParams().width_margin_m

    def judge(self, failure: Failure | None) -> None:
        """At the end, before the scene closes: a refusal in ``grasp_planning`` judged on the truth."""
        if failure is not None and failure.stage is Stage.GRASP_PLANNING:
            self.grasp_existed = self.grasp_exists()

    def grasp_exists(self) -> bool:
        """Whether a grasp the hand can make exists on the truth (:func:`~pickdemo.runtime.grasp_truth.grasp_exists`:
        the other objects' true boxes and the fixtures kept out of); a shape it does not judge, by
        :meth:`fits_hand`. The truth, for scoring a refusal only."""
        placement = self.world.placement(self.target)
        others = [
            true_box(self.world.true_pose(p.name), p.geometry) for p in self.world.layout if p.name != self.target
        ]
        others += list(seen_boxes(self.scenario.fixtures))
        if self.world.robot.gripper.cup is not None:  # (the fingers' geometry is no cup's: by the face alone)
            return self.fits_hand()
        found = grasp_exists(self._truth(), placement.geometry, others, self.world.robot.gripper)
        return self.fits_hand() if found is None else found

    def lifted_mm(self) -> float | None:
        if self.start_pose is None:
            return None
        return (self.max_z_m - float(self.start_pose.position[2])) * 1e3


#: An object whose centre rests over the tray's footprint no higher than this above its rim is in it.
IN_TRAY_ABOVE_RIM_M = 0.03
#: ... and has come to rest there below this speed (m/s).
RESTING_SPEED_M_S = 0.02
#: A round is scored with its objects at rest, the arm holding where it ended: a part let go over the
#: tray as the round ended is judged where it lands, not in the air (it falls and bounces for up to
#: 0.4 s, measured). At most this much simulated time (s), which is not the round's.
SCORE_SETTLE_S = 2.0


@dataclass
class ClearReferee(_WorldScoring):
    """The truth's view of a clear round: which objects the round started with (those on the table once
    they came to rest), which ended in the tray and by which pick. It has the calls of a pick's
    :class:`Referee` (those about one target do nothing here)."""

    scenario: Scenario
    world: World
    in_round: list[str] | None = None
    off_table_at_start: list[str] | None = None
    entered: dict[str, float] | None = None  # name -> when it came to lie in the tray (watched every tick)
    tried: dict[str, int] | None = None  # name -> grasp attempts at it
    start_s: float = 0.0
    picks: list = field(default_factory=list)  # the picks' records, as they ended
    world_score: WorldScore = field(default_factory=WorldScore)  # the robot's world model against the truth
    grasp_existed = None
    perception = None
    place_error_mm = None
    tracking_error_mm = None
    tracking_yaw_deg = None
    wrong_estimates = 0
    wrong_estimates_accepted = 0
    wrong_estimates_self_rejected = 0
    off_table: bool | None = None
    end_s: float | None = None  # when the round ended (before its objects were let come to rest)

    def _on_table(self, name: str) -> bool:
        x, y, z = self.world.true_pose(name).position
        return bool(z > -0.005 and self.scenario.table.holds(float(x), float(y)))

    def in_tray(self, name: str) -> bool:
        tray = self.world.tray
        assert tray is not None
        p = self.world.true_position(name)
        return tray.holds(p[:2]) and float(p[2]) <= tray.rim_z + IN_TRAY_ABOVE_RIM_M

    def started(self) -> None:
        names = [p.name for p in self.world.layout]
        self.in_round = [n for n in names if self._on_table(n) and not self.in_tray(n)]
        self.off_table_at_start = [n for n in names if n not in self.in_round]
        self.tried = {}
        self.entered = {}
        self.start_s = self.world.sim_time_s
        self.log_collisions(None, None, names)

    def watch(self) -> None:
        """A tick: an object that has come to rest in the tray since the last (one still held over it,
        or falling, has not)."""
        assert self.in_round is not None and self.entered is not None
        now = self.world.sim_time_s
        for n in self.in_round:
            if not self.in_tray(n):
                self.entered.pop(n, None)  # (bounced out again)
            elif n not in self.entered and self.world.scene.true_speed(n) < RESTING_SPEED_M_S:
                self.entered[n] = now

    def decided(self, controller) -> None:  # noqa: ANN001 - a pickdemo.skills.clear.ClearSequencer
        """The controller has just decided (or been stopped), before the physics step: the picks that
        ended then, read from its records (the controller is handed nothing of the referee)."""
        for record in controller.picks[len(self.picks) :]:
            self.pick_ended(record)

    def pick_ended(self, record) -> None:  # noqa: ANN001 - a pickdemo.skills.clear.PickRecord
        """A pick is over. One that let go over the tray is credited with the object that comes into
        the tray after it let go (:meth:`clear_score`); a failed one's attempts were at the object
        nearest where the survey saw the one chosen."""
        assert self.in_round is not None and self.tried is not None and self.entered is not None
        self.picks.append(record)
        if record.outcome == "placed":
            return
        left = [n for n in self.in_round if n not in self.entered]
        if left:
            seen = np.asarray(record.seen_at[:2])
            at = min(left, key=lambda n: float(np.linalg.norm(self.world.true_pose(n).position[:2] - seen)))
            self.tried[at] = self.tried.get(at, 0) + max(len(record.attempts), 1)

    def _credit(self) -> dict[str, int]:
        """Each object in the tray, the pick that put it there: the last to let go before it came in."""
        assert self.entered is not None
        released = [(r.released_s, r.index) for r in self.picks if r.outcome == "placed"]
        out = {}
        end = self.world.sim_time_s
        # in the tray at the end but not yet at rest there (the last one dropped): as if now
        entered = {**{n: end for n in self.in_round if self.in_tray(n)}, **self.entered}
        for n, t in entered.items():
            before = [k for at, k in released if at <= t + 1e-6]
            if before:
                out[n] = before[-1]
        return out

    def first_estimate(self, result) -> None:  # noqa: ANN001
        pass

    def error_mm(self, result) -> None:  # noqa: ANN001
        return None

    def delivered(self, result, error_mm, status) -> None:  # noqa: ANN001
        pass

    def committed(self, predicted, symmetry_rad) -> None:  # noqa: ANN001
        pass

    def carried(self) -> None:
        pass

    def tick(self, carrying: bool) -> None:
        """After a control tick's physics: what came to rest in the tray, when."""
        self.watch()
        self.judge_contacts(False)

    def round_score(self, controller) -> dict | None:  # noqa: ANN001 - a pickdemo.skills.clear.ClearSequencer
        """``result.json``'s ``clear`` (read before the scene closes), or None if the round never started."""
        if self.in_round is None or controller is None:
            return None
        return self.clear_score(controller.picks, controller.attempts)

    def lifted_mm(self) -> None:
        return None

    def fits_hand(self) -> None:
        """A round has no one target: its refusals are not judged here."""
        return None

    def judge(self, failure: Failure | None) -> None:
        """A round has no one target: its refusals are not judged here."""

    def named_moves(self, failure: Failure | None) -> Failure | None:
        """(A clear round moves every object: its failures say which were left.)"""
        return failure

    def _at_rest(self) -> None:
        """The round is over: its objects let come to rest before they are judged (once)."""
        if self.end_s is None:
            self.end_s = self.world.sim_time_s
            scene = self.world.scene
            scene.settle(round(SCORE_SETTLE_S / scene.time_step_s))

    def ended(self) -> None:
        if self.in_round is not None:
            self._at_rest()
            self.off_table = any(not self._on_table(n) and not self.in_tray(n) for n in self.in_round)

    def left(self) -> list[str]:
        assert self.in_round is not None
        return [n for n in self.in_round if not self.in_tray(n)]

    def score(self) -> None:
        """Success: every object of the round in the tray (raises the failure)."""
        self._at_rest()
        left = self.left()
        if left:
            names = ", ".join(left)
            raise EpisodeFailure(Stage.PERCEPTION, f"the round ended with {len(left)} object(s) left: {names}")

    def clear_score(self, picks, attempts) -> dict:  # noqa: ANN001 - PickRecords, AttemptRecords
        """``result.json``'s ``clear``: each object's fate, the round's figures."""
        assert self.in_round is not None and self.entered is not None and self.tried is not None
        end = self.world.sim_time_s if self.end_s is None else self.end_s
        credit = self._credit()
        objects = []
        for p in self.world.layout:
            name = p.name
            if name not in self.in_round:
                outcome = "not in the round (off the table once at rest)"
            elif self.in_tray(name):
                outcome = "cleared"
            elif self._on_table(name):
                outcome = "left on the table"
            else:
                outcome = "knocked off the table"
            k = credit.get(name)
            by = None if k is None or outcome != "cleared" else (k, self.entered.get(name, end))
            g = p.geometry
            objects.append({
                "name": name,
                "urdf": getattr(g, "urdf", None),
                "scale": getattr(g, "scale", None),
                "outcome": outcome,
                "attempts": self.tried.get(name, 0) + (by is not None),
                "pick": None if by is None else by[0],
                "cleared_at_s": None if by is None else round(by[1], 4),
                # (where it came to lie: a part left outside the region the robot looks at is told apart)
                "at_m": [round(float(v), 4) for v in self.world.true_position(name)],
            })  # fmt: skip
        cleared = sum(1 for o in objects if o["outcome"] == "cleared")
        total = len(self.in_round)
        successes = len({o["pick"] for o in objects if o["pick"] is not None})
        n_attempts = len(attempts)
        duration = max(end - self.start_s, 1e-9)
        return {
            "objects": objects,
            "picks": [r.to_dict() for r in picks],
            "cleared": cleared,
            "total": total,
            "percent_cleared": 100.0 * cleared / total if total else 100.0,
            "grasp_attempts": n_attempts,
            "successful_grasps": successes,
            "grasp_success_rate": successes / n_attempts if n_attempts else None,
            "round_time_s": round(duration, 4),
            "picks_per_hour": 3600.0 * cleared / duration,
        }
