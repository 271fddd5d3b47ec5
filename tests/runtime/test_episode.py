"""Perception to control, end to end in the simulator: real outcomes, reproducibility, typed failures,
and the closed loop's properties (limits kept across re-targets, straight descent, pushes, slips)."""

from __future__ import annotations

import numpy as np
import pytest
from episodes import at_least, episodes

from pickdemo import Stage, run_episode
from pickdemo.core.result import WALL_CLOCK_KEYS
from pickdemo.robot import robot_named
from pickdemo.scenario.load import Scenario, load_scenario
from pickdemo.scenario.reach import grasp_params

pytestmark = pytest.mark.sim

PICK_STATES = ["look", "approach", "descend", "close", "lift", "transport", "lower", "release", "retreat", "home",
               "verify", "done"]  # fmt: skip


def _states(r) -> list[str]:
    """The states entered, in order (a thing noticed within a state repeats its name)."""
    return [p.phase for i, p in enumerate(r.phases) if i == 0 or p.phase != r.phases[i - 1].phase]


def _strip_wall(d: dict) -> dict:
    return {k: v for k, v in d.items() if k not in WALL_CLOCK_KEYS}


CUBE_SEEDS = tuple(range(10, 18))


#: How much higher than the grasp the hand carries what it holds (the robot's skill's own figure).
HAND_RISE_MM = grasp_params(robot_named()).transport_height_m * 1e3


def test_cube_is_picked_and_placed(cube_scenario: Scenario) -> None:
    rs = episodes("pick_cube", CUBE_SEEDS, record_trace=True)
    ok = at_least(rs, len(rs) - 1)  # 100/100 measured; one failure of 8 is allowed, not two
    # Success says only that the cube rose 50 mm and ended within 20 mm. The truth says more: it rose
    # as high as the hand did (120 mm; seeds 10-17: 119.85-120.31 mm, so 3 mm is ten times the widest
    # gap seen), so it did not slip in the fingers; and it was put down a few mm from the place (seeds
    # 10-17: median 0.63 mm, largest 2.23; the suite's 50 seeds: median 0.40, largest 2.3; an earlier
    # 100: largest 2.32). For the median of these 8 to pass 3 mm, four would have to land farther off
    # than any of those.
    at_least(ok, len(rs) - 1, lambda r: abs(r.lift_height_mm - HAND_RISE_MM) < 3.0, "rise with the hand")
    assert float(np.median([r.place_error_mm for r in ok])) < 3.0
    for r in ok:
        assert r.perception is not None and r.perception.position_error_mm < 2.0 and r.perception.yaw_error_deg < 1.0
        # It kept looking while it moved: at the scenario's rate, through a region of interest.
        assert r.perception_rate_hz == pytest.approx(cube_scenario.control.perception_rate_hz, rel=0.05)
        assert r.perception_frames > 20
        assert r.tracking_error_mm is not None and r.tracking_error_mm < 10.0
    first = at_least(
        ok, len(rs) - 1, lambda r: [a.outcome for a in r.attempts] == ["placed"], "place on the first attempt"
    )
    for r in first:
        assert _states(r) == PICK_STATES
    assert float(np.median([r.perception.position_error_mm for r in ok])) < 0.5
    assert float(np.median([r.tracking_error_mm for r in ok])) < 1.0


@pytest.mark.slow
def test_cylinder_is_picked_and_placed() -> None:
    rs = episodes("pick_cylinder", (0, 1, 2, 3))
    for r in at_least(rs, 3):
        assert r.perception.yaw_error_deg is None  # a cylinder has no yaw
        assert r.perception.position_error_mm < 2.0


def test_same_seed_same_result() -> None:
    pushed = load_scenario("pick_pushed")
    a = run_episode(pushed, 7).to_dict()
    b = run_episode(pushed, 7).to_dict()
    assert _strip_wall(a) == _strip_wall(b)
    assert a["disturbances"] and a["perception_frames"] > 20
    c = run_episode(pushed, 8).to_dict()
    assert c["perception"]["true_pose"] != a["perception"]["true_pose"]


