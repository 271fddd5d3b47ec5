"""The commanded joint motion against the Franka's datasheet limits: the peak ratio per quantity
(``peak_joint_limit_ratio`` in result.json) agrees with the exceedances the motion plot marks."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.result import limit_exceedances, peak_limit_ratios
from pickdemo.robot import robot_named

ROBOT = robot_named()


def _sine(amplitude_rad: float, omega: float) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, 4.0, 1.0 / 120.0)
    q = np.zeros((len(t), 7))
    q[:, 1] = amplitude_rad * np.sin(omega * t)  # joint 2: velocity a w, acceleration a w^2
    return t, q


@pytest.mark.parametrize("scale", [0.5, 0.99, 1.2])
def test_peak_ratio_is_the_largest_share_of_the_limit(scale: float) -> None:
    omega = 2.0
    a = scale * ROBOT.limits.max_acceleration_rad_s2[1] / omega**2  # joint 2's acceleration peaks at scale x its limit
    t, q = _sine(a, omega)
    ratio = peak_limit_ratios(t, q, ROBOT.limits.rates())
    assert ratio["acceleration"] == pytest.approx(scale, rel=2e-3)
    assert ratio["velocity"] == pytest.approx(a * omega / ROBOT.limits.max_velocity_rad_s[1], rel=2e-3)
    over = {e.quantity for e in limit_exceedances(t, q, ROBOT.limits.rates())}
    assert ("acceleration" in over) == (ratio["acceleration"] > 1.0)
    assert ("velocity" in over) == (ratio["velocity"] > 1.0)


def test_too_short_a_command_has_no_ratio() -> None:
    assert peak_limit_ratios(np.zeros(3), np.zeros((3, 7)), ROBOT.limits.rates()) is None
