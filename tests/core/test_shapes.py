"""The shapes as types: each derivation of a box and a cylinder, and where they are built from."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

import pickdemo
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import SHAPES, Box, Cylinder, make_shape
from pickdemo.core.streams import spawn_rngs
from pickdemo.scenario.base import ScenarioError
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.load import load_scenario, parse_scenario
from pickdemo.scenario.task import target_model


def test_box_derivations() -> None:
    box = Box((0.06, 0.04, 0.05))
    assert box.kind == "box" and box.size == (0.06, 0.04, 0.05)
    assert box.height_m == 0.05
    assert box.footprint_radius_m == pytest.approx(0.5 * np.hypot(0.06, 0.04))
    assert box.bounding_radius_m == pytest.approx(0.5 * np.linalg.norm([0.06, 0.04, 0.05]))
    assert box.yaw_symmetry_rad == np.pi
    assert Box((0.05, 0.05, 0.03)).yaw_symmetry_rad == np.pi / 2.0
    assert box.grasp_width_m == 0.04
    assert box.top_extents_m == (0.06, 0.04)
    assert box.resting_height_m(np.eye(3)) == pytest.approx(0.025)
    on_side = Pose.from_xyz_rpy(np.zeros(3), roll=np.pi / 2.0).rotation  # its y axis up
    assert box.resting_height_m(on_side) == pytest.approx(0.02)
    tilt, extent = box.resting_face(on_side)
    assert tilt == pytest.approx(0.0, abs=1e-6) and extent == 0.04
    assert len(box.outline_xy(0.0)) == 4
    assert np.allclose(np.abs(box.outline_xy(0.0)), [0.03, 0.02])


def test_cylinder_derivations() -> None:
    cyl = Cylinder(0.04, 0.1)
    assert cyl.kind == "cylinder" and cyl.size == (0.04, 0.1)
    assert cyl.height_m == 0.1 and cyl.footprint_radius_m == 0.02 and cyl.grasp_width_m == 0.04
    assert cyl.yaw_symmetry_rad == 0.0 and cyl.top_extents_m == (0.04, 0.04)
    assert cyl.resting_height_m(np.eye(3)) == pytest.approx(0.05)
    lying = Pose.from_xyz_rpy(np.zeros(3), pitch=np.pi / 2.0).rotation
    assert cyl.resting_height_m(lying) == pytest.approx(0.02)
    tilt, extent = cyl.resting_face(lying)
    assert tilt == pytest.approx(90.0) and extent == 0.1
    assert np.allclose(np.linalg.norm(cyl.outline_xy(1.0), axis=1), 0.02)


def test_surface_points_and_outline() -> None:
    box, cyl = Box((0.2, 0.1, 0.06)), Cylinder(0.04, 0.1)
    q, n = box.closest_points(np.array([[0.2, 0.0, 0.0], [0.0, 0.0, 0.01]]))
    assert np.allclose(q[0], [0.1, 0.0, 0.0]) and np.allclose(n[0], [1.0, 0.0, 0.0])
    assert np.allclose(q[1], [0.0, 0.0, 0.03]) and np.allclose(n[1], [0.0, 0.0, 1.0])
    q, n = cyl.closest_points(np.array([[0.03, 0.0, 0.01]]))
    assert np.allclose(q[0], [0.02, 0.0, 0.01]) and np.allclose(n[0], [1.0, 0.0, 0.0])
    assert np.allclose(box.outline_residuals(np.array([[0.1, 0.0], [0.0, 0.06]])), [0.0, 0.01])
    assert np.allclose(cyl.outline_residuals(np.array([[0.02, 0.0], [0.0, 0.01]])), [0.0, -0.01])


def test_make_shape_by_name() -> None:
    assert make_shape("box", (0.05, 0.04, 0.03)) == Box((0.05, 0.04, 0.03))
    assert make_shape("cylinder", [0.04, 0.08]) == Cylinder(0.04, 0.08)
    assert set(SHAPES) == {"box", "cylinder", "mesh"}
    with pytest.raises(ValueError, match="unknown shape 'sphere'"):
        make_shape("sphere", (0.05,))
    with pytest.raises(ValueError):
        make_shape("cylinder", (0.05, 0.04, 0.03))


def _scenario(obj: dict) -> dict:
    return {"name": "t", "objects": [{"name": "a", "color": [1, 0, 0], "position": [0.5, 0.0], "target": True, **obj}],
            "place": {"position": [0.5, 0.2]}}  # fmt: skip


def test_the_schema_asks_the_shapes() -> None:
    with pytest.raises(ScenarioError, match=r"a box needs 3 values \(x, y, z extents\), got 2"):
        parse_scenario(_scenario({"shape": "box", "size": [0.05, 0.05]}))
    with pytest.raises(ScenarioError, match=r"a cylinder needs 2 values \(diameter, height\), got 3"):
        parse_scenario(_scenario({"shape": "cylinder", "size": [0.05, 0.05, 0.05]}))
    spec = parse_scenario(_scenario({"shape": "box", "size_range": [[0.03, 0.04], [0.05, 0.06], [0.02, 0.03]]})).target
    assert spec.largest_size == (0.04, 0.06, 0.03) and spec.largest_shape == Box((0.04, 0.06, 0.03))


@pytest.mark.parametrize("name", ["pick_cube", "pick_box", "pick_cylinder", "pick_cluttered"])
def test_placement_and_target_model_carry_one_shape(name: str) -> None:
    """The layout builds each object's shape once; the target model is told that same shape."""
    sc = load_scenario(name, check=False)
    layout = sample_layout(sc, spawn_rngs(0)["layout"])
    for placement in layout:
        spec = next(o for o in sc.objects if o.name == placement.name)
        assert placement.geometry.kind == placement.shape == spec.shape
        assert placement.size == placement.geometry.size and placement.height_m == placement.geometry.height_m
    placement = next(p for p in layout if p.name == sc.target.name)
    model = target_model(sc, placement)
    assert model.geometry is placement.geometry
    assert (model.shape, model.size, model.height_m) == (placement.shape, placement.size, placement.height_m)


