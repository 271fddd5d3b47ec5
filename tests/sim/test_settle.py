"""Settling the scene before the robot's first tick: it stops once the objects are at rest, and when
they are not within the steps allowed it says so, in the episode's result, instead of going on quietly."""

from __future__ import annotations

import pytest

from pickdemo.runtime.episode import run_episode
from pickdemo.runtime.tasks import PickTask
from pickdemo.runtime.world import World
from pickdemo.scenario.load import load_scenario
from pickdemo.sim.scene import REST_STEPS


def test_settle_stops_at_rest_and_says_when_the_objects_are_not() -> None:
    sc = load_scenario("pick_cube")
    with World.build(sc, 0) as world:
        settled = world.scene.settle(480)
        assert REST_STEPS <= settled.steps < 480 and settled.note is None
        assert world.scene.steps == settled.steps
    with World.build(sc, 0) as world:
        short = world.scene.settle(REST_STEPS - 1)  # too few steps to be at rest that many in a row
        assert short.steps == REST_STEPS - 1 and world.scene.steps == short.steps
        assert short.note is not None and "had not come to rest in 0.04 s of settling" in short.note
        assert ": cube at " in short.note  # the one object, named with its speed


def test_an_episode_whose_objects_never_came_to_rest_says_so_in_its_result(monkeypatch: pytest.MonkeyPatch) -> None:
    """The note is the result's first phase (``settle``), before the robot's first state; an episode
    settled in time has none."""
    sc = load_scenario("pick_cube")
    sc = sc.model_copy(update={"sim": sc.sim.model_copy(update={"max_sim_time_s": 0.2})})  # over soon after
    phases = run_episode(sc, 0).to_dict()["phases"]
    assert phases and all(p["phase"] != "settle" for p in phases)
    monkeypatch.setattr(PickTask, "settle_max_s", 5 * sc.sim.time_step_s)
    phases = run_episode(sc, 0).to_dict()["phases"]
    first = phases[0]
    assert first["phase"] == "settle" and first["sim_time_s"] == pytest.approx(5 * sc.sim.time_step_s, abs=1e-6)
    assert first["message"].startswith("the objects had not come to rest in 0.02 s of settling")
    assert [p["phase"] for p in phases[1:]].count("settle") == 0


def test_an_object_turning_in_place_is_not_at_rest() -> None:
    """At rest means its points move slower than REST_SPEED_M_S from its turning too: the 50 mm cube
    (43 mm bounding radius) turning at 0.1 rad/s (4.3 mm/s at its corners) is not; at 0.03 (1.3 mm/s) it is."""
    sc = load_scenario("pick_cube")
    with World.build(sc, 0) as world:
        scene = world.scene
        assert scene.settle(480).note is None and scene.objects_at_rest()
        assert scene.radius_m["cube"] == pytest.approx(0.05 * 3**0.5 / 2)
        cube = scene.bodies["cube"]
        for spin, at_rest in ((0.1, False), (0.03, True)):
            scene.client.resetBaseVelocity(cube, [0.0, 0.0, 0.0], [0.0, 0.0, spin])
            assert scene.objects_at_rest() is at_rest, spin
        scene.client.resetBaseVelocity(cube, [0.0, 0.0, 0.0], [0.0, 0.0, 0.1])
        assert scene._fastest_object() == ("cube", pytest.approx(0.1 * scene.radius_m["cube"]))  # what a note says
