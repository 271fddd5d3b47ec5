"""A vacuum cup's physics as numbers: when its rim seals on a surface, and what wrench the seal holds.

Pure (numpy only): the simulator's cup (:mod:`pickdemo.sim.suction`) applies it to what it measures
each physics step, the suction grasp planner (:mod:`pickdemo.grasping.suction`) to the points it sees,
and the unit tests to numbers. The model is Dex-Net 3.0's in its simplest form (Mahler et al. 2018): a
compliant ring that seals where its rim meets the surface all round within the bellows' stroke, held
on by the vacuum's force (the pressure difference times the cup's area: Schmalz's F = dp A); the
seal breaks when the pull along the cup's axis, the shear, the bending (peel) moment or the twist
ask more than what the vacuum's preload, less the pull, gives through the rim's friction and its
radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

GRAVITY_M_S2 = 9.81


@dataclass(frozen=True)
class Cup:
    """A bellows suction cup on its vacuum (SI units; pressures in kPa below the ambient)."""

    diameter_m: float  # the lip's outer diameter
    stroke_m: float  # how far the bellows compresses: the rim conforms over this much
    bellows_force_n: float  # what the bellows pushes back with, compressed (its spring, as a preload)
    vacuum_kpa: float  # the vacuum the generator holds at a sealed cup
    friction: float = 0.5  # the lip's friction on a surface (rubber on a dry, smooth face)
    #: a sealed cup's vacuum switch reads "part present" above this share of the vacuum
    switch_share: float = 0.6
    #: the vacuum a leaking cup still reads (share of the full): the generator pulls against the leak
    leak_share: float = 0.15

    @property
    def radius_m(self) -> float:
        return self.diameter_m / 2.0

    @property
    def area_m2(self) -> float:
        return math.pi * self.radius_m**2

    @property
    def holding_force_n(self) -> float:
        """The vacuum's pull on a sealed face, normal to it: F = dp A."""
        return self.vacuum_kpa * 1e3 * self.area_m2

    @property
    def switch_kpa(self) -> float:
        return self.switch_share * self.vacuum_kpa


class Seal(str, Enum):
    """What the rim makes of a surface."""

    OPEN = "open"  # nothing under the lip (not touching)
    LEAK = "leak"  # touching, but air gets in: over an edge, across a step deeper than the stroke
    SEALED = "sealed"


#: The lip touches a surface this near (m): a physics step's contact and the estimate's millimetre.
TOUCH_M = 0.002


def rim_points(cup: Cup, n: int = 16) -> np.ndarray:
    """(n, 2) the rim's points in the cup's own plane (m), at its lip's radius less a millimetre (inside
    the lip's rubber, where it meets the face)."""
    a = np.arange(n) * (2.0 * math.pi / n)
    r = cup.radius_m - 0.001
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


def seal(cup: Cup, gaps_m: np.ndarray, on_one_face: np.ndarray) -> Seal:
    """The seal of a rim whose points are ``gaps_m`` from the surface along the cup's axis (m; beyond
    the lip positive, NaN where nothing is within reach), each ``on_one_face`` (the same body as the
    rest: a rim across two objects leaks). Sealed: the nearest point touches, every point is on the one
    body, and the farthest is within the bellows' stroke of the nearest (the rim bends that far)."""
    gaps = np.asarray(gaps_m, dtype=float)
    found = np.isfinite(gaps)
    if not found.any() or float(np.nanmin(gaps)) > TOUCH_M:
        return Seal.OPEN
    if not found.all() or not np.all(on_one_face):
        return Seal.LEAK
    if float(gaps.max() - gaps.min()) > cup.stroke_m:
        return Seal.LEAK
    return Seal.SEALED


@dataclass(frozen=True)
class Load:
    """A wrench on a sealed cup, in the cup's frame (z along its axis, out of the lip): what it takes
    as shares of what the seal holds (over 1: the seal breaks)."""

    pull: float  # the pull along the axis, of the vacuum's force
    shear: float  # the sideways force, of the friction the preload gives
    peel: float  # the bending moment, of the preload's moment about the rim's far edge
    twist: float  # the moment about the axis, of the rim's friction moment

    @property
    def worst(self) -> float:
        return max(self.pull, self.shear, self.peel, self.twist)

    @property
    def holds(self) -> bool:
        return self.worst <= 1.0


def load(cup: Cup, force_n: np.ndarray, torque_nm: np.ndarray) -> Load:
    """The shares of the seal ``force_n`` and ``torque_nm`` take, both on the held object at the cup's
    centre, in the cup's frame (z out of the lip, towards the object: a pull is along +z).

    The vacuum presses the lip on the face with F = dp A; a pull f_n along the axis leaves F - f_n of
    it; that net preload, with the lip's friction mu, resists a shear up to mu (F - f_n) and a twist up
    to mu (F - f_n) r; about the rim's far edge, a bending moment up to (F - f_n) r."""
    f = np.asarray(force_n, dtype=float)
    t = np.asarray(torque_nm, dtype=float)
    held = cup.holding_force_n
    pull = max(float(f[2]), 0.0)
    net = held - pull
    if net <= 0.0:
        return Load(pull / held, math.inf, math.inf, math.inf)
    shear = float(np.hypot(f[0], f[1]))
    bend = float(np.hypot(t[0], t[1]))
    r, mu = cup.radius_m, cup.friction
    return Load(pull / held, shear / (mu * net), bend / (net * r), abs(float(t[2])) / (mu * net * r))


def hanging_load(cup: Cup, mass_kg: float, lever_m: np.ndarray, axis_up: np.ndarray) -> Load:
    """The load of a ``mass_kg`` object hanging still from the cup, its centre of mass ``lever_m`` from
    the cup's centre (world), the cup's axis pointing ``axis_up``... into the object being ``-axis_up``
    (a cup on a top face, pointing down: ``axis_up`` is +z). For the planner: the weight's pull, shear
    and moment about the cup, in the cup's frame."""
    axis = -np.asarray(axis_up, dtype=float) / np.linalg.norm(axis_up)  # the cup's z: into the object
    weight = np.array([0.0, 0.0, -mass_kg * GRAVITY_M_S2])
    moment = np.cross(np.asarray(lever_m, dtype=float), weight)
    x = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    frame = np.stack([x, np.cross(axis, x), axis])  # rows: the cup's x, y, z in the world
    return load(cup, frame @ weight, frame @ moment)
