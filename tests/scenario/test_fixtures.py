"""A scenario's fixtures: a bin's boxes where its spec puts them, what stands in it rests on its floor,
the simulator builds it where the robot is told it is, and perception leaves it out of its cloud."""

from __future__ import annotations

import dataclasses

import numpy as np

from pickdemo.core.geometry import box_surface_points
from pickdemo.perception import PerceptionParams
from pickdemo.perception.unknown import survey_objects
from pickdemo.runtime.world import World
from pickdemo.scenario.fixtures import fixture_boxes
from pickdemo.scenario.load import load_scenario


def test_a_bin_is_a_floor_and_four_walls_where_its_spec_puts_it() -> None:
    sc = load_scenario("clear_bin")
    (b,) = sc.fixtures
    boxes = b.boxes()
    assert len(boxes) == 5
    pts = np.vstack([box.corners() for box in boxes])
    ox, oy = b.half_outer
    cx, cy = b.position
    assert np.allclose(pts[:, 0].min(), cx - ox) and np.allclose(pts[:, 0].max(), cx + ox)
    assert np.allclose(pts[:, 1].min(), cy - oy) and np.allclose(pts[:, 1].max(), cy + oy)
    assert np.isclose(pts[:, 2].max(), b.rim_z) and np.isclose(pts[:, 2].min(), 0.0)
    # what stands inside rests on its floor; outside, on the table
    assert sc.surface_z(cx, cy) == b.floor_z > 0.0
    assert sc.surface_z(cx + ox + 0.05, cy) == 0.0
    # the middle of the bin is in no box; a point in a wall is
    assert not any(box.contains(np.array([[cx, cy, b.floor_z + 0.01]]))[0] for box in boxes)
    wall = np.array([[cx + b.inner_size[0] / 2.0 + b.wall_thickness_m / 2.0, cy, b.rim_z / 2.0]])
    assert any(box.contains(wall)[0] for box in boxes)
    # its faces as points a grasp keeps out of: on the boxes' surfaces, none inside the bin's space
    surface = box_surface_points(boxes)
    assert len(surface) > 1000
    inner = (np.abs(surface[:, 0] - cx) < b.inner_size[0] / 2.0 - 1e-6) & (
        np.abs(surface[:, 1] - cy) < b.inner_size[1] / 2.0 - 1e-6
    )
    assert np.all(surface[inner, 2] <= b.floor_z + 1e-9)


def test_the_simulated_bin_stands_where_the_robot_is_told_and_the_camera_does_not_see_it_as_an_object() -> None:
    sc = load_scenario("clear_bin")
    (b,) = sc.fixtures
    with World.build(sc, 0) as world:
        scene = world.scene
        aabbs = [scene.client.getAABB(body) for body in scene.fixture_bodies["bin"]]
        lo = np.min([a[0] for a in aabbs], axis=0)
        hi = np.max([a[1] for a in aabbs], axis=0)
        corners = np.vstack([box.corners() for box in b.boxes()])
        assert np.allclose(lo, corners.min(axis=0), atol=2e-3) and np.allclose(hi, corners.max(axis=0), atol=2e-3)
        # the pile fallen into it: what the camera finds is in the bin, none of it its walls or floor
        scene.settle(4 * 240)
        frame = dataclasses.replace(
            world.camera.take(scene, None, None),
            robot_boxes=fixture_boxes(sc.fixtures, PerceptionParams().min_height_m),
        )
        found = survey_objects(frame)
        centres = [o.centre for o in found.objects]
        # (the robot and the tray are left out by the loop as well; here they are found, far from the bin)
        ox, oy = b.half_outer
        near = [c for c in centres if abs(c[0] - b.position[0]) < ox + 0.03 and abs(c[1] - b.position[1]) < oy + 0.03]
        assert 1 <= len(near) <= 5, centres
        assert all(b.inside(float(x), float(y)) for x, y, _ in near), near


def test_the_simulated_shelf_stands_where_its_boxes_say_and_its_item_on_its_board() -> None:
    """A model fixture: the simulator loads its file where the scenario puts its frame (PyBullet places
    a body by its inertial frame, 1.2 m up the kiva shelf), and its item stands on the board under it."""
    sc = load_scenario("pick_shelf")
    (shelf,) = sc.fixtures
    assert shelf.kind == "model"
    with World.build(sc, 0) as world:
        scene = world.scene
        (body,) = scene.fixture_bodies["shelf"]
        lo, hi = (np.array(v) for v in scene.client.getAABB(body))
        corners = np.vstack([box.corners() for box in shelf.boxes()])
        assert np.allclose(lo, corners.min(axis=0), atol=0.02) and np.allclose(hi, corners.max(axis=0), atol=0.02)
        item = world.placement(next(o.name for o in sc.objects if o.target))
        board = sc.surface_z(float(item.pose.position[0]), float(item.pose.position[1]), 0.1)
        assert abs(board - (0.814 - 0.75)) < 1e-3
        scene.settle(240)
        p = world.true_pose(item.name).position
        assert abs(p[2] - item.pose.position[2]) < 0.005  # it stood on the board, as placed
