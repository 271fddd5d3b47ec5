"""Reach from above as ``validate`` checks it: the hand pointing down at one of four angles, solved by the
arm's IK from home (shared by the checks of objects, places and fixtures). Pure: no simulator."""

from __future__ import annotations

import dataclasses

import numpy as np

from pickdemo.grasping.top_down import GraspParams, top_down
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.kinematics import IKParams, Kinematics
from pickdemo.scenario.base import ScenarioError


def grasp_params(robot: RobotDescription) -> GraspParams:
    """The heights of a pick as the robot's skill will use them (the robot's own where it has them)."""
    return dataclasses.replace(GraspParams(), **dict(robot.grasp_heights))


#: Hand angles tried for reach from above, the first that solves wins (an arm of five joints turns its
#: hand through a range short of a whole turn: some spots it reaches at some angles only).
REACH_YAWS = (0.0, np.pi / 2.0, np.pi, -np.pi / 2.0)


def reach_from_above(
    kin: Kinematics, at: np.ndarray, rng: np.random.Generator, what: str, width_m: float = 0.0
) -> None:
    """The hand pointing down at one of :data:`REACH_YAWS` to grasp what is ``width_m`` wide at ``at``
    (a jaw's TCP beside it: :meth:`~pickdemo.robot.description.Gripper.tcp_offset_m`), else the spot
    is out of reach."""
    reasons = []
    offset = kin.robot.gripper.tcp_offset_m(width_m)
    for yaw in REACH_YAWS:
        tcp = at if offset == 0.0 else at + top_down(np.zeros(3), yaw).rotation[:, 1] * offset
        res = kin.solve(top_down(tcp, yaw), kin.robot.home_q, rng, IKParams())
        if res.success:
            return
        reasons.append(res.reason)
    raise ScenarioError(f"{what}: out of the arm's reach from above ({reasons[0]})")
