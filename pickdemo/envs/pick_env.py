"""The Gymnasium environment: one pickdemo scenario, stepped by an agent (:class:`PickEnv`).

Each ``step`` holds the agent's action for the control ticks of one agent step (``agent_rate_hz``,
10 Hz by default, at most the scenario's control tick), each tick the episode's own loop
(:class:`~pickdemo.runtime.episode.Episode`): the command through the robot's rate limiter and
reflex, the cameras' frames and perception's estimates at their own rate and latency, 240 Hz physics.
The loop's controller is a :class:`~pickdemo.envs.pilot.Pilot` carrying the action.

- Observations (``obs_mode``): ``state`` is what the robot's controller has: joint positions and
  velocities, each finger's opening and contacts, the wrist's force (a suction robot: its vacuum too),
  the clock, the place it is told,
  and the target's pose (x, y, z, yaw) and covariance as pickdemo's perception tracks it. ``rgbd``
  adds each camera's RGB and depth (metres, 0 where the sensor has no return). ``privileged`` adds the
  target's true pose (position and quaternion x, y, z, w): for baselines, named so.
- Reward (``reward_mode``): ``sparse`` is 1 on the step the task is done, else 0; ``dense`` is the
  staged reward in :func:`dense_reward` (the truth's distances: a reward is scored, never observed).
- ``terminated``: the task done (the referee's success, the hand let go), or the episode failed
  (``terminate_on_failure``: the target off the table, the robot's reflex, an error); ``truncated``:
  the scenario's simulated-time budget spent. At the end ``info["result"]`` is the referee's
  :class:`~pickdemo.core.result.EpisodeResult`; every step has ``info["is_success"]`` and
  ``info["success"]``.
"""

from __future__ import annotations

import os
import sys
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from pickdemo.core.interfaces import Observation
from pickdemo.core.result import EpisodeFailure, EpisodeResult, Stage
from pickdemo.envs.control import GRIPPERS, MODES, EeDelta, JointPos, from_unit
from pickdemo.envs.pilot import Pilot, Watcher
from pickdemo.runtime.episode import THIRD_PERSON_K, THIRD_PERSON_POSE, Episode, EpisodeOptions
from pickdemo.runtime.world import FIXED_CAMERA, WRIST_CAMERA
from pickdemo.scenario.load import Scenario, load_scenario
from pickdemo.sim.render import render_rgb
from pickdemo.skills.controller import Controller

OBS_MODES = ("state", "rgbd", "privileged")
#: The observation's images' depth noise: a random stream of its own, beside the episode's (from the seed).
IMAGE_STREAM = 0x1A6E
REWARD_MODES = ("sparse", "dense")


def _box(shape: tuple[int, ...], low: float = -np.inf, high: float = np.inf) -> spaces.Box:
    return spaces.Box(low, high, shape, dtype=np.float64)


