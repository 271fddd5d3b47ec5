"""The pick skill: look, approach, descend, close, lift, carry, place, verify; closed loop.

The machine (:mod:`~pickdemo.skills.pick.machine`) holds the state and decides; the states
(:mod:`~pickdemo.skills.pick.states`) are functions dispatched from one table; its parts return
values and never write its state: where to look (:mod:`~pickdemo.skills.pick.views`), what moved
(:mod:`~pickdemo.skills.pick.watch`), which grasp (:mod:`~pickdemo.skills.pick.chooser`), meeting a
moving target (:mod:`~pickdemo.skills.pick.intercept`), how the arm gets there
(:mod:`~pickdemo.skills.pick.arm`). Its vocabulary, parameters and retry policy are in
:mod:`~pickdemo.skills.pick.params`.
"""

from pickdemo.skills.pick.machine import PickMachine
from pickdemo.skills.pick.params import (
    HAND_OVER_TARGET,
    HELD_STATES,
    TRACKING_STATES,
    CameraModel,
    Event,
    FrameRequest,
    MachineParams,
    State,
)

__all__ = [
    "HAND_OVER_TARGET",
    "HELD_STATES",
    "TRACKING_STATES",
    "CameraModel",
    "Event",
    "FrameRequest",
    "MachineParams",
    "PickMachine",
    "State",
]
