"""Moving targets: the belt, the intercept, and picks off a running conveyor (the tracker on a belt
is in ``test_tracker``).

The pure parts (the belt's speed schedule, the scenario's rules, Ruckig's intercept) run without a
simulator; the rest (marked ``sim``) run the belt and whole episodes.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from episodes import at_least, episodes

from pickdemo import Stage, run_episode
from pickdemo.core.result import WALL_CLOCK_KEYS
from pickdemo.motion.online import OnlineMotion
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.scenario.load import ScenarioError, load_scenario, parse_scenario
from pickdemo.skills.pick import MachineParams

ROBOT = robot_named()

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"


def _conveyor_toml(**edits: str) -> str:
    text = (SCENARIOS / "pick_conveyor.toml").read_text()
    for old, new in edits.items():
        assert old in text, old
        text = text.replace(old, new)
    return text


def _load(tmp_path: Path, text: str):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return load_scenario(path)


# ------------------------------------------------------------------------------------- scenario
def test_belt_speed_changes_ramp_at_half_a_g_twentieth() -> None:
    import tomllib

    data = tomllib.loads(_conveyor_toml())
    data["conveyor"]["speed_changes"] = [[1.0, 0.10], [3.0, 0.0]]
    belt = parse_scenario(data).conveyor
    assert belt.speed_at(0.5) == pytest.approx(0.05)
    assert belt.speed_at(1.05) == pytest.approx(0.075)  # 0.5 m/s^2
    assert belt.speed_at(1.2) == pytest.approx(0.10)
    assert belt.speed_at(3.1) == pytest.approx(0.05)
    assert belt.speed_at(10.0) == 0.0


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        ({"position = [0.25, 0.3]": "position = [0.5, 0.3]"}, "place.position: (0.500, 0.300) m is on the belt"),
        ({"[[0.45, 0.55], [-0.35, -0.25]]": "[[0.30, 0.55], [-0.35, -0.25]]"}, "straddles the belt's edge"),
        ({"x_range_m = [0.35, 0.65]": "x_range_m = [0.65, 0.35]"}, "conveyor: x_range_m must be [min, max]"),
        ({"y_range_m = [-0.6, 0.6]": "y_range_m = [-0.6, 0.9]"}, "conveyor: its strip"),
        ({"y_range_m = [-0.6, 0.6]": "y_range_m = [-0.6, 0.6]\nspeed_changes = [[4.0, 0.1], [2.0, 0.2]]"},
         "increasing time order"),
        ({"y_range_m = [-0.6, 0.6]": "y_range_m = [-0.6, 0.6]\nspeed_changes = [[4.0, 0.9]]"},
         "conveyor.speed_changes"),
        ({"velocity_m_s = [0.0, 0.05]": "velocity_m_s = [0.0, 0.0]\nspeed_changes = [[1.0, 0.1]]"},
         "need a non-zero velocity_m_s"),
        ({"velocity_m_s = [0.0, 0.05]": "velocity_m_s = [0.0, 0.05]\nspeed = 0.1"}, "conveyor.speed: unknown key"),
    ],
)  # fmt: skip
def test_bad_conveyor_is_one_line_naming_the_key(tmp_path: Path, edit: dict, message: str) -> None:
    with pytest.raises(ScenarioError) as info:
        _load(tmp_path, _conveyor_toml(**edit))
    text = str(info.value)
    assert message in text and "\n" not in text


# The belt's body (its slab) is BELT_REWIND_M longer than its strip and slides along the belt's
# direction: a place on that overhang is carried away (issue 17: 0/10 on a short or diagonal belt).
SHORT = {"y_range_m = [-0.6, 0.6]": "y_range_m = [-0.45, 0.1]"}  # the strip ends at y 0.1; its slab at 0.3
DIAGONAL = {
    "velocity_m_s = [0.0, 0.05]": "velocity_m_s = [0.035, 0.035]",
    "y_range_m = [-0.6, 0.6]": "y_range_m = [-0.45, 0.0]",
}


@pytest.mark.parametrize(
    ("edit", "place", "refused"),
    [
        (SHORT, "[0.5, 0.2]", True),  # past the strip's end, on the overhang
        (SHORT, "[0.5, 0.36]", False),  # past the overhang, by more than the cube's footprint
        (DIAGONAL, "[0.7, 0.05]", True),  # off the strip's corner, where the diagonal slab slides
        (DIAGONAL, "[0.45, 0.3]", False),
        ({**SHORT, "velocity_m_s = [0.0, 0.05]": "velocity_m_s = [0.0, -0.05]",
          "[[0.45, 0.55], [-0.35, -0.25]]": "[[0.45, 0.55], [-0.05, 0.05]]"}, "[0.5, -0.6]", True),  # the other way
    ],
)  # fmt: skip
def test_place_on_the_belts_overhang_is_refused(tmp_path: Path, edit: dict, place: str, refused: bool) -> None:
    text = _conveyor_toml(**edit, **{"position = [0.25, 0.3]": f"position = {place}"})
    if not refused:
        assert _load(tmp_path, text).conveyor is not None
        return
    with pytest.raises(ScenarioError) as info:
        _load(tmp_path, text)
    msg = str(info.value)
    assert "\n" not in msg and "place.position: " in msg and "is on the belt's overhang" in msg, msg


def test_object_on_the_belts_overhang_is_refused(tmp_path: Path) -> None:
    other = '\n[[objects]]\nname = "other"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.1, 0.1, 0.9]\n'
    with pytest.raises(ScenarioError, match=r"objects\.other: .* reaches onto the belt's overhang"):
        _load(tmp_path, _conveyor_toml(**SHORT) + other + "position = [0.5, 0.2]\n")


@pytest.mark.sim
def test_the_checks_keep_off_the_footprint_the_simulated_slab_sweeps() -> None:
    """One geometry (ConveyorSpec.slab) for the simulator and the checks: the slab PyBullet builds
    lies where the checks say, at both ends of its travel."""
    import pybullet as p
    import tomllib
    from pybullet_utils.bullet_client import BulletClient

    from pickdemo.scenario.checks import belt_sweep_mm
    from pickdemo.sim.conveyor import Belt

    data = tomllib.loads(_conveyor_toml(**DIAGONAL))
    spec = parse_scenario(data).conveyor
    slab = spec.slab()
    assert slab.direction == pytest.approx((2**-0.5, 2**-0.5))
    client = BulletClient(connection_mode=p.DIRECT)
    try:
        belt = Belt(client, spec)
        assert belt.slab == slab
        for q in slab.travel_m:
            client.resetJointState(belt.body, 0, q, 0.0)
            lo, hi = client.getAABB(belt.body, 0)
            corners = np.array(slab.corners_at(q))
            assert lo[:2] == pytest.approx(corners.min(axis=0), abs=0.03)  # PyBullet's AABB margin
            assert hi[:2] == pytest.approx(corners.max(axis=0), abs=0.03)
    finally:
        client.disconnect()
    sweep = belt_sweep_mm(spec).reshape(-1, 2) / 1e3
    every = np.array(slab.swept_corners())
    assert sweep.min(axis=0) == pytest.approx(every.min(axis=0), abs=1e-6)
    assert sweep.max(axis=0) == pytest.approx(every.max(axis=0), abs=1e-6)
    (x0, x1), (y0, y1) = spec.x_range_m, spec.y_range_m
    grow = 0.2 * 2**-0.5  # the rewind's share along x and y, at each end of the travel
    assert every.min(axis=0) == pytest.approx((x0 - grow, y0 - grow)) and every.max(axis=0) == pytest.approx(
        (x1 + grow + 0.035 * 2**0.5 / 240 * 2**-0.5, y1 + grow + 0.035 * 2**0.5 / 240 * 2**-0.5)
    )


def test_objects_on_the_belt_rest_on_its_top(tmp_path: Path) -> None:
    from pickdemo.core.streams import spawn_rngs
    from pickdemo.scenario.layout import sample_layout

    sc = load_scenario("pick_conveyor")
    (cube,) = sample_layout(sc, spawn_rngs(0)["layout"])
    assert cube.pose.position[2] == pytest.approx(sc.conveyor.height_m + 0.025)
    assert sc.surface_z(*sc.place.position) == 0.0


# ----------------------------------------------------------------------------- intercept (Ruckig)
@pytest.fixture(scope="module")
def motion() -> OnlineMotion:
    return OnlineMotion(kinematics_of(ROBOT), ROBOT.home_q, 1.0 / 120.0, MachineParams().free)


@pytest.mark.parametrize("speed", [0.05, 0.1, 0.2])
def test_intercept_is_the_soonest_meeting(motion: OnlineMotion, speed: float) -> None:
    x4 = np.array([0.52, -0.33, 0.135, 0.35])
    vel4 = np.array([0.0, speed, 0.0, 0.0])
    t = motion.intercept(lambda s: x4 + vel4 * s, vel4)
    assert t is not None and 1.0 < t < 2.5
    assert motion.time_to(x4 + vel4 * t, vel4) <= t + 1e-3  # the hand can be there by then
    earlier = t - 0.01
    assert motion.time_to(x4 + vel4 * earlier, vel4) > earlier  # and not 10 ms sooner


def test_intercept_gives_up_on_a_target_faster_than_the_hand(motion: OnlineMotion) -> None:
    x4 = np.array([0.52, -0.33, 0.135, 0.35])
    vel4 = np.array([0.0, -0.29, 0.0, 0.0])  # running away, nearly as fast as the hand (0.3 m/s an axis)
    assert motion.intercept(lambda s: x4 + vel4 * s, vel4, latest_s=3.0) is None


def test_hand_arrives_with_the_target_and_moves_with_it() -> None:
    m = OnlineMotion(kinematics_of(ROBOT), ROBOT.home_q, 1.0 / 120.0, MachineParams().free)
    x4 = np.array([0.52, -0.33, 0.135, 0.35])
    vel4 = np.array([0.0, 0.1, 0.0, 0.0])
    t = m.intercept(lambda s: x4 + vel4 * s, vel4)
    m.set_target(x4 + vel4 * t, velocity=vel4, arrive_in_s=t)
    n = int(round(t * 120))
    for _ in range(n):
        m.step()
    assert m.finished
    assert np.allclose(m.setpoint, x4 + vel4 * n / 120.0, atol=2e-3)
    for _ in range(60):  # and carries on with it: half a second later, 5 cm on
        sample = m.step()
    assert np.allclose(sample.velocity, vel4, atol=1e-9)
    assert np.allclose(m.setpoint, x4 + vel4 * (n + 60) / 120.0, atol=2e-3)


# ---------------------------------------------------------------------------- the belt (simulator)
@pytest.mark.sim
@pytest.mark.parametrize("speed", [0.05, 0.2])
def test_belt_carries_a_cube_at_its_speed_by_friction(tmp_path: Path, speed: float) -> None:
    from pickdemo.core.streams import spawn_rngs
    from pickdemo.scenario.layout import sample_layout
    from pickdemo.sim.scene import Scene

    sc = _load(tmp_path, _conveyor_toml(**{"velocity_m_s = [0.0, 0.05]": f"velocity_m_s = [0.0, {speed}]"}))
    with Scene(sc, sample_layout(sc, spawn_rngs(0)["layout"])) as scene:
        scene.settle(480)
        scene.start_belt()
        start = scene.true_pose("cube").position
        scene.step(480)  # 2 s
        end = scene.true_pose("cube").position
        assert end[1] - start[1] == pytest.approx(2.0 * speed, abs=1e-3)
        assert abs(end[0] - start[0]) < 2e-4 and abs(end[2] - start[2]) < 2e-4  # rides flat on it
        assert scene.belt.rewinds == (1 if speed > 0.1 else 0)  # the slab slid back unseen (every 0.2 m)


# ------------------------------------------------------------------------------------ episodes


@pytest.mark.sim
@pytest.mark.parametrize("name", ["pick_conveyor", "pick_conveyor_rush"])
@pytest.mark.slow
def test_cube_is_picked_off_a_running_belt(name: str) -> None:
    rs = episodes(name, (0, 1, 2))
    for r in at_least(rs, 2, lambda r: [a.outcome for a in r.attempts] == ["placed"], "place it at the first attempt"):
        assert r.success, r.failure
        assert any("moving with it" in p.message for p in r.phases)  # met where it was going, at its speed
        assert r.tracking_error_mm is not None and r.tracking_error_mm < 2.0  # the tracker's belief at the grasp
        assert r.place_error_mm < 5.0
        assert r.perception_rate_hz == pytest.approx(10.0, rel=0.05)
    assert not any(r.target_off_table for r in rs)


@pytest.mark.sim
@pytest.mark.slow
def test_belt_speeding_up_mid_approach_is_followed() -> None:
    rs = episodes("pick_conveyor_speed_change", (0, 1, 2))
    for r in at_least(rs, 2):
        assert r.tracking_error_mm < 2.0


@pytest.mark.sim
def test_open_loop_closes_where_the_cube_was() -> None:
    # One look: it closes where the cube was seen, and the belt has carried it on (0/100 placed, measured).
    rs = episodes("pick_conveyor", (0, 1, 2), open_loop=True)
    assert not any(r.attempts and r.attempts[0].outcome == "placed" for r in rs)
    at_least(rs, 1, lambda r: bool(r.attempts) and r.attempts[0].outcome == "missed", "miss the first attempt")


@pytest.mark.sim
def test_target_too_fast_to_meet_in_reach_fails_by_name(tmp_path: Path) -> None:
    sc = _load(tmp_path, _conveyor_toml(**{"velocity_m_s = [0.0, 0.05]": "velocity_m_s = [0.0, 0.45]"}))
    r = run_episode(sc, 0)
    assert not r.success and r.failure.stage is Stage.IK
    assert "leaves the arm's reach" in r.failure.reason or "too fast" in r.failure.reason
    assert r.diagnosis == "not_committed"


@pytest.mark.sim
@pytest.mark.slow
def test_conveyor_episodes_are_the_same_with_one_or_two_workers() -> None:
    from pickdemo.apps.bench import Job, run_bench
    from pickdemo.apps.executors import LocalExecutor
    from pickdemo.scenario.load import resolve_scenario_path

    path = str(resolve_scenario_path("pick_conveyor_fast"))
    jobs = [Job(path, "pick_conveyor_fast", s) for s in (3, 8)]

    def stripped(results: list[dict]) -> list[str]:
        return sorted(json.dumps({k: v for k, v in r.items() if k not in WALL_CLOCK_KEYS}, sort_keys=True)
                      for r in results)  # fmt: skip

    one = run_bench(jobs, LocalExecutor(1), progress=False).results
    two = run_bench(jobs, LocalExecutor(2), progress=False).results
    assert stripped(one) == stripped(two)
