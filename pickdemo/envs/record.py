"""Recording the expert's episodes through the environment, at a dataset's frame rate.

:func:`record_episode` runs :class:`~pickdemo.envs.expert.ExpertPolicy` in a
:class:`~pickdemo.envs.pick_env.PickEnv` (``joint_pos``, one action a control tick) and hands a sink
one row per dataset frame (every ``stride`` control ticks): the state observation, the action a
policy at the dataset's rate would send (the joint goal at the row's last tick, and the gripper),
every tick's action of the row (for an exact replay), the simulator's state at the row's start (for a
replay from states), and each camera's RGB and depth. :func:`replay_episode` plays a recorded episode
again in a fresh environment, from its actions alone or set to its states row by row, and says
whether it succeeds again. A part of the environments: no file formats here (:mod:`pickdemo.apps.datasets`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from pickdemo.envs.expert import ExpertPolicy
from pickdemo.envs.pick_env import PickEnv

#: The state observation's parts, in the order of a dataset's ``observation.state``.
STATE_KEYS = (
    "joint_pos", "joint_vel", "fingers", "finger_contacts", "wrist_force", "tcp_pose", "place", "target_pose",
    "target_tracked",
)  # fmt: skip


def state_names(env: PickEnv) -> list[str]:
    """One name per number of ``observation.state``."""
    n = env.robot.dof
    names = [f"joint_pos.{i}" for i in range(n)] + [f"joint_vel.{i}" for i in range(n)]
    names += ["finger.0", "finger.1", "contacts.0", "contacts.1", "wrist_force.x", "wrist_force.y", "wrist_force.z"]
    names += ["tcp.x", "tcp.y", "tcp.z", "tcp.qx", "tcp.qy", "tcp.qz", "tcp.qw", "place.x", "place.y"]
    names += ["target.x", "target.y", "target.z", "target.yaw", "target.tracked"]
    return names + (["vacuum_kpa"] if env.robot.gripper.suction else [])


def action_names(env: PickEnv) -> list[str]:
    return [f"joint_goal.{i}" for i in range(env.robot.dof)] + ["gripper", "gripper_force"][
        : env.action_space.shape[0] - env.robot.dof
    ]


def action_bounds(env: PickEnv) -> tuple[list[float], list[float]]:
    """The recorded actions' bounds (``joint_pos``: the joints' limits, the gripper's numbers in [-1, 1]), in
    float64: what an action in [-1, 1] is scaled onto (``unit_actions``)."""
    lim = env.robot.limits
    g = env.action_space.shape[0] - env.robot.dof
    low = np.concatenate([lim.min_position_rad, -np.ones(g)])
    high = np.concatenate([lim.max_position_rad, np.ones(g)])
    return low.tolist(), high.tolist()


def state_vector(obs: dict[str, np.ndarray]) -> np.ndarray:
    """An environment's state observation as a dataset's ``observation.state`` (:data:`STATE_KEYS`, in order;
    a suction cup's vacuum last)."""
    return np.concatenate([np.ravel(obs[k]) for k in (*STATE_KEYS, "vacuum") if k in obs])


@dataclass
class Row:
    """One dataset frame."""

    time_s: float
    state: np.ndarray  # (S,) the state observation (:data:`STATE_KEYS`)
    sim_state: np.ndarray  # the simulator's state at the frame's first tick
    images: dict[str, tuple[np.ndarray, np.ndarray]]  # camera -> (RGB (H, W, 3) uint8, depth (H, W) float32 m)
    ticks: list[np.ndarray]  # every tick's action of the frame (1 .. stride of them)

    @property
    def action(self) -> np.ndarray:
        return self.ticks[-1]


class Sink(Protocol):
    def row(self, row: Row) -> None: ...


@dataclass
class Recorded:
    """What an episode came to."""

    seed: int
    frames: int
    ticks: int
    success: bool
    failure: str | None  # the failed stage
    reason: str
    result: dict[str, Any]  # the referee's EpisodeResult, as result.json has it


def make_env(
    scenario: str,
    robot: str | None = None,
    *,
    image_width: int | None = None,
    image_height: int | None = None,
    perception: bool = True,
) -> PickEnv:
    """The environment demonstrations are recorded and replayed in (its images ``image_width`` across, or
    ``image_width`` x ``image_height``: :class:`~pickdemo.envs.pick_env.PickEnv`'s): the
    gripper's opening and force in each action, so that the skill's own force is recorded and replayed;
    ``perception`` False for a replay (what perception sees never moves the robot there)."""
    return PickEnv(
        scenario, robot=robot, obs_mode="state", control_mode="joint_pos", agent_rate_hz=None,
        image_width=image_width, image_height=image_height, gripper="opening_force", perception=perception,
    )  # fmt: skip


def stride_for(env: PickEnv, fps: float) -> int:
    control = env.scenario.control.control_rate_hz
    stride = control / fps
    if fps <= 0 or abs(stride - round(stride)) > 1e-9:
        raise ValueError(f"--fps {fps:g}: the control tick ({control:g} Hz) divided by a whole number")
    return int(round(stride))


def record_episode(env: PickEnv, seed: int, stride: int, sink: Sink, *, images: bool = True) -> Recorded:
    """Run the expert for ``seed``, one :class:`Row` to ``sink`` every ``stride`` control ticks."""
    expert = ExpertPolicy(env)
    obs, _ = env.reset(seed=seed)
    row: Row | None = None
    k = 0
    while True:
        if k % stride == 0:
            scene = env.episode.world.scene
            shots = env.camera_images() if images else {}
            row = Row(float(obs["time"][0]), state_vector(obs), scene.state(), shots, [])
        action = expert.act(env.episode.observation)  # (what obs carries of the robot)
        row.ticks.append(action)
        if (k + 1) % stride == 0:  # a frame starts next: its observation
            obs, _, terminated, truncated, _ = env.step(action)
        else:  # inside a frame: none built
            terminated, truncated = env.advance(action)
        k += 1
        if k % stride == 0 or terminated or truncated:
            sink.row(row)
        if terminated or truncated:
            break
    result = env.result()
    f = result.failure
    return Recorded(
        seed=seed,
        frames=(k + stride - 1) // stride,
        ticks=k,
        success=result.success,
        failure=None if f is None else f.stage.value,
        reason="" if f is None else f.reason,
        result=result.to_dict(),
    )


@dataclass
class Replayed:
    success: bool
    failure: str | None
    identical: bool | None  # from actions: every state the same, bit for bit, as recorded (None: not compared)
    ticks: int


def replay_episode(
    env: PickEnv, seed: int, ticks: list[np.ndarray], stride: int, states: list[np.ndarray], *, from_states: bool
) -> Replayed:
    """Play ``ticks`` (every tick's action, in order) from the seed's first state. ``from_states``: the
    simulator is set to each row's recorded state (one every ``stride`` ticks) before its ticks; else
    from the actions alone, each row's state compared with the recorded one (``identical``). The
    episode ends as the environment ends it; when the actions run out first, the last is held for up to
    two simulated seconds."""
    env.reset(seed=seed)
    scene = env.episode.world.scene
    info: dict = {}
    terminated = truncated = False
    identical = True
    k = 0
    for k, action in enumerate(ticks):
        if k % stride == 0:
            recorded = states[k // stride]
            if from_states:
                scene.set_state(recorded)
            else:
                now = scene.state()
                identical = identical and now.shape == recorded.shape and bool(np.array_equal(now, recorded))
        _, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    extra = int(2.0 * env.scenario.control.control_rate_hz)
    while not (terminated or truncated) and extra > 0:
        _, _, terminated, truncated, info = env.step(ticks[-1])
        extra -= 1
    same = None if from_states else identical and k + 1 == len(ticks)
    if not (terminated or truncated):
        env.close()
        return Replayed(False, "unfinished", same, k + 1)
    result = info["result"]
    return Replayed(result.success, None if result.failure is None else result.failure.stage.value, same, k + 1)
