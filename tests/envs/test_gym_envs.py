"""The Gymnasium environments: Gymnasium's own checker on every id and mode, seeded resets, random
actions, bad actions refused in words, the expert through the env, the vector env."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import pickdemo.envs  # noqa: E402,F401 - registers the ids
from pickdemo.envs import ENV_IDS, OBS_MODES, ExpertPolicy  # noqa: E402

pytestmark = pytest.mark.sim

MODES = [(i, o, c) for i in ENV_IDS for o in OBS_MODES for c in ("joint_pos", "ee_delta")]


@pytest.mark.parametrize(("env_id", "obs_mode", "control_mode"), MODES)
@pytest.mark.slow
def test_check_env_passes(env_id: str, obs_mode: str, control_mode: str) -> None:
    env = gym.make(env_id, obs_mode=obs_mode, control_mode=control_mode, render_mode="rgb_array")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (its advice on infinite bounds and on a joint-limit action space)
        check_env(env.unwrapped)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8 and frame.std() > 0
    env.close()


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("env_id", list(ENV_IDS))
def test_a_seeded_reset_gives_the_same_scene_and_the_same_steps(env_id: str) -> None:
    one, two = gym.make(env_id, obs_mode="privileged"), gym.make(env_id, obs_mode="privileged")
    for seed in (3, 4):
        o1, _ = one.reset(seed=seed)
        o2, _ = two.reset(seed=seed)
        assert _same(o1, o2)
        rng = np.random.default_rng(seed)
        for _ in range(15):
            a = rng.uniform(one.action_space.low, one.action_space.high)
            assert _same(one.step(a)[0], two.step(a)[0])
    assert not np.array_equal(one.reset(seed=5)[0]["objects_true_pose"], one.reset(seed=6)[0]["objects_true_pose"])
    one.close()
    two.close()


@pytest.mark.parametrize("env_id", list(ENV_IDS))
@pytest.mark.parametrize("control_mode", ["joint_pos", "ee_delta"])
@pytest.mark.slow
def test_a_thousand_random_actions_run_within_the_robots_limits(env_id: str, control_mode: str) -> None:
    env = gym.make(env_id, control_mode=control_mode)
    env.action_space.seed(0)
    env.reset(seed=0)
    ends = []
    for _ in range(1000):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert env.observation_space.contains(obs)
        if terminated or truncated:
            ends.append(info["result"])
            env.reset()
    env.close()
    # no action the robot refuses: every command passed the limiter; no episode ends in the reflex or an error
    for result in ends:
        assert result.failure is None or result.failure.stage.value not in ("reflex", "error"), result.failure
        assert not result.limit_exceedances


def test_the_observation_is_the_robots_after_the_step() -> None:
    env = gym.make("pickdemo/Pick-v0", agent_rate_hz=None)
    obs, info = env.reset(seed=0)
    assert obs["time"][0] == info["time_s"]
    for _ in range(3):
        obs, _, _, _, info = env.step(np.append(obs["joint_pos"], 1.0))
        assert obs["time"][0] == info["time_s"] > 0  # not the tick's start: the agent acts on what is now
    env.close()


def test_perception_and_images_never_move_the_robot() -> None:
    """The same actions give the same physics whether the loop looks, and whatever the agent observes."""
    runs = []
    for kwargs in ({"perception": False, "obs_mode": "privileged"}, {"obs_mode": "privileged"}, {"obs_mode": "rgbd"}):
        env = gym.make("pickdemo/Pick-v0", control_mode="ee_delta", **kwargs)
        obs, _ = env.reset(seed=2)
        rng = np.random.default_rng(0)
        for _ in range(20):
            obs, *_ = env.step(rng.uniform(-1, 1, 5))
        runs.append((obs["joint_pos"], obs["target_tracked"], obs.get("objects_true_pose")))
        env.close()
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][2], runs[1][2])
    assert np.array_equal(runs[0][0], runs[2][0])
    assert runs[0][1][0] == 0.0 and runs[1][1][0] == 1.0  # blind: no track; looking: the target tracked


def test_bad_actions_are_refused_in_words_and_the_env_goes_on() -> None:
    env = gym.make("pickdemo/Pick-v0", control_mode="ee_delta")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="not finite"):
        env.step(np.array([0.0, np.nan, 0.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match=r"action\[2\] = 3.0 is outside the action space \[-1.0, 1.0\]"):
        env.step(np.array([0.0, 0.0, 3.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(7))
    obs, *_ = env.step(np.zeros(5))
    assert obs["time"][0] > 0
    env.close()


def test_a_float32_action_at_its_bound_is_taken() -> None:
    """Policies and datasets are float32: the joint limit 2.8973 comes as 2.8973000049591064, and is the
    limit; the action space is float32 (as Gymnasium and Stable-Baselines3 recommend)."""
    env = gym.make("pickdemo/Pick-v0", control_mode="joint_pos")
    env.reset(seed=0)
    assert env.action_space.dtype == np.float32
    high = env.action_space.high.astype(np.float32)
    assert env.action_space.contains(high)
    assert high[0] > env.unwrapped.robot.limits.max_position_rad[0]  # (float32 rounds it up)
    obs, *_ = env.step(high)  # taken, clipped to the limit
    with pytest.raises(ValueError, match=r"action\[0\] = 2.9\d* is outside the action space"):
        env.step(np.append(2.9, high[1:]))
    env.close()


def test_bad_arguments_are_refused_in_words() -> None:
    with pytest.raises(ValueError, match="obs_mode='depth'"):
        gym.make("pickdemo/Pick-v0", obs_mode="depth")
    with pytest.raises(ValueError, match="agent_rate_hz=7"):
        gym.make("pickdemo/Pick-v0", agent_rate_hz=7)
    with pytest.raises(ValueError, match="task 'clear'"):
        gym.make("pickdemo/Pick-v0", scenario="clear_pile")
    with pytest.raises(ValueError, match="agent_rate_hz=None"):
        ExpertPolicy(gym.make("pickdemo/Pick-v0"))


@pytest.mark.slow
def test_the_expert_succeeds_through_the_env_on_most_seeds() -> None:
    env = gym.make("pickdemo/Pick-v0", scenario="pick_cube", agent_rate_hz=None)
    expert = ExpertPolicy(env)
    outcomes = []
    for seed in range(3):
        obs, info = env.reset(seed=seed)
        total = 0.0
        while True:
            obs, reward, terminated, truncated, info = env.step(expert(obs))
            total += reward
            if terminated or truncated:
                break
        outcomes.append(info["is_success"])
        assert info["success"] == info["is_success"] == info["result"].success
        assert total == float(info["is_success"])  # sparse: 1 on the step it is done
    env.close()
    assert sum(outcomes) >= 2, outcomes


def test_the_async_vector_env_steps() -> None:
    envs = gym.make_vec("pickdemo/Pick-v0", num_envs=2, vectorization_mode="async")
    obs, info = envs.reset(seed=[0, 1])
    assert obs["joint_pos"].shape[0] == 2
    for _ in range(5):
        obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample())
    assert obs["time"].shape == (2, 1) and np.all(obs["time"] > 0)
    envs.close()


@pytest.mark.slow
def test_a_suction_robot_in_the_env_sucks_and_reads_its_vacuum() -> None:
    """The UR5 with a suction cup: Gymnasium's checker, its vacuum in the observation and in the
    dataset's state, the gripper's number its valve, and the expert's picks through the env."""
    from pickdemo.envs.record import state_names, state_vector

    env = gym.make("pickdemo/Pick-v0", scenario="suction_pick_box", agent_rate_hz=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        check_env(env.unwrapped)
    expert = ExpertPolicy(env)
    outcomes, sucked = [], []
    for seed in range(2):
        obs, info = env.reset(seed=seed)
        assert obs["vacuum"].shape == (1,) and len(state_vector(obs)) == len(state_names(env.unwrapped))
        while True:
            action = expert(obs)
            obs, reward, terminated, truncated, info = env.step(action)
            sucked.append((action[-1] < 0.0, float(obs["vacuum"][0])))
            if terminated or truncated:
                break
        outcomes.append(info["is_success"])
    env.close()
    assert sum(outcomes) >= 1, outcomes
    assert any(on and kpa > 30.0 for on, kpa in sucked)  # sealed while the valve was on
    assert all(kpa == 0.0 for on, kpa in sucked if not on)  # (the valve shut: no vacuum)
