"""The skill's grip of a suction cup (no simulator): closing opens the valve, what it holds is what the
vacuum sensor says, a cup that has not sealed soon has stopped on nothing, and it has let go once the
vacuum falls; the command carries the valve."""

from __future__ import annotations

import numpy as np

from pickdemo.core.interfaces import Observation
from pickdemo.robot import robot_named
from pickdemo.skills.actions import Grip, GripParams, Suck, grip_for

DT = 1.0 / 120.0


def _obs(kpa: float, t: float = 0.0) -> Observation:
    return Observation(t, np.zeros(6), np.zeros(6), np.zeros(2), (0, 0), vacuum_kpa=kpa)


def test_a_suction_robot_gets_a_cup_and_a_finger_robot_fingers() -> None:
    assert isinstance(grip_for(GripParams(), DT, robot_named("ur5_suction").gripper), Suck)
    panda = grip_for(GripParams(), DT, robot_named("panda").gripper)
    assert type(panda) is Grip and panda.vacuum is False


def test_the_cup_holds_what_its_vacuum_says() -> None:
    cup = robot_named("ur5_suction").gripper.cup
    g = grip_for(GripParams(), DT, robot_named("ur5_suction").gripper)
    g.close(20.0)
    g.watch()
    assert g.vacuum
    assert g.holding(_obs(cup.vacuum_kpa), 0.0) and g.stopped(_obs(cup.vacuum_kpa))
    leak = cup.leak_share * cup.vacuum_kpa
    assert not g.holding(_obs(leak), 0.0) and not g.too_wide(_obs(cup.vacuum_kpa), 0.05)
    waits = [g.stopped(_obs(leak)) for _ in range(int(Suck.SEAL_WAIT_S / DT) + 1)]
    assert not waits[0] and waits[-1]  # a leak: the close ends on nothing after the wait
    g.open()
    assert not g.vacuum and not g.opened(_obs(cup.vacuum_kpa))  # (the sensor still reads the seal)
    assert g.opened(_obs(0.0)) and not g.stopped(_obs(cup.vacuum_kpa))