def test_open_loop_looks_once() -> None:
    rs = episodes("pick_cube", (3, 4, 5), open_loop=True)
    for r in rs:
        assert r.open_loop and r.perception_rate_hz == 0.0  # no frame while it moved
    for r in at_least(rs, 2):
        # one look an attempt, and the last look's frames until two agree (the target has settled)
        assert len(r.attempts) + 2 <= r.perception_frames <= len(r.attempts) + 10


PUSHED_SEEDS = (0, 1, 2, 3)


@pytest.mark.slow
def test_push_is_noticed_before_the_gripper_closes() -> None:
    closed = episodes("pick_pushed", PUSHED_SEEDS, record_trace=True)
    at_least(closed, len(closed) - 1)
    noticed = at_least(closed, len(closed) - 1, lambda r: r.target_moves_detected >= 1, "notice the push")
    at_least(noticed, len(closed) - 1, lambda r: len(r.attempts) == 1 and r.tracking_error_mm < 3.0,
             "grasp it on the first attempt within 3 mm of the belief")  # fmt: skip
    # One look: it closes where the cube was (measured: 1 of 100 placed on the first attempt).
    opened = episodes("pick_pushed", PUSHED_SEEDS, open_loop=True)
    at_least(opened, len(opened) - 1, lambda r: r.attempts[0].outcome != "placed", "miss the first attempt")


def test_commanded_motion_within_ruckig_limits_across_retargets() -> None:
    """Over pushed episodes (re-targets mid-motion), the commanded velocity, acceleration and jerk
    never exceed the limits Ruckig was given, neither as Ruckig reports them nor by differences."""
    rs = episodes("pick_pushed", PUSHED_SEEDS, record_trace=True)
    for r in rs:
        t = r.trace
        tol = 1.0 + 1e-6
        assert np.all(np.abs(t.velocity) <= t.max_velocity * tol + 1e-9)
        assert np.all(np.abs(t.acceleration) <= t.max_acceleration * tol + 1e-9)
        assert np.all(np.abs(t.jerk) <= t.max_jerk * tol + 1e-9)
        dt = np.diff(t.time_s)[:, None]
        jerk_fd = np.diff(t.acceleration, axis=0) / dt
        assert np.all(np.abs(jerk_fd) <= np.maximum(t.max_jerk[1:], t.max_jerk[:-1]) * tol + 1e-6)
        acc_fd = np.diff(t.velocity, axis=0) / dt
        assert np.all(np.abs(acc_fd) <= np.maximum(t.max_acceleration[1:], t.max_acceleration[:-1]) * tol + 1e-6)
    assert sum(r.retargets for r in rs) >= 2


def test_last_5cm_of_descent_is_vertical_over_the_tracked_target() -> None:
    """The last 5 cm of every descent are straight down, above where the tracker put the target."""
    checked = 0
    for r in episodes("pick_cube", CUBE_SEEDS, record_trace=True):
        t = r.trace
        descend = np.array([s == "descend" for s in t.state])
        if not descend.any():
            continue
        grasp_z = t.setpoint[descend][-1, 2]
        last = descend & (t.tcp_true[:, 2] < grasp_z + 0.05)
        assert last.sum() > 20
        tcp, tracked = t.tcp_true[last, :2], t.tracked[last, :2]
        drift = np.linalg.norm(tcp - tcp[0], axis=1).max()
        # straight down (the hand follows the tracker, whose belief drifts by prediction while the
        # hand hides the target: seen 1.03 mm here on one seed of eight)
        assert drift < 1.5e-3, (r.seed, drift)
        # over the target as the tracker believed it when the last 5 cm began (the belief may drift
        # afterwards, by prediction alone, while the hand hides the target: seen up to 2 mm)
        assert np.linalg.norm(tcp[0] - tracked[0]) < 3e-3, r.seed
        checked += 1
    assert checked >= len(CUBE_SEEDS) - 1


