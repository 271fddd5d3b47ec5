"""The contacts that begin, each physics step, between the robot's links (or one watched body, the
object the hand may hold) and anything else in the scene: the truth, for scoring only (the
``collisions`` of ``result.json``, :mod:`pickdemo.runtime.collisions`); the controller never reads it.

A contact begins when its pair (who, which link, what) was not touching in the last
:data:`GAP_STEPS` steps: a pair that chatters on and off as it slides is one contact, not hundreds.
Touching means at most :data:`TOUCH_M` apart: Bullet keeps a pair's points in its contact manifold
from a few millimetres apart on (its contact threshold about convex hulls), and such a point, with no
force, is no touch (a hand 2.5 mm above a wall's top had been counted as meeting it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pybullet as p

if TYPE_CHECKING:  # (the scene imports this module)
    from pickdemo.sim.scene import Scene

#: A pair apart for fewer steps than this (0.1 s at 240 Hz) touching again is the same contact.
GAP_STEPS = 24
#: Two bodies touch when their nearest points are at most this far apart (m; below 0: penetrating).
TOUCH_M = 0.0


@dataclass(frozen=True)
class Contact:
    """A contact that began: ``who`` (``robot`` or the watched body's name), its link's name
    (``""`` for a body's base), what it touched, where (m, on ``who``) and when (s)."""

    who: str
    link: str
    other: str
    position: tuple[float, float, float]
    time_s: float
    base: bool = False  # a link of the robot's that no joint moves (its base: it stands where it stands)


class ContactLog:
    """Reads the robot's contacts (and the watched body's) after each step; :meth:`take` hands over
    those that began since it was last asked."""

    def __init__(
        self, client, bodies: dict[str, int], parts: dict[str, list[int]], links: dict[int, str], fixed: set[int]
    ) -> None:  # noqa: ANN001 - a BulletClient
        """``links``: the robot's links' names by index; ``fixed``: the indices of those no joint moves."""
        self._contacts = client.getContactPoints
        self.robot = bodies["robot"]
        self.names = {b: n for n, b in bodies.items()}
        self.names.update({b: n for n, ids in parts.items() for b in ids})
        self.links, self.fixed = links, fixed
        self.watched: tuple[str, int] | None = None
        self._last: dict[tuple[int, int, int, int], int] = {}
        self._began: list[Contact] = []
        self.step = 0

    def watch(self, name: str | None) -> None:
        """Read this body's contacts too (None: no more), beside the robot's."""
        self.watched = None if name is None else (name, next(b for b, n in self.names.items() if n == name))

    def read(self, time_s: float) -> None:
        """After a physics step: the contacts that began."""
        self.step += 1
        self._pairs(self.robot, "robot", time_s)
        if self.watched is not None:
            self._pairs(self.watched[1], self.watched[0], time_s)

    def _pairs(self, body: int, who: str, time_s: float) -> None:
        for pt in self._contacts(bodyA=body):
            other = pt[2]
            if other == self.robot or other == body or pt[8] > TOUCH_M:  # (apart: in the manifold, not touching)
                continue
            key = (body, pt[3], other, pt[4])
            last = self._last.get(key)
            self._last[key] = self.step
            if last is not None and self.step - last <= GAP_STEPS:
                continue
            link = self.links.get(pt[3], "") if body == self.robot else ""
            where = tuple(float(v) for v in np.asarray(pt[5], dtype=float))
            name = self.names.get(other, f"body {other}")
            self._began.append(Contact(who, link, name, where, time_s, base=body == self.robot and pt[3] in self.fixed))

    def take(self) -> list[Contact]:
        """The contacts that began since the last call."""
        out, self._began = self._began, []
        return out


def log_contacts(scene: Scene) -> ContactLog:
    """From now on, the contacts that begin between the scene's robot and anything else, read after
    each step (the truth, for scoring only)."""
    c, robot = scene.client, scene.bodies["robot"]
    links = {j: n for n, j in scene.link_index.items()}
    fixed = {-1}  # the links no joint moves (the base, and what is fixed to it)
    for j in range(c.getNumJoints(robot)):  # (a parent's index is below its child's)
        info = c.getJointInfo(robot, j)
        if info[2] == p.JOINT_FIXED and info[16] in fixed:
            fixed.add(j)
    scene.contact_log = ContactLog(c, scene.bodies, scene.fixture_bodies, links, fixed)
    return scene.contact_log
