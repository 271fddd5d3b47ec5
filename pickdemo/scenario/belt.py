"""A conveyor (``[conveyor]``): its strip, its speed over time and its kinematics, the slab the
simulator moves."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from pydantic import Field, model_validator

from pickdemo.scenario.base import Coord, Friction, Model, UnitFloat

Speed = Annotated[float, Field(ge=0.0, le=0.5)]  # m/s, a belt's speed
#: How fast a belt changes speed (m/s^2): a change of 0.05 m/s takes 0.1 s.
BELT_ACCELERATION_M_S2 = 0.5
#: How far the belt's slab travels before it is slid back (m); the slab is this much longer than
#: its strip along the belt's direction (see :mod:`pickdemo.sim.conveyor`).
BELT_REWIND_M = 0.2
#: The longest physics step a scenario may have (s): the slab overruns its travel by at most one.
MAX_TIME_STEP_S = 1.0 / 240.0


@dataclass(frozen=True)
class BeltSlab:
    """The belt's body: a slab (a box) that slides along the belt's direction on a prismatic joint.

    One pure description, used by the simulator to build it and by :mod:`pickdemo.scenario.checks` to keep
    things off where it goes, so that the two cannot disagree. Positions are in the table's frame (m).
    """

    centre: tuple[float, float, float]  # of the slab at joint position 0: the strip's centre, half its height up
    half_extents: tuple[float, float, float]  # the strip's, lengthened by half the rewind along the direction
    direction: tuple[float, float]  # unit vector of its travel (+y for a belt that never moves)
    travel_m: tuple[float, float]  # the joint positions it takes: it starts at the first, is slid back past the second
    rewind_m: float

    def corners_at(self, q: float) -> list[tuple[float, float]]:
        """The slab's outline seen from above (4 corners, counter-clockwise) at joint position ``q``."""
        cx, cy = self.centre[0] + q * self.direction[0], self.centre[1] + q * self.direction[1]
        hx, hy = self.half_extents[0], self.half_extents[1]
        return [(cx - hx, cy - hy), (cx + hx, cy - hy), (cx + hx, cy + hy), (cx - hx, cy + hy)]

    def swept_corners(self) -> list[tuple[float, float]]:
        """The corners of the slab at both ends of its travel: the convex hull of these 8 points is
        the whole footprint it sweeps on the table (the strip, plus the overhang and its travel)."""
        return self.corners_at(self.travel_m[0]) + self.corners_at(self.travel_m[1])


class ConveyorSpec(Model):
    """A belt across the table that carries what rests on it (by friction, as a real belt does).

    The robot knows where the belt is (the cell's layout), never how fast it runs: that it measures.
    Its clock starts with the robot's (the first control tick): ``speed_changes`` are timed from then.
    """

    velocity_m_s: tuple[Annotated[float, Field(ge=-0.5, le=0.5)], Annotated[float, Field(ge=-0.5, le=0.5)]]  # x, y
    x_range_m: tuple[Coord, Coord]  # the belt's strip on the table
    y_range_m: tuple[Coord, Coord]
    speed_changes: tuple[tuple[Annotated[float, Field(ge=0.0, le=600.0)], Speed], ...] = ()  # (time s, speed m/s)
    height_m: Annotated[float, Field(ge=0.002, le=0.1)] = 0.01  # its top surface above the table
    color: tuple[UnitFloat, UnitFloat, UnitFloat] = (0.16, 0.17, 0.19)
    friction: Friction = 0.9

    @model_validator(mode="after")
    def _check(self) -> ConveyorSpec:
        for key in ("x_range_m", "y_range_m"):
            lo, hi = getattr(self, key)
            if hi - lo < 0.05:
                raise ValueError(f"{key} must be [min, max] and at least 0.05 m wide")
        if sum(v * v for v in self.velocity_m_s) ** 0.5 > 0.5:
            raise ValueError("velocity_m_s: at most 0.5 m/s")
        times = [t for t, _ in self.speed_changes]
        if times != sorted(times) or len(set(times)) != len(times):
            raise ValueError("speed_changes must be in increasing time order")
        if self.speed_changes and self.speed == 0.0:
            raise ValueError("speed_changes need a non-zero velocity_m_s (it gives the belt's direction)")
        return self

    @property
    def speed(self) -> float:
        return float(sum(v * v for v in self.velocity_m_s) ** 0.5)

    def speed_at(self, t_s: float) -> float:
        """The belt's speed ``t_s`` after it started: its speed, then each change, ramped at
        :data:`BELT_ACCELERATION_M_S2`."""
        speed = self.speed
        for at, new in self.speed_changes:
            if t_s <= at:
                break
            ramp = (t_s - at) * BELT_ACCELERATION_M_S2
            speed = new if abs(new - speed) <= ramp else speed + (ramp if new > speed else -ramp)
        return float(speed)

    @property
    def top_speed(self) -> float:
        """The fastest the belt ever runs (m/s)."""
        return max([self.speed, *(s for _, s in self.speed_changes)])

    def slab(self) -> BeltSlab:
        """The belt's body and where it goes (:class:`BeltSlab`).

        The slab is the strip lengthened by :data:`BELT_REWIND_M` along the belt's direction (half
        at each end: on a diagonal belt, its x and y extents grow by their share of it), starts at
        joint position ``-rewind/2`` and is slid back by ``rewind`` once it is past ``+rewind/2`` (at
        most one physics step past). A belt that never moves stays where it starts.
        """
        (x0, x1), (y0, y1) = self.x_range_m, self.y_range_m
        speed = self.speed
        dx, dy = (self.velocity_m_s[0] / speed, self.velocity_m_s[1] / speed) if speed > 0 else (0.0, 1.0)
        r = BELT_REWIND_M
        start = -r / 2.0
        end = r / 2.0 + self.top_speed * MAX_TIME_STEP_S if self.top_speed > 0 else start
        return BeltSlab(
            centre=((x0 + x1) / 2.0, (y0 + y1) / 2.0, self.height_m / 2.0),
            half_extents=(
                (x1 - x0) / 2.0 + abs(dx) * r / 2.0,
                (y1 - y0) / 2.0 + abs(dy) * r / 2.0,
                self.height_m / 2.0,
            ),
            direction=(dx, dy),
            travel_m=(start, end),
            rewind_m=r,
        )

    def holds(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether (x, y) lies on the belt, ``margin`` inside its edges."""
        (x0, x1), (y0, y1) = self.x_range_m, self.y_range_m
        return x0 + margin <= x <= x1 - margin and y0 + margin <= y <= y1 - margin

    def touches(self, x: float, y: float, radius: float) -> bool:
        """Whether a footprint of ``radius`` about (x, y) reaches onto the belt."""
        (x0, x1), (y0, y1) = self.x_range_m, self.y_range_m
        return x0 - radius < x < x1 + radius and y0 - radius < y < y1 + radius
