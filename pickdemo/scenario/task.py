"""The task as the robot is told it: what the target looks like (a pick order or a CAD model).

Shared by an episode and ``perceive``: the robot knows a box's or a cylinder's shape, size and
colour, never where it is; of a mesh, only its rough size (an object nobody described: found by its
geometry).
"""

from __future__ import annotations

from pickdemo.core.shapes import Mesh, Unknown
from pickdemo.perception import TargetModel
from pickdemo.scenario.layout import Placement
from pickdemo.scenario.schema import Scenario


def target_model(scenario: Scenario, placement: Placement) -> TargetModel:
    """What the task tells the robot about an object: a box's or a cylinder's shape (at the size
    placed) and colour; of a mesh, or a cylinder lying on its side, only its rough size as it lies (a
    cue to tell it from other objects): it is found and grasped by its geometry."""
    spec = next(o for o in scenario.objects if o.name == placement.name)
    # its rough size as a cue among other objects, no more (the shapes' models stand upright)
    if isinstance(placement.geometry, Mesh) or spec.lying:
        return TargetModel(geometry=Unknown(size_cue_m=spec.rough_size(placement.geometry)), color=None)
    assert spec.color is not None  # the schema requires it of a box or cylinder
    return TargetModel(geometry=placement.geometry, color=tuple(spec.color))
