"""Gymnasium environments of pickdemo's scenarios, and its skill as an expert policy.

``import pickdemo.envs`` registers:

- ``pickdemo/Pick-v0``: a pick (default scenario ``pick_cube``; any scenario whose task is ``pick``);
- ``pickdemo/Clear-v0``: a clear round (default ``clear_pile``; any scenario whose task is ``clear``).

Made with ``gymnasium.make(id, scenario=..., robot=..., obs_mode=..., control_mode=...,
render_mode=..., agent_rate_hz=..., reward_mode=...)`` (:class:`~pickdemo.envs.pick_env.PickEnv`).
:class:`~pickdemo.envs.expert.ExpertPolicy` is pickdemo's closed-loop skill acting through the same
actions. Needs the ``gym`` extra (``pip install "pickdemo[gym]"``).
"""

from __future__ import annotations

import gymnasium as gym

from pickdemo.envs.expert import ExpertPolicy
from pickdemo.envs.pick_env import OBS_MODES, REWARD_MODES, PickEnv

ENV_IDS = {"pickdemo/Pick-v0": ("pick", "pick_cube"), "pickdemo/Clear-v0": ("clear", "clear_pile")}

for _id, (_task, _scenario) in ENV_IDS.items():
    if _id not in gym.registry:
        gym.register(_id, entry_point="pickdemo.envs.pick_env:PickEnv", kwargs={"task": _task, "scenario": _scenario})

__all__ = ["ENV_IDS", "OBS_MODES", "REWARD_MODES", "ExpertPolicy", "PickEnv"]
