"""Moving or not, as the belief decides it: a slow belt is a belt, noise is no motion, a push that
stopped has stopped, and the decision holds while the hand hides the target (no estimates)."""

from __future__ import annotations

import numpy as np
import pytest
from test_tracker import _est

from pickdemo.core.shapes import Box
from pickdemo.perception import TargetModel
from pickdemo.skills.pick.params import BELT_MOVING_SPEED_M_S, MachineParams
from pickdemo.tracking.belief import Counters, GateParams, TargetBelief

BELT = MachineParams().on_a_belt()


def _belief(params: MachineParams = BELT) -> TargetBelief:
    model = TargetModel(Box((0.05, 0.05, 0.05)), color=(0.85, 0.1, 0.1))
    return TargetBelief(
        model, np.pi / 2, params.tracker, GateParams(), surface_z=lambda x, y, z=None: 0.0, counters=Counters()
    )


def _feed(b: TargetBelief, times: np.ndarray, ys: np.ndarray, rng: np.random.Generator, noise_m: float = 1e-3) -> None:
    for t, y in zip(times, ys, strict=True):
        b.offer(_est(0.5 + rng.normal(0, noise_m), y + rng.normal(0, noise_m), sd_m=noise_m), float(t),
                hand_over_target=False)  # fmt: skip


@pytest.mark.parametrize("speed", [0.01, 0.02, 0.03, 0.05])
def test_a_slow_belt_is_moving_within_a_second_and_stays_so_while_hidden(speed: float) -> None:
    for seed in range(5):
        b, rng = _belief(), np.random.default_rng(seed)
        t = np.arange(0.0, 1.6, 0.1)
        _feed(b, t, -0.3 + speed * t, rng)
        v = b.moving_velocity(1.5, BELT_MOVING_SPEED_M_S)
        assert v is not None and abs(v[1] - speed) < 0.005
        # the hand hides the target for two seconds: no estimate, the decision holds
        assert all(b.moving_velocity(1.5 + dt, BELT_MOVING_SPEED_M_S) is not None for dt in np.arange(0.0, 2.0, 0.1))


def test_noise_is_no_motion() -> None:
    flips = 0
    for seed in range(10):
        b, rng = _belief(), np.random.default_rng(seed)
        for k, t in enumerate(np.arange(0.0, 10.0, 0.1)):
            _feed(b, np.array([t]), np.array([0.1]), rng, noise_m=1.5e-3)
            flips += b.moving_velocity(float(t), BELT_MOVING_SPEED_M_S) is not None and k >= 10
    assert flips == 0


def test_a_push_that_stopped_has_stopped_on_a_table() -> None:
    for seed in range(5):
        b, rng = _belief(MachineParams()), np.random.default_rng(seed)
        t = np.arange(0.0, 6.0, 0.1)
        y = np.clip((t - 2.0) / 0.3, 0.0, 1.0) * 0.04  # 4 cm in 0.3 s at 2 s, then still
        _feed(b, t, y, rng)
        assert b.moving_velocity(5.9, MachineParams().moving_speed_m_s) is None
