"""The joint command stays within the Franka's datasheet: libfranka's rate limiter on the controller's
side, the reflex on the robot's; and over every kind of episode, the peak ratio is at most 1."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.result import peak_limit_ratios
from pickdemo.robot import robot_named
from pickdemo.robot.rate_limit import LIMITER_SHARE, JointRates, RateLimiter, Reflex, ReflexError
from tests.episodes import episodes

ROBOT = robot_named()

DT = 1.0 / 120.0


def _run(commands: np.ndarray) -> np.ndarray:
    lim = RateLimiter(ROBOT.home_q, DT, ROBOT.limits)
    reflex = Reflex(ROBOT.home_q, DT, ROBOT.limits)
    out = []
    for k, q in enumerate(commands):
        sent, _ = lim(q)
        reflex.check(sent, k * DT)  # never raises: the limiter keeps below the datasheet
        out.append(sent)
    return np.array(out)


def test_a_step_command_is_followed_within_the_limits() -> None:
    target = ROBOT.home_q + np.array([1.0, -0.5, 0.8, 0.6, -1.0, 0.7, 1.5])
    sent = _run(np.repeat(target[None], 600, axis=0))
    t = np.arange(len(sent)) * DT
    ratios = peak_limit_ratios(np.r_[-DT, t], np.vstack([ROBOT.home_q, sent]), ROBOT.limits.rates())
    assert ratios is not None and max(ratios.values()) <= LIMITER_SHARE + 1e-9, ratios
    np.testing.assert_allclose(sent[-1], target, atol=1e-3)  # and it gets there


def test_a_command_within_the_limits_passes_bit_for_bit() -> None:
    t = np.arange(240) * DT
    wave = ROBOT.home_q[None] + 0.2 * (1.0 - np.cos(2.0 * t))[:, None]  # from rest: 0.4 rad/s, 0.8 rad/s^2
    sent = _run(wave)
    assert np.array_equal(sent, wave)


def test_the_reflex_stops_a_command_beyond_the_datasheet() -> None:
    reflex = Reflex(ROBOT.home_q, DT, ROBOT.limits, JointRates.datasheet(ROBOT.limits))
    q = ROBOT.home_q.copy()
    q[1] += 8.0 * DT * DT  # joint 2 accelerated at 8 rad/s^2 in one tick: its limit is 7.5
    with pytest.raises(ReflexError, match=r"joint 2 commanded at 8 rad/s\^2, beyond its limit 7.5"):
        reflex.check(q, 0.5)
    far = ROBOT.home_q.copy()
    far[3] = 0.0  # joint 4 stops at -0.0698
    with pytest.raises(ReflexError, match="joint 4 commanded to 0.0000 rad, outside"):
        Reflex(far, DT, ROBOT.limits).check(far, 0.0)


PEAK_SEEDS = tuple(range(20))
SCENARIOS = (
    "pick_cube pick_cube_3cm pick_cube_7cm pick_box pick_cylinder pick_cluttered pick_far_camera "
    "pick_lookalike_table pick_oblique_camera pick_two_colours pick_anywhere pick_heavy "
    "pick_conveyor pick_conveyor_cylinder pick_conveyor_fast pick_conveyor_rush pick_conveyor_speed_change "
    "pick_pushed pick_slippery"
).split()


@pytest.mark.sim
@pytest.mark.parametrize("name", SCENARIOS)
@pytest.mark.slow
def test_no_episode_commands_beyond_the_datasheet(name: str) -> None:
    """The suite, the conveyors, the pushes and the slippery cube, 20 seeds each: every episode's
    commanded joint motion within the datasheet (and none stopped by the reflex)."""
    rs = episodes(name, PEAK_SEEDS)
    peaks = {r.seed: max(r.peak_joint_limit_ratio.values()) for r in rs if r.peak_joint_limit_ratio}
    assert len(peaks) == len(rs)
    assert max(peaks.values()) <= 1.0, {s: p for s, p in peaks.items() if p > 1.0}
    assert not [r for r in rs if r.failure is not None and r.failure.stage.value == "reflex"]
