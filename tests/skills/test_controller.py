"""Both shipped skills are controllers by the same protocol: the loop asks nothing else of them."""

from __future__ import annotations

import numpy as np

from pickdemo.core.camera import Intrinsics, look_at_pose
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.load import load_scenario
from pickdemo.scenario.task import target_model
from pickdemo.scenario.tray import Tray
from pickdemo.skills.clear import ClearSequencer
from pickdemo.skills.controller import Controller
from pickdemo.skills.pick import CameraModel, PickMachine

ROBOT = robot_named()


def test_the_pick_skill_and_a_clear_round_are_controllers() -> None:
    kin = kinematics_of(ROBOT)
    K = Intrinsics.from_fov(640, 480, 57.0, 43.0)
    camera = CameraModel(K, look_at_pose(np.array([1.1, 0.0, 0.75]), np.array([0.5, 0.0, 0.0])))
    common = dict(kin=kin, cameras=[camera], q0=ROBOT.home_q, dt_s=1.0 / 120.0, rng=np.random.default_rng(0))
    sc = load_scenario("pick_cube")
    model = target_model(sc, sample_layout(sc, np.random.default_rng(0))[0])
    pick = PickMachine(model=model, symmetry_rad=np.pi / 2.0, place_xy=(0.45, 0.3), **common)
    tray = Tray.of(load_scenario("clear_pile"))
    assert tray is not None
    clear = ClearSequencer(tray=tray, **common)
    for controller in (pick, clear):
        assert isinstance(controller, Controller)
        assert controller.views(0.0) == []  # nothing asked before its first tick
        assert not controller.finished and controller.progress
