"""A robot file's ``[speeds]`` set the pick's speeds for that robot; a robot without them keeps the
skill's (the parallel-jaw robots unchanged), and a scenario's ``[motion]`` scales slow either."""

from __future__ import annotations

import dataclasses

import pytest

from pickdemo.robot import robot_named
from pickdemo.runtime.tasks import robot_speeds
from pickdemo.skills.pick.params import MachineParams


def test_the_suction_robot_sets_its_own_speeds() -> None:
    speeds = dict(robot_named("ur5_suction").speeds)
    p = robot_speeds(MachineParams(), speeds)
    skill = MachineParams()
    assert p.near.velocity == pytest.approx(speeds["near_m_s"])
    f = speeds["near_m_s"] / skill.near.velocity
    assert p.near.acceleration == pytest.approx(skill.near.acceleration * f)
    assert p.near.jerk == pytest.approx(skill.near.jerk * f)
    assert p.side_line_scale == pytest.approx(min(1.0, skill.side_line_scale * f))
    # the lines near the object are checked at the speed they run at; the slowest taken is the same in m/s
    assert p.goals.line_speed_m_s == pytest.approx(speeds["near_m_s"])
    slowest = p.goals.line_speed_m_s * p.goals.min_line_speed_scale
    assert slowest == pytest.approx(skill.goals.line_speed_m_s * skill.goals.min_line_speed_scale)
    assert p.free.velocity == pytest.approx(speeds["free_m_s"])
    assert (p.transfer_scale, p.carry_scale) == (speeds["transfer_scale"], speeds["carry_scale"])


@pytest.mark.parametrize("name", ["panda", "so101", "ur5_franka_hand"])
def test_a_robot_without_speeds_keeps_the_skills(name: str) -> None:
    assert robot_named(name).speeds == ()
    assert robot_speeds(MachineParams(), {}) == MachineParams()


def test_a_side_lines_share_stops_at_the_joints_limits() -> None:
    slow = dataclasses.replace(MachineParams(), side_line_scale=0.5)
    assert robot_speeds(slow, {"near_m_s": 1.0}).side_line_scale == 1.0
