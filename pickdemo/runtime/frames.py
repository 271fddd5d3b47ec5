"""A frame's way through the loop: taken (the robot's own body, the tray and the fixtures told to it),
perceived, and in flight to the controller for perception's latency; and the loop's wall-clock timer
of its stages (what ``profile`` reports).

Part of the runtime: it renders through the simulator's world and reads the truth only for the
referee's figures that travel with a result (:class:`InFlight`'s ``error_mm``).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.core.interfaces import Observation
from pickdemo.perception import PerceptionError, PerceptionParams, PoseEstimate, TargetModel
from pickdemo.perception.estimators import Estimator
from pickdemo.robot.kinematics import Kinematics
from pickdemo.robot.self_geometry import robot_body
from pickdemo.runtime.world import World
from pickdemo.scenario.fixtures import seen_boxes
from pickdemo.scenario.load import Scenario
from pickdemo.skills.pick import FrameRequest
from pickdemo.worldmodel import SceneView


class Timer:
    def __init__(self) -> None:
        self.times: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - t0


@dataclass(frozen=True)
class InFlight:
    """A frame's result on its way to the controller (perception's latency)."""

    arrival_s: float
    taken_s: float
    result: PoseEstimate | PerceptionError | SceneView
    error_mm: float | None  # against the truth when the frame was taken: for the referee only
    camera: str = "camera"  # which camera took the frame


def estimate(
    estimator: Estimator, frame: RGBDFrame, model: TargetModel, params: PerceptionParams
) -> PoseEstimate | PerceptionError:
    """The estimator's estimate of the target in ``frame`` (or its word that it found none). What stands
    around it is the world model's (:func:`~pickdemo.worldmodel.split_view`, every frame), not the
    estimate's."""
    try:
        result = estimator(frame, model)
        if not isinstance(result, PoseEstimate):
            raise TypeError(f"the perception method returned {type(result).__name__}, not a PoseEstimate")
        return result
    except PerceptionError as exc:
        return exc


def take_frame(
    world: World, scenario: Scenario, request: FrameRequest, obs: Observation | None, kin: Kinematics
) -> RGBDFrame:
    """The requested frame, rendered, with what is no object on the table in it: the robot's own body at
    the joint states ``obs`` (when the frame was taken), the cell's tray and its fixtures."""
    rig = world.cameras[request.camera]
    # on the hand: told where it was by the arm's kinematics at those joint states
    T_world_tcp = kin.forward(obs.arm_q) if rig.on_hand and obs is not None else None
    frame = rig.take(world.scene, request.roi, T_world_tcp)
    frame = dataclasses.replace(frame, camera=request.camera)
    if obs is not None:
        boxes = robot_body(world.robot).boxes(obs.arm_q, obs.fingers_m)
        if world.tray is not None:  # the cell's tray, and what is in it, is no object on the table
            boxes = (*boxes, world.tray.box())
        # nor are its fixtures, as near them as the depth noise reaches
        frame = dataclasses.replace(frame, robot_boxes=boxes, fixture_boxes=seen_boxes(scenario.fixtures))
    if scenario.conveyor is not None:  # the belt's top: what the objects on it rest on
        (x0, x1), (y0, y1) = scenario.conveyor.x_range_m, scenario.conveyor.y_range_m
        half = np.array([(x1 - x0) / 2.0, (y1 - y0) / 2.0, scenario.conveyor.height_m / 2.0])
        belt = OrientedBox(Pose(np.array([(x0 + x1) / 2.0, (y0 + y1) / 2.0, half[2]]), np.eye(3)), -half, half)
        frame = dataclasses.replace(frame, support_boxes=(belt,))
    return frame
