"""A scenario's fixtures: a bin's boxes where its spec puts them, what stands in it rests on its floor,
the simulator builds it where the robot is told it is, and perception leaves it out of its cloud."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from pickdemo.core.geometry import box_surface_points
from pickdemo.perception import PerceptionParams
from pickdemo.runtime.world import World
from pickdemo.scenario.base import ScenarioError
from pickdemo.scenario.fixtures import fixture_boxes
from pickdemo.scenario.load import load_scenario
from pickdemo.worldmodel import WorldModel, split_view


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
        world, view = WorldModel(), split_view(frame)
        world.update(view)
        found = world.survey(view)
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


def _cubby(gap_m: float) -> str:
    """A cubby's URDF: a board whose top is 20 mm above the table, two side walls, and a roof ``gap_m``
    above the board (160 x 160 mm inside)."""
    roof_z = 0.02 + gap_m + 0.005

    def box(size: tuple[float, float, float], xyz: tuple[float, float, float]) -> str:
        return (
            f'<collision><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}"/><geometry><box size="{size[0]} {size[1]} '
            f'{size[2]}"/></geometry></collision>'
        )

    parts = [
        box((0.16, 0.16, 0.02), (0.0, 0.0, 0.01)),
        box((0.16, 0.16, 0.01), (0.0, 0.0, roof_z)),
        *(box((0.16, 0.01, roof_z), (0.0, y, roof_z / 2.0)) for y in (-0.085, 0.085)),
    ]
    return f'<robot name="cubby"><link name="cubby">{"".join(parts)}</link></robot>'


def _block_in_a_cubby(tmp_path: Path, gap_m: float) -> Path:
    """A pick whose other object, a 40 mm block, stands at a fixed position on a cubby's board (a folder
    of its own for each cubby: a model file is read once per path)."""
    folder = tmp_path / f"gap_{gap_m * 1e3:.0f}mm"
    folder.mkdir()
    (folder / "cubby.urdf").write_text(_cubby(gap_m))
    f = folder / "s.toml"
    f.write_text(
        'name = "t"\n[camera]\nposition = [1.1, 0.0, 0.75]\nlook_at = [0.5, 0.0, 0.0]\n'
        '[[objects]]\nname = "cube"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.85, 0.1, 0.1]\n'
        "position_range = [[0.45, 0.55], [-0.05, 0.05]]\ntarget = true\n"
        '[[objects]]\nname = "block"\nshape = "box"\nsize = [0.04, 0.04, 0.04]\ncolor = [0.1, 0.1, 0.9]\n'
        "position = [0.5, -0.3]\nlevel_m = 0.03\n"
        '[[fixtures]]\nkind = "model"\nname = "cubby"\nfile = "cubby.urdf"\nposition = [0.5, -0.3, 0.0]\n'
        "[place]\nposition = [0.45, 0.3]\n"
    )
    return f


def test_an_object_on_a_model_s_board_is_checked_against_the_model(tmp_path: Path) -> None:
    """An object at a fixed position standing on a model's top (``level_m``) must not be inside the
    model either: a 40 mm block on a cubby's board under a roof 30 mm above it is refused (the model's
    check used to leave every object with a ``level_m`` out, where the bin's took them in); under a roof
    150 mm up it stands, the board it stands on not taken for an obstacle."""
    with pytest.raises(ScenarioError, match=r"objects\.block\.position: \(0\.500, -0\.300\) m is inside or against "):
        load_scenario(_block_in_a_cubby(tmp_path, gap_m=0.03))
    sc = load_scenario(_block_in_a_cubby(tmp_path, gap_m=0.15))
    assert sc.surface_z(0.5, -0.3, 0.03) == pytest.approx(0.02)  # it stands on the board