@pytest.mark.slow
def test_slipping_object_is_retried_with_more_force() -> None:
    rs = episodes("pick_slippery", (0, 1, 2))
    # 20 N cannot hold the 1 kg steel cube: every first lift slips (by design, 100/100 measured).
    at_least(rs, len(rs), lambda r: r.attempts[0].outcome == "dropped while lifting", "slip on the first lift")
    for r in at_least(rs, len(rs) - 1):
        assert len(r.attempts) == 2  # held on the second (100/100 measured), not the third
        assert r.attempts[-1].grip_force_n > r.attempts[0].grip_force_n
        assert r.attempts[-1].lift_speed_scale < 1.0


def test_objects_settle_before_the_first_look(cube_scenario: Scenario) -> None:
    # Spawned 3 cm above the table: it falls and comes to rest before the robot looks.
    obj = cube_scenario.objects[0].model_copy(update={"position": (0.5, 0.0, 0.055), "position_range": None})
    r = run_episode(cube_scenario.model_copy(update={"objects": (obj,)}), 0)
    assert r.perception is not None
    assert r.perception.true_pose["position_m"][2] == pytest.approx(0.025, abs=1e-3)


def test_no_target_in_view_fails_in_perception(cube_scenario: Scenario) -> None:
    # The camera looks away from the table: the target is never seen; the episode names the stage.
    cam = cube_scenario.camera.model_copy(update={"look_at": (3.0, 0.0, 0.75)})
    sc = cube_scenario.model_copy(update={"camera": cam})
    r = run_episode(sc, 0)
    assert not r.success and r.failure.stage is Stage.PERCEPTION
    assert "colour" in r.failure.reason


def test_too_wide_object_fails_in_grasp_planning(cube_scenario: Scenario) -> None:
    obj = cube_scenario.objects[0].model_copy(update={"size": (0.09, 0.09, 0.05)})
    sc = cube_scenario.model_copy(update={"objects": (obj,)})
    r = run_episode(sc, 0)
    assert not r.success and r.failure.stage is Stage.GRASP_PLANNING


def test_simulated_time_budget_is_a_timeout(cube_scenario: Scenario) -> None:
    sc = cube_scenario.model_copy(update={"sim": cube_scenario.sim.model_copy(update={"max_sim_time_s": 2.0})})
    r = run_episode(sc, 0)
    assert not r.success and r.failure.stage is Stage.TIMEOUT
    assert r.sim_time_s == pytest.approx(2.0, abs=0.01)
    assert np.isfinite(r.perception.position_error_mm)
    assert r.attempts and r.attempts[-1].outcome == "failed"


@pytest.mark.slow
def test_motion_scales_slow_the_arm(cube_scenario: Scenario) -> None:
    slow = cube_scenario.model_copy(
        update={"motion": cube_scenario.motion.model_copy(update={"velocity_scale": 0.5, "acceleration_scale": 0.5})}
    )
    compared = 0
    for seed in (2, 3):
        fast, slowed = run_episode(cube_scenario, seed), run_episode(slow, seed)
        if fast.success and slowed.success and len(fast.attempts) == len(slowed.attempts) == 1:
            assert slowed.sim_time_s > fast.sim_time_s + 3.0
            compared += 1
    assert compared >= 1


def test_unreachable_place_ends_in_ik_with_the_reason(cube_scenario: Scenario) -> None:
    # Well formed, impossible, and run from Python without the loader's checks: a named stage, a reason.
    far = cube_scenario.model_copy(
        update={
            "place": cube_scenario.place.model_copy(update={"position": (1.05, 0.5)}),
            "table": cube_scenario.table.model_copy(update={"size": (2.4, 1.4)}),
        }
    )
    r = run_episode(far, 0)
    assert not r.success and r.failure.stage is Stage.IK
    assert "place pose out of reach" in r.failure.reason
