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
