"""``pickdemo profile``: the stages account for the loop, the reference is measured, the wrappers go."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from pickdemo.apps.profile import STAGES, Profiler, profile
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.scenario.load import load_scenario

ROBOT = robot_named()


def test_a_stage_counts_its_calls_without_the_wrapped_calls_they_make() -> None:
    class Part:
        def outer(self, inner) -> int:
            return inner() + 1

        def inner(self) -> int:
            return 1

    part = Part()
    prof = Profiler()
    with prof.wrapped():
        prof.wrap(part, "outer", "a")
        prof.wrap(part, "inner", "b")
        assert part.outer(part.inner) == 2 and part.inner() == 1
        assert "outer" in part.__dict__
    assert prof.stages["a"].calls == 1 and prof.stages["b"].calls == 2
    assert 0.0 <= prof.stages["a"].seconds and 0.0 <= prof.stages["b"].seconds
    assert "outer" not in part.__dict__ and "inner" not in part.__dict__  # restored: the class's methods again


@pytest.mark.sim
def test_profile_of_an_episode_accounts_for_its_loop_and_leaves_nothing_wrapped() -> None:
    kin = kinematics_of(ROBOT)  # shared by every episode in a process: wrapped for one, then restored
    report = profile(load_scenario("pick_cube"), [0])
    (e,) = report.episodes
    assert e.success and e.sim_time_s > 5.0
    assert set(e.stages) == set(STAGES)
    total = sum(s.seconds for s in e.stages.values())
    assert total == pytest.approx(e.loop_s, rel=0.02)  # every second of the loop under one stage
    dt = load_scenario("pick_cube").sim.time_step_s
    steps = round(e.sim_time_s / dt)  # (the objects' settling before the first tick included)
    assert steps - round(1.0 / dt) < e.stages["physics"].calls < steps  # one call a physics step of the loop
    for stage in ("physics", "robot I/O", "render", "perception", "tracker", "skill", "motion", "kinematics"):
        assert e.stages[stage].calls > 0 and e.stages[stage].seconds > 0.0, stage
    assert report.reference.steps > 0 and report.reference.real_time_factor > 0.0
    assert 0.0 < report.ratio < 1.0  # the loop costs more than the bare physics
    # its own physics, replayed: the loop's span step for step, ending where the episode did, bit for bit
    assert e.replay is not None and e.replay.same_state is True
    assert e.replay.steps * dt == pytest.approx(e.loop_sim_s) and e.loop_sim_s < e.sim_time_s
    assert 0.0 < e.share_of_replay < 1.0 and report.share_of_replay == pytest.approx(e.share_of_replay)
    assert not any(name in kin.__dict__ for name in ("track", "solve", "forward"))
    assert np.allclose(kin.forward(np.zeros(7)).position, kinematics_of(ROBOT).forward(np.zeros(7)).position)


@pytest.mark.sim
def test_profile_json() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "pickdemo", "profile", "pick_cube", "--seeds", "1", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["scenario"] == "pick_cube" and len(out["episodes"]) == 1
    assert out["ratio_to_reference"] == pytest.approx(out["real_time_factor"] / out["reference"]["real_time_factor"])
    assert out["share_of_replay"] == pytest.approx(out["real_time_factor"] / out["replay_real_time_factor"])
    assert out["episodes"][0]["replay"]["same_state"] is True
    assert set(out["stages"]) == set(STAGES)


@pytest.mark.sim
def test_profile_open_loop_has_fewer_frames_and_its_own_replay() -> None:
    closed, opened = (profile(load_scenario("pick_cube"), [2], open_loop=o).episodes[0] for o in (False, True))
    assert opened.stages["render"].calls < closed.stages["render"].calls  # (whatever the seed's outcome)
    assert opened.replay is not None and opened.replay.same_state is True
