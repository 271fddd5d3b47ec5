"""Scoring an episode against the simulator's truth, as it runs and at its end.

The referee reads the truth (the target's true pose and speed) and nothing it measures ever reaches
the controller: how far each estimate was off when its frame was taken (and whether the controller
acted on the wrong ones), the first estimate's error, the tracker's error when the robot committed to
the grasp, how high the target was carried, where it ended, and whether the pick succeeded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.geometry import Pose, wrap_angle
from pickdemo.metrics import score_perception, score_place
from pickdemo.perception import PerceptionError, PoseEstimate
from pickdemo.result import EpisodeFailure, Failure, PerceptionScore, Stage
from pickdemo.scenario import Scenario
from pickdemo.shapes import Mesh
from pickdemo.world import World

#: Above this, the tracker's belief was off when the robot committed to the grasp (scored on the truth).
PERCEPTION_OFF_MM = 5.0


def diagnose(failure: Failure | None, tracking_error_mm: float | None) -> str | None:
    """For a failed episode, from the truth (for reading, never for control): was perception off
    when the robot committed to the grasp? ``perception_off``, ``perception_ok`` (the failure lies
    elsewhere), or ``not_committed`` (it never closed the gripper)."""
    if failure is None:
        return None
    if tracking_error_mm is None:
        return "not_committed"
    return "perception_off" if tracking_error_mm > PERCEPTION_OFF_MM else "perception_ok"


@dataclass
class Referee:
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

    def _truth(self) -> Pose:
        return self.world.true_pose(self.target)

    @property
    def _mesh(self) -> Mesh | None:
        geometry = self.world.placement(self.target).geometry
        return geometry if isinstance(geometry, Mesh) else None

    def _seen_truth(self) -> Pose:
        """What an estimate is scored against: the target's pose (a mesh's: at its bounding box's
        centre, which an object nobody described is seen by)."""
        truth = self._truth()
        mesh = self._mesh
        if mesh is None:
            return truth
        return Pose(truth.transform_points(mesh.box_centre[None, :])[0], truth.rotation)

    def started(self) -> None:
        """The objects are at rest and the robot is about to move: where the target starts."""
        self.start_pose = self._truth()
        self.max_z_m = float(self.start_pose.position[2])

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

    def ended(self) -> None:
        """The episode is over: whether the target ended off the table (below its top, beyond its edges)."""
        if self.start_pose is None:
            return
        x, y, z = self._truth().position
        self.off_table = bool(z < -0.005 or not self.scenario.table.holds(float(x), float(y)))

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

    def lifted_mm(self) -> float | None:
        if self.start_pose is None:
            return None
        return (self.max_z_m - float(self.start_pose.position[2])) * 1e3