def _imports() -> dict[str, set[str]]:
    """Each pickdemo module's pickdemo imports, at its top or inside functions (late) alike."""
    root = Path(pickdemo.__file__).parent
    names = {".".join(p.relative_to(root.parent).with_suffix("").parts).removesuffix(".__init__"): p
             for p in root.rglob("*.py")}  # fmt: skip
    graph: dict[str, set[str]] = {}
    for name, path in names.items():
        found: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("pickdemo"):
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    found.add(sub if sub in names else node.module)
            elif isinstance(node, ast.Import):
                found.update(a.name for a in node.names if a.name.startswith("pickdemo"))
        graph[name] = {m for m in found if m in names and m != name and m != "pickdemo"}
    return graph


def test_the_scenario_modules_import_one_way() -> None:
    """shapes <- schema <- layout <- checks <- scenario, with no late import that turns back."""
    graph = _imports()

    def reaches(a: str, b: str) -> bool:
        seen, todo = set(), [a]
        while todo:
            m = todo.pop()
            if m == b:
                return True
            if m not in seen:
                seen.add(m)
                todo.extend(graph[m])
        return False

    chain = (
        "pickdemo.core.shapes",
        "pickdemo.scenario.schema",
        "pickdemo.scenario.layout",
        "pickdemo.scenario.checks",
        "pickdemo.scenario.load",
    )
    for low, high in zip(chain, chain[1:], strict=False):
        assert reaches(high, low) and not reaches(low, high), (low, high)
    for pure in chain[:-1]:
        assert not any(m.startswith("pickdemo.sim") for m in graph[pure])


@pytest.mark.parametrize("shape", [Box((0.06, 0.04, 0.05)), Cylinder(0.05, 0.08)], ids=["box", "cylinder"])
def test_a_ray_enters_where_it_first_meets_the_surface(shape) -> None:  # noqa: ANN001 - a Shape
    """Rays from outside toward points inside: the entry lies on the surface with its outward normal,
    and the ray is outside just before it (nothing nearer along the ray); rays that pass miss."""
    rng = np.random.default_rng(7)
    origins = rng.normal(size=(500, 3))
    origins *= (0.3 + rng.random((500, 1))) / np.linalg.norm(origins, axis=1, keepdims=True)
    targets = (rng.random((500, 3)) - 0.5) * np.array([0.02, 0.02, 0.03])  # inside either shape
    q, n, hit = shape.ray_entry(origins, targets - origins)
    assert hit.all()
    closest, normal = shape.closest_points(q)
    assert np.allclose(closest, q, atol=1e-9)
    d = (targets - origins) / np.linalg.norm(targets - origins, axis=1, keepdims=True)
    assert np.all(np.einsum("ij,ij->i", n, d) < 0.0)  # the ray enters against the outward normal
    before = q - 1e-5 * d
    assert np.all(np.linalg.norm(shape.closest_points(before)[0] - before, axis=1) > 0.0)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    # A ray aimed well to the side of the shape, parallel to the line toward it, misses.
    side = np.cross(d, [0.0, 0.0, 1.0]) + np.cross(d, [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    _, _, hit_far = shape.ray_entry(origins + 0.2 * side, targets - origins)
    assert not hit_far.any()
