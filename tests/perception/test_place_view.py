"""What stands at the place, through a camera told its pose only to 10 mm and 2 deg: the table itself
must not (the plane fitted to it is the table as far as that calibration explains), and a box standing
there must."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.skills.pick.params import MachineParams
from pickdemo.worldmodel import WorldModel, split_view

pytestmark = pytest.mark.sim

PLACE = (0.5, -0.3)


def _view(with_box: bool, seed: int) -> float:
    """The surface (m^2) the world model sees standing within 10 cm of the place."""
    from pickdemo.core.camera import calibration_error
    from pickdemo.scenario.layout import sample_layout
    from pickdemo.scenario.load import parse_scenario
    from pickdemo.sim.render import Camera
    from pickdemo.sim.scene import Scene

    objects = [{"name": "cube", "shape": "box", "size": [0.04, 0.04, 0.04], "color": [0.8, 0.1, 0.1],
                "position": [0.55, 0.1], "target": True}]  # fmt: skip
    if with_box:
        objects.append({"name": "carton", "shape": "box", "size": [0.06, 0.08, 0.05], "color": [0.25, 0.35, 0.8],
                        "position": list(PLACE)})  # fmt: skip
    scenario = parse_scenario({
        "name": "place_seen", "objects": objects, "place": {"position": list(PLACE)},
        "camera": {"position": [1.2, 0.4, 0.8], "look_at": [0.5, 0.0, 0.0], "extrinsic_error": [10.0, 2.0]},
    })  # fmt: skip
    scene = Scene(scenario, sample_layout(scenario, np.random.default_rng(0)))
    try:
        error = calibration_error(10.0, 2.0, np.random.default_rng(seed))
        camera = Camera(scenario.camera, np.random.default_rng(seed), calibration_error=error)
        world = WorldModel()
        world.update(split_view(camera.capture(scene)))
        return float(world.standing_near(PLACE, 0.1)[1].sum())
    finally:
        scene.close()


def test_a_free_place_is_free_under_a_bad_calibration() -> None:
    # (16 draws of the error's direction; 3 cm alone saw one of them, seed 10, as 4,894 points standing)
    areas = [_view(False, seed) for seed in range(16)]
    assert max(areas) < MachineParams().place_taken_area_m2, areas


@pytest.mark.parametrize("seed", [0, 10])
def test_a_taken_place_is_taken_under_a_bad_calibration(seed: int) -> None:
    assert _view(True, seed) > 20 * MachineParams().place_taken_area_m2
