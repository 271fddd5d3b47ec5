"""robomimic's interface to a pickdemo environment (:mod:`pickdemo.envs.robomimic_env`): made from an HDF5
dataset's ``env_args`` as robomimic makes one, its observations the file's keys and shapes, and the
file's actions stepping it to the demonstration's success. Needs robomimic (not a dependency: skipped
without it; checked with robomimic 0.3.0, whose ``train.py`` ran its rollouts through it)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("robomimic")
h5py = pytest.importorskip("h5py")

import robomimic.utils.env_utils as env_utils  # noqa: E402

from pickdemo.apps.cli import main  # noqa: E402
from pickdemo.envs import robomimic_env  # noqa: E402

pytestmark = pytest.mark.sim


def test_robomimic_makes_the_environment_of_the_files_env_args_and_its_actions_succeed(tmp_path: Path) -> None:
    out = tmp_path / "h5"
    assert main(["demos", "pick_cube", "--seeds", "0", "--out", str(out), "--format", "hdf5", "--no-progress"]) == 0
    with h5py.File(out / "demos.hdf5") as f:
        env_meta = json.loads(f["data"].attrs["env_args"])
        g = f["data"]["demo_0"]
        actions, shapes = g["actions"][:], {k: v.shape[1:] for k, v in g["obs"].items()}
    env_utils.get_env_class = robomimic_env._get_env_class  # (as the launcher does)
    env = env_utils.create_env_from_metadata(env_meta=env_meta)
    assert isinstance(env, robomimic_env.PickdemoEnv)
    obs = env.reset()
    assert {k: v.shape for k, v in obs.items()} == shapes
    env.env.reset(seed=0)  # (the demonstration's seed)
    for a in actions:
        env.step(a)
        if env.is_done():
            break
    assert env.is_success()["task"]
    # a policy's image inputs (their modalities registered, as train.py registers them): processed as
    # robomimic's own environments process them, (C, H, W) in [0, 1]
    import robomimic.utils.obs_utils as obs_utils

    obs_utils.initialize_obs_modality_mapping_from_dict(
        {"low_dim": ["state"], "rgb": ["camera_rgb"], "depth": ["camera_depth"]}
    )
    seen = env.reset()
    h, w, _ = shapes["camera_rgb"]
    assert seen["camera_rgb"].shape == (3, h, w) and seen["camera_depth"].shape == (1, h, w)
    assert seen["camera_rgb"].dtype == np.float32 and 0.0 <= seen["camera_rgb"].min() <= seen["camera_rgb"].max() <= 1.0
