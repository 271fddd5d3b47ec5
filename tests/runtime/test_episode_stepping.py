"""An episode stepped from outside, one control tick at a time, is the episode ``run_episode`` runs;
observers watch the loop through one interface and change nothing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from pickdemo import Episode, EpisodeOptions, Stage, load_scenario, run_episode
from pickdemo.core.interfaces import Observation
from pickdemo.core.result import WALL_CLOCK_KEYS
from pickdemo.runtime.observers import Observer

pytestmark = pytest.mark.sim


def _strip_wall(d: dict) -> dict:
    return {k: v for k, v in d.items() if k not in WALL_CLOCK_KEYS}


class Log(Observer):
    """Counts what it is told, in order."""

    def __init__(self) -> None:
        self.calls: list[str] = []
        self.ticks: list[float] = []
        self.frames = 0
        self.estimates: list[str] = []
        self.phases: list[str] = []
        self.closed = 0

    def tick(self, ep, now):
        self.calls.append("tick")
        self.ticks.append(now)

    def frame(self, ep, now, frame, result):
        self.calls.append("frame")
        self.frames += 1
        assert frame.time_s == pytest.approx(now)

    def estimate(self, ep, now, taken_s, result, status):
        self.calls.append("estimate")
        assert taken_s < now
        self.estimates.append(status)

    def phase(self, ep, record):
        self.calls.append("phase")
        self.phases.append(record.phase)

    def end(self, ep, now):
        self.calls.append("end")

    def close(self):
        self.closed += 1


def _trace_equal(a, b) -> None:
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            np.testing.assert_array_equal(x, y, err_msg=f.name)
        else:
            assert x == y, f.name


def test_a_stepped_episode_is_run_episodes() -> None:
    """pick_pushed seed 1 (pushed after its first look: re-targets on the way) stepped from a test,
    watched by an observer: the same result, key for key, and the same trace, as run_episode's."""
    scenario = load_scenario("pick_pushed")
    options = EpisodeOptions(record_trace=True)
    reference = run_episode(scenario, 1, options=options)

    log = Log()
    ep = Episode(scenario, 1, options, observers=(log,))
    with pytest.raises(RuntimeError):
        ep.step()  # reset first
    first = ep.reset()
    assert isinstance(first, Observation) and first.time_s == ep.time_s > 0.0  # the objects came to rest
    assert first.arm_q.shape == (7,)
    with pytest.raises(RuntimeError):
        ep.result()  # not over yet
    steps, times, states = 0, [], set()
    while not ep.step():
        steps += 1
        times.append(ep.time_s)
        states.add(ep.state.value)
        assert ep.observation is not None and ep.observation.time_s == pytest.approx(ep.time_s - ep.dt_ctl)
    assert ep.done and ep.step()  # over stays over
    result = ep.result()

    assert _strip_wall(result.to_dict()) == _strip_wall(reference.to_dict())
    _trace_equal(result.trace, reference.trace)
    assert np.allclose(np.diff(times), ep.dt_ctl)  # one control tick a step
    assert {"approach", "descend", "lift", "transport"} <= states
    # The observer saw every tick the trace holds, every frame, every phase, the end, once closed.
    assert steps == len(log.ticks) == len(result.trace.time_s)
    assert log.ticks == list(result.trace.time_s)
    assert log.frames == result.perception_frames
    assert log.phases == [p.phase for p in result.phases]
    assert log.calls.count("end") == 1 and log.calls[-1] in ("end", "phase") and log.closed == 1
    assert "accepted" in log.estimates  # what the controller made of each estimate handed to it


def test_stepping_can_be_reset_and_closed_early() -> None:
    """reset() again starts the same episode over; close() stops one before its end. Its world is
    the one perceive builds for the seed (one layout, one camera)."""
    from pickdemo.runtime.world import World

    scenario = load_scenario("pick_cube")
    with Episode(scenario, 3) as ep:
        a = ep.reset()
        for _ in range(50):
            assert not ep.step()
        b = ep.reset()  # from the seed again
        np.testing.assert_array_equal(a.arm_q, b.arm_q)
        assert a.time_s == b.time_s == ep.time_s
        with World.build(scenario, 3) as world:
            assert [p.name for p in world.layout] == [p.name for p in ep.world.layout]
            for p, q in zip(world.layout, ep.world.layout, strict=True):
                np.testing.assert_array_equal(p.pose.position, q.pose.position)
            np.testing.assert_array_equal(world.camera.T_world_cam.position, ep.world.camera.T_world_cam.position)
            np.testing.assert_array_equal(world.camera.T_world_cam.rotation, ep.world.camera.T_world_cam.rotation)
    assert ep.world.scene.client is None  # closed


def test_an_episode_that_cannot_start_is_over_at_reset() -> None:
    ep = Episode(load_scenario("pick_cube"), 0, EpisodeOptions(perception_method="nosuchmodule:nofunction"))
    assert ep.reset() is None
    assert ep.step()
    r = ep.result()
    assert not r.success and r.failure.stage is Stage.PERCEPTION
    assert r.phases[-1].phase == "failed"
    expected = run_episode(load_scenario("pick_cube"), 0, options=ep.options)
    assert _strip_wall(r.to_dict()) == _strip_wall(expected.to_dict())
