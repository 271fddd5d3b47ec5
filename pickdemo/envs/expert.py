"""pickdemo's closed-loop pick skill as a policy of the environments (:class:`ExpertPolicy`).

The expert is the skill ``bench`` runs (:class:`~pickdemo.skills.pick.PickMachine`, or a clear
round's sequencer), told what it is told there. It acts only through the environment's actions, on
the observation it is given, and it looks through the environment's cameras: the environment makes
it the pilot's eye (:mod:`pickdemo.envs.pilot`), so its frames are the ones it asks for, at the
scenario's perception rate and latency, and its estimates reach it before it decides each tick.
It decides every control tick, as in ``bench``: make the environment with ``agent_rate_hz=None``.
In ``joint_pos`` each action is the skill's joint command and gripper; in ``ee_delta`` it is the
nearest displacement of a hand pointing down (grasps from any side are not expressible there).
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.interfaces import Observation
from pickdemo.envs.pick_env import PickEnv


def observation_of(obs: dict[str, np.ndarray]) -> Observation:
    """The robot's :class:`~pickdemo.core.interfaces.Observation` in an environment's observation."""
    return Observation(
        time_s=float(obs["time"][0]),
        arm_q=np.asarray(obs["joint_pos"], dtype=float),
        arm_dq=np.asarray(obs["joint_vel"], dtype=float),
        fingers_m=np.asarray(obs["fingers"], dtype=float),
        finger_contacts=(int(obs["finger_contacts"][0]), int(obs["finger_contacts"][1])),
        wrist_force_n=np.asarray(obs["wrist_force"], dtype=float),
        vacuum_kpa=float(obs["vacuum"][0]) if "vacuum" in obs else 0.0,
    )


class ExpertPolicy:
    """``action = expert(obs)``: made once for an environment, before its ``reset``::

    env = gymnasium.make("pickdemo/Pick-v0", scenario="pick_cube", agent_rate_hz=None)
    expert = ExpertPolicy(env)
    obs, info = env.reset(seed=0)
    while True:
        obs, reward, terminated, truncated, info = env.step(expert(obs))
        if terminated or truncated:
            break
    """

    def __init__(self, env) -> None:  # noqa: ANN001 - a PickEnv, or a wrapper of one
        base = env.unwrapped
        if not isinstance(base, PickEnv):
            raise TypeError(f"ExpertPolicy needs a pickdemo environment, not {type(base).__name__}")
        if base.ticks != 1:
            raise ValueError(
                f"the expert decides every control tick ({base.scenario.control.control_rate_hz:g} Hz); this "
                f"environment acts at {base.agent_rate_hz:g} Hz: make it with agent_rate_hz=None"
            )
        if not base.perception:
            raise ValueError("the expert sees through the env's cameras: make it with perception=True")
        base.expert_eye = True
        self.env = base

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.act(observation_of(obs))

    def act(self, observation: Observation) -> np.ndarray:
        """The action for the robot's own observation (what the environment's observation carries of it)."""
        env = self.env
        if env.pilot is None:
            raise RuntimeError("reset() the environment first")
        if not hasattr(env.pilot.eye, "update"):
            raise RuntimeError("the expert was made after this episode's reset(): reset() the environment again")
        return env.mode.action_for(env.pilot.eye.update(observation))

    @property
    def failure(self):  # noqa: ANN201 - the skill's Failure, if it gave up
        return self.env.pilot.eye.failure if self.env.pilot is not None else None
