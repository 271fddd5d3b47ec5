"""What counts as a collision, on the scoring side: the ``collisions`` of ``result.json`` (issue 59).

Read from the simulator's contacts as they begin (:class:`~pickdemo.sim.contacts.ContactLog`, the
truth). Written once, here:

- the robot may touch the target (it grasps it), the tray (a clear round drops into it) and the
  table near the place (what it holds is put down there); its base stands where it stands;
- the held object, while the hand holds it off the table, may touch the robot, the tray and the
  table near the place;
- anything else either of them touches is a collision: the table elsewhere, a fixture, another
  object. A clear round's objects are each some pick's target, so there the robot's touches of them
  are not counted; its fixtures' and the table's are.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pickdemo.sim.contacts import Contact

#: The table counts as the place within this of the place position (m): the held object's footprint
#: and the fingers around it, put down a place tolerance off.
PLACE_RADIUS_M = 0.12
#: How many collisions ``result.json`` describes one by one (all are counted).
DESCRIBED = 5


@dataclass
class CollisionTally:
    """The collisions of one episode (see the module docstring)."""

    target: str | None  # the pick's target (None: a clear round, any object may be one)
    place_xy: tuple[float, float] | None  # where things are put down (None: nowhere on the table)
    allowed_objects: frozenset[str] = frozenset()  # a clear round's objects
    count: int = 0
    first: list[dict] = field(default_factory=list)

    def judge(self, contacts: list[Contact], held: bool) -> None:
        """The contacts that began since the last tick; ``held``: the hand held the target off the table."""
        for c in contacts:
            if c.who != "robot" and not held:
                continue  # (the target standing among its neighbours, or put down: not the robot's doing)
            if not self.allowed(c):
                self.count += 1
                if len(self.first) < DESCRIBED:
                    self.first.append(self.describe(c))

    def allowed(self, c: Contact) -> bool:
        if c.base or c.other in ("tray", self.target) or c.other in self.allowed_objects:
            return True
        if c.other == "table" and self.place_xy is not None:
            dx, dy = c.position[0] - self.place_xy[0], c.position[1] - self.place_xy[1]
            return dx * dx + dy * dy <= PLACE_RADIUS_M**2
        return False

    @staticmethod
    def describe(c: Contact) -> dict:
        who = f"robot.{c.link}" if c.who == "robot" else f"objects.{c.who} (held)"
        return {"who": who, "with": c.other, "sim_time_s": round(c.time_s, 4),
                "at_m": [round(v, 4) for v in c.position]}  # fmt: skip

    def summary(self) -> dict:
        return {"count": self.count, "first": list(self.first)}
