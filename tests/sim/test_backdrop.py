"""A fixed camera's whole view rendered over its backdrop (the still boxes rendered once) is the whole
render, pixel for pixel: colour and depth buffer, at moments through an expert's episode, in scenes
with a bin, a belt, a shelf's model and another robot."""

from __future__ import annotations

import numpy as np
import pytest

pytestmark = pytest.mark.sim


@pytest.mark.parametrize("scenario", ["pick_cube", "clear_bin", "pick_conveyor", "pick_shelf", "so101_pick_cube"])
def test_view_over_backdrop_is_the_whole_render(scenario: str) -> None:
    from pickdemo.envs.expert import ExpertPolicy
    from pickdemo.envs.record import make_env

    env = make_env(scenario, image_width=160)
    try:
        expert = ExpertPolicy(env)
        obs, _ = env.reset(seed=3)
        world = env.episode.world
        fixed = [c for c in world.cameras.values() if not c.on_hand]
        assert fixed and world.scene.still_boxes
        compared = 0
        for k in range(361):
            if k % 60 == 0:
                for cam in fixed:
                    for w, h in ((160, 120), (97, 61)):
                        rgb, zbuf = cam.whole_view(world.scene, w, h)
                        rgb_all, zbuf_all = cam.whole_view(world.scene, w, h, backdrop=False)
                        assert np.array_equal(zbuf, zbuf_all), (k, w)
                        assert np.array_equal(rgb, rgb_all), (k, w, int((rgb != rgb_all).any(-1).sum()))
                        compared += 1
            obs, _, terminated, truncated, _ = env.step(expert(obs))
            if terminated or truncated:
                break
        assert compared >= 4
    finally:
        env.close()