class PickEnv(gym.Env):
    """A pickdemo scenario as a Gymnasium environment (``pickdemo/Pick-v0``, ``pickdemo/Clear-v0``)."""

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 10}

    def __init__(
        self,
        scenario: str | Scenario = "pick_cube",
        *,
        robot: str | None = None,
        obs_mode: str = "state",
        control_mode: str = "joint_pos",
        render_mode: str | None = None,
        agent_rate_hz: float | None = 10.0,
        reward_mode: str = "sparse",
        terminate_on_failure: bool = True,
        task: str | None = None,
        options: EpisodeOptions | None = None,
        image_width: int | None = None,
        gripper: str = "opening",
        image_height: int | None = None,
        perception: bool = True,
        unit_actions: bool = False,
    ) -> None:
        """``scenario``: a shipped scenario's name, a file, or a loaded one; ``robot``: another robot than
        its own (a shipped one's name or a robot file); ``agent_rate_hz`` None: every control tick;
        ``task``: the task the scenario must have (the id's: ``pick`` or ``clear``); ``image_width``: the
        ``rgbd`` images' width in pixels (the same field of view, both sides rounded to even; default: each
        camera's own); ``image_height`` (with ``image_width``): each camera's images exactly so large,
        rendered at its own aspect over the whole of it and cut to it about the middle (as a real camera's
        narrower mode is); ``gripper``: ``"opening"`` (one number) or ``"opening_force"`` (and the force);
        ``perception`` False: no camera frames and no estimates in the loop (``target_pose`` stays zeros;
        faster: a replay, an agent on ``privileged`` observations); ``unit_actions``: each action in [-1, 1],
        mapped linearly onto the control mode's own bounds (robomimic's policies act so)."""
        for what, value, allowed in (
            ("obs_mode", obs_mode, OBS_MODES),
            ("control_mode", control_mode, tuple(MODES)),
            ("reward_mode", reward_mode, REWARD_MODES),
            ("gripper", gripper, GRIPPERS),
            ("render_mode", render_mode, (None, *self.metadata["render_modes"])),
        ):
            if value not in allowed:
                raise ValueError(f"{what}={value!r}: one of {', '.join(map(repr, allowed))}")
        sc = scenario if isinstance(scenario, Scenario) else load_scenario(scenario, robot=robot)
        if task is not None and sc.task != task:
            raise ValueError(f"scenario {sc.name!r} has task {sc.task!r}; this environment is for task {task!r}")
        self.scenario = sc
        self.obs_mode, self.control_mode, self.render_mode = obs_mode, control_mode, render_mode
        self.reward_mode, self.terminate_on_failure = reward_mode, terminate_on_failure
        self.gripper = gripper
        self.perception = perception
        self.unit_actions = unit_actions
        self.robot = sc.robot_description
        if image_width is not None and not 16 <= image_width <= 4096:
            raise ValueError(f"image_width={image_width}: 16 to 4096 pixels")
        if image_height is not None and (image_width is None or not 16 <= image_height <= 4096):
            raise ValueError(f"image_height={image_height}: 16 to 4096 pixels, with an image_width")
        self.image_width, self.image_height = image_width, image_height
        control_hz = sc.control.control_rate_hz
        rate = control_hz if agent_rate_hz is None else float(agent_rate_hz)
        ticks = control_hz / rate
        if rate <= 0 or abs(ticks - round(ticks)) > 1e-9:
            raise ValueError(
                f"agent_rate_hz={agent_rate_hz}: the control tick ({control_hz:g} Hz) divided by a whole number"
            )
        self.ticks = int(round(ticks))
        self.agent_rate_hz = rate
        self.metadata = {**self.metadata, "render_fps": rate}
        gui = render_mode == "human" and _has_display()
        if render_mode == "human" and not gui:
            warnings.warn("render_mode='human' needs a display (none here): the simulator runs headless", stacklevel=2)
        self.options = options or EpisodeOptions(gui=gui)
        self.expert_eye = False  # pickdemo's own skill looks (the expert policy asks for it)
        self.episode: Episode | None = None
        self.pilot: Pilot | None = None
        self.mode: JointPos | EeDelta | None = None
        self._result: EpisodeResult | None = None
        self._succeeded = False
        self._closed = False
        self.native_action_space = self._action_space()
        n = self.native_action_space.shape
        self.action_space = spaces.Box(-1.0, 1.0, n, dtype=np.float32) if unit_actions else self.native_action_space
        self.observation_space = self._observation_space()

    # ================================================================================== spaces
    def _action_space(self) -> spaces.Box:
        lim = self.robot.limits
        g = GRIPPERS.index(self.gripper) + 1
        if self.control_mode == "joint_pos":
            low, high = np.append(lim.min_position_rad, -np.ones(g)), np.append(lim.max_position_rad, np.ones(g))
            return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        # (float32, as Gymnasium and Stable-Baselines3 recommend: policies and datasets are float32)
        return spaces.Box(-1.0, 1.0, (4 + g,), dtype=np.float32)

    def _observation_space(self) -> spaces.Dict:
        n = self.robot.dof
        d: dict[str, spaces.Space] = {
            "joint_pos": _box((n,)),
            "joint_vel": _box((n,)),
            "fingers": _box((2,)),
            "finger_contacts": _box((2,), 0.0),
            "wrist_force": _box((3,)),
            "time": _box((1,), 0.0),
            # (the position unbounded, the unit quaternion within [-1, 1]: bounds where a quantity has them)
            "tcp_pose": spaces.Box(
                np.r_[np.full(3, -np.inf), -np.ones(4)], np.r_[np.full(3, np.inf), np.ones(4)], dtype=np.float64
            ),
            "place": _box((2,)),
            "target_pose": _box((4,)),
            "target_cov": _box((4, 4)),
            "target_tracked": _box((1,), 0.0, 1.0),
        }
        if self.robot.gripper.suction:  # its vacuum sensor (kPa below the ambient)
            d["vacuum"] = _box((1,), 0.0, 101.325)
        if self.obs_mode == "rgbd":
            for name, (w, h) in self._camera_sizes().items():
                d[f"{name}_rgb"] = spaces.Box(0, 255, (h, w, 3), dtype=np.uint8)
                d[f"{name}_depth"] = spaces.Box(0.0, np.inf, (h, w), dtype=np.float32)
        if self.obs_mode == "privileged":
            d["target_true_pose"] = _box((7,))  # (a clear round: zeros)
            d["objects_true_pose"] = _box((self._object_count(), 7))
        return spaces.Dict(d)

    def _object_count(self) -> int:
        clear = self.scenario.clear
        return len(self.scenario.objects) + (clear.count if clear is not None else 0)

    def camera_specs(self) -> dict:
        """Each camera's scenario spec, by its name in the observation."""
        specs = {FIXED_CAMERA: self.scenario.camera}
        if self.scenario.wrist_camera is not None:
            specs[WRIST_CAMERA] = self.scenario.wrist_camera
        return specs

    def _camera_sizes(self) -> dict[str, tuple[int, int]]:
        """Each camera's images' (width, height) in the observation."""
        sizes = {}
        for name, spec in self.camera_specs().items():  # (even: a video's chroma is half the size)
            w = 2 * max(1, (self.image_width or spec.width) // 2)
            h = self.image_height or round(w * spec.height / spec.width)
            sizes[name] = (w, 2 * max(1, round(h / 2)))
        return sizes

    def _rendered_sizes(self) -> dict[str, tuple[int, int]]:
        """Each camera's size rendered at its own aspect, over the whole of its images' (then cut to them)."""
        sizes = {}
        for name, (w, h) in self._camera_sizes().items():
            spec = self.camera_specs()[name]
            scale = max(w / spec.width, h / spec.height)
            sizes[name] = (max(w, round(spec.width * scale)), max(h, round(spec.height * scale)))
        return sizes

    # ================================================================================ episodes
    def _wrap(self, skill: Controller, told: dict) -> Controller:
        """The loop's controller: a pilot carrying the agent's action, its eye the skill or a watcher."""
        mode_class = MODES[self.control_mode]
        force = told["params"].grip_force_n
        # from where the robot was last told to be (its reflex checks the first command against that)
        q_sent = self.episode.robot.reflex.q.copy()
        self.mode = mode_class(told["kin"], q_sent, told["dt_s"], self.ticks, force, self.gripper)
        if self.expert_eye:
            eye = skill
        else:
            w = self.episode.world
            eye = Watcher(
                told["kin"], told["cameras"], skill.model, told["params"], w.place_xy, told["q0"],
                surface_z=getattr(getattr(skill, "belief", None), "surface_z", None), looking=self.perception,
            )  # fmt: skip
        self.pilot = Pilot(eye, self.mode)
        return self.pilot

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        super().reset(seed=seed)
        if seed is None:
            seed = int(self.np_random.integers(0, 2**31 - 1))
        self.close()
        self.episode = Episode(self.scenario, int(seed), self.options, wrap_controller=self._wrap)
        self._result, self._succeeded, self._closed = None, False, False
        if self.episode.reset() is None:  # a seed whose world cannot be built: said, not stepped
            result = self.episode.result()
            failure = result.failure
            raise RuntimeError(f"{self.scenario.name} seed {seed}: {failure.stage.value}: {failure.reason}")
        self.seed_used = int(seed)
        self._image_rng = np.random.default_rng([int(seed), IMAGE_STREAM])
        return self._observe(), self._info()

    def step(self, action: np.ndarray) -> tuple[dict, float, bool, bool, dict]:
        terminated, truncated = self.advance(action)
        return self._observe(), self._reward(), terminated, truncated, self._info()

    def advance(self, action: np.ndarray) -> tuple[bool, bool]:
        """:meth:`step` without building its observation, reward and info: ``(terminated, truncated)``. For
        a recorder that keeps an observation every few ticks (:func:`~pickdemo.envs.record.record_episode`);
        the robot's own (``episode.observation``) is read every tick all the same."""
        if self.episode is None:
            raise RuntimeError("step() before reset()")
        if self._closed:
            raise RuntimeError("step() on a closed environment: reset() first")
        if self.episode.done:
            raise RuntimeError("step() after the episode ended: reset() first")
        if self.unit_actions:  # onto the mode's own bounds (float64: the float32 space rounds them)
            action = from_unit(action, self.mode.bounds, self.mode.name)
        self.mode.set(action)
        ep = self.episode
        for _ in range(self.ticks):
            if ep.step():
                break
        if not ep.done:
            ep.observe()  # the robot's sensors after the physics: what the agent acts on
            ep.deliver()  # what perception has delivered by now: in this observation
            self._succeeded = self._task_done()
            if self._succeeded or (self.terminate_on_failure and self._target_lost()):
                self.pilot.stop()
                ep.step()  # (no tick: the loop ends and the referee scores)
        if not ep.done:
            return False, False
        self._result = ep.result()
        timeout = self._result.failure is not None and self._result.failure.stage is Stage.TIMEOUT
        return not timeout, timeout

    def _task_done(self) -> bool:
        """The referee's success now (truth, for the reward and the end only), the hand let go of it."""
        obs = self.episode.observation
        cup = self.robot.gripper.cup
        if obs is None or any(obs.finger_contacts) or (cup is not None and obs.vacuum_kpa >= cup.switch_kpa):
            return False
        try:
            self.episode.referee.score()
        except EpisodeFailure:
            return False
        return True

    def _target_lost(self) -> bool:
        name = self.episode.target_name
        if not name:
            return False
        x, y, z = self.episode.world.true_position(name)
        return bool(z < -0.05 or not self.scenario.table.holds(float(x), float(y)) and z < 0.0)

    def _reward(self) -> float:
        if self.reward_mode == "sparse":
            return 1.0 if self._success() else 0.0
        return dense_reward(self)

    def result(self) -> EpisodeResult | None:
        """The referee's result once the episode is over (``info["result"]``), else None."""
        return self._result

    def _success(self) -> bool:
        return self._result.success if self._result is not None else self._succeeded

    def _info(self) -> dict[str, Any]:
        ok = self._success()
        info: dict[str, Any] = {"is_success": ok, "success": ok, "time_s": self.episode.time_s}
        if self._result is not None:
            info["result"] = self._result
            info["failure"] = None if self._result.failure is None else self._result.failure.stage.value
        return info

    # ============================================================================ observations
    def _observe(self) -> dict[str, np.ndarray]:
        ep = self.episode
        o: Observation = ep.observation
        tracker = self.pilot.eye.tracker if self.pilot is not None else None
        tracked = tracker is not None and tracker.initialised
        pose, cov = np.zeros(4), np.zeros((4, 4))
        if tracked:
            tp = tracker.predict(o.time_s)
            pose = np.array([*tp.position, tp.yaw_rad])
            cov = np.array(tp.covariance[:4, :4], dtype=float)
        place = ep.world.place_xy if ep.world is not None else (0.0, 0.0)
        tcp = self.pilot.kin.forward(o.arm_q)  # where the joints put the hand: the robot's kinematics, not the truth
        out = {
            "joint_pos": np.array(o.arm_q, dtype=float),
            "joint_vel": np.array(o.arm_dq, dtype=float),
            "fingers": np.array(o.fingers_m, dtype=float),
            "finger_contacts": np.array(o.finger_contacts, dtype=float),
            "wrist_force": np.array(o.wrist_force_n, dtype=float),
            **({"vacuum": np.array([o.vacuum_kpa])} if self.robot.gripper.suction else {}),
            "time": np.array([o.time_s]),
            "tcp_pose": np.concatenate([tcp.position, tcp.quaternion_xyzw]),
            "place": np.array(place, dtype=float),
            "target_pose": pose,
            "target_cov": cov,
            "target_tracked": np.array([float(tracked)]),
        }
        if self.obs_mode == "rgbd":
            out.update(self._images())
        if self.obs_mode == "privileged":
            out["target_true_pose"], out["objects_true_pose"] = self._true_poses()
        return out

    def camera_images(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Each camera's whole view now: (RGB, depth in m with 0 for no return), at ``image_width``. Their
        depth noise has its own random stream (from the seed): looking leaves the episode as it was."""
        ep = self.episode
        if ep.done or ep.world is None or ep.world.scene is None:  # (the scene is closed: the last again)
            return self._last_images
        sizes, rendered = self._camera_sizes(), self._rendered_sizes()
        self._last_images = {}
        for name, rig in ep.world.cameras.items():
            rgb, depth = rig.snapshot(ep.world.scene, *rendered[name], self._image_rng)
            (w, h), (rw, rh) = sizes[name], rendered[name]
            x0, y0 = (rw - w) // 2, (rh - h) // 2  # (the middle: the same when nothing is cut)
            self._last_images[name] = (rgb[y0 : y0 + h, x0 : x0 + w], depth[y0 : y0 + h, x0 : x0 + w])
        return self._last_images

    def _images(self) -> dict[str, np.ndarray]:
        out = {}
        for name, (rgb, depth) in self.camera_images().items():
            out[f"{name}_rgb"], out[f"{name}_depth"] = rgb, depth
        return out

    def _true_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Truth (privileged): the target's pose and every object's, in the layout's order (x, y, z, qx, qy, qz, qw)."""
        ep = self.episode
        if ep.done or ep.world is None or ep.world.scene is None:
            return self._last_true
        poses = np.zeros((self._object_count(), 7))
        target = np.zeros(7)
        for i, placement in enumerate(ep.world.layout[: len(poses)]):
            pose = ep.world.true_pose(placement.name)
            poses[i] = np.concatenate([pose.position, pose.quaternion_xyzw])
            if placement.name == ep.target_name:
                target = poses[i].copy()
        self._last_true = (target, poses)
        return self._last_true

    # ================================================================================ render
    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None  # "human": the simulator's own window, opened at reset
        ep = self.episode
        if ep is None or ep.done or ep.world is None or ep.world.scene is None:
            return getattr(self, "_last_render", np.zeros((THIRD_PERSON_K.height, THIRD_PERSON_K.width, 3), np.uint8))
        self._last_render = render_rgb(ep.world.scene, THIRD_PERSON_POSE, THIRD_PERSON_K)
        return self._last_render

    def close(self) -> None:
        if self.episode is not None and not self.episode.done and not self._closed:
            if self.render_mode == "rgb_array":
                self.render()
            self.episode.close()
        self._closed = True


def _has_display() -> bool:
    """Whether a window can open (PyBullet's GUI ends the process when it cannot)."""
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def dense_reward(env: PickEnv) -> float:
    """In [0, 1], from the truth: 1 when the task is done; else a third each for the hand near the
    target (1 - tanh(5 d)), the target lifted (its rise over the scenario's lift height, at most 1)
    and the target near the place (1 - tanh(5 d), once lifted). A clear round: its share in the tray."""
    if env._success():
        return 1.0
    ep = env.episode
    if ep.done or ep.world is None or ep.world.scene is None:
        return 0.0
    if not ep.target_name:  # a clear round
        ref = ep.referee
        if not ref.in_round:
            return 0.0
        return sum(ref.in_tray(n) for n in ref.in_round) / len(ref.in_round)
    target = ep.world.true_position(ep.target_name)
    tcp = ep.machine.kin.forward(ep.observation.arm_q).position
    reach = 1.0 - np.tanh(5.0 * np.linalg.norm(tcp - target))
    start = ep.referee.start_pose.position[2]
    lifted = min(max((ep.referee.max_z_m - start) / env.scenario.success.lift_height, 0.0), 1.0)
    place = 1.0 - np.tanh(5.0 * np.hypot(*(target[:2] - np.array(ep.world.place_xy))))
    return float((reach + lifted + lifted * place) / 3.0)


__all__ = ["OBS_MODES", "REWARD_MODES", "PickEnv", "dense_reward"]
