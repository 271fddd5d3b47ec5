"""Scenario files: the shipped ones load; bad ones give one line naming the file and the key."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from pickdemo.scenario import checks, load
from pickdemo.scenario.checks import check_scenario
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.load import ScenarioError, list_scenarios, load_scenario, suite_scenarios
from pickdemo.scenario.parse import parse_scenario

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"

GOOD = """
name = "t"
[[objects]]
name = "cube"
shape = "box"
size = [0.05, 0.05, 0.05]
color = [0.85, 0.1, 0.1]
position = [0.5, 0.0]
target = true
[place]
position = [0.45, 0.3]
"""


def test_shipped_scenarios_load() -> None:
    names = list_scenarios()
    assert {"pick_cube", "pick_cylinder"} <= set(names)
    for name in names:
        sc = load_scenario(name)
        assert sc.name == name
        assert sc.clear is not None if sc.task == "clear" else sc.target.target


def test_a_shipped_scenario_that_does_not_load_fails_the_suite(tmp_path: Path, monkeypatch) -> None:
    # Issue 57: it was left out, and a plain `bench` gated a smaller suite than it said.
    (tmp_path / "good.toml").write_text(GOOD.replace('name = "t"', 'name = "good"\ntags = ["suite"]'))
    monkeypatch.setattr(load, "builtin_scenario_dirs", lambda: [tmp_path])
    assert suite_scenarios() == ["good"]
    (tmp_path / "broken.toml").write_text(GOOD.replace('name = "t"', 'name = "broken"\ntags = ["suite"]\nspeed = 3'))
    with pytest.raises(ScenarioError) as err:
        suite_scenarios()
    msg = str(err.value)
    assert "'broken'" in msg and str(tmp_path / "broken.toml") in msg and "speed" in msg and "\n" not in msg, msg


def test_issue_keys_of_pick_cube() -> None:
    sc = load_scenario("pick_cube")
    assert sc.camera.fov_deg == (57.0, 43.0) and sc.camera.depth_noise == "kinect"
    assert sc.target.position_range == ((0.4, 0.6), (-0.15, 0.15))
    assert sc.success.lift_height == 0.05 and sc.success.place_tolerance == 0.02


def test_load_by_path(tmp_path: Path) -> None:
    f = tmp_path / "mine.toml"
    f.write_text(GOOD)
    assert load_scenario(f).name == "t"
    assert load_scenario(str(f)).target.name == "cube"


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda s: s.replace("[0.05, 0.05, 0.05]", "[0.05, 0.05]"), "objects.cube.size"),
        (lambda s: s.replace('shape = "box"', 'shape = "sphere"'), "objects.cube.shape"),
        (lambda s: s.replace("target = true", "target = false"), "target = true"),
        (lambda s: s + "\n[camera]\nfov_deg = [57.0, 200.0]\n", "camera.fov_deg"),
        (lambda s: s + '\n[camera]\ndepht_noise = "kinect"\n', "camera.depht_noise"),
        (
            lambda s: s.replace("[place]\nposition = [0.45, 0.3]", "[place]"),
            "place: give exactly one of position, position_range",
        ),
        (lambda s: s.replace('name = "t"', 'name = "t'), "invalid TOML"),
        (lambda s: s.replace("position = [0.5, 0.0]", ""), "position"),
    ],
)
def test_bad_input_is_one_line_naming_file_and_key(tmp_path: Path, edit, expected: str) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(edit(GOOD))
    with pytest.raises(ScenarioError) as err:
        load_scenario(f)
    msg = str(err.value)
    assert "\n" not in msg
    assert str(f) in msg
    assert expected in msg


def test_default_task_is_the_task_of_a_file_without_one(tmp_path: Path) -> None:
    f = tmp_path / "static.toml"
    f.write_text(GOOD.replace("target = true", "target = true\nstatic = true"))
    with pytest.raises(ScenarioError, match="objects.cube: the target of a pick cannot be static"):
        load_scenario(f)
    assert load_scenario(f, default_task="perceive").task == "perceive"
    assert load_scenario("pick_cube", default_task="perceive").task == "perceive"
    assert load_scenario("perceive_boxes").task == "perceive"  # said in the file: the default does not matter
    f.write_text('task = "pick"\n' + f.read_text())
    with pytest.raises(ScenarioError, match="cannot be static"):
        load_scenario(f, default_task="perceive")  # the file says it is a pick: checked as one


def test_one_path_style_for_schema_and_geometry_errors(tmp_path: Path) -> None:
    """An object is named by its name in every error (`objects.cube.size`), schema or geometry."""
    f = tmp_path / "s.toml"
    f.write_text(GOOD.replace("[0.05, 0.05, 0.05]", "[0.05, 0.05]"))
    with pytest.raises(ScenarioError, match=r"objects\.cube\.size: "):
        load_scenario(f)
    f.write_text(GOOD.replace("[0.05, 0.05, 0.05]", "[0.077, 0.09, 0.05]"))
    with pytest.raises(ScenarioError, match=r"objects\.cube\.size: its narrower side"):
        load_scenario(f)


def test_unknown_name_lists_known() -> None:
    with pytest.raises(ScenarioError, match="unknown scenario.*pick_cube"):
        load_scenario("no_such_scenario")


def test_missing_file() -> None:
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario("does/not/exist.toml")


def test_tilted_object_must_be_static(tmp_path: Path) -> None:
    f = tmp_path / "tilt.toml"
    f.write_text(GOOD.replace("target = true", "target = true\npitch_deg = 5.0"))
    with pytest.raises(ScenarioError, match="static"):
        load_scenario(f)
    perceive = GOOD.replace('name = "t"', 'name = "t"\ntask = "perceive"')
    f.write_text(perceive.replace("target = true", "target = true\npitch_deg = 5.0\nstatic = true"))
    assert load_scenario(f).target.static


def test_camera_ranges_come_together(tmp_path: Path) -> None:
    f = tmp_path / "cam.toml"
    f.write_text(GOOD + "\n[camera]\ndistance_range_m = [0.5, 1.0]\n")
    with pytest.raises(ScenarioError, match="camera"):
        load_scenario(f)


def test_layout_samples_sizes_tilts_and_camera() -> None:
    import numpy as np

    from pickdemo.scenario.layout import camera_position, sample_layout

    sc = load_scenario("perceive_boxes")
    rng = np.random.default_rng(0)
    (p,) = sample_layout(sc, rng)
    lo = [r[0] for r in sc.target.size_range]
    hi = [r[1] for r in sc.target.size_range]
    assert all(a <= s <= b for a, s, b in zip(lo, p.size, hi, strict=True))
    # Resting on the table: its lowest corner at z = 0.
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * np.array(p.size) / 2
    assert p.pose.transform_points(corners)[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    pos = camera_position(sc.camera, np.random.default_rng(1))
    d = np.linalg.norm(pos - np.array(sc.camera.look_at))
    assert 0.5 <= d <= 1.0


def test_a_place_region_is_drawn_per_seed_clear_of_the_objects() -> None:
    from pickdemo.core.streams import spawn_rngs
    from pickdemo.scenario.layout import sample_layout, sample_place

    sc = load_scenario("pick_anywhere")
    (x0, x1), (y0, y1) = sc.place.position_range
    spots = []
    for seed in range(20):
        rngs = spawn_rngs(seed)
        layout = sample_layout(sc, rngs["layout"])
        xy = sample_place(sc, layout, rngs["place"])
        assert x0 <= xy[0] <= x1 and y0 <= xy[1] <= y1
        target = next(p for p in layout if p.name == sc.target.name)
        for p in layout:  # somewhere else: clear of every object's start, the target's own included
            gap = target.geometry.footprint_radius_m + p.geometry.footprint_radius_m + sc.layout.clearance_m
            assert np.linalg.norm(np.array(xy) - p.pose.position[:2]) >= gap - 1e-12
        again = spawn_rngs(seed)
        assert sample_place(sc, sample_layout(sc, again["layout"]), again["place"]) == xy  # one seed, one spot
        spots.append(xy)
    assert len(set(spots)) == 20
    fixed = load_scenario("pick_cube")
    rngs = spawn_rngs(0)
    assert sample_place(fixed, sample_layout(fixed, rngs["layout"]), rngs["place"]) == tuple(fixed.place.position)


@pytest.mark.parametrize(
    ("place", "message"),
    [
        (
            "position_range = [[0.35, 0.6], [0.2, 0.9]]",
            "place.position_range: the region reaches off the table: (0.350, 0.725) m is off the table",
        ),
        ("position = [0.45, 0.3]\nposition_range = [[0.3, 0.4], [0.2, 0.3]]", "give exactly one of position"),
        ("position_range = [[0.6, 0.3], [0.2, 0.3]]", "position_range bounds must be [min, max]"),
    ],
)
def test_a_bad_place_region_is_one_line_naming_the_key(tmp_path, place: str, message: str) -> None:
    text = (SCENARIOS / "pick_cube.toml").read_text().replace("position = [0.45, 0.3]", place)
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ScenarioError) as err:
        load_scenario(f)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_place_is_refused_only_when_an_object_takes_it() -> None:
    """The target put down at the place needs its footprint clear: a box whose footprint reaches
    within the target's footprint radius of the spot takes it; one beside it does not."""

    def with_box(x: float) -> dict:
        data = tomllib.loads((SCENARIOS / "pick_cube.toml").read_text())
        box = {"name": "box", "shape": "box", "size": [0.04, 0.04, 0.08], "color": [0.1, 0.1, 0.9]}
        place = data["place"]["position"]
        data["objects"].append({**box, "position": [place[0] + x, place[1]]})
        return data

    check_scenario(parse_scenario(with_box(0.09)))  # 7 cm from the spot to its side: free
    with pytest.raises(ScenarioError, match="is taken: objects.box stands there"):
        check_scenario(parse_scenario(with_box(0.04)))  # its side 2 cm from the spot: a 5 cm cube needs 3.5


