"""Clearing a table: a sequencer above the pick skill, for ``task = "clear"``.

Pure: no simulator. :class:`ClearSequencer` looks at the whole table (a survey: every object of the
round's world model the look showed, :meth:`~pickdemo.worldmodel.WorldModel.survey`), chooses the next object
(:class:`~pickdemo.skills.clear_choice.ObjectChooser`: the best reachable grasp over all of them), and
hands it to a :class:`~pickdemo.skills.pick.PickMachine` told only where the object was seen and its
rough size; the pick's closed loop tracks it from there (a neighbour's pick may have
moved it), drops it into the tray and comes home; then it looks at the table again. The round ends
when the table is clear, when no grasp is found, or after ``max_consecutive_failures`` failed
attempts in a row (VGN's clutter-removal protocol).

To the episode it is a controller like a pick's: the same calls (:meth:`update`, :meth:`on_estimate`,
:meth:`views`), the events and attempts of all its picks in one list, and what observers
read of the pick under way.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from pickdemo.core.camera import project
from pickdemo.core.geometry import OrientedBox, box_surface_points
from pickdemo.core.interfaces import Command, Observation
from pickdemo.core.result import AttemptRecord, Failure, Stage
from pickdemo.core.shapes import Unknown
from pickdemo.grasping.antipodal import AnySideGrasps
from pickdemo.grasping.cloud import CloudGrasps
from pickdemo.grasping.selection import GraspSelector, TopDownFirst
from pickdemo.grasping.suction import SuctionGrasps
from pickdemo.grasping.top_down import GraspParams, GraspPlan
from pickdemo.motion.online import MotionSample
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel
from pickdemo.perception.unknown import SeenObject, Survey
from pickdemo.robot.collision import Obstacle
from pickdemo.robot.description import Gripper
from pickdemo.robot.kinematics import Kinematics
from pickdemo.robot.self_geometry import robot_body
from pickdemo.scenario.tray import Tray
from pickdemo.skills.clear_choice import TRIED_RADIUS_M, Choice, ObjectChooser
from pickdemo.skills.pick import CameraModel, Event, FrameRequest, MachineParams, PickMachine, State
from pickdemo.tracking.belief import Counters, Verdict
from pickdemo.tracking.tracker import TargetTracker
from pickdemo.worldmodel import SceneView, WorldModel

#: Let go of an object this far above the tray's rim (its bottom): it drops in.
TRAY_DROP_M = 0.02
#: A clear round's objects rest on the table: the tracker's prior on their speed and turn rate
STILL_SPEED_SIGMA_M_S = 0.002
STILL_YAW_RATE_SIGMA_RAD_S = 0.01
#: A hold lost this long (s) is a drop (a moment's loss of one finger's contact is not)
HEAP_DROP_S = 0.1
#: The regions a pick looks at are this much larger than the object seen (and 2 cm)
EXTENT_MARGIN = 1.5
#: The arm's links' boxes, padded by this (m), must project clear of what is on the table for the camera to
#: look at it with the arm where it let go of an object (else it goes home first)
ARM_VIEW_PAD_M = 0.03


@dataclass(frozen=True)
class PickRecord:
    """One pick of a round: the object chosen (as seen), what became of it, when."""

    index: int
    seen_at: tuple[float, float, float]  # m: where the survey saw the object chosen
    seen_size_m: tuple[float, float, float]  # its top's height, its footprint's sides, as seen
    grasp_cost: float
    attempts: tuple[AttemptRecord, ...]
    outcome: str  # "placed" (let go over the tray) or "failed"
    reason: str
    start_s: float
    end_s: float
    released_s: float | None = None  # when it began to let go over the tray

    def to_dict(self) -> dict[str, Any]:
        return {
            "index": self.index,
            "seen_at": [round(v, 4) for v in self.seen_at],
            "seen_size_mm": [round(v * 1e3, 1) for v in self.seen_size_m],
            "grasp_cost": round(self.grasp_cost, 3),
            "attempts": [a.to_dict() for a in self.attempts],
            "outcome": self.outcome,
            "reason": self.reason,
            "start_s": round(self.start_s, 4),
            "end_s": round(self.end_s, 4),
        }


class ClearSequencer:
    """Picks every object on the table into the tray, one after another; see the module docstring."""

    def __init__(
        self,
        *,
        kin: Kinematics,
        tray: Tray,
        cameras: list[CameraModel],
        q0: np.ndarray,
        dt_s: float,
        rng: np.random.Generator,
        max_consecutive_failures: int = 2,
        params: MachineParams | None = None,
        surface_z: Callable[..., float] | None = None,
        fixtures: tuple[OrientedBox, ...] = (),
        solids: tuple[OrientedBox, ...] = (),
        grasp_rng: np.random.Generator | None = None,
        cell: tuple[Obstacle, ...] = (),
        plan_rng: np.random.Generator | None = None,
    ) -> None:
        """``surface_z(x, y, z)``: the height of what an object at (x, y), its centre at ``z``, rests on (a
        bin's floor, the table);
        ``fixtures``: the cell's fixtures (a bin's walls), known from the task: the grasps keep clear of them;
        ``solids``: every fixture's boxes, which each pick's open hand and arm keep out of;
        ``grasp_rng``: the draw of grasps from any side; ``cell``, ``plan_rng``: what motions are planned
        around, and the planner's seeds (:class:`~pickdemo.skills.pick.PickMachine`'s)."""
        self.kin = kin
        self.surface_z, self.fixtures, self.solids, self.grasp_rng = surface_z, fixtures, solids, grasp_rng
        self.tray = tray
        self.cell, self.plan_rng = cell, plan_rng
        self.world = WorldModel()  # every object seen, kept across the round's picks
        # A clear round looks through its fixed camera alone (not yet through one on the hand).
        self.cameras = [c for c in cameras if not c.on_hand][:1]
        self.camera = self.cameras[0]
        self.dt_s = dt_s
        self.rng = rng
        self.max_consecutive_failures = max_consecutive_failures
        p = params or MachineParams()
        # The round's objects rest on the table (no belt): tracked as standing still (a push is a jump).
        still = dataclasses.replace(p.tracker, initial_speed_sigma_m_s=STILL_SPEED_SIGMA_M_S,
                                    initial_yaw_rate_sigma_rad_s=STILL_YAW_RATE_SIGMA_RAD_S)  # fmt: skip
        # In a heap a held object brushes its neighbours as it rises: a finger may lose its contact a
        # moment; a drop is the fingers without a hold this long (a real one closes them on nothing).
        grip = dataclasses.replace(p.grip, drop_ticks=max(p.grip.drop_ticks, round(HEAP_DROP_S / dt_s)))
        self.p = dataclasses.replace(
            p,
            tracker=still,
            grip=grip,
            verify_place=False,
            drop_place=True,
            home_after_place=False,
            end_at_rest=True,
        )
        self.any_side = grasp_rng if kin.robot.grasps_any_side and self.p.joint_transfers else None
        self.chooser = ObjectChooser(
            kin,
            rng,
            self.p.grasp,
            self.p.goals.ik,
            surface_z=surface_z,
            fixture_points=box_surface_points(fixtures) if fixtures else None,
            any_side=self.any_side,
            goals=self.p.goals,
        )  # which object next; fmt: skip
        self.events: list[Event] = []
        self.picks: list[PickRecord] = []
        self.failure: Failure | None = None
        self.consecutive_failures = 0
        self.surveys = 0
        self.last_survey: Survey | None = None
        self._done = False
        self._surveying = True
        self._survey_asked = False
        self._survey_asked_s = 0.0
        self._seen_events = 0
        self._choice: Choice | None = None
        self._counted: list[Counters] = []  # the finished picks' counters
        self._homed = True  # the arm went home for the survey under way (else it looks from where it let go)
        self._tried: list[np.ndarray] = []  # where picks failed since the last that placed an object
        self._slipped: list[np.ndarray] = []  # where objects slipped out of the fingers (this round)
        self._failed_grasps: list[tuple[np.ndarray, float]] = []  # (TCP position, hand angle) that failed
        self._pick_start_s = 0.0
        self._now_s = 0.0
        self.current = self._machine(q0, TargetModel(Unknown(), color=None))  # at home: surveys from there
        self.events.append(Event(State.LOOK, 0.0, "looking at the table", note=True))

    # ================================================================================ interface
    @property
    def finished(self) -> bool:
        return self._done

    @property
    def state(self) -> State:
        if self._done:
            return State.FAILED if self.failure is not None else State.DONE
        return State.LOOK if self._surveying else self.current.state

    @property
    def model(self) -> TargetModel:
        """The target model of the pick under way (what perception looks for)."""
        return self.current.model

    @property
    def counters(self) -> Counters:
        """What every pick of the round counted of perception and motion, summed."""
        out = Counters()
        for c in [*self._counted, *([] if self._surveying or self._done else [self.current.counters])]:
            for f in ("estimates", "rejected", "perception_errors", "jumps", "retargets"):
                setattr(out, f, getattr(out, f) + getattr(c, f))
            out.last_error = c.last_error or out.last_error
        return out

    @property
    def attempts(self) -> list[AttemptRecord]:
        """Every grasp attempt of the round, in order (numbered within their pick)."""
        out = [a for rec in self.picks for a in rec.attempts]
        if not self._surveying and not self._done:
            out.extend(self.current.attempts)
        return out

    # What observers read of the pick under way (its tracker, plan, motion, ...).
    @property
    def tracker(self) -> TargetTracker:
        return self.current.tracker

    @property
    def plan(self) -> GraspPlan | None:
        return self.current.plan

    @property
    def symmetry(self) -> float:
        return self.current.symmetry

    @property
    def look_at(self) -> np.ndarray | None:
        return self.current.look_at

    @property
    def progress(self) -> str:
        """Where the round is, said for a viewer: the pick under way."""
        return f"pick {len(self.picks) + 1}"

    @property
    def last_sample(self) -> MotionSample | None:
        return self.current.last_sample

    @property
    def grasp_width_m(self) -> float | None:
        return self.current.grasp_width_m

    @property
    def released_at_s(self) -> float | None:
        return self.current.released_at_s

    def cartesian_limits(self) -> tuple[list[float], list[float], list[float]]:
        return self.current.cartesian_limits()

    def views(self, now_s: float) -> list[FrameRequest]:
        """A survey of the whole table from the fixed camera, or the pick under way's frames."""
        if self._done:
            return []
        if self._surveying:
            if self._survey_asked or not (self.current.entered and self.current.arm.finished):
                return []
            self._survey_asked = True  # (asked only when a frame is due: the episode takes it now)
            self._survey_asked_s = now_s
            return [FrameRequest(None, survey=True, camera=self.camera.name)]
        return self.current.views(now_s)

    def on_estimate(
        self, result: PoseEstimate | PerceptionError | SceneView, frame_time_s: float, camera: str = "camera"
    ) -> Verdict:
        if self._done:
            return Verdict.UNUSED
        if isinstance(result, SceneView):  # (the round's world model, whatever it is doing)
            self.world.update(result)
            if self._surveying and self._survey_asked and frame_time_s >= self._survey_asked_s - 1e-9:
                self._surveyed(self.world.survey(result))  # (the survey's own frame: what stands there now)
                return Verdict.ACCEPTED
            return Verdict.UNUSED
        if self._surveying:
            return Verdict.UNUSED
        return self.current.on_estimate(result, frame_time_s, camera)

    def update(self, obs: Observation) -> Command:
        self._now_s = obs.time_s
        cmd = self.current.update(obs)
        self._take_events()
        if self._done:
            return cmd
        if not self._surveying and self.current.finished and self.current.at_rest:
            self._pick_ended(obs)
        return cmd

    def abort(self, stage: Stage, reason: str) -> None:
        """End the round from outside (the step budget is spent)."""
        if not self._surveying and not self.current.finished:
            self.current.abort(stage, reason)
            self._take_events()
            self._record_pick()
        self._fail(stage, reason)

    # ================================================================================== internals
    def _machine(
        self, q0: np.ndarray, model: TargetModel, params: MachineParams | None = None, **kw: Any
    ) -> PickMachine:
        return PickMachine(
            kin=self.kin,
            model=model,
            symmetry_rad=model.geometry.yaw_symmetry_rad,
            place_xy=kw.pop("place_xy", self.tray.position),
            cameras=self.cameras,
            q0=q0,
            dt_s=self.dt_s,
            rng=self.rng,
            params=params or self.p,
            place_tolerance_m=None,
            surface_z=self.surface_z,
            fixtures=self.fixtures,
            solids=self.solids,
            grasp_rng=self.grasp_rng,
            world=self.world,
            cell=self.cell,
            plan_rng=self.plan_rng,
            **kw,
        )

    def _take_events(self) -> None:
        new = self.current.events[self._seen_events :]
        self._seen_events = len(self.current.events)
        if not self._surveying:  # (the machine that only takes the arm home to survey says nothing)
            self.events.extend(new)

    def _fail(self, stage: Stage, reason: str) -> None:
        if self._done:
            return
        self.failure = Failure(stage, reason)
        self._done = True
        self.events.append(Event(State.FAILED, self._now_s, f"{stage.value}: {reason}"))

    def _finish(self, message: str) -> None:
        self._done = True
        self.events.append(Event(State.DONE, self._now_s, message))

    def _surveyed(self, survey: Survey) -> None:
        """A survey's frame came in: choose the next object, or end the round."""
        self.surveys += 1
        self.last_survey = survey
        if not survey.objects:
            self._finish(f"the table is clear: {self._placed()} object(s) put into the tray")
            return
        choice = self.chooser.choose(survey, self._tried)
        if choice is None:
            n = len(survey.objects)
            self._fail(Stage.GRASP_PLANNING, f"no grasp found for the {n} object(s) left on the table")
            return
        self._choice = choice
        seen = choice.seen
        h, wide, narrow = seen.size_m
        q0 = self.current.commanded_q
        k = len([r for r in self.picks if r.outcome == "placed"])
        # where an object slipped out of the fingers, the next grip there is twice as hard (as a retry's)
        slipped = any(np.linalg.norm(seen.centre[:2] - t) < TRIED_RADIUS_M for t in self._slipped)
        force = min(2.0 * self.p.grip_force_n, self.kin.robot.gripper.max_force_n) if slipped else self.p.grip_force_n
        self.current = self._machine(
            q0,
            TargetModel(Unknown(max_extent_m=_extent(seen), size_cue_m=seen.size_m, heap=True), color=None),
            params=dataclasses.replace(self.p, grip_force_n=force),
            selector=selector_for_round(
                self.p.grasp, tuple(self._failed_grasps), self.any_side, gripper=self.kin.robot.gripper
            ),
            place_xy=self.tray.spot(k),
            place_z_m=self.tray.rim_z + TRAY_DROP_M,
            look_at=seen.centre,
            look_from_here=not self._homed,
            # a failed attempt ends the pick: the next is chosen from a new look, another object first
            max_attempts=1,
        )
        self._seen_events = 0
        self._surveying = False
        self._pick_start_s = self._now_s
        c = seen.centre
        self.events.append(
            Event(State.LOOK, self._now_s,
                  f"{len(survey.objects)} object(s) on the table; the next: at ({c[0]:.3f}, {c[1]:.3f}), "
                  f"{h * 1e3:.0f} mm tall, {wide * 1e3:.0f} x {narrow * 1e3:.0f} mm (grasp cost {choice.cost:.2f})",
                  note=True)
        )  # fmt: skip

    def _placed(self) -> int:
        return sum(1 for r in self.picks if r.outcome == "placed")

    def _record_pick(self) -> PickRecord:
        m, choice = self.current, self._choice
        assert choice is not None
        self._counted.append(m.counters)
        placed = m.failure is None and any(a.outcome == "placed" for a in m.attempts)
        rec = PickRecord(
            index=len(self.picks),
            seen_at=tuple(float(v) for v in choice.seen.centre),  # type: ignore[arg-type]
            seen_size_m=choice.seen.size_m,
            grasp_cost=choice.cost,
            attempts=tuple(m.attempts),
            outcome="placed" if placed else "failed",
            reason="" if m.failure is None else f"{m.failure.stage.value}: {m.failure.reason}",
            start_s=self._pick_start_s,
            end_s=self._now_s,
            released_s=m.released_at_s if placed else None,
        )
        self.picks.append(rec)  # (the referee reads them: nothing of it is handed to the round)
        return rec

    def _pick_ended(self, obs: Observation) -> None:
        """The pick under way is over: count its attempts, then look at the table again (or stop)."""
        rec = self._record_pick()
        attempts = rec.attempts or (None,)  # a pick that never tried a grasp failed one all the same
        for a in attempts:
            if a is not None and a.outcome == "placed":
                self.consecutive_failures = 0
                self._tried.clear()
            else:
                self.consecutive_failures += 1
        if rec.outcome != "placed":
            self._tried.append(np.asarray(rec.seen_at[:2]))
        plan = self.current.plan
        if rec.outcome != "placed" and plan is not None:  # that grasp comes after the others next time
            self._failed_grasps.append((plan.grasp.position.copy(), float(plan.hand_yaw_rad)))
        if any(a.outcome.startswith("dropped") for a in rec.attempts):
            self._slipped.append(np.asarray(rec.seen_at[:2]))
        if self.consecutive_failures >= self.max_consecutive_failures:
            f = self.current.failure
            stage = f.stage if f is not None else Stage.GRASP
            last = rec.reason or "failed"
            self._fail(stage, f"{self.consecutive_failures} failed attempts in a row; the last: {last}")
            return
        q0 = self.current.commanded_q
        self._homed = self._arm_hides(q0)
        if self._homed:  # home first (a machine that only takes the arm home), then look
            self.current = self._machine(q0, TargetModel(Unknown(), color=None))
            self._seen_events = 0
        # (else the finished pick holds the arm, at rest where it let go, while the camera looks)
        self._surveying = True
        self._survey_asked = False
        self._choice = None

    def _arm_hides(self, q: np.ndarray) -> bool:
        """Whether the arm, at ``q`` with its fingers open, may hide from the camera any of what the last
        survey saw on the table (its links' boxes projected over those points): then it looks from home."""
        if self.last_survey is None or not self.last_survey.objects:
            return True
        K, T_cam_world = self.camera.intrinsics, self.camera.pose.inverse()
        pts = np.vstack([o.cloud.points[:: max(1, len(o.cloud.points) // 200)] for o in self.last_survey.objects])
        p_cam = T_cam_world.transform_points(pts)
        uv = project(p_cam[p_cam[:, 2] > 1e-3], K).astype(np.float32)
        robot = self.kin.robot
        fingers = np.full(2, robot.gripper.finger_max_m)
        for box in robot_body(robot).boxes(q, fingers, pad_m=ARM_VIEW_PAD_M):
            c = T_cam_world.transform_points(box.corners())
            if np.any(c[:, 2] <= 1e-3):
                return True  # a link beside or behind the camera: home, to be sure
            hull = cv2.convexHull(project(c, K).astype(np.float32))
            if any(cv2.pointPolygonTest(hull, (float(u), float(v)), False) >= 0 for u, v in uv):
                return True
        return False


def _extent(seen: SeenObject) -> float:
    """A bound on the size of an object seen (m): what sizes the regions the pick looks at (tight, so
    that its neighbours stay out of them as far as they can; at most a whole object's default)."""
    return float(min(Unknown().max_extent_m, EXTENT_MARGIN * max(seen.size_m) + 0.02))


def selector_for_round(
    params: GraspParams, avoid: tuple, any_side: np.random.Generator | None, *, gripper: Gripper
) -> GraspSelector:
    """A round's pick's grasps: top-down on its cloud (those that failed before last), and where none fits,
    from any side (if ``any_side``, the draw, is given); a suction cup's seals (those that failed last)."""
    if gripper.suction:
        return SuctionGrasps(params, avoid=avoid)
    top = CloudGrasps(params, avoid=avoid)
    return top if any_side is None else TopDownFirst(top, AnySideGrasps(any_side, params))
