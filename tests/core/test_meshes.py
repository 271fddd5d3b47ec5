"""Mesh objects from URDF files: their shape read from the file (in PyBullet's base frame, at scale),
placed by the layout, built by the scene where the layout says, one file a seed from a glob."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pickdemo.core.geometry import Pose
from pickdemo.core.meshes import expand, obj_vertices, pybullet_data_dir, read_urdf
from pickdemo.core.shapes import Box, Mesh
from pickdemo.core.streams import spawn_rngs
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.parse import parse_scenario


def _scenario(*objects: dict) -> dict:
    cube = {"name": "cube", "shape": "box", "size": [0.05] * 3, "color": [0.8, 0.1, 0.1], "position": [0.45, 0.0],
            "target": True}  # fmt: skip
    return {"name": "t", "objects": [cube, *objects], "place": {"position": [0.45, 0.3]}}


def _mesh(**kw: object) -> dict:
    return {"name": "m", "shape": "mesh", "position_range": [[0.35, 0.65], [-0.25, 0.25]], **kw}


def test_a_box_from_a_urdf_has_the_box_s_geometry() -> None:
    """The jenga block's URDF is a 0.15 x 0.05 x 0.03 box mesh: as a Mesh it answers what a Box does."""
    scale = 0.8
    mesh = Mesh("pybullet_data:jenga/jenga.urdf", scale, read_urdf("pybullet_data:jenga/jenga.urdf").vertices * scale)
    box = Box((0.15 * scale, 0.05 * scale, 0.03 * scale))
    np.testing.assert_allclose(mesh.size, box.size, atol=1e-9)
    assert mesh.footprint_radius_m == pytest.approx(box.footprint_radius_m)
    assert mesh.bounding_radius_m == pytest.approx(box.bounding_radius_m)
    assert mesh.grasp_width_m == pytest.approx(box.grasp_width_m)
    assert mesh.min_width_m == pytest.approx(box.size[2], abs=1e-3)
    assert mesh.top_extents_m == pytest.approx((np.hypot(*box.size[:2]), box.size[1]))
    rng = np.random.default_rng(0)
    for _ in range(10):
        r, p, y = rng.uniform(-np.pi, np.pi, 3)
        R = Pose.from_xyz_rpy(np.zeros(3), roll=r, pitch=p, yaw=y).rotation
        assert mesh.resting_height_m(R) == pytest.approx(box.resting_height_m(R))


def test_a_urdf_s_frames_are_applied() -> None:
    """Lego: its collision box is offset and turned in the link frame; the duck's inertial origin is
    off the link's. Vertices are in the inertial frame (PyBullet's base frame)."""
    lego = read_urdf("pybullet_data:lego/lego.urdf").vertices
    assert np.ptp(lego, axis=0) == pytest.approx([0.032, 0.032, 0.023], abs=1e-6)  # a 32 x 23 x 32 mm box, rolled
    duck = read_urdf("pybullet_data:duck_vhacd.urdf")
    assert duck.mass_kg == pytest.approx(0.1) and duck.color == (1.0, 1.0, 0.4)
    raw = obj_vertices(pybullet_data_dir() / "duck_vhacd.obj") * 0.05  # the URDF's mesh scale
    np.testing.assert_allclose(duck.vertices, raw - [0.0, 0.02, 0.0], atol=1e-12)  # its inertial origin


def test_a_broken_file_is_left_out_of_a_glob_s_choice() -> None:
    """random_urdfs/168 has only NaN vertices: named alone it is an error, in a glob it is left out."""
    from pickdemo.core.meshes import MeshFileError, usable

    assert "pybullet_data:random_urdfs/168/168.urdf" in expand("pybullet_data:random_urdfs/16?/*.urdf", None)
    kept = usable("pybullet_data:random_urdfs/16?/*.urdf")
    assert len(kept) == 9 and "pybullet_data:random_urdfs/168/168.urdf" not in kept
    with pytest.raises(MeshFileError, match="a vertex that is not finite"):
        read_urdf("pybullet_data:random_urdfs/168/168.urdf")


def test_a_glob_walks_a_sorted_set_and_a_seed_draws_the_same_file() -> None:
    files = expand("pybullet_data:random_urdfs/??0/*.urdf", None)
    assert len(files) == 100 and list(files) == sorted(files)
    sc = parse_scenario(_scenario(_mesh(urdf_choice="pybullet_data:random_urdfs/??0/*.urdf", scale_range=[0.5, 0.7])))
    drawn = []
    for seed in range(12):
        rngs = spawn_rngs(seed)
        m = sample_layout(sc, rngs["layout"], rngs["objects"])[1].geometry
        again = spawn_rngs(seed)
        assert sample_layout(sc, again["layout"], again["objects"])[1].geometry == m  # one seed, one file
        assert 0.5 <= m.scale <= 0.7
        drawn.append(m.urdf)
    assert len(set(drawn)) >= 8  # seeds walk the set
    # the mesh's file and scale come from their own stream: the objects before it are laid out as before
    plain = parse_scenario(_scenario())
    for seed in range(3):
        a, b = spawn_rngs(seed), spawn_rngs(seed)
        cube, cube_too = sample_layout(plain, a["layout"])[0], sample_layout(sc, b["layout"], b["objects"])[0]
        assert np.array_equal(cube.pose.position, cube_too.pose.position) and cube.geometry == cube_too.geometry