def test_reach_is_checked_inside_a_region_not_only_at_its_corners(monkeypatch: pytest.MonkeyPatch) -> None:
    """A region near the base whose four corners the arm reaches from above, while points inside it
    it does not (by the same IK the skill uses), is refused."""
    data = tomllib.loads((SCENARIOS / "pick_cube.toml").read_text())
    data["objects"][0]["position_range"] = [[0.2, 0.3], [-0.2, 0.2]]
    with pytest.raises(ScenarioError, match=r"objects.cube at \(0.2\d, -?0.\d\d\): out of the arm's reach"):
        check_scenario(parse_scenario(data))
    monkeypatch.setattr(checks, "REACH_GRID", 2)  # its corners alone: it passed so
    check_scenario(parse_scenario(data))


def test_an_object_beside_another_touches_it_on_the_sides_drawn() -> None:
    """``beside``: flush against the other object's face (their footprints touch), turned as it is,
    on each of its four sides over the seeds; clear of the place."""
    sc = load_scenario("pick_beside_carton")
    sides = set()
    for seed in range(12):
        cube, carton = sample_layout(sc, np.random.default_rng(seed))
        yaw = float(cube.pose.rpy[2])
        assert float(carton.pose.rpy[2]) == pytest.approx(yaw)
        c, s = np.cos(yaw), np.sin(yaw)
        local = np.array([[c, s], [-s, c]]) @ (carton.pose.position[:2] - cube.pose.position[:2])
        k = int(np.argmax(np.abs(local)))
        touching = cube.size[k] / 2 + (carton.size[k] / 2)
        assert abs(local[k]) == pytest.approx(touching, abs=1e-9) and abs(local[1 - k]) < 1e-9
        sides.add((k, bool(local[k] > 0)))
    assert len(sides) == 4


