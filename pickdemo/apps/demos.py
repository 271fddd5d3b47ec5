"""``pickdemo demos`` and ``pickdemo replay``: the expert's episodes recorded as datasets, and
played again from them.

``demos SCENARIO --seeds 0-99 --out DIR --format lerobot|hdf5`` runs the closed-loop expert
(:class:`~pickdemo.envs.expert.ExpertPolicy`) through the Gymnasium environment one seed after
another and writes each episode (:mod:`pickdemo.apps.datasets`); ``--only-success`` keeps the
successful ones; ``--resume`` goes on with a run that was stopped. ``replay DIR --episode N`` plays an
episode again from its simulator states and from its actions, and says whether it succeeds again
(from its actions, on the machine that recorded it, bit for bit).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from pickdemo.apps import datasets
from pickdemo.apps.bench import parse_seeds
from pickdemo.apps.datasets import STAGING, DatasetError
from pickdemo.apps.files import write_atomic
from pickdemo.envs.follower import FollowerChannels
from pickdemo.envs.record import (
    action_bounds,
    action_names,
    make_env,
    record_episode,
    replay_episode,
    state_names,
    stride_for,
)
from pickdemo.scenario.instruction import instruction
from pickdemo.scenario.load import list_scenarios, load_scenario, resolve_scenario_path

#: The cameras' width where neither the command nor a follower says (px)
DEFAULT_IMAGE_WIDTH = 224


def run_demos(
    scenario: str,
    seeds: list[int],
    out: Path,
    *,
    fmt: str,
    fps: float,
    only_success: bool,
    resume: bool,
    progress: bool,
    robot: str | None = None,
    image_width: int | None = None,
    task: str | None = None,
    features: str | None = None,
) -> dict:
    """Record the seeds not staged yet and make the dataset; the run's figures. ``task``: the episodes'
    task string (None: the scenario's instruction); ``image_width``: None for the follower's or 224;
    ``features`` (LeRobot's format): "follower", a robot file's ``[lerobot]`` follower's (the default
    where it has one), or "pickdemo", the environment's own state and action."""
    from tqdm import tqdm

    if fmt == "lerobot" and fps != int(fps):
        raise DatasetError(f"--fps {fps:g}: LeRobot datasets have a whole number of frames per second")
    described = load_scenario(scenario, robot=robot).robot_description  # (the follower's sizes: before the env)
    profile = described.lerobot if fmt == "lerobot" and features != "pickdemo" else None
    if features == "follower" and profile is None:
        raise DatasetError(
            f"--features follower: the {described.label}'s robot file has no [lerobot] table"
            if fmt == "lerobot" else "--features: LeRobot's format only (--format lerobot)"
        )  # fmt: skip
    image_height = None
    if profile is not None:  # the follower's cameras' size; another width keeps their aspect, every camera's
        w, h = profile.image_size
        image_width = image_width or w
        image_height = 2 * max(1, round(image_width * h / w / 2))
    image_width = image_width or DEFAULT_IMAGE_WIDTH
    env = make_env(scenario, robot, image_width=image_width, image_height=image_height)
    stride = stride_for(env, fps)
    meta = {
        "format": fmt,
        "scenario": scenario if scenario in list_scenarios() else str(resolve_scenario_path(scenario)),
        "scenario_name": env.scenario.name,
        "robot": robot,
        "robot_name": env.robot.name,
        "control_rate_hz": env.scenario.control.control_rate_hz,
        "fps": fps,
        "stride": stride,
        "state_names": state_names(env),
        "action_names": action_names(env),
        "action_bounds": list(action_bounds(env)),
        "image_width": image_width,
        "image_height": image_height,
        "cameras": {name: list(size) for name, size in env._camera_sizes().items()},
        "far_m": {name: float(spec.far_m) for name, spec in env.camera_specs().items()},
        "task": task or instruction(env.scenario),
        "env_id": "pickdemo/Clear-v0" if env.scenario.task == "clear" else "pickdemo/Pick-v0",
    }
    if fmt == "lerobot":
        meta["codec"] = profile.video_codec if profile is not None else "h264"
    follower = None
    if profile is not None:
        follower = FollowerChannels(profile, env.robot, meta["state_names"])
        cams = dict(profile.cameras)
        meta["follower"] = {"robot_type": profile.robot_type, "names": follower.names,
                            "cameras": {c: cams.get(c, c) for c in meta["cameras"]}}  # fmt: skip
    meta_path = out / STAGING / "meta.json"
    done = datasets.staged(out)
    if meta_path.is_file():
        before = json.loads(meta_path.read_text())
        if not resume:
            raise DatasetError(f"{out}: holds a recording already (add --resume to go on with it, or another --out)")
        if before != meta:
            changed = sorted(k for k in meta if before.get(k) != meta[k])
            raise DatasetError(f"{meta_path}: recorded with other settings ({', '.join(changed)}): use another --out")
    (out / STAGING).mkdir(parents=True, exist_ok=True)
    write_atomic(meta_path, json.dumps(meta) + "\n")
    todo = [s for s in seeds if s not in done]
    ok = sum(r["success"] for r in done.values() if r["seed"] in seeds)
    t0 = time.perf_counter()
    bar = tqdm(total=len(seeds), initial=len(seeds) - len(todo), disable=not progress, unit="ep", dynamic_ncols=True)
    try:
        for seed in todo:
            sink = datasets.open_episode(fmt, out, seed, stride, meta, follower)
            try:
                recorded = record_episode(env, seed, stride, sink)
            except BaseException:
                sink.close(keep=False)
                raise
            keep = recorded.success or not only_success
            sink.close(keep=keep, success=recorded.success)
            datasets.write_record(out, recorded, {"kept": keep})
            ok += recorded.success
            bar.update(1)
            bar.set_postfix_str(f"success {ok}/{bar.n}", refresh=False)
    finally:
        bar.close()
        env.close()
    wall = time.perf_counter() - t0
    records = datasets.staged(out)  # (every episode recorded here: an earlier run's other seeds too)
    kept = datasets.finalize(fmt, out, records, meta, only_success=only_success)
    asked = [r for s, r in records.items() if s in seeds]
    return {"episodes": len(asked), "successes": sum(r["success"] for r in asked), "kept": kept,
            "staged": len(records), "recorded": len(todo), "wall_s": wall}  # fmt: skip


def replay_meta(out: Path) -> dict:
    """What a dataset was recorded with, from the dataset itself (a copy of it replays too)."""
    if (out / "meta" / "pickdemo.json").is_file():
        return json.loads((out / "meta" / "pickdemo.json").read_text())
    if (out / "demos.hdf5").is_file():
        return datasets.hdf5_meta(out)
    raise DatasetError(f"{out}: not a pickdemo demos dataset (no meta/pickdemo.json, no demos.hdf5)")


def episodes_in(out: Path, which: str) -> list[int]:
    """``all``, or episode numbers as seeds are written (``3``, ``0-9``, ``0-9,20``)."""
    meta = replay_meta(out)
    n = datasets.count_episodes(meta["format"], out)
    if which == "all":
        return list(range(n))
    chosen = parse_seeds(which)
    beyond = [k for k in chosen if k >= n]
    if beyond:
        raise DatasetError(f"{out}: no episode {beyond[0]} (it has {n}: 0-{n - 1})")
    return chosen


def run_replay(out: Path, episode: int, env=None) -> dict:  # noqa: ANN001 - a PickEnv to reuse, or None
    """Replay episode ``episode`` of the dataset in ``out`` from its states and from its actions (in
    ``env``, made blind for replays by :func:`replay_env`, or one made here)."""
    meta = replay_meta(out)
    attrs, ticks, counts, states = datasets.read_episode(meta["format"], out, episode)
    stride = int(meta["stride"])
    actions = datasets.acted_ticks(ticks, counts, len(meta["action_names"]))
    own = env is None
    env = replay_env(out) if own else env
    try:
        seed = int(attrs["seed"])
        from_states = replay_episode(env, seed, actions, stride, list(states), from_states=True)
        from_actions = replay_episode(env, seed, actions, stride, list(states), from_states=False)
    finally:
        if own:
            env.close()
    return {
        "episode": episode,
        "seed": seed,
        "recorded_success": bool(attrs["success"]),
        "from_states": {"success": from_states.success, "failure": from_states.failure},
        "from_actions": {
            "success": from_actions.success,
            "failure": from_actions.failure,
            "identical": from_actions.identical,
        },
    }


def replay_env(out: Path):  # noqa: ANN201 - a PickEnv
    """The environment the dataset in ``out`` replays in: its scenario and robot, no perception (what
    perception sees never moves the robot in a replay)."""
    meta = replay_meta(out)
    return make_env(meta["scenario"], meta["robot"], perception=False)
