"""A grasp from the side re-drawn on the way in (:func:`pickdemo.skills.pick.take._same_side`): no
simulator, the plans as the selector makes them."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from pickdemo.grasping.antipodal import AntipodalGrasp
from pickdemo.grasping.side_plans import tilted_pick
from pickdemo.grasping.top_down import GraspParams
from pickdemo.skills.pick.plans import turned_plan
from pickdemo.skills.pick.take import _same_side


def _side_plan(approach_deg: float = 90.0):  # noqa: ANN202
    a = np.radians(approach_deg)
    z = np.array([np.cos(a), np.sin(a), 0.0])  # level, into a shelf
    y = np.array([0.0, 0.0, 1.0])  # the fingers close up and down
    R = np.column_stack([np.cross(y, z), y, z])
    g = AntipodalGrasp(np.array([0.0, 0.55, 0.1]), R, 0.05, 0.0)
    return tilted_pick(g, np.array([0.0, 0.57, 0.1]), 0.0, (0.45, -0.25), GraspParams())


def test_a_redrawn_side_grasp_comes_as_the_equivalent_nearest_the_hand_and_a_turned_approach_is_refused() -> None:
    plan = _side_plan()
    m = SimpleNamespace(plan=plan)
    redrawn = turned_plan(plan, pick=True, place=True)  # the same grasp, turned half a turn about its approach
    assert np.dot(redrawn.grasp.rotation[:, 1], plan.grasp.rotation[:, 1]) < 0.0
    kept = _same_side(m, redrawn)
    assert kept is not None
    np.testing.assert_allclose(kept.grasp.rotation, plan.grasp.rotation, atol=1e-12)
    np.testing.assert_allclose(kept.grasp.position, plan.grasp.position, atol=1e-12)
    assert _same_side(m, plan) is plan
    assert _same_side(m, _side_plan(110.0)) is None  # its approach turned 20 deg: another grasp
