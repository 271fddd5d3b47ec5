"""The world the robot moves through: a neighbour flush against the target, a far sensor's speckle,
a target no view shows. Episodes over several seeds; properties of them all, never one seed's fate."""

from __future__ import annotations

import pytest

from tests.episodes import at_least, describe, episodes, no_bugs


@pytest.mark.slow
def test_a_cube_flush_against_a_taller_box_is_picked_with_the_palm_over_the_box() -> None:
    """``world_flush_taller_box``: no seed refused (a grasp exists: along the box's face, raised
    until the palm passes over it), and the world model knows both objects and no phantom."""
    results = no_bugs(episodes("world_flush_taller_box", (0, 1, 2, 3)))
    at_least(results, 3, what="are picked")
    for r in results:
        assert r.failure is None or r.failure.stage.value != "grasp_planning", describe(r)
        assert r.world is not None and r.world["phantoms"] == 0, describe(r)
        assert r.world["found"] == r.world["in_view"], describe(r)


@pytest.mark.slow
def test_a_target_no_view_shows_is_looked_for_with_the_hand_camera() -> None:
    """``world_hidden_wrist``: the fixed camera never sees the cube behind the tall box; the hand's
    camera, moved over the table no view has seen, finds it."""
    results = no_bugs(episodes("world_hidden_wrist", (0, 1, 2)))
    at_least(results, 2, what="are picked")
    for r in results:
        said = " ".join(p.message or "" for p in r.phases)
        assert "looking with the hand's camera from above" in said, describe(r)
