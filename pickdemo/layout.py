"""Where each object of a scenario starts: sampled from the scenario's ranges with the scene's RNG.

Pure: no simulator. Objects are placed in file order; an object that would overlap one already
placed is re-drawn (a bounded number of times), so a seed always gives the same layout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.geometry import Pose
from pickdemo.scenario import ObjectSpec, Scenario

MAX_DRAWS = 200


class LayoutError(ValueError):
    """The scenario's ranges leave no room to place its objects apart."""


@dataclass(frozen=True)
class Placement:
    name: str
    pose: Pose  # world pose of the object's centre


def footprint_radius_m(obj: ObjectSpec) -> float:
    """Radius of the circle that holds the object's footprint on the table."""
    if obj.shape == "box":
        return 0.5 * float(np.hypot(obj.size[0], obj.size[1]))
    return 0.5 * obj.size[0]


def _draw(obj: ObjectSpec, rng: np.random.Generator) -> tuple[np.ndarray, float]:
    if obj.position is not None:
        xy = np.array(obj.position, dtype=float)
    else:
        (x0, x1), (y0, y1) = obj.position_range  # type: ignore[misc]
        xy = np.array([rng.uniform(x0, x1), rng.uniform(y0, y1)])
    if obj.yaw_deg is not None:
        yaw = np.radians(obj.yaw_deg)
    elif obj.yaw_range_deg is not None:
        yaw = np.radians(rng.uniform(*obj.yaw_range_deg))
    else:
        yaw = 0.0
    return xy, float(yaw)


def sample_layout(scenario: Scenario, rng: np.random.Generator) -> tuple[Placement, ...]:
    """Start poses of all objects, resting on the table (z = half their height)."""
    placed: list[tuple[np.ndarray, float]] = []
    out: list[Placement] = []
    for obj in scenario.objects:
        r = footprint_radius_m(obj)
        for _ in range(MAX_DRAWS):
            xy, yaw = _draw(obj, rng)
            if all(np.linalg.norm(xy - q) >= r + rq + scenario.layout.clearance_m for q, rq in placed):
                break
        else:
            raise LayoutError(f"objects.{obj.name}: no free spot found in {MAX_DRAWS} draws")
        placed.append((xy, r))
        pose = Pose.from_xyz_rpy(np.array([xy[0], xy[1], obj.height_m / 2.0]), yaw=yaw)
        out.append(Placement(name=obj.name, pose=pose))
    return tuple(out)
