"""The pick's vertical descent where a small arm's hand points down only low (the SO-101 near its base):
it starts lower, where the arm follows it, and only when no hand angle will do from the full height.
No simulator: the grasp chooser of a machine built for the robot, asked for a first plan."""

from __future__ import annotations

import numpy as np

from pickdemo.core.camera import Intrinsics, look_at_pose
from pickdemo.core.geometry import Pose
from pickdemo.core.result import Failure
from pickdemo.motion.ik_goals import line_speed_scale
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import IKParams, kinematics_of
from pickdemo.runtime.tasks import machine_params
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.load import load_scenario
from pickdemo.scenario.task import target_model
from pickdemo.skills.pick import CameraModel, MachineParams, PickMachine
from pickdemo.skills.pick.chooser import DESCENT_OUT_OF_REACH


def so101_machine() -> PickMachine:
    sc = load_scenario("so101_pick_cube")
    robot = robot_named("so101")
    camera = CameraModel(
        Intrinsics.from_fov(640, 480, 57.0, 43.0), look_at_pose(np.array([0.55, 0.0, 0.35]), np.array([0.17, 0.0, 0.0]))
    )
    return PickMachine(
        kin=kinematics_of(robot), model=target_model(sc, sample_layout(sc, np.random.default_rng(0))[0]),
        symmetry_rad=np.pi / 2.0, place_xy=(0.16, 0.14), cameras=[camera], q0=robot.home_q, dt_s=1.0 / 120.0,
        rng=np.random.default_rng(1), params=machine_params(sc, MachineParams()),
    )  # fmt: skip


def test_a_descent_the_arm_cannot_follow_from_the_full_height_starts_lower() -> None:
    """A target standing 3 cm high, 11.5 cm from the SO-101's base: from 35 mm above the grasp no hand
    angle has a descent the arm follows (the episode failed in ``ik`` before); the plan's descent starts
    lower, no lower than half the height, and from there the arm follows it."""
    m = so101_machine()
    pose = Pose.from_xyz_rpy(np.array([0.115, 0.01, 0.03]), yaw=np.radians(10.0))
    full = m.p.grasp.pregrasp_height_m
    request = m.chooser.request(pose, (None,))
    yaws = tuple(m.chooser.selector.hand_yaws(request))
    reasons = [m.chooser.unreachable(p, 0.0) for p in m.chooser.selector.candidates(m.chooser.request(pose, yaws))]
    assert DESCENT_OUT_OF_REACH in reasons and "" not in reasons, reasons  # (the other angles: no grasp at all)
    plan = m.chooser.first_plan(pose, None, (), 0.0)
    assert not isinstance(plan, Failure), plan.reason
    height = float(plan.pregrasp.position[2] - plan.grasp.position[2])
    assert full * m.p.min_descent_share - 1e-9 <= height < full
    assert np.isclose(m.chooser.descent_drop_m, full - height)
    q = m.kin.solve(plan.grasp, m.arm.motion.q, np.random.default_rng(0), IKParams()).q
    assert line_speed_scale(m.kin, q, plan.grasp, plan.pregrasp, m.p.goals) >= m.p.goals.min_line_speed_scale
    # the attempt's re-plans keep the lower start; the next attempt's first plan plans afresh
    again = m.chooser.grasp(pose, plan.hand_yaw_rad)
    assert np.isclose(again.pregrasp.position[2], plan.pregrasp.position[2])


def test_a_descent_the_arm_follows_from_the_full_height_is_not_lowered() -> None:
    """Mid-table, and near the base for a low target, the descent starts at the robot's pregrasp height."""
    m = so101_machine()
    for xyz in ([0.19, 0.0, 0.0125], [0.125, 0.01, 0.0125]):
        plan = m.chooser.first_plan(Pose.from_xyz_rpy(np.array(xyz), yaw=np.radians(10.0)), None, (), 0.0)
        assert not isinstance(plan, Failure), plan.reason
        assert np.isclose(plan.pregrasp.position[2] - plan.grasp.position[2], m.p.grasp.pregrasp_height_m)
        assert m.chooser.descent_drop_m == 0.0
