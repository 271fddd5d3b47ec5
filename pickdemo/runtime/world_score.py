"""The robot's world model scored against the simulator's truth (the referee's; nothing of it reaches
the controller), MOT-style: after every view the world took in, its objects are matched to the true
objects (a world object's centre within the true object's footprint's circle and 1 cm; the nearest in
place and in footprint area first), and

- a true object in that view (2 cm across or more, at rest, a third of its top's points shown: the
  view's own depth says so) is **found** when an object matches it, **missed** when none does;
- a world object seen in that view that matches no true object within its size is a **phantom**;
- a true object matched to another id than the last time it was matched is an **id switch**.

Per episode: the objects ever in view and those found when in view, the distinct phantom ids, the
id switches; and at the end each world object with the true object it matched and how far off it is.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pickdemo.runtime.world import World
from pickdemo.worldmodel import SceneView, WorldModel

#: A true object this far (m) outside its footprint's circle from a world object's centre is not it.
MATCH_SLACK_M = 0.01
#: The objects scored: at least this across (m) ...
MIN_SIZE_M = 0.02
#: ... with at least this share of their top's points shown by the view
MIN_SHOWN = 1.0 / 3.0
#: ... and at rest where they stood (not carried: no higher than this above where they started, m)
LIFTED_M = 0.01


@dataclass
class WorldScore:
    """The world model's scores over one episode (see the module docstring)."""

    in_view: set[str] = field(default_factory=set)
    found: set[str] = field(default_factory=set)
    checks: int = 0  # (object, view) pairs in view
    checks_found: int = 0
    phantoms: set[int] = field(default_factory=set)
    id_switches: int = 0
    _last_id: dict[str, int] = field(default_factory=dict)
    _start_z: dict[str, float] = field(default_factory=dict)
    _matches: dict[int, tuple[str, float]] = field(default_factory=dict)  # id -> (name, error m) at the last view

    def view(self, world_model: WorldModel, view: SceneView, world: World) -> None:
        """Score the world model after it took in ``view``."""
        truth = {}
        for p in world.layout:
            pose = world.true_pose(p.name)
            self._start_z.setdefault(p.name, float(pose.position[2]))
            truth[p.name] = (pose, p.geometry)
        objs = list(world_model.objects.values())
        pairs = []
        for obj in objs:
            for name, (pose, geometry) in truth.items():
                d = float(np.hypot(*(obj.centre[:2] - pose.position[:2])))
                if d <= geometry.footprint_radius_m + MATCH_SLACK_M:
                    # the nearest in place and in size first (a sliver beside the true object is not it)
                    a, b = geometry.top_extents_m
                    size = abs(float(np.log(max(obj.extents[0] * obj.extents[1], 1e-6) / (a * b))))
                    pairs.append((d / geometry.footprint_radius_m + size, d, obj.id, name))
        pairs.sort()
        matched: dict[str, int] = {}
        used: set[int] = set()
        self._matches = {}
        for _, d, oid, name in pairs:
            if oid in used or name in matched:
                continue
            used.add(oid)
            matched[name] = oid
            self._matches[oid] = (name, d)
        for name, oid in matched.items():
            last = self._last_id.get(name)
            if last is not None and last != oid:
                self.id_switches += 1
            self._last_id[name] = oid
        for name, (pose, geometry) in truth.items():
            if not self._scored(name, pose, geometry, view):
                continue
            self.in_view.add(name)
            self.checks += 1
            if name in matched:
                self.found.add(name)
                self.checks_found += 1
        for obj in objs:
            if obj.id in used or obj.last_seen_s != view.time_s:
                continue
            near = any(
                float(np.hypot(*(obj.centre[:2] - pose.position[:2])))
                <= 0.5 * obj.extents[0] + geometry.footprint_radius_m + MATCH_SLACK_M
                for pose, geometry in truth.values()
            )
            if not near:
                self.phantoms.add(obj.id)

    def _scored(self, name: str, pose, geometry, view: SceneView) -> bool:  # noqa: ANN001 - Pose, Shape
        if min(geometry.top_extents_m) < MIN_SIZE_M:
            return False
        if float(pose.position[2]) > self._start_z[name] + LIFTED_M:
            return False
        a, b = geometry.top_extents_m
        top = float(pose.position[2]) + geometry.resting_height_m(pose.rotation) / 2.0
        grid = np.array([[u * a / 2.0, v * b / 2.0] for u in (-0.7, 0.0, 0.7) for v in (-0.7, 0.0, 0.7)])
        yaw = float(np.arctan2(pose.rotation[1, 0], pose.rotation[0, 0]))
        c, s = np.cos(yaw), np.sin(yaw)
        xy = grid @ np.array([[c, s], [-s, c]]) + pose.position[:2]
        pts = np.column_stack([xy, np.full(len(xy), top)])
        return float(np.mean(view.sees(pts, margin_m=0.01))) >= MIN_SHOWN

    def summary(self, world_model: WorldModel | None) -> dict:
        """``result.json``'s ``world``."""
        objects = []
        for obj in [] if world_model is None else sorted(world_model.objects.values(), key=lambda o: o.id):
            row = obj.summary()
            match = self._matches.get(obj.id)
            row["truth"] = None if match is None else match[0]  # (the referee's: never the robot's)
            row["error_mm"] = None if match is None else round(match[1] * 1e3, 2)
            objects.append(row)
        return {
            "objects": objects,
            "in_view": len(self.in_view),
            "found": len(self.found),
            "missed": sorted(self.in_view - self.found),
            "checks": self.checks,
            "checks_found": self.checks_found,
            "phantoms": len(self.phantoms),
            "id_switches": self.id_switches,
            "views": 0 if world_model is None else world_model.views,
        }
