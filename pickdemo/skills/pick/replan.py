"""Whether the path under way is still free (issue 59): the rest of a joint transfer's straight line,
and the planned path's waypoints after it, checked again against the world model each time a view
changes it (an object pushed into the way, or seen only now). A part of the pick skill: it answers
what the path would meet and keeps only its own count; the machine brings the arm to rest and enters
the state again, which plans from there (:mod:`pickdemo.skills.pick.routes`).

Checked at the tight margins (:data:`~pickdemo.skills.pick.routes.TIGHT_MARGIN_M`): a path planned at
the wider ones is not stopped for an estimate that wavers by a few millimetres. A Cartesian motion
(the descent, the lift, a straight carry) is not watched.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pickdemo.skills.pick.routes import TIGHT_MARGIN_M
from pickdemo.skills.pick.states import State

if TYPE_CHECKING:
    from pickdemo.core.interfaces import Observation
    from pickdemo.skills.pick.machine import PickMachine

#: The states whose joint transfers are watched: to above the target, the carry, home.
WATCHED = frozenset({State.APPROACH, State.TRANSPORT, State.HOME})


class PathWatch:
    """The path's check, once per change of the world model (see the module docstring)."""

    def __init__(self) -> None:
        self.views = -1  # the world model's views at the last check
        self.attempt = 0
        self.replans = 0  # this attempt's

    def blocked(self, m: PickMachine, obs: Observation) -> tuple[State, str] | None:
        """Where to go once at rest, and why, if the path under way would meet something now: the state
        again (it plans from there), or, on the way to a grasp whose own pose meets it, a look again (a
        grasp chosen with it in view); None: the path is free."""
        if not (m.p.plan_around and m.p.replan_on_change) or m.state not in WATCHED or m.world.views == self.views:
            return None
        self.views = m.world.views
        if m.attempt != self.attempt:
            self.attempt, self.replans = m.attempt, 0
        ahead = m.arm.ahead()
        if not ahead or m.arm.finished or self.replans >= m.p.max_replans:
            return None
        held = m.held if m.state is State.TRANSPORT else None
        fingers = m.grip.finger_max_m  # (as each state's motion was planned)
        if held is not None:
            fingers = 0.5 * (m.grasp_width_m if m.grasp_width_m is not None else obs.opening_m)
        elif m.state is State.APPROACH and m.plan is not None and m.plan.open_m is not None:
            fingers = m.plan.open_m
        scene = m.router.scene(m.world, held=held, held_at=m.held_at, margin_m=TIGHT_MARGIN_M)
        hit = m.router.path_contact(scene, m.arm.q, ahead, fingers)
        if hit is None:
            return None
        self.replans += 1
        said = f"{hit[0]} would meet {hit[1]} on the way"
        if m.state is State.APPROACH and scene.contact(ahead[-1], fingers) is not None:
            return State.LOOK, f"{said}, at the grasp's pregrasp too: at rest, looking again"
        return m.state, f"{said}: at rest, planning it again"
