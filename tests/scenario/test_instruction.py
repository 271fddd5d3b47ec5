"""A scenario's task as an instruction (a dataset's task string): made from its target and its place, or
the scenario's own ``instruction``."""

from __future__ import annotations

from pickdemo.scenario.instruction import colour_name, instruction
from pickdemo.scenario.load import load_scenario


def test_an_instruction_is_made_from_the_target_and_the_place() -> None:
    assert instruction(load_scenario("pick_cube")) == "pick up the red 5 cm cube and put it at x 0.45 m, y 0.30 m"
    assert instruction(load_scenario("clear_pile")) == "pick up every object on the table and put it in the tray"
    assert colour_name((0.1, 0.25, 0.8)) == "blue" and colour_name((0.92, 0.9, 0.93)) == "white"


def test_a_scenarios_own_instruction_is_kept() -> None:
    sc = load_scenario("pick_cube").model_copy(update={"instruction": "put the red block on the pad"})
    assert instruction(sc) == "put the red block on the pad"
