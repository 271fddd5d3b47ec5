"""Tasks by name: what an episode builds for each task a scenario may name (``task = "pick"`` or
``"clear"``): what the robot is told of its target and how it sees it, the controller that does the
task, the referee that scores it against the truth, and how long the objects settle first.

A task is a value in :data:`TASKS`; the episode looks its scenario's up and never branches on the
name. ``perceive`` runs no episode (``pickdemo perceive`` looks at its scenes), so it has none here.
A new task is a class with these methods and an entry in :data:`TASKS` (and its scenario checks in
:mod:`pickdemo.scenario.checks`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.core.result import EpisodeFailure, Stage
from pickdemo.core.shapes import Unknown
from pickdemo.perception import PerceptionParams, PoseEstimate, TargetModel, estimate_pose
from pickdemo.perception.estimators import EstimatorError, resolve_estimator
from pickdemo.robot.collision import TABLE, Obstacle
from pickdemo.runtime.referee import ClearReferee, Referee
from pickdemo.runtime.world import World
from pickdemo.scenario.fixtures import fixture_boxes
from pickdemo.scenario.load import Scenario
from pickdemo.scenario.objects import TABLE_THICKNESS_M
from pickdemo.scenario.task import target_model
from pickdemo.skills.clear import ClearSequencer
from pickdemo.skills.controller import Controller
from pickdemo.skills.pick import MachineParams, PickMachine

Estimator = Callable[..., PoseEstimate]


@dataclass(frozen=True)
class Told:
    """What the robot is told of its task's target, and how it sees it."""

    target_name: str  # "" when the task has no one target (a clear round)
    model: TargetModel
    estimator: Estimator


class EpisodeTask(Protocol):
    """One task an episode can run."""

    name: str
    settle_max_s: float  # the objects come to rest before the first look, within this

    def check(self, scenario: Scenario) -> None:
        """An :class:`EpisodeFailure` for a scenario this task cannot run (before its world is laid out)."""
        ...

    def told(
        self, scenario: Scenario, world: World, method: str, perception: PerceptionParams, open_loop: bool
    ) -> Told:
        """The target, its model and the estimator; an :class:`EpisodeFailure` when the task cannot run so."""
        ...

    def referee(self, scenario: Scenario, world: World, told: Told) -> Referee | ClearReferee: ...

    def controller(
        self, scenario: Scenario, world: World, told: Told, referee: Any, open_loop: bool, common: dict
    ) -> Controller:
        """The controller (:class:`~pickdemo.skills.pick.PickMachine` or a sequencer of them)."""
        ...

    def settled(self, world: World) -> None:
        """The objects have come to rest: the scene before the robot's first tick."""
        ...


def _paper(perception: PerceptionParams, scenario: Scenario | None = None) -> Estimator:
    """The paper's method; an object nobody described stands on what the cell's models have under it
    (a shelf's board: ``Scenario.surface_z``), where the scenario has a model, else on the table."""
    models = scenario is not None and any(f.kind == "model" for f in scenario.fixtures)
    support = scenario.surface_z if models else None
    return lambda frame, model: estimate_pose(frame, model, perception, support)


def machine_params(sc: Scenario, params: MachineParams) -> MachineParams:
    """The skill's parameters for this scenario's cell: its robot's heights of a pick, a belt's, the
    motion's scales, its transfers."""
    robot = sc.robot_description
    if robot.grasp_heights:  # (a small arm reaches only so high with its hand pointing down)
        params = dataclasses.replace(params, grasp=dataclasses.replace(params.grasp, **dict(robot.grasp_heights)))
    params = robot_speeds(params, dict(robot.speeds))
    if robot.gripper.grip_force_n is not None:
        params = dataclasses.replace(params, grip_force_n=robot.gripper.grip_force_n)
    if sc.conveyor is not None:  # the cell has a belt: targets may move, at an unknown speed
        params = params.on_a_belt()
    m = sc.motion
    scales = (m.velocity_scale, m.acceleration_scale, m.jerk_scale)
    if scales != (1.0, 1.0, 1.0):
        params = dataclasses.replace(params, near=params.near.scaled_by(*scales), free=params.free.scaled_by(*scales))
    return dataclasses.replace(params, joint_transfers=m.transfers == "joint")


def robot_speeds(params: MachineParams, speeds: dict[str, float]) -> MachineParams:
    """The skill's speeds with those a robot file sets (``[speeds]``): a Cartesian velocity scales its
    limits' accelerations and jerks by the same factor (the near one, the side grasps' lines near the
    object too, up to the joints' limits); the transfers' shares replace the skill's."""
    changes: dict = {k: speeds[k] for k in ("transfer_scale", "carry_scale") if k in speeds}
    for key, name in (("near_m_s", "near"), ("free_m_s", "free")):
        if key in speeds:
            limits = getattr(params, name)
            f = speeds[key] / limits.velocity
            changes[name] = limits.scaled_by(f, f, f)
            if name == "near":  # (the lines near the object are checked at the speed they run at; the
                # slowest share still taken stays the same speed in m/s)
                changes["side_line_scale"] = min(1.0, params.side_line_scale * f)
                g = params.goals
                changes["goals"] = dataclasses.replace(
                    g, line_speed_m_s=g.line_speed_m_s * f, min_line_speed_scale=min(1.0, g.min_line_speed_scale / f)
                )
    return dataclasses.replace(params, **changes) if changes else params


