"""Demonstration datasets on disk: HDF5 (one file, robomimic's layout; here) and LeRobot's v3 format
(:mod:`pickdemo.apps.lerobot_dataset`), written episode by episode and read back for replay.

Each episode is first written whole into ``DIR/.staging/`` with its record
(:mod:`pickdemo.apps.staging`). The dataset itself is made from the staging by :func:`finalize`, after
every episode and again at the end: a run killed and started again with ``--resume`` records only the
seeds not staged yet, and an episode is never in the dataset twice. Episodes are numbered in seed order.

- **HDF5** (``DIR/demos.hdf5``): ``data/demo_K`` per episode with ``obs/state``, ``obs/<camera>_rgb``,
  ``obs/<camera>_depth``, ``actions``, ``action_ticks`` (every control tick's action; a short last
  frame's missing ticks hold its last action), ``action_tick_counts``,
  ``states`` (the simulator's, per frame); attributes ``seed``, ``success``, ``failure``,
  ``num_samples``; ``data`` has ``env_args`` (JSON) and ``total``.
- **LeRobot v3**: see :mod:`pickdemo.apps.lerobot_dataset`.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from pickdemo.apps.lerobot_dataset import LeRobotEpisode, finalize_lerobot, read_lerobot
from pickdemo.apps.staging import STAGING, DatasetError, acted_ticks, hold_ticks, staged, write_record
from pickdemo.envs.record import Row

__all__ = ["STAGING", "DatasetError", "acted_ticks", "staged", "write_record"]  # (for the apps: one place)

#: robomimic's ``EnvType.GYM_TYPE`` (``robomimic/envs/env_base.py``): an HDF5's ``env_args["type"]``
ROBOMIMIC_GYM_TYPE = 2
#: a camera's far plane where the recording does not say it (m): depth is kept as a share of it
DEPTH_FAR_M = 3.0
FORMATS = ("lerobot", "hdf5")


# ===================================================================================== HDF5
class Hdf5Episode:
    """One episode's rows into ``.staging/seed-N.h5`` (renamed from a temporary name by :meth:`close`)."""

    def __init__(self, out: Path, seed: int, stride: int, far_m: dict[str, float] | None = None) -> None:
        import h5py  # the demos extra

        self.path = out / STAGING / f"seed-{seed}.h5"
        self.tmp = self.path.with_suffix(".h5.tmp")
        self.file = h5py.File(self.tmp, "w")
        self.stride = stride
        self.far_m = far_m or {}  # each camera's far plane: its depth is kept as a share of it
        self.n = 0

    def _append(self, name: str, value: np.ndarray, **kw: Any) -> None:
        value = np.asarray(value)
        if name not in self.file:
            self.file.create_dataset(name, shape=(0, *value.shape), maxshape=(None, *value.shape), dtype=value.dtype,
                                     chunks=(1, *value.shape), **kw)  # fmt: skip
        d = self.file[name]
        d.resize(d.shape[0] + 1, axis=0)
        d[-1] = value

    def row(self, row: Row) -> None:
        self._append("obs/state", row.state)
        self._append("rewards", np.array(0.0))  # (the last one set by close: 1 for a success)
        self._append("dones", np.array(0, dtype=np.uint8))
        self._append("actions", row.action)
        self._append("action_ticks", hold_ticks(row.ticks, self.stride))
        self._append("action_tick_counts", np.array(len(row.ticks), dtype=np.int64))
        self._append("states", row.sim_state)
        self._append("timestamps", np.array(row.time_s))
        for cam, (rgb, depth) in row.images.items():
            self._append(f"obs/{cam}_rgb", rgb, compression="lzf")
            far = self.far_m.get(cam, DEPTH_FAR_M)
            self._append(f"obs/{cam}_depth", (np.asarray(depth, dtype=np.float32) / far)[..., None], compression="lzf")
            self.file[f"obs/{cam}_depth"].attrs["scale_m"] = far
        self.n += 1

    def close(self, keep: bool, success: bool = False) -> None:
        if self.n:
            self.file["dones"][-1] = 1
            self.file["rewards"][-1] = float(success)
        self.file.close()
        if keep:
            os.replace(self.tmp, self.path)
        else:
            self.tmp.unlink()


