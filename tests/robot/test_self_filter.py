"""The self-filter: the robot's links posed by its joint states bound its own pixels in a frame, so a
target of the arm's or the hand's colour is not mistaken for them (a grey or a black box)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.robot import robot_named
from pickdemo.robot.self_geometry import link_bounds, robot_body
from pickdemo.robot.stl import stl_vertices

ROBOT = robot_named()


def test_a_binary_stl_is_read() -> None:
    tri = np.zeros(1, dtype=[("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    tri["v"][0] = [[0, 0, 0], [1, 0, 0], [0, 2, 0]]
    data = b"x" * 80 + np.uint32(1).tobytes() + tri.tobytes()
    np.testing.assert_allclose(stl_vertices(data), [[0, 0, 0], [1, 0, 0], [0, 2, 0]])
    with pytest.raises(ValueError, match="not a binary STL"):
        stl_vertices(data[:-10])


def test_every_link_of_the_arm_and_hand_is_bounded() -> None:
    names = set(link_bounds(ROBOT))
    assert {f"panda_link{i}" for i in range(8)} <= names
    assert {"panda_hand", *ROBOT.gripper.finger_links} <= names
    for lo, hi in link_bounds(ROBOT).values():
        assert np.all(hi - lo > 0.01) and np.all(hi - lo < 0.4)


def test_the_boxes_follow_the_joints() -> None:
    """The TCP lies between the fingers' boxes and below the hand's, wherever the arm is; a point a
    few centimetres beside the hand is in none."""
    from pickdemo.robot.kinematics import kinematics_of

    kin = kinematics_of(ROBOT)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = ROBOT.home_q + rng.uniform(-0.4, 0.4, 7)
        tcp = kin.forward(q)
        boxes = dict(zip(link_bounds(ROBOT), robot_body(ROBOT).boxes(q, [0.02, 0.02], pad_m=0.0), strict=True))
        pads = tcp.transform_points(np.array([[0.0, 0.02, 0.0], [0.0, -0.02, 0.0]]))  # where the finger pads are
        assert boxes["panda_leftfinger"].contains(pads).any() and boxes["panda_rightfinger"].contains(pads).any()
        assert not any(b.contains(tcp.position[None])[0] for b in boxes.values())  # between the open fingers
        beside = tcp.transform_points(np.array([[0.12, 0.0, 0.0]]))
        assert not any(b.contains(beside)[0] for b in boxes.values())


def test_an_oriented_box_contains_what_lies_inside() -> None:
    box = OrientedBox(Pose.from_xyz_rpy(np.array([1.0, 0.0, 0.0]), yaw=np.pi / 2), np.array([-0.1, -0.2, -0.3]),
                      np.array([0.1, 0.2, 0.3]))  # fmt: skip
    pts = np.array([[1.0, 0.0, 0.0], [1.15, 0.0, 0.0], [1.0, 0.15, 0.0], [1.0, 0.0, np.nan]])
    assert box.contains(pts).tolist() == [True, True, False, False]  # turned: its y along world x
    assert box.corners().shape == (8, 3)


@pytest.mark.sim
def test_the_arm_in_view_is_filtered_out_and_the_rest_is_not() -> None:
    """A full frame with the arm reaching into the camera's view: the pixels the self-filter marks are
    the robot's (by the simulator's labels: a test may use them), and almost all of the robot's
    pixels above the table are marked."""
    from pickdemo.perception.segmentation import robot_pixels, world_heights
    from pickdemo.runtime.world import World
    from pickdemo.scenario.load import load_scenario

    sc = load_scenario("pick_cube")
    q = ROBOT.home_q + np.array([0.3, 0.5, 0.0, 0.4, 0.0, -0.2, 0.0])  # the hand down into the view
    with World.build(sc, 0) as world:
        scene = world.scene
        for j, qj in zip(scene.arm_joints, q, strict=True):
            scene.client.resetJointState(scene.bodies["robot"], j, float(qj))
        frame, seg = world.camera.capture_labels(scene)
        robot_id = scene.bodies["robot"]
    frame = dataclasses.replace(frame, robot_boxes=robot_body(ROBOT).boxes(q, [ROBOT.gripper.finger_max_m] * 2))
    above = np.nan_to_num(world_heights(frame), nan=-1.0) > 0.005
    marked = robot_pixels(frame, above)
    is_robot = (seg & ((1 << 24) - 1)) == robot_id
    assert marked.sum() > 1000
    assert (marked & ~is_robot).sum() < 0.01 * marked.sum()  # what it marks is the robot
    assert (marked & is_robot & above).sum() > 0.97 * (is_robot & above).sum()  # and it marks the robot
    cube = (seg & ((1 << 24) - 1)) == scene.bodies["cube"]
    assert not (marked & cube).any()


@pytest.mark.sim
@pytest.mark.slow
def test_boxes_of_the_arm_s_colours_are_picked() -> None:
    """A grey and a black box (the arm is white, the hand dark grey), 4 seeds each: at least 3 each."""
    from episodes import at_least, episodes

    for name in ("pick_grey_box", "pick_black_box"):
        at_least(episodes(name, (0, 1, 2, 3)), 3)
