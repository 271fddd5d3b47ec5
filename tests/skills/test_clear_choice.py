"""Which object a clear round picks next, where the survey's sparse points show no grasp on any: a
suction cup's round looks closer at the largest object not tried since the last place, rather than end."""

from __future__ import annotations

import numpy as np

from pickdemo.grasping.top_down import GraspParams
from pickdemo.perception.model import ObjectCloud
from pickdemo.perception.unknown import SeenObject, Survey
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import IKParams, kinematics_of
from pickdemo.skills.clear_choice import UNSEEN_SEAL_COST, ObjectChooser


def _seen(x: float, y: float, n: int) -> SeenObject:
    """An object seen as a few points (fewer than any seal is judged on)."""
    rng = np.random.default_rng(n)
    pts = np.column_stack([x + rng.uniform(-0.01, 0.01, n), y + rng.uniform(-0.01, 0.01, n), np.full(n, 0.03)])
    cloud = ObjectCloud(points=pts, obstacles=np.zeros((0, 3)), time_s=0.0)
    return SeenObject(np.array([x, y, 0.015]), (0.03, 0.02, 0.02), n, cloud)


def _chooser(robot: str) -> ObjectChooser:
    return ObjectChooser(kinematics_of(robot_named(robot)), np.random.default_rng(0), GraspParams(), IKParams())


def test_with_no_seal_seen_on_any_a_suction_round_looks_closer_at_the_largest_untried() -> None:
    small, large = _seen(0.45, -0.05, 6), _seen(0.55, 0.05, 9)
    survey = Survey((small, large), 0.0)
    cup = _chooser("ur5_suction")
    first = cup.choose(survey, [])
    assert first is not None and first.seen is large and first.cost == UNSEEN_SEAL_COST
    second = cup.choose(survey, [large.centre[:2]])  # (a pick failed there since the last place)
    assert second is not None and second.seen is small
    assert cup.choose(survey, [large.centre[:2], small.centre[:2]]) is None  # each tried: the round ends
    assert _chooser("panda").choose(survey, []) is None  # (fingers: no grasp from above, none looked at)