def finalize_hdf5(out: Path, records: dict[int, dict], meta: dict, *, only_success: bool) -> int:
    """``out/demos.hdf5`` from the staged episodes (rewritten whole); how many episodes it holds.

    As robomimic reads it: ``env_args`` that rebuild the environment the actions act in (robomimic's Gym
    type, the frames' rate, the images, each action in [-1, 1]: ``unit_actions``); ``actions`` in
    [-1, 1] on the bounds in ``data.attrs["action_bounds"]`` (the joints' limits: the native actions stay
    in ``action_ticks``); depth (N, H, W, 1) as a share of the camera's far plane (robomimic clips a frame
    to [0, 1]; ``obs/<camera>_depth`` attrs ``scale_m``: metres = value x scale); ``next_obs/<key>`` the
    next frame's (the last its own), as virtual datasets on ``obs/``."""
    import h5py

    kept = [r for _, r in sorted(records.items()) if r["kept"] and (r["success"] or not only_success)]
    low, high = (np.asarray(b, dtype=np.float64) for b in meta["action_bounds"])
    tmp = out / "demos.hdf5.tmp"
    with h5py.File(tmp, "w") as f:
        data = f.create_group("data")
        env_kwargs = {"scenario": meta["scenario"], "robot": meta["robot"],
                      "obs_mode": "rgbd" if meta["cameras"] else "state", "control_mode": "joint_pos",
                      "agent_rate_hz": meta["fps"], "gripper": "opening_force", "image_width": meta["image_width"],
                      "image_height": meta.get("image_height"),
                      "unit_actions": True}  # fmt: skip
        data.attrs["env_args"] = json.dumps(
            {"env_name": meta["env_id"], "type": ROBOMIMIC_GYM_TYPE, "env_kwargs": env_kwargs}
        )
        data.attrs["action_bounds"] = json.dumps({"low": low.tolist(), "high": high.tolist()})
        data.attrs["pickdemo"] = json.dumps(meta)
        total = 0
        for k, r in enumerate(kept):
            with h5py.File(out / STAGING / f"seed-{r['seed']}.h5", "r") as src:
                g = data.create_group(f"demo_{k}")
                for name in src:
                    src.copy(src[name], g, name=name)
            g["actions"][...] = np.clip(2.0 * (g["actions"][...] - low) / (high - low) - 1.0, -1.0, 1.0)
            for key, obs in g["obs"].items():  # the next frame's, without copying it
                n = obs.shape[0]
                layout = h5py.VirtualLayout(shape=obs.shape, dtype=obs.dtype)
                source = h5py.VirtualSource(obs)
                layout[: n - 1] = source[1:]
                layout[n - 1] = source[n - 1]
                g.create_virtual_dataset(f"next_obs/{key}", layout)
            g.attrs.update(seed=r["seed"], success=r["success"], failure=r["failure"] or "", num_samples=r["frames"])
            total += r["frames"]
        data.attrs["total"] = total
    os.replace(tmp, out / "demos.hdf5")
    return len(kept)


def hdf5_meta(out: Path) -> dict:
    """What ``out/demos.hdf5`` was recorded with."""
    import h5py

    with h5py.File(out / "demos.hdf5", "r") as f:
        return json.loads(f["data"].attrs["pickdemo"])


def read_hdf5(out: Path, episode: int) -> tuple[dict, dict, np.ndarray, np.ndarray | None, np.ndarray]:
    """(meta, the episode's attributes, every tick's action (T x stride, A), how many ticks each frame
    acted (None: written before the counts), the states (T, Z))."""
    import h5py

    path = out / "demos.hdf5"
    if not path.is_file():
        raise DatasetError(f"{path}: no such file (record with `pickdemo demos ... --format hdf5`)")
    with h5py.File(path, "r") as f:
        meta = json.loads(f["data"].attrs["pickdemo"])
        name = f"demo_{episode}"
        if name not in f["data"]:
            raise DatasetError(f"{path}: no episode {episode} (it has {len(f['data'])})")
        g = f["data"][name]
        attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in g.attrs.items()}
        counts = np.asarray(g["action_tick_counts"]) if "action_tick_counts" in g else None
        return meta, attrs, np.asarray(g["action_ticks"]), counts, np.asarray(g["states"])


# ================================================================================ by format
def open_episode(
    fmt: str, out: Path, seed: int, stride: int, meta: dict, follower: Any = None
) -> Hdf5Episode | LeRobotEpisode:
    """An episode's sink; ``follower``: a LeRobot follower's channels (:mod:`pickdemo.envs.follower`)."""
    if fmt == "hdf5":
        return Hdf5Episode(out, seed, stride, meta.get("far_m"))
    return LeRobotEpisode(out, seed, stride, meta["fps"], meta.get("codec", "h264"), follower)


def finalize(fmt: str, out: Path, records: dict[int, dict], meta: dict, *, only_success: bool) -> int:
    if fmt == "hdf5":
        return finalize_hdf5(out, records, meta, only_success=only_success)
    return finalize_lerobot(out, records, meta, only_success=only_success)


def count_episodes(fmt: str, out: Path) -> int:
    """How many episodes the dataset in ``out`` holds."""
    if fmt == "hdf5":
        import h5py

        path = out / "demos.hdf5"
        if not path.is_file():
            raise DatasetError(f"{path}: no such file")
        with h5py.File(path, "r") as f:
            return len(f["data"])
    path = out / "meta" / "info.json"
    if not path.is_file():
        raise DatasetError(f"{path}: no such file")
    return int(json.loads(path.read_text())["total_episodes"])


def read_episode(fmt: str, out: Path, episode: int) -> tuple[dict, np.ndarray, np.ndarray | None, np.ndarray]:
    """(the episode's attributes: seed, success, failure; every tick's action by frame (T, stride x A); how
    many ticks each frame acted; the simulator's states)."""
    if fmt == "hdf5":
        _meta, attrs, ticks, counts, states = read_hdf5(out, episode)
        return attrs, ticks, counts, states
    return read_lerobot(out, episode)
