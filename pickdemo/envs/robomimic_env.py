"""A pickdemo environment as robomimic 0.3 runs one (its ``EnvBase``), so that robomimic's ``train.py``
makes the environment a ``pickdemo demos --format hdf5`` file's ``env_args`` describe and runs its
rollouts there; and the launcher that lets it: ``python -m pickdemo.envs.robomimic_env --config CFG``.

robomimic 0.3 builds a ``type: 2`` (Gym) environment with its ``EnvGym``, written for the old ``gym``
API and MuJoCo's simulator, and has no way to register another class: the launcher hands robomimic
this one for type 2 (in ``robomimic.utils.env_utils.get_env_class``), then runs its ``train.py``.
Observations as the file holds them: ``state`` (:func:`~pickdemo.envs.record.state_vector`), each
camera's ``<camera>_rgb`` and ``<camera>_depth`` (H, W, 1) as a share of its far plane; those a
policy takes as images processed for it as robomimic's own environments process them (with
``postprocess_visual_obs``: (C, H, W) in [0, 1]; measured: without, a BC policy on the images stopped
its first rollout on their shape). Each episode
is reset to the next seed from 1,000,000 (none a dataset records by default). Needs robomimic (not a
dependency of pickdemo: install it beside it)."""

from __future__ import annotations

import runpy
import sys

import gymnasium as gym
import numpy as np
import robomimic.envs.env_base as env_base
import robomimic.utils.env_utils as env_utils
import robomimic.utils.obs_utils as obs_utils

import pickdemo.envs  # noqa: F401 - (registers the environments' ids)
from pickdemo.envs.record import state_vector

#: The first seed of a rollout's episodes (each next one a seed on)
FIRST_SEED = 1_000_000


class PickdemoEnv(env_base.EnvBase):
    """One pickdemo environment (``gym.make(env_name, **env_kwargs)``) behind robomimic's interface."""

    def __init__(
        self, env_name: str, render: bool = False, render_offscreen: bool = False, use_image_obs: bool = False,
        postprocess_visual_obs: bool = True, **kwargs,
    ) -> None:  # fmt: skip
        self._env_name, self._kwargs = env_name, dict(kwargs)
        self.postprocess_visual_obs = postprocess_visual_obs
        self.env = gym.make(env_name, **kwargs).unwrapped
        self.far_m = {name: float(spec.far_m) for name, spec in self.env.camera_specs().items()}
        self._seed = FIRST_SEED - 1
        self._obs: dict | None = None
        self._reward, self._done, self._success = 0.0, False, False

    def _observation(self, obs: dict) -> dict:
        out = {"state": state_vector(obs).astype(np.float64)}
        for name, far in self.far_m.items():
            if f"{name}_rgb" in obs:
                out[f"{name}_rgb"] = obs[f"{name}_rgb"]
                out[f"{name}_depth"] = (np.asarray(obs[f"{name}_depth"], dtype=np.float32) / far)[..., None]
        if self.postprocess_visual_obs:  # as robomimic's own environments do: a policy's images (C, H, W) in [0, 1]
            for key in out:
                if key in (obs_utils.OBS_KEYS_TO_MODALITIES or {}) and any(
                    obs_utils.key_is_obs_modality(key=key, obs_modality=m) for m in ("rgb", "depth")
                ):  # fmt: skip
                    out[key] = obs_utils.process_obs(obs=out[key], obs_key=key)
        return out

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(np.asarray(action, dtype=np.float32))
        self._obs, self._reward, self._done = obs, float(reward), bool(terminated or truncated)
        self._success = bool(info.get("is_success", False))
        return self._observation(obs), self._reward, self._done, info

    def reset(self) -> dict:
        self._seed += 1
        self._obs, _ = self.env.reset(seed=self._seed)
        self._reward, self._done, self._success = 0.0, False, False
        return self._observation(self._obs)

    def reset_to(self, state: dict) -> dict:
        raise NotImplementedError("a pickdemo episode is reset by its seed, not to a state")

    def render(self, mode: str = "human", height: int | None = None, width: int | None = None, camera_name=None):  # noqa: ANN001, ANN201
        raise NotImplementedError("render with the environment's own render_mode")

    def get_observation(self) -> dict:
        assert self._obs is not None
        return self._observation(self._obs)

    def get_state(self) -> dict:
        return {"states": self.env.episode.world.scene.state()}

    def get_reward(self) -> float:
        return self._reward

    def get_goal(self) -> dict:
        raise NotImplementedError

    def set_goal(self, **kwargs) -> None:  # noqa: ANN003
        raise NotImplementedError

    def is_done(self) -> bool:
        return self._done

    def is_success(self) -> dict:
        return {"task": self._success}

    @property
    def action_dimension(self) -> int:
        return int(self.env.action_space.shape[0])

    @property
    def name(self) -> str:
        return self._env_name

    @property
    def type(self) -> int:
        return env_base.EnvType.GYM_TYPE

    def serialize(self) -> dict:
        return {"env_name": self.name, "type": self.type, "env_kwargs": self._kwargs}

    @classmethod
    def create_for_data_processing(
        cls, env_name: str, camera_names, camera_height, camera_width, reward_shaping, **kwargs
    ):  # noqa: ANN001, ANN003, ANN206
        raise NotImplementedError

    @property
    def rollout_exceptions(self) -> tuple:
        return ()


def _get_env_class(env_meta=None, env_type=None, env=None):  # noqa: ANN001, ANN202
    """robomimic's ``get_env_class``, with this class for its Gym type."""
    if env_utils.get_env_type(env_meta=env_meta, env_type=env_type, env=env) == env_base.EnvType.GYM_TYPE:
        return PickdemoEnv
    return _robomimic_get_env_class(env_meta=env_meta, env_type=env_type, env=env)


_robomimic_get_env_class = env_utils.get_env_class


def main(argv: list[str] | None = None) -> None:
    """robomimic's ``train.py`` with its arguments, pickdemo's environments for the Gym type."""
    env_utils.get_env_class = _get_env_class
    sys.argv = ["train", *(sys.argv[1:] if argv is None else argv)]
    runpy.run_module("robomimic.scripts.train", run_name="__main__")


if __name__ == "__main__":
    main()
