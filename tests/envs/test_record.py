"""Recording builds the environment's observation only at a dataset frame's first tick
(:meth:`PickEnv.advance` between): its rows must be those of the expert stepped through ``env.step``
every tick, as any user would run it."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.sim


class Rows:
    def __init__(self) -> None:
        self.rows = []

    def row(self, row) -> None:  # noqa: ANN001 - a Row
        self.rows.append(row)


@pytest.mark.parametrize("seed", [0, 1])
def test_recorded_rows_are_those_of_the_expert_stepped_every_tick(seed: int) -> None:
    from pickdemo.envs.expert import ExpertPolicy
    from pickdemo.envs.record import make_env, record_episode, state_vector

    stride = 12
    env = make_env("pick_cube", image_width=64)
    try:
        sink = Rows()
        recorded = record_episode(env, seed, stride, sink, images=False)
        expert = ExpertPolicy(env)
        obs, _ = env.reset(seed=seed)
        states, actions, info = [], [], {}
        for k in range(len(sink.rows) * stride):
            if k % stride == 0:
                states.append(state_vector(obs))
            actions.append(expert(obs))
            obs, _, terminated, truncated, info = env.step(actions[-1])
            if terminated or truncated:
                break
        assert recorded.ticks == len(actions) and recorded.success == info["result"].success
        assert len(states) == len(sink.rows)
        for k, row in enumerate(sink.rows):
            assert np.array_equal(row.state, states[k])
            assert np.array_equal(np.array(row.ticks), np.array(actions[k * stride : (k + 1) * stride]))
    finally:
        env.close()
