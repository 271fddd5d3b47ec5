"""The task as the robot is told it: what the target looks like (a pick order or a CAD model).

Shared by an episode and ``perceive``: the robot knows the target's shape, size and colour, never
where it is.
"""

from __future__ import annotations

from pickdemo.layout import Placement
from pickdemo.perception import TargetModel
from pickdemo.schema import Scenario


def target_model(scenario: Scenario, placement: Placement) -> TargetModel:
    """What the task tells the robot about an object: its shape (at the size placed) and colour."""
    spec = next(o for o in scenario.objects if o.name == placement.name)
    return TargetModel(geometry=placement.geometry, color=tuple(spec.color))
