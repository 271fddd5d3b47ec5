"""Steps per second of ``pickdemo/Pick-v0`` (``state`` observations, random actions) beside
panda-gym's ``PandaPickAndPlace-v3``, in one process, one after the other, on the same machine.

    PYTHONPATH=PANDA_GYM_SOURCE python tests/env_speed.py [--steps 2000]

panda-gym is not a dependency: put its source (and scipy) on ``PYTHONPATH`` to compare; without it
only pickdemo's figures are printed. A panda-gym step is 20 physics steps of 2 ms (25 Hz); a
pickdemo step is one agent step (``agent_rate_hz``) of 120 Hz control ticks, 240 Hz physics, with
perception in the loop at the scenario's 10 Hz (about 30 ms of render and fit a frame).
"""

from __future__ import annotations

import argparse
import time
import warnings


def rate(env_id: str, steps: int, **kwargs: object) -> tuple[float, float, int]:
    """(steps per wall second, simulated seconds per wall second, resets) over ``steps`` random actions."""
    import gymnasium as gym

    env = gym.make(env_id, **kwargs)
    env.action_space.seed(0)
    env.reset(seed=0)
    resets, sim_s = 0, 0.0
    u = env.unwrapped
    dt = 1.0 / u.agent_rate_hz if hasattr(u, "agent_rate_hz") else u.sim.timestep * u.sim.n_substeps
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        sim_s += dt
        if terminated or truncated:
            env.reset()
            resets += 1
    wall = time.perf_counter() - t0
    env.close()
    return steps / wall, sim_s / wall, resets


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=2000)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    import pickdemo.envs  # noqa: F401

    rows = []
    try:
        import panda_gym  # noqa: F401

        rows.append(("PandaPickAndPlace-v3 (25 Hz)", "PandaPickAndPlace-v3", {}))
    except ImportError:
        print("panda-gym is not importable: pickdemo alone")
    rows += [
        ("pickdemo/Pick-v0 state, joint_pos, 10 Hz", "pickdemo/Pick-v0", {}),
        ("pickdemo/Pick-v0 state, ee_delta, 10 Hz", "pickdemo/Pick-v0", {"control_mode": "ee_delta"}),
        ("pickdemo/Pick-v0 state, joint_pos, 24 Hz", "pickdemo/Pick-v0", {"agent_rate_hz": 24}),
        (
            "pickdemo/Pick-v0 privileged, no perception, joint_pos, 10 Hz",
            "pickdemo/Pick-v0",
            {"obs_mode": "privileged", "perception": False},
        ),
    ]
    for name, env_id, kwargs in rows:
        sps, rtf, resets = rate(env_id, args.steps, **kwargs)
        print(f"{name}: {sps:.0f} steps/s, {rtf:.1f} simulated s per wall s ({args.steps} steps, {resets} resets)")


if __name__ == "__main__":
    main()
