"""The cup's seal and hold as numbers (no simulator)."""

from __future__ import annotations

import numpy as np

from pickdemo.robot.suction import GRAVITY_M_S2, Cup, Seal, hanging_load, load, seal

CUP = Cup(diameter_m=0.03, stroke_m=0.008, bellows_force_n=6.0, vacuum_kpa=60.0, friction=0.5)


def test_the_holding_force_is_pressure_times_area() -> None:
    assert abs(CUP.holding_force_n - 60e3 * np.pi * 0.015**2) < 1e-9


def test_a_rim_seals_touching_all_round_within_the_stroke() -> None:
    flat = np.zeros(16)
    assert seal(CUP, flat, np.ones(16, bool)) is Seal.SEALED
    tilted = np.linspace(0.0, 0.007, 16)  # a face tilted 13 deg: 7 mm across the rim, within the stroke
    assert seal(CUP, tilted, np.ones(16, bool)) is Seal.SEALED
    assert seal(CUP, np.linspace(0.0, 0.012, 16), np.ones(16, bool)) is Seal.LEAK  # deeper than the stroke
    assert seal(CUP, flat + 0.01, np.ones(16, bool)) is Seal.OPEN  # not touching


def test_a_rim_over_an_edge_or_across_two_bodies_leaks() -> None:
    over = np.zeros(16)
    over[5:9] = np.nan
    assert seal(CUP, over, np.ones(16, bool)) is Seal.LEAK
    two = np.ones(16, bool)
    two[:3] = False
    assert seal(CUP, np.zeros(16), two) is Seal.LEAK


def test_the_pull_holds_to_the_vacuums_force_and_no_further() -> None:
    f = CUP.holding_force_n
    assert load(CUP, np.array([0, 0, 0.99 * f]), np.zeros(3)).pull < 1.0
    assert not load(CUP, np.array([0, 0, 1.01 * f]), np.zeros(3)).holds
    assert load(CUP, np.array([0, 0, -100.0]), np.zeros(3)).holds  # pushed on: nothing asked of the seal


def test_a_pull_leaves_less_for_shear_and_peel() -> None:
    side = np.array([5.0, 0.0, 0.0])
    assert load(CUP, side, np.zeros(3)).shear < load(CUP, side + [0, 0, 20.0], np.zeros(3)).shear
    assert load(CUP, np.zeros(3), np.array([0.3, 0.0, 0.0])).peel > 0.3 / (CUP.holding_force_n * CUP.radius_m) - 1e-9


def test_a_weight_held_off_its_centre_peels() -> None:
    up = np.array([0.0, 0.0, 1.0])
    centred = hanging_load(CUP, 1.0, np.array([0.0, 0.0, -0.05]), up)
    off = hanging_load(CUP, 1.0, np.array([0.06, 0.0, -0.05]), up)
    assert centred.holds and abs(centred.pull - GRAVITY_M_S2 / CUP.holding_force_n) < 1e-9
    assert off.peel > centred.peel and not off.holds  # 9.8 N at 6 cm: 0.59 N m against 0.49
