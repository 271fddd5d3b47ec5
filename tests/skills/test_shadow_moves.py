"""A move seen only while the hand is over the target, gone again once the hand is away, is the hand's
shadow on the view (the cup's tube hides part of a small part and its seal point shifts 8-11 mm), not a
move: after ``shadow_back_offs`` such back-offs the descent goes on to the plan it set out with. Before,
a pick in ``suction_clear_bin`` backed off 15 times in a row for it, 25 s of a round (measured)."""

from __future__ import annotations

import pytest

from pickdemo.runtime.episode import run_episode
from pickdemo.scenario.load import load_scenario
from pickdemo.skills.pick.params import MachineParams

pytestmark = [pytest.mark.sim, pytest.mark.slow]

MOVED = "during the descent: backing off to approach again"


@pytest.mark.parametrize("seed", [15, 16, 18])
def test_a_pick_backs_off_for_its_hands_shadow_only_so_often(seed: int) -> None:
    result = run_episode(load_scenario("suction_clear_bin"), seed)
    in_a_row = worst = 0
    for phase in result.phases:
        if "looking for the target" in phase.message:  # (a pick, or an attempt, begins)
            in_a_row = 0
        if phase.phase == "back_off" and MOVED in phase.message:
            in_a_row += 1
            worst = max(worst, in_a_row)
    # the back-offs counted, plus one: the last, for a move the approach did not find the target back from
    assert worst <= MachineParams().shadow_back_offs + 1, worst
