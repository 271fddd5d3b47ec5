"""What crosses between the robot and its controller once per control tick, as frozen dataclasses.

:class:`Observation` is what the robot's own sensors report (encoders, finger openings, finger
contacts, the wrist's force, a suction cup's vacuum); :class:`Command` is what the controller sends
back (arm joint targets with velocity feed-forward, the gripper's target opening and force, a suction
cup's valve). Camera frames travel separately, at their own rate (:class:`pickdemo.core.camera.RGBDFrame`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Observation:
    """The robot's proprioception at one tick."""

    time_s: float  # simulated time
    arm_q: np.ndarray  # (7,) rad
    arm_dq: np.ndarray  # (7,) rad/s
    fingers_m: np.ndarray  # (2,) m, each finger's opening from the centre
    finger_contacts: tuple[int, int]  # contact points on each finger with anything but the robot
    #: (3,) N: the force the hand (and what it holds) puts on the wrist flange, in the hand's frame,
    #: as a wrist force sensor reads it (the Franka estimates it from its joint torques)
    wrist_force_n: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: kPa below the ambient at a suction cup, as its vacuum sensor reads it (0: no cup, or the valve off)
    vacuum_kpa: float = 0.0

    @property
    def opening_m(self) -> float:
        """Distance between the fingers (m)."""
        f = self.fingers_m
        return float(f[0] + f[1])  # (np.sum of two, without its overhead: read several times a tick)


@dataclass(frozen=True)
class Command:
    """What the controller sends for the next tick."""

    arm_q: np.ndarray  # (7,) rad, position targets
    arm_dq: np.ndarray  # (7,) rad/s, velocity feed-forward
    finger_opening_m: float  # target of each finger, 0 .. 0.04 m
    finger_force_n: float  # force limit of each finger's motor (N)
    vacuum: bool = False  # a suction cup's valve: on sucks, off releases (fingers: unused)
