"""Grasps from any side in the loop: an object resting on an edge, which a top-down grasp misses, is
picked from the side on the next attempt (the hand tilted, in and out along its approach, within the
arm's limits); over several seeds, as every outcome test is."""

from __future__ import annotations

import pytest
from episodes import at_least, episodes, none_fails_in


@pytest.mark.slow
def test_an_object_on_its_edge_is_picked_from_the_side_after_a_top_down_miss() -> None:
    results = episodes("pick_tilted", (0, 1, 2, 3))
    at_least(results, 3)
    none_fails_in(results, "ik", "trajectory", "reflex", "error")
    tilted = [p.message for r in results for p in r.phases if "from the side: tilted" in p.message]
    assert tilted, "no grasp from the side"
    assert all(max((r.peak_joint_limit_ratio or {"": 0.0}).values()) <= 1.0 for r in results)


@pytest.mark.slow
def test_a_round_in_a_walled_bin_puts_objects_into_the_tray() -> None:
    """The bin's walls stay: its floor is what the objects rest on, perception leaves it out, the grasps
    keep out of its walls; over two rounds, objects go into the tray and no motion fails."""
    results = episodes("clear_bin", (0, 1))
    none_fails_in(results, "trajectory", "reflex", "error")
    cleared = [r.clear["cleared"] for r in results if r.clear is not None]
    assert len(cleared) == 2 and all(c >= 2 for c in cleared), cleared
