"""The task as the robot is told it: what the target looks like (a pick order or a CAD model).

Shared by an episode and ``perceive``: the robot knows a box's or a cylinder's shape, size and
colour, never where it is; of a mesh or a cylinder lying (an object nobody described: found by its
geometry), nothing but the rough size the scenario file states (``rough_size_m``), if it states one.
Never anything a seed drew: what the robot is told is the file's words, the same for every seed.
"""

from __future__ import annotations

from pickdemo.core.shapes import Unknown
from pickdemo.perception import TargetModel
from pickdemo.scenario.layout import Placement
from pickdemo.scenario.schema import Scenario


def target_model(scenario: Scenario, placement: Placement) -> TargetModel:
    """What the task tells the robot about an object: a box's or a cylinder's shape (at the size
    placed) and colour; of a mesh, or a cylinder lying on its side, only the rough size its file states
    (a cue to tell it from other objects), or nothing: it is found and grasped by its geometry."""
    spec = next(o for o in scenario.objects if o.name == placement.name)
    if spec.told_nothing:  # a mesh, or a cylinder lying (the shapes' models stand upright)
        return TargetModel(geometry=Unknown(size_cue_m=spec.rough_size_m), color=None)
    assert spec.color is not None  # the schema requires it of a box or cylinder
    return TargetModel(geometry=placement.geometry, color=tuple(spec.color))