@pytest.mark.sim
@pytest.mark.parametrize(
    ("urdf", "scale"),
    [("pybullet_data:duck_vhacd.urdf", 1.0), ("pybullet_data:jenga/jenga.urdf", 0.8),
     ("pybullet_data:lego/lego.urdf", 1.0), ("pybullet_data:teddy_vhacd.urdf", 0.8),
     ("pybullet_data:random_urdfs/000/000.urdf", 0.6)],
)  # fmt: skip
def test_the_scene_builds_a_mesh_resting_where_the_layout_put_it(urdf: str, scale: float) -> None:
    """PyBullet's base frame is the frame of the vertices: the body starts at the layout's pose with its
    lowest point on the table, and settling moves it little (a stable pose, upright as the file stands)."""
    from pickdemo.runtime.world import World

    mesh = {"name": "m", "shape": "mesh", "urdf": urdf, "scale": scale, "position": [0.55, -0.2], "yaw_deg": 30.0}
    sc = parse_scenario(_scenario(mesh))
    with World.build(sc, 0) as world:
        placed = world.placement("m")
        start = world.true_pose("m")
        np.testing.assert_allclose(start.position, placed.pose.position, atol=1e-6)
        assert start.transform_points(placed.geometry.vertices)[:, 2].min() == pytest.approx(0.0, abs=1e-6)
        world.scene.settle(2000)
        rest = world.true_pose("m")
        low = rest.transform_points(placed.geometry.vertices)[:, 2].min()
        assert -0.5e-3 < low < 2e-3  # on the table (PyBullet keeps a collision margin of about 1 mm)
        assert np.linalg.norm(rest.position[:2] - start.position[:2]) < 0.01


@pytest.mark.sim
@pytest.mark.slow
def test_the_cube_is_picked_among_meshes() -> None:
    """A duck, a jenga block and a random test-split object (one a seed) beside the red cube: the loop
    picks the cube (6 seeds, at least 5)."""
    from episodes import at_least, episodes

    rs = episodes("pick_among_meshes", tuple(range(6)))
    at_least(rs, 5)


def test_a_mesh_on_its_edge_is_scored_by_the_middle_of_what_it_covers() -> None:
    """A wedge (a right triangle 6 x 10 cm, 3 cm thick) leaning 30 deg: its centre is the middle of its
    footprint as it rests, at half its height (what the camera sees of it), which its upright footprint's
    middle turned with it is not; turned about the vertical only, the two are the same."""
    tri = np.array([[0.0, 0.0], [0.06, 0.0], [0.0, 0.1]])  # (x, z)
    v = np.array([[x, y, z] for x, z in tri for y in (0.0, 0.03)]) - [0.02, 0.015, 0.03]
    wedge = Mesh("wedge", 1.0, v)
    R = Pose.from_xyz_rpy(np.zeros(3), pitch=np.radians(30.0), yaw=np.radians(20.0)).rotation
    world = v @ R.T
    lo, hi = world.min(axis=0), world.max(axis=0)
    centre = R @ wedge.centre_turned(R)
    # the footprint: a rectangle turned 20 deg (the wedge is symmetric across its thickness), whose
    # middle is its extents' middle along its sides
    a = np.radians(20.0)
    sides = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])  # columns: its sides' directions
    along = world[:, :2] @ sides
    middle = sides @ ((along.min(axis=0) + along.max(axis=0)) / 2.0)
    assert centre[:2] == pytest.approx(middle, abs=1e-3)
    assert centre[2] == pytest.approx((lo[2] + hi[2]) / 2.0)
    assert np.linalg.norm((R @ wedge.box_centre)[:2] - centre[:2]) > 0.005  # (upright's middle: elsewhere)
    yaw = Pose.from_xyz_rpy(np.zeros(3), yaw=np.radians(35.0)).rotation
    assert wedge.centre_turned(yaw) == pytest.approx(wedge.box_centre)


def test_an_object_s_urdf_and_a_fixture_s_model_file_are_refused_the_same_way(tmp_path: Path) -> None:
    """Both readers read XML the one guarded way (``read_xml``): a directory, a missing, a too large or
    a malformed file is one line naming the file, each in its reader's words."""
    from pickdemo.core.meshes import MAX_URDF_BYTES, MeshFileError
    from pickdemo.core.model_file import read_model

    big = tmp_path / "big.urdf"
    big.write_bytes(b"<robot>" + b" " * MAX_URDF_BYTES + b"</robot>")
    bad = tmp_path / "bad.urdf"
    bad.write_text("<robot><link></robot>")
    cases = [
        (tmp_path, "is a directory, not {}"),
        (tmp_path / "none.urdf", "no such file"),
        (big, f"bytes; {{}} is at most {MAX_URDF_BYTES}"),
        (bad, "not {} (not XML: mismatched tag"),
    ]
    for path, said in cases:
        for read, kind in ((lambda f: read_urdf(str(f)), "a URDF"), (read_model, "a URDF or SDF file")):
            with pytest.raises(MeshFileError) as err:
                read(path)
            text = str(err.value)
            assert text.startswith(f"{path}: ") and said.format(kind) in text and "\n" not in text, text
