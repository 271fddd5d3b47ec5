"""What counts as a collision on the scoring side (``result.json``'s ``collisions``): the rules written
once in :mod:`pickdemo.runtime.collisions`, and the simulator's contacts read into them in an episode."""

from __future__ import annotations

import pytest
from episodes import describe, episodes

from pickdemo.runtime.collisions import PLACE_RADIUS_M, CollisionTally
from pickdemo.sim.contacts import Contact, ContactLog


def _c(who: str, other: str, at: tuple[float, float, float] = (0.5, 0.0, 0.0), *, base: bool = False) -> Contact:
    return Contact(who, "panda_hand" if who == "robot" else "", other, at, 1.0, base=base)


def test_the_target_the_tray_the_base_and_the_table_at_the_place_are_allowed_and_nothing_else() -> None:
    tally = CollisionTally("cube", (0.45, 0.3))
    allowed = [
        _c("robot", "cube"),
        _c("robot", "tray"),
        _c("robot", "table", base=True),
        _c("robot", "table", (0.45 + 0.5 * PLACE_RADIUS_M, 0.3, 0.0)),
        _c("cube", "table", (0.45, 0.3 - 0.5 * PLACE_RADIUS_M, 0.0)),
    ]
    tally.judge(allowed, held=True)
    assert tally.count == 0
    hits = [_c("robot", "table", (0.45, 0.3 - 2.0 * PLACE_RADIUS_M, 0.0)), _c("robot", "wall"), _c("cube", "tin")]
    tally.judge(hits, held=True)
    assert tally.count == 3
    assert [f["who"] for f in tally.first] == ["robot.panda_hand", "robot.panda_hand", "objects.cube (held)"]
    assert [f["with"] for f in tally.first] == ["table", "wall", "tin"]


def test_the_targets_own_contacts_count_only_while_the_hand_holds_it_off_the_table() -> None:
    tally = CollisionTally("cube", (0.45, 0.3))
    tally.judge([_c("cube", "tin")], held=False)  # (standing against its neighbour: not the robot's doing)
    assert tally.count == 0
    tally.judge([_c("cube", "tin")], held=True)
    assert tally.count == 1


def test_a_clear_rounds_objects_are_each_some_picks_target() -> None:
    tally = CollisionTally(None, None, frozenset({"drawn_0", "drawn_1"}))
    tally.judge([_c("robot", "drawn_1"), _c("robot", "tray")], held=False)
    assert tally.count == 0
    tally.judge([_c("robot", "bin"), _c("robot", "table")], held=False)
    assert tally.count == 2


@pytest.mark.slow
def test_a_held_mug_carried_past_a_tall_box_touches_nothing_and_every_episode_says_so() -> None:
    results = episodes("pick_mug_carried_past_a_tall_box", (0, 1, 2, 3, 4, 5, 6, 7))
    assert all(r.collisions is not None for r in results)
    hit = [r for r in results if r.success and r.collisions["count"] > 0]  # type: ignore[index]
    assert not hit, "; ".join(f"{describe(r)}: {r.collisions}" for r in hit)
    assert sum(r.success for r in results) >= 7, "; ".join(describe(r) for r in results)


class _Client:
    """A stand-in for a BulletClient: the contact points of one step (pybullet's tuple layout)."""

    def __init__(self) -> None:
        self.points: list[tuple] = []

    def getContactPoints(self, bodyA: int) -> list[tuple]:  # noqa: N802, N803 - pybullet's names
        return [pt for pt in self.points if pt[1] == bodyA]


def _point(distance_m: float, force_n: float) -> tuple:
    # (flag, bodyA, bodyB, linkA, linkB, onA, onB, normal, distance, normal force, ...)
    return (0, 1, 2, 8, -1, (0.4, 0.0, 0.2), (0.4, 0.0, 0.2), (0.0, 0.0, 1.0), distance_m, force_n)


def test_a_point_bullet_keeps_a_few_millimetres_apart_is_no_contact_and_a_touch_is_one() -> None:
    client = _Client()
    log = ContactLog(client, {"robot": 1, "wall": 2}, {}, {8: "panda_hand"}, set())
    client.points = [_point(0.0025, 0.0)]  # (as seen: a hand 2.5 mm above a wall's top, no force)
    log.read(1.0)
    assert log.take() == []
    client.points = [_point(-0.0002, 3.0)]
    log.read(1.1)
    began = log.take()
    assert [(c.who, c.link, c.other) for c in began] == [("robot", "panda_hand", "wall")]
