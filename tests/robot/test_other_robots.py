"""Other robots from their files: the UR5 with a Franka Hand and the SO-101 pick, place and clear
what they see, within their own joint limits, from a scenario that names them (properties over
several seeds)."""

from __future__ import annotations

import pytest
from episodes import at_least, describe, episodes, none_fails_in

from pickdemo import load_scenario
from pickdemo.robot import robot_named


def test_a_scenario_names_its_robot_and_the_checks_use_it() -> None:
    sc = load_scenario("ur5_pick_anywhere")
    assert sc.robot == "ur5_franka_hand" and sc.robot_description is robot_named("ur5_franka_hand")
    assert load_scenario("pick_cube").robot_description is robot_named("panda")


@pytest.mark.slow
def test_the_ur5_picks_anywhere_within_its_own_limits() -> None:
    results = episodes("ur5_pick_anywhere", (0, 1, 2, 3, 4))
    at_least(results, 4)
    none_fails_in(results, "ik", "trajectory", "reflex", "error")
    for r in results:
        assert r.robot == "ur5_franka_hand", describe(r)
        if r.peak_joint_limit_ratio is not None:
            assert max(r.peak_joint_limit_ratio.values()) <= 1.0, describe(r)


@pytest.mark.slow
def test_the_ur5_clears_a_pile() -> None:
    # (four rounds, at least 15 of their 20 parts: a round that ends early, two failed lifts in a row,
    # is one seed's fate: on this machine seed 1 ends after 2 parts, as at a7cdcae, where CI passed it)
    results = episodes("ur5_clear_pile", (0, 1, 2, 3))
    none_fails_in(results, "ik", "trajectory", "reflex", "error")
    cleared = sum(r.clear["cleared"] for r in results if r.clear)  # type: ignore[index]
    assert cleared >= 15, "; ".join(describe(r) for r in results)


@pytest.mark.slow
def test_the_so101_picks_a_small_cube_by_friction_within_its_own_limits() -> None:
    """One jaw against a fixed one, no weld: it holds what it lifts by friction alone."""
    results = episodes("so101_pick_cube", (0, 1, 2))
    at_least(results, 2)
    none_fails_in(results, "ik", "trajectory", "reflex", "error")
    for r in results:
        assert r.robot == "so101", describe(r)
        if r.peak_joint_limit_ratio is not None:
            assert max(r.peak_joint_limit_ratio.values()) <= 1.0, describe(r)


@pytest.mark.slow
def test_the_so101_waits_for_a_target_that_slides_out_of_its_reach_and_stops() -> None:
    """The cube slides toward the base as the arm sets off: where the arm would meet it is out of reach
    while it slides; it stood still when the pick was planned, so the arm looks again once it stops
    (it failed in ``ik`` at once before)."""
    results = episodes("so101_pick_cube_slid_off", (0, 1, 2))
    at_least(results, 2)
    none_fails_in(results, "ik", "trajectory", "reflex", "error")


@pytest.mark.slow
def test_the_so101_picks_near_its_base() -> None:
    """12-13.5 cm from the base the SO-101's hand points down only low: a re-plan that turned the hand
    to an angle whose descent it cannot follow failed in ``ik`` (seeds 8 and 9 of these before); it
    keeps the angle the pick was planned with."""
    results = episodes("so101_pick_cube_near_base", (6, 7, 8, 9))
    at_least(results, 3)
    none_fails_in(results, "ik", "trajectory", "reflex", "error")


@pytest.mark.slow
def test_the_so101_pushes_a_heavier_cube_to_its_fixed_jaw() -> None:
    """A 60 g cube: the moving jaw's arc presses it into the table as it pushes it, and the jaw stalled
    short of the fixed one at 5 N (0 of 5 before); stalled on the cube alone, it closes harder."""
    results = episodes("so101_pick_heavier_cube", (0, 1, 2))
    at_least(results, 2)
    none_fails_in(results, "ik", "trajectory", "reflex", "error")
    # its wrist weighs what it holds (its sensor reads in the roll joint's frame, upside down from the TCP's)
    weighed = [a.payload_kg for r in results for a in r.attempts if a.payload_kg is not None]
    assert weighed and all(abs(w - 0.06) < 0.02 for w in weighed), weighed
