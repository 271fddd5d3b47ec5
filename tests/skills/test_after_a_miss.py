"""After a miss, the grasps the selector puts first (from any side) are tried first; where none of them
gives a plan the arm can do, the attempt is planned as before any miss, not failed. No simulator: the
grasp chooser of a machine, its selector's after-a-miss grasps made unreachable."""

from __future__ import annotations

import dataclasses

import numpy as np

from pickdemo.core.camera import Intrinsics, look_at_pose
from pickdemo.core.geometry import Pose
from pickdemo.core.result import Failure
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.runtime.tasks import machine_params
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.load import load_scenario
from pickdemo.scenario.task import target_model
from pickdemo.skills.pick import CameraModel, MachineParams, PickMachine


@dataclasses.dataclass
class OutOfReachAfterAMiss:
    """The inner selector's grasps, carried 2 m away once the target was missed."""

    inner: object

    def hand_yaws(self, request):  # noqa: ANN001, ANN201
        return self.inner.hand_yaws(request)

    def candidates(self, request):  # noqa: ANN001, ANN201
        far = np.array([2.0, 0.0, 0.0]) if request.misses else np.zeros(3)
        for plan in self.inner.candidates(request):
            yield dataclasses.replace(
                plan, pregrasp=Pose(plan.pregrasp.position + far, plan.pregrasp.rotation),
                grasp=Pose(plan.grasp.position + far, plan.grasp.rotation),
            )  # fmt: skip


def test_after_a_miss_no_reachable_grasp_falls_back_to_the_grasps_before_it() -> None:
    sc = load_scenario("pick_cube")
    robot = robot_named()
    camera = CameraModel(
        Intrinsics.from_fov(640, 480, 57.0, 43.0), look_at_pose(np.array([0.9, 0.0, 0.6]), np.array([0.5, 0.0, 0.0]))
    )
    m = PickMachine(
        kin=kinematics_of(robot), model=target_model(sc, sample_layout(sc, np.random.default_rng(0))[0]),
        symmetry_rad=np.pi / 2.0, place_xy=(0.45, 0.3), cameras=[camera], q0=robot.home_q, dt_s=1.0 / 120.0,
        rng=np.random.default_rng(1), params=machine_params(sc, MachineParams()),
    )  # fmt: skip
    m.chooser.selector = OutOfReachAfterAMiss(m.chooser.selector)
    pose = Pose.from_xyz_rpy(np.array([0.5, 0.0, 0.025]), yaw=np.radians(10.0))
    m.chooser.misses = 1
    plan = m.chooser.first_plan(pose, None, (), 0.0)
    assert not isinstance(plan, Failure), plan.reason
    assert np.linalg.norm(plan.grasp.position[:2] - pose.position[:2]) < 0.03
    assert m.chooser.misses == 1  # (the count stands: the next attempt tries the other grasps first again)
