"""Disturbances: the world changes while the robot works (the target is pushed across the table).

A push slides the target kinematically from where it is to an offset and a turn, over a short time,
with a smooth (smoothstep) profile, so that a frame taken during it sees the object on its way. The
offsets and turns are drawn when the episode starts, from the seed's ``disturbance`` stream.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.scenario.load import DisturbanceSpec
from pickdemo.sim.scene import Scene


@dataclass(frozen=True)
class Push:
    """A slide of the target by ``offset_m`` (x, y) and ``yaw_rad``, from ``start_s`` for ``duration_s``."""

    start_s: float  # simulated time (absolute)
    duration_s: float
    offset_m: tuple[float, float]
    yaw_rad: float

    def to_dict(self) -> dict[str, float | list[float]]:
        return {
            "start_s": self.start_s,
            "duration_s": self.duration_s,
            "offset_m": list(self.offset_m),
            "yaw_deg": float(np.degrees(self.yaw_rad)),
        }


def draw_push(spec: DisturbanceSpec, first_look_s: float, rng: np.random.Generator) -> Push:
    """The push a disturbance spec describes, drawn once per episode from ``rng``."""
    if spec.offset_m is not None:
        offset = np.asarray(spec.offset_m, dtype=float)
    elif spec.offset_range_m is not None:
        offset = np.array([rng.uniform(*spec.offset_range_m[0]), rng.uniform(*spec.offset_range_m[1])])
    else:
        distance = rng.uniform(*spec.distance_range_m)  # type: ignore[misc]
        direction = rng.uniform(0.0, 2.0 * np.pi)
        offset = distance * np.array([np.cos(direction), np.sin(direction)])
    yaw = rng.uniform(*spec.yaw_range_deg) if spec.yaw_range_deg is not None else spec.yaw_deg
    if spec.yaw_either_way and rng.uniform() < 0.5:
        yaw = -yaw
    return Push(
        start_s=first_look_s + spec.at_time_s,
        duration_s=spec.duration_s,
        offset_m=(float(offset[0]), float(offset[1])),
        yaw_rad=float(np.radians(yaw)),
    )


class PushPlayer:
    """Plays a :class:`Push` on one body, one physics step at a time."""

    def __init__(self, push: Push, body: str) -> None:
        self.push = push
        self.body = body
        self._from: Pose | None = None
        self.done = False

    def step(self, scene: Scene) -> None:
        """Call before each physics step."""
        t = scene.sim_time_s
        if self.done or t < self.push.start_s:
            return
        if self._from is None:
            self._from = scene.true_pose(self.body)
        s = min((t - self.push.start_s) / self.push.duration_s, 1.0)
        s = s * s * (3.0 - 2.0 * s)
        start = self._from
        position = start.position + s * np.array([*self.push.offset_m, 0.0])
        turn = Pose.from_xyz_rpy(np.zeros(3), yaw=s * self.push.yaw_rad).rotation
        scene.set_pose(self.body, Pose(position, turn @ start.rotation))
        if s >= 1.0:
            self.done = True
