"""The world model: every object the robot has seen, with its identity, kept across views and
cameras, and the space it has seen free. Beside :mod:`pickdemo.perception` (a frame's estimate of the
target) and :mod:`pickdemo.tracking` (the target's belief over time): one frame's instances
(:mod:`.instances`, perception's part, run on every frame) and the objects they add up to
(:mod:`.objects`, the robot's part, which every consumer reads: the grasps' clearance, the place,
looking again). Pure: no simulator.
"""

from pickdemo.worldmodel.instances import Instance, SceneView, split_view
from pickdemo.worldmodel.objects import TrackedObject, WorldModel

__all__ = ["Instance", "SceneView", "TrackedObject", "WorldModel", "split_view"]
