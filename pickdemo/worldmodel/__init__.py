"""The world model: every object the robot has seen, with its identity, kept across views and
cameras, and the space it has seen free. Beside :mod:`pickdemo.perception` (a frame's estimate of the
target) and :mod:`pickdemo.tracking` (the target's belief over time): one frame's instances
(:mod:`.instances`, perception's part, run on every frame) and the objects they add up to
(:mod:`.objects`, the robot's part, which every consumer reads: the grasps' clearance, what stands at
the place, a clear round's next object, looking for a target no view has shown), and the space seen
free apart from the never seen (:mod:`.occupancy`).
Pure: no simulator.
"""

from pickdemo.worldmodel.instances import Instance, SceneView, split_view
from pickdemo.worldmodel.objects import PlaceView, TrackedObject, WorldModel
from pickdemo.worldmodel.occupancy import FREE, OCCUPIED, UNKNOWN, Occupancy

__all__ = [
    "FREE",
    "OCCUPIED",
    "UNKNOWN",
    "Instance",
    "Occupancy",
    "PlaceView",
    "SceneView",
    "TrackedObject",
    "WorldModel",
    "split_view",
]
