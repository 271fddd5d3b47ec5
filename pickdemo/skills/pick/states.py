"""The pick skill's states: each state's entry action (run once, when it is entered: plan, send a
target) and exit test (run every tick: the next state and what it says, or stay), as functions of
the machine, and the table :data:`STATES` the machine dispatches from.

States, in the order of a pick::

    LOOK -> APPROACH -> DESCEND -> CLOSE -> LIFT -> TRANSPORT -> LOWER -> RELEASE -> RETREAT -> HOME
         -> VERIFY -> DONE
    DESCEND --(the target moved)--> BACK_OFF -> APPROACH
    CLOSE --(nothing held)--> BACK_OFF -> LOOK          (a retry, up to ``max_attempts``)
    LIFT / TRANSPORT --(dropped)--> BACK_OFF -> LOOK    (a retry with more grip force, a slower lift)
    VERIFY --(seen put down off the place)--> LOOK      (picked up again, within ``max_attempts``)

While it approaches, descends and closes it keeps looking (closed loop): the tracker fuses every
estimate, and the motion is re-targeted to where the tracker says the target is. With
``open_loop`` it looks only in ``LOOK`` and plays the plan from that one look, for comparison. A
target the tracker sees moving (a belt) is met where it will be
(:class:`~pickdemo.skills.pick.intercept.Interceptor`); one that will have left the arm's reach by
the time it is held, or that runs faster than the hand, fails the episode in ``ik`` by name.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pickdemo.core.interfaces import Observation
from pickdemo.skills.pick import carry, close, take
from pickdemo.skills.pick.params import HAND_OVER_TARGET, State, Transition

if TYPE_CHECKING:  # (the machine imports this table: a type only, for the reader and the checker)
    from pickdemo.skills.pick.machine import PickMachine


@dataclass(frozen=True)
class StateHandlers:
    """A state's entry action (run once, when it is entered) and exit test (run every tick)."""

    enter: Callable[[PickMachine, Observation], None]
    tick: Callable[[PickMachine, Observation], Transition]


#: The dispatch table: every state the machine runs (``FAILED`` is final and runs nothing).
STATES: dict[State, StateHandlers] = {
    State.LOOK: StateHandlers(take.enter_look, take.tick_look),
    State.APPROACH: StateHandlers(take.enter_approach, take.tick_approach),
    State.DESCEND: StateHandlers(take.enter_descend, take.tick_descend),
    State.CLOSE: StateHandlers(close.enter_close, close.tick_close),
    State.LIFT: StateHandlers(carry.enter_lift, carry.tick_lift),
    State.TRANSPORT: StateHandlers(carry.enter_transport, carry.tick_transport),
    State.LOWER: StateHandlers(carry.enter_lower, carry.tick_lower),
    State.RELEASE: StateHandlers(carry.enter_release, carry.tick_release),
    State.RETREAT: StateHandlers(carry.enter_retreat, carry.tick_retreat),
    State.HOME: StateHandlers(carry.enter_home, carry.tick_home),
    State.VERIFY: StateHandlers(carry.enter_verify, carry.tick_verify),
    State.BACK_OFF: StateHandlers(carry.enter_back_off, carry.tick_back_off),
    State.DONE: StateHandlers(carry.enter_done, carry.tick_done),
}

__all__ = ["HAND_OVER_TARGET", "STATES", "StateHandlers"]
