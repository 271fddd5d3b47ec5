"""The camera on the hand: rendered from where the hand is, told its pose by the arm's kinematics and
its hand-eye calibration; seeing through the descent, and correcting a miscalibrated fixed camera."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from episodes import at_least, episodes

from pickdemo.core.geometry import Pose
from pickdemo.core.result import Stage
from pickdemo.perception import PerceptionParams, estimate_pose
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.robot.self_geometry import robot_body
from pickdemo.runtime.episode import run_episode
from pickdemo.runtime.world import World
from pickdemo.scenario.load import load_scenario
from pickdemo.scenario.task import target_model

ROBOT = robot_named()


def _hand_over(world: World, position: np.ndarray, height_m: float) -> np.ndarray:
    """Put the arm (in the simulator) with its TCP this high over a point, pointing down; its joints."""
    kin = kinematics_of(ROBOT)
    r = kin.solve(
        Pose(position + [0.0, 0.0, height_m], np.diag([1.0, -1.0, -1.0])), ROBOT.home_q, np.random.default_rng(0)
    )
    assert r.success
    robot = world.scene.bodies["robot"]
    for j, q in zip(world.scene.arm_joints, r.q, strict=True):
        world.scene.client.resetJointState(robot, j, float(q))
    return r.q


@pytest.mark.parametrize("height_m", [0.10, 0.05, 0.0])
def test_the_hands_camera_sees_the_target_from_above_it_down_to_the_grasp(height_m: float) -> None:
    sc = load_scenario("pick_cube_wrist")
    with World.build(sc, 0) as world:
        world.scene.settle(240)
        truth = world.true_pose("cube")
        q = _hand_over(world, truth.position, height_m)
        kin = kinematics_of(ROBOT)
        frame = world.wrist_camera.capture_from(world.scene, kin.forward(q))
        # told where it is by the arm's kinematics: where the simulator renders it from (no hand-eye error)
        assert np.allclose(frame.T_world_cam.position, world.wrist_camera.T_world_cam_true.position, atol=1e-6)
        fingers = np.array([ROBOT.gripper.finger_max_m] * 2)
        frame = dataclasses.replace(frame, robot_boxes=robot_body(ROBOT).boxes(q, fingers))
        est = estimate_pose(frame, target_model(sc, world.placement("cube")), PerceptionParams())
        assert np.linalg.norm(est.pose.position - truth.position) < 0.001


def test_a_hand_eye_error_is_drawn_per_seed_and_the_robot_is_told_the_calibrated_pose() -> None:
    sc = load_scenario("pick_cube_wrist")
    wc = sc.wrist_camera.model_copy(update={"hand_eye_error": (5.0, 1.0)})
    sc = sc.model_copy(update={"wrist_camera": wc})
    offsets = []
    for seed in (0, 1):
        with World.build(sc, seed) as world:
            cam = world.wrist_camera
            err = cam.T_tcp_cam_true.inverse() @ cam.T_tcp_cam
            assert np.linalg.norm(err.position) == pytest.approx(0.005)
            angle = np.degrees(np.arccos(np.clip((np.trace(err.rotation) - 1.0) / 2.0, -1.0, 1.0)))
            assert angle == pytest.approx(1.0, abs=1e-6)
            offsets.append(err.position)
    assert not np.allclose(offsets[0], offsets[1])  # drawn per seed


def test_a_miscalibrated_fixed_camera_alone_is_refused_by_name_before_the_arm_moves() -> None:
    sc = load_scenario("pick_miscalibrated")
    for seed in (0, 1, 2):
        r = run_episode(sc, seed)
        assert not r.success and r.failure.stage is Stage.PERCEPTION
        assert "clearance" in r.failure.reason and "not tried" in r.failure.reason
        assert r.attempts == () or len(r.attempts) <= 1
        assert r.sim_time_s < 1.0  # before it runs


@pytest.mark.slow
def test_a_camera_on_the_hand_makes_the_miscalibrated_cells_grasps_safe() -> None:
    """The fixed camera's first look is off (its pose is off by 5 mm and 1 deg: seeds 0-7, 9.4-20.2
    mm against the truth); what the robot believed when it closed the gripper, seen by the hand's
    camera, is not (seeds 0-7: 0.006-0.12 mm; 2 mm is over ten times that, and under a fifth of the
    fixed camera's least error); and the cube is put down a few mm from the place (seeds 0-3: median
    1.3 mm; 50 seeds: median 0.53, largest 2.4: for the median of four to pass 3 mm, two must land
    farther off than any of those 50)."""
    rs = episodes("pick_miscalibrated_wrist", (0, 1, 2, 3))
    ok = at_least(rs, len(rs) - 1)
    assert float(np.median([r.perception.position_error_mm for r in rs if r.perception is not None])) > 5.0
    at_least(ok, len(rs) - 1, lambda r: r.tracking_error_mm < 2.0, "close within 2 mm of the truth")
    assert float(np.median([r.place_error_mm for r in ok])) < 3.0


@pytest.mark.slow
def test_a_push_during_the_descent_is_seen_by_the_hands_camera_and_the_first_attempt_goes_on() -> None:
    sc = load_scenario("pick_pushed_descent_wrist")
    results = [run_episode(sc, seed) for seed in (0, 1, 2, 3)]
    first = [r for r in results if r.success and len(r.attempts) == 1]
    assert len(first) >= 3, [(r.failure, len(r.attempts)) for r in results]
    backed_off = [p.message for r in results for p in r.phases if p.phase == "back_off"]
    assert any("from where it was tracked" in m for m in backed_off)  # it saw the move under the hand