def test_a_cylinder_may_lie_on_its_side_and_a_box_may_not_tilt(tmp_path: Path) -> None:
    """A cylinder on its side rests stably (accepted, told to the robot by its rough size); a box
    tilted, or a cylinder half lying, would fall over (refused)."""
    f = tmp_path / "lying.toml"
    cyl = GOOD.replace('shape = "box"', 'shape = "cylinder"').replace("size = [0.05, 0.05, 0.05]", "size = [0.05, 0.1]")
    assert cyl != GOOD
    f.write_text(cyl.replace("target = true", "target = true\nroll_deg = 90.0"))
    assert load_scenario(f).target.lying
    for bad in (cyl.replace("target = true", "target = true\nroll_deg = 45.0"),
                GOOD.replace("target = true", "target = true\nroll_deg = 90.0")):  # fmt: skip
        f.write_text(bad)
        with pytest.raises(ScenarioError, match="may lie on its side"):
            load_scenario(f)


def test_a_target_told_only_its_rough_size_is_refused_beside_an_object_as_large(tmp_path: Path) -> None:
    """The mug (a mesh: the robot is told only its rough size) beside a can as tall: refused, naming
    the can; a can 20 mm taller (the shipped scene) is told apart by its height."""
    from pickdemo.scenario.load import builtin_scenario_dirs

    assert load_scenario("pick_mug_among_lookalikes")
    text = next(d / "pick_mug_among_lookalikes.toml" for d in builtin_scenario_dirs()).read_text()
    f = tmp_path / "mug.toml"
    f.write_text(text.replace("size = [0.066, 0.1]", "size = [0.066, 0.085]"))
    with pytest.raises(ScenarioError, match="objects.can: about as large as the target objects.mug"):
        load_scenario(f)