def cell_obstacles(scenario: Scenario) -> tuple[Obstacle, ...]:
    """The table and every fixture's solid parts, by name, as the task tells the robot: what its motions
    are planned around (:mod:`pickdemo.skills.pick.routes`)."""
    t = scenario.table
    half = np.array([t.size[0] / 2.0, t.size[1] / 2.0, TABLE_THICKNESS_M / 2.0])
    table = OrientedBox(Pose(np.array([t.center[0], t.center[1], -half[2]]), np.eye(3)), -half, half)
    named = [Obstacle(f"fixtures.{f.name}", b) for f in scenario.fixtures for b in f.boxes()]
    return (Obstacle(TABLE, table), *named)


class PickTask:
    """Pick one target and put it down at the place."""

    name = "pick"
    settle_max_s = 2.0

    def check(self, scenario: Scenario) -> None:
        if len(scenario.targets) != 1:
            n = len(scenario.targets)
            raise EpisodeFailure(Stage.ERROR, f"a pick needs exactly one target; the scenario has {n}")

    def told(
        self, scenario: Scenario, world: World, method: str, perception: PerceptionParams, open_loop: bool
    ) -> Told:
        # What the robot is told is the file's (target_model), never this seed's draw; whether a drawn
        # mesh can be held is the grasp planner's to say, from what the camera saw.
        name = scenario.target.name
        model = target_model(scenario, world.placement(name))
        if isinstance(model.geometry, Unknown) and method != "paper":
            raise EpisodeFailure(
                Stage.PERCEPTION, f"the target is a mesh nobody described: perception {method!r} needs its model"
            )
        if method == "paper":  # (an object nobody described: estimate_pose sends it to estimate_unknown)
            return Told(name, model, _paper(perception, scenario))
        try:
            return Told(name, model, resolve_estimator(method))
        except EstimatorError as exc:
            raise EpisodeFailure(Stage.PERCEPTION, str(exc)) from None

    def referee(self, scenario: Scenario, world: World, told: Told) -> Referee:
        return Referee(scenario, world, told.target_name)

    def controller(
        self, scenario: Scenario, world: World, told: Told, referee: Any, open_loop: bool, common: dict
    ) -> Controller:
        return PickMachine(
            model=told.model,
            symmetry_rad=told.model.geometry.yaw_symmetry_rad,
            place_xy=world.place_xy,
            max_attempts=scenario.control.max_attempts,
            place_tolerance_m=scenario.success.place_tolerance,
            open_loop=open_loop,
            surface_z=scenario.surface_z,
            fixtures=fixture_boxes(tuple(f for f in scenario.fixtures if f.kind == "bin")),
            solids=fixture_boxes(scenario.fixtures),
            **common,
        )

    def settled(self, world: World) -> None:
        pass


class ClearTask:
    """Clear the table: every object into the tray, one pick after another."""

    name = "clear"
    settle_max_s = 4.0  # a pile falls into its heap

    def check(self, scenario: Scenario) -> None:
        pass

    def told(
        self, scenario: Scenario, world: World, method: str, perception: PerceptionParams, open_loop: bool
    ) -> Told:
        """Every object is one nobody described, found by its geometry (the paper's method)."""
        if method != "paper":
            raise EpisodeFailure(
                Stage.PERCEPTION, f"a clear round finds its objects by their geometry: perception {method!r} cannot"
            )
        if open_loop:
            raise EpisodeFailure(Stage.ERROR, "a clear round runs closed loop only (--open-loop is for a pick)")
        return Told("", TargetModel(Unknown(), color=None), _paper(perception, scenario))

    def referee(self, scenario: Scenario, world: World, told: Told) -> ClearReferee:
        return ClearReferee(scenario, world)

    def controller(
        self, scenario: Scenario, world: World, told: Told, referee: Any, open_loop: bool, common: dict
    ) -> Controller:
        assert scenario.clear is not None and world.tray is not None
        return ClearSequencer(
            tray=world.tray,
            max_consecutive_failures=scenario.clear.max_consecutive_failures,
            surface_z=scenario.surface_z,
            fixtures=fixture_boxes(tuple(f for f in scenario.fixtures if f.kind == "bin")),
            solids=fixture_boxes(scenario.fixtures),
            **common,
        )

    def settled(self, world: World) -> None:
        # a round's objects lie still but for the one picked: those at rest leave the solver
        world.scene.let_objects_sleep()


#: The tasks an episode runs, by the scenario's ``task``.
TASKS: dict[str, EpisodeTask] = {task.name: task for task in (PickTask(), ClearTask())}


def episode_task(name: str) -> EpisodeTask:
    """The task of this name; an :class:`EpisodeFailure` for one that runs no episode (``perceive``)."""
    task = TASKS.get(name)
    if task is None:
        raise EpisodeFailure(Stage.ERROR, f'task = "{name}" runs no episode (use `pickdemo perceive` to look at it)')
    return task
