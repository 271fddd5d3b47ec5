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


def test_images_of_a_size_unlike_the_cameras_aspect_are_cut_from_its_view_about_the_middle() -> None:
    """A follower's 4:3 images from a camera of another aspect (the SO-101's hand camera): rendered at the
    camera's aspect over the whole of them, then cut (square pixels, as a real camera's narrower mode)."""
    from pickdemo.envs.record import make_env

    wide = make_env("so101_pick_cube", image_width=64)
    cut = make_env("so101_pick_cube", image_width=64, image_height=48)
    try:
        wide.reset(seed=0)
        cut.reset(seed=0)
        w, c = wide.camera_images(), cut.camera_images()
        for name in w:
            assert c[name][0].shape == (48, 64, 3) and c[name][1].shape == (48, 64)
        wh, ww = w["wrist_camera"][0].shape[:2]
        assert ww == 64 and wh < 48  # (the hand camera is wider than 4:3: its view is rendered wider, then cut)
        rendered = cut._rendered_sizes()["wrist_camera"]
        assert rendered[1] == 48 and rendered[0] > 64
        with pytest.raises(ValueError, match="image_height=48: 16 to 4096 pixels, with an image_width"):
            make_env("so101_pick_cube", image_height=48)
    finally:
        wide.close()
        cut.close()
