"""Perception to control, end to end in the simulator: real outcomes, reproducibility, typed failures."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo import Stage, run_episode
from pickdemo.scenario import Scenario

pytestmark = pytest.mark.sim


def _strip_wall(d: dict) -> dict:
    d = dict(d)
    d.pop("wall_time_s")
    d.pop("stage_wall_times_s")
    return d


@pytest.mark.parametrize("seed", [11, 22, 33, 44])
def test_cube_is_picked_and_placed(cube_scenario: Scenario, seed: int) -> None:
    r = run_episode(cube_scenario, seed)
    assert r.success, r.failure
    assert r.perception is not None and r.perception.position_error_mm < 2.0 and r.perception.yaw_error_deg < 1.0
    assert r.lift_height_mm >= cube_scenario.success.lift_height * 1e3
    assert r.place_error_mm <= cube_scenario.success.place_tolerance * 1e3
    assert [p["phase"] for p in r.phases] == ["perceive", "plan", "approach", "grasp", "lift", "place", "verify"]


@pytest.mark.parametrize("seed", [5, 6])
def test_cylinder_is_picked_and_placed(cylinder_scenario: Scenario, seed: int) -> None:
    r = run_episode(cylinder_scenario, seed)
    assert r.success, r.failure
    assert r.perception.yaw_error_deg is None  # a cylinder has no yaw
    assert r.perception.position_error_mm < 2.0


def test_same_seed_same_result(cube_scenario: Scenario) -> None:
    a = run_episode(cube_scenario, 7).to_dict()
    b = run_episode(cube_scenario, 7).to_dict()
    assert _strip_wall(a) == _strip_wall(b)
    c = run_episode(cube_scenario, 8).to_dict()
    assert c["perception"]["true_pose"] != a["perception"]["true_pose"]


def test_no_target_in_view_fails_in_perception(cube_scenario: Scenario) -> None:
    # The camera looks away from the table: the target is never seen; the episode names the stage.
    cam = cube_scenario.camera.model_copy(update={"look_at": (3.0, 0.0, 0.75)})
    sc = cube_scenario.model_copy(update={"camera": cam})
    r = run_episode(sc, 0)
    assert not r.success and r.failure.stage is Stage.PERCEPTION
    assert "colour" in r.failure.reason


def test_too_wide_object_fails_in_grasp_planning(cube_scenario: Scenario) -> None:
    obj = cube_scenario.objects[0].model_copy(update={"size": (0.09, 0.09, 0.05)})
    sc = cube_scenario.model_copy(update={"objects": (obj,)})
    r = run_episode(sc, 0)
    assert not r.success and r.failure.stage is Stage.GRASP_PLANNING


def test_simulated_time_budget_is_a_timeout(cube_scenario: Scenario) -> None:
    sc = cube_scenario.model_copy(update={"sim": cube_scenario.sim.model_copy(update={"max_sim_time_s": 2.0})})
    r = run_episode(sc, 0)
    assert not r.success and r.failure.stage is Stage.TIMEOUT
    assert r.sim_time_s == pytest.approx(2.0, abs=0.01)
    assert np.isfinite(r.perception.position_error_mm)
