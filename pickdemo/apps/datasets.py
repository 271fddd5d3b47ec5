"""Demonstration datasets on disk: HDF5 (one file, robomimic's layout) and LeRobot's v3 format
(Parquet tables, an MP4 per camera, ``meta/``), written episode by episode and read back for replay.

Each episode is first written whole into ``DIR/.staging/`` (into a temporary name, renamed when it is
complete: a killed run leaves no half episode there), with its record (``seed-N.json``). The dataset
itself is made from the staging by :func:`finalize`, after every episode and again at the end: a run
killed and started again with ``--resume`` records only the seeds not staged yet, and an episode is
never in the dataset twice. Episodes are numbered in seed order.

- **HDF5** (``DIR/demos.hdf5``): ``data/demo_K`` per episode with ``obs/state``, ``obs/<camera>_rgb``,
  ``obs/<camera>_depth``, ``actions``, ``action_ticks`` (every control tick's action; a short last
  frame's missing ticks hold its last action), ``action_tick_counts``,
  ``states`` (the simulator's, per frame); attributes ``seed``, ``success``, ``failure``,
  ``num_samples``; ``data`` has ``env_args`` (JSON) and ``total``.
- **LeRobot v3**: ``data/chunk-000/file-K.parquet`` and ``videos/observation.images.<camera>/chunk-000/
  file-K.mp4`` per episode (H.264), ``meta/info.json``, ``meta/stats.json``, ``meta/tasks.parquet``,
  ``meta/episodes/chunk-000/file-000.parquet``; pickdemo's own columns beside LeRobot's,
  outside its ``observation.*`` and ``action*`` names, which its policies take as inputs and outputs
  (``pickdemo.sim_state``, ``pickdemo.action_ticks``, ``pickdemo.tick_count``), ``next.reward`` and
  ``next.success``, each episode's statistics in its row of ``meta/episodes/`` (LeRobot's writer's
  ``stats/<feature>/<stat>``), and ``meta/pickdemo.json``.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from pickdemo.apps.files import write_atomic
from pickdemo.envs.record import Recorded, Row

STAGING = ".staging"
#: robomimic's ``EnvType.GYM_TYPE`` (``robomimic/envs/env_base.py``): an HDF5's ``env_args["type"]``
ROBOMIMIC_GYM_TYPE = 2
#: a camera's far plane where the recording does not say it (m): depth is kept as a share of it
DEPTH_FAR_M = 3.0
FORMATS = ("lerobot", "hdf5")


class DatasetError(Exception):
    """A dataset directory that cannot be used; the message is one line naming the file."""


# ================================================================================== staging
def staged(out: Path) -> dict[int, dict]:
    """The episodes staged in ``out``: seed -> its record (``seed-N.json``, written last)."""
    stage = out / STAGING
    records = {}
    for path in sorted(stage.glob("seed-*.json")) if stage.is_dir() else ():
        record = json.loads(path.read_text())
        records[int(record["seed"])] = record
    return records


def write_record(out: Path, recorded: Recorded, extra: dict) -> None:
    write_atomic(out / STAGING / f"seed-{recorded.seed}.json", json.dumps({**asdict(recorded), **extra}) + "\n")


def _hold_ticks(ticks: list[np.ndarray], stride: int) -> np.ndarray:
    """A frame's ticks' actions as (stride, A): a short last frame's missing ticks hold its last action
    (no NaN: LeRobot's tools turn a NaN into a null that no frame then loads); its count says how many
    were acted."""
    out = np.repeat(np.asarray(ticks[-1], dtype=np.float64)[None, :], stride, axis=0)
    out[: len(ticks)] = ticks
    return out


def acted_ticks(ticks: np.ndarray, counts: np.ndarray | None, width: int) -> list[np.ndarray]:
    """Every acted tick's action of an episode, in order, from its frames' ``ticks`` (T, stride x A) and
    how many each acted (None: a dataset written before the counts, its missing ticks NaN)."""
    rows = np.asarray(ticks, dtype=np.float64).reshape(len(ticks), -1, width)
    if counts is None:
        return [row for frame in rows for row in frame if not np.isnan(row).any()]
    return [row for frame, n in zip(rows, counts, strict=True) for row in frame[: int(n)]]


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
        self._append("action_ticks", _hold_ticks(row.ticks, self.stride))
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


# =================================================================================== LeRobot
CHUNK = "chunk-000"
#: tasks.parquet's pandas metadata: LeRobot reads the task strings as the table's (pandas) index
TASKS_PANDAS = {
    "index_columns": ["task"],
    "column_indexes": [],
    "columns": [
        {
            "name": "task_index",
            "field_name": "task_index",
            "pandas_type": "int64",
            "numpy_type": "int64",
            "metadata": None,
        },
        {"name": "task", "field_name": "task", "pandas_type": "unicode", "numpy_type": "object", "metadata": None},
    ],
}
IMAGE_KEY = "observation.images.{}"
#: pickdemo's own columns, outside LeRobot's ``observation.*`` and ``action*`` (which its policies take as
#: their inputs and outputs): the simulator's state (float64, for an exact replay), every tick's action
#: and how many ticks a frame acted (a short last frame's missing ones hold its last action)
SIM_STATE, ACTION_TICKS, TICK_COUNTS = "pickdemo.sim_state", "pickdemo.action_ticks", "pickdemo.tick_count"
#: the columns whose values are an episode's place in the dataset: their statistics made there
POSITIONAL = (
    "timestamp",
    "frame_index",
    "episode_index",
    "index",
    "task_index",
    "next.reward",
    "next.done",
    "next.success",
)


class LeRobotEpisode:
    """One episode into ``.staging/seed-N/``: its rows' table and an H.264 MP4 per camera."""

    def __init__(self, out: Path, seed: int, stride: int, fps: float) -> None:
        self.dir = out / STAGING / f"seed-{seed}"
        self.tmp = out / STAGING / f"seed-{seed}.tmp"
        if self.tmp.exists():
            _remove_tree(self.tmp)
        self.tmp.mkdir(parents=True)
        self.stride, self.fps = stride, fps
        self.rows: dict[str, list] = {"state": [], "action": [], "ticks": [], "counts": [], "sim_state": []}
        self.videos: dict[str, Any] = {}
        self.pixels: dict[str, list[np.ndarray]] = {}  # every fourth frame's every 16th pixel, for the statistics

    def _video(self, cam: str, rgb: np.ndarray) -> Any:
        if cam not in self.videos:
            import av  # the demos extra (PyAV)

            container = av.open(str(self.tmp / f"{cam}.mp4"), "w")
            stream = container.add_stream("libx264", rate=int(round(self.fps)))
            stream.width, stream.height = rgb.shape[1], rgb.shape[0]
            stream.pix_fmt = "yuv420p"
            # A key frame every other (LeRobot seeks by time). One thread: the same bytes on any number of
            # cores, and faster for frames this small (evidence: docs/decisions.md#gymnasium-and-demonstrations).
            stream.options = {"crf": "23", "g": "2", "bf": "0", "preset": "veryfast", "threads": "1"}
            self.videos[cam] = (container, stream)
        return self.videos[cam]

    def row(self, row: Row) -> None:
        import av

        self.rows["state"].append(row.state.astype(np.float32))
        self.rows["action"].append(row.action.astype(np.float32))
        self.rows["ticks"].append(_hold_ticks(row.ticks, self.stride).ravel())
        self.rows["counts"].append(len(row.ticks))
        self.rows["sim_state"].append(row.sim_state)
        for cam, (rgb, _depth) in row.images.items():
            if (len(self.rows["state"]) - 1) % 4 == 0:
                self.pixels.setdefault(cam, []).append(rgb.reshape(-1, 3)[::16] / 255.0)
            container, stream = self._video(cam, rgb)
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
            frame.pts = len(self.rows["state"]) - 1  # frame k at k / fps exactly: LeRobot finds frames by time
            frame.time_base = Fraction(1, int(round(self.fps)))
            for packet in stream.encode(frame):
                container.mux(packet)

    def close(self, keep: bool, success: bool = False) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        for container, stream in self.videos.values():
            for packet in stream.encode():
                container.mux(packet)
            container.close()
        if keep:
            n = len(self.rows["state"])

            def vectors(rows: list[np.ndarray], dtype: Any) -> Any:  # LeRobot's Sequence(length=N): a fixed-size list
                return pa.array(list(rows), type=pa.list_(dtype, len(rows[0])))

            table = pa.table(
                {
                    "observation.state": vectors(self.rows["state"], pa.float32()),
                    "action": vectors(self.rows["action"], pa.float32()),
                    SIM_STATE: vectors(self.rows["sim_state"], pa.float64()),
                    ACTION_TICKS: vectors(self.rows["ticks"], pa.float64()),
                    TICK_COUNTS: pa.array(self.rows["counts"], type=pa.int64()),
                    "frame_index": pa.array(np.arange(n), type=pa.int64()),
                }
            )
            pq.write_table(table, self.tmp / "frames.parquet")
            # the episode's own statistics, once (the dataset's are made of them: LeRobot's way)
            stats = {name: _stats(_column(table, name)) for name in table.column_names if name != "frame_index"}
            stats |= {IMAGE_KEY.format(cam): _pixel_stats(px) for cam, px in self.pixels.items()}
            write_atomic(self.tmp / "stats.json", json.dumps(stats) + "\n")
            if self.dir.exists():
                _remove_tree(self.dir)
            os.replace(self.tmp, self.dir)
        else:
            _remove_tree(self.tmp)


def _remove_tree(path: Path) -> None:
    for p in sorted(path.rglob("*"), reverse=True):
        p.rmdir() if p.is_dir() else p.unlink()
    path.rmdir()


QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)


def _column(table: Any, name: str) -> np.ndarray:
    values = table.column(name).to_numpy(zero_copy_only=False)
    return np.stack(values) if values.dtype == object else values


def _stats(values: np.ndarray) -> dict[str, list]:
    """LeRobot's per-feature statistics over an episode's frames (a scalar feature's as one-element lists)."""
    v = np.asarray(values, dtype=np.float64)
    v = v.reshape(len(v), -1)
    out = {"min": v.min(0), "max": v.max(0), "mean": v.mean(0), "std": v.std(0)}
    out |= {f"q{int(q * 100):02d}": np.quantile(v, q, axis=0) for q in QUANTILES}
    return {k: x.tolist() for k, x in out.items()} | {"count": [int(len(v))]}


def _pixel_stats(pixels: list[np.ndarray]) -> dict[str, list]:
    """Per channel, of the pixels in [0, 1], as LeRobot keeps them (shape (3, 1, 1)): from every fourth
    frame, every 16th pixel of it; the count is the frames sampled."""
    x = np.concatenate(pixels)
    out = {"min": x.min(0), "max": x.max(0), "mean": x.mean(0), "std": x.std(0)}
    out |= {f"q{int(q * 100):02d}": np.quantile(x, q, axis=0) for q in QUANTILES}
    return {k: [[[float(c)]] for c in v] for k, v in out.items()} | {"count": [len(pixels)]}


def aggregate_stats(episodes: list[dict[str, dict]]) -> dict[str, dict]:
    """The dataset's statistics from its episodes', as LeRobot's ``aggregate_stats`` makes them: the
    least and the most; the mean and the variance weighted by the episodes' counts (the variance about
    the whole mean); the quantiles as their count-weighted means."""
    out: dict[str, dict] = {}
    for name in episodes[0] if episodes else ():
        parts = [e[name] for e in episodes if name in e]
        n = np.array([p["count"][0] for p in parts], dtype=np.float64)
        w = (n / n.sum()).reshape(-1, *([1] * np.ndim(parts[0]["mean"])))
        mean = np.sum([np.asarray(p["mean"]) for p in parts] * w, axis=0)
        var = np.sum([np.asarray(p["std"]) ** 2 + (np.asarray(p["mean"]) - mean) ** 2 for p in parts] * w, axis=0)
        agg = {"min": np.min([p["min"] for p in parts], axis=0), "max": np.max([p["max"] for p in parts], axis=0),
               "mean": mean, "std": np.sqrt(var)}  # fmt: skip
        agg |= {q: np.sum([np.asarray(p[q]) for p in parts] * w, axis=0) for q in parts[0] if q.startswith("q")}
        out[name] = {k: np.asarray(v).tolist() for k, v in agg.items()} | {"count": [int(n.sum())]}
    return out


def finalize_lerobot(out: Path, records: dict[int, dict], meta: dict, *, only_success: bool) -> int:
    """LeRobot v3's layout in ``out`` from the staged episodes (its tables and meta rewritten, each
    episode's MP4 linked in); how many episodes it holds."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    kept = [r for _, r in sorted(records.items()) if r["kept"] and (r["success"] or not only_success)]
    fps = meta["fps"]
    cams = list(meta["cameras"])
    (out / "meta" / "episodes" / CHUNK).mkdir(parents=True, exist_ok=True)
    (out / "data" / CHUNK).mkdir(parents=True, exist_ok=True)
    for old in (out / "data" / CHUNK).glob("file-*.parquet"):
        old.unlink()
    episodes: list[dict] = []
    per_episode: list[dict[str, dict]] = []
    index = 0
    sim_size = 0
    for k, r in enumerate(kept):
        src = out / STAGING / f"seed-{r['seed']}"
        table = pq.read_table(src / "frames.parquet")
        n = table.num_rows
        frame_index = np.arange(n, dtype=np.int64)
        done = np.zeros(n, dtype=bool)
        done[-1] = True
        success = done & bool(r["success"])
        table = (
            table.drop_columns(["frame_index"])
            .append_column("timestamp", pa.array((frame_index / fps).astype(np.float32)))
            .append_column("frame_index", pa.array(frame_index))
            .append_column("episode_index", pa.array(np.full(n, k, dtype=np.int64)))
            .append_column("index", pa.array(np.arange(index, index + n, dtype=np.int64)))
            .append_column("task_index", pa.array(np.zeros(n, dtype=np.int64)))
            .append_column("next.reward", pa.array(success.astype(np.float32)))
            .append_column("next.done", pa.array(done))
            .append_column("next.success", pa.array(success))
        )
        pq.write_table(table, out / "data" / CHUNK / f"file-{k:03d}.parquet")
        sim_size = len(table.column(SIM_STATE)[0])
        # the episode's statistics: those made as it was recorded, and its place in the dataset's columns
        stats = json.loads((src / "stats.json").read_text())
        stats |= {name: _stats(_column(table, name)) for name in POSITIONAL}
        per_episode.append(stats)
        ep = {
            "episode_index": k,
            "tasks": [meta["task"]],
            "length": n,
            "data/chunk_index": 0,
            "data/file_index": k,
            "dataset_from_index": index,
            "dataset_to_index": index + n,
            "meta/episodes/chunk_index": 0,
            "meta/episodes/file_index": 0,
            "pickdemo/seed": r["seed"],
            "pickdemo/success": bool(r["success"]),
            "pickdemo/failure": r["failure"] or "",
        }
        for cam in cams:
            key = IMAGE_KEY.format(cam)
            dst = out / "videos" / key / CHUNK / f"file-{k:03d}.mp4"
            dst.parent.mkdir(parents=True, exist_ok=True)
            if dst.exists():
                dst.unlink()
            os.link(src / f"{cam}.mp4", dst)
            ep |= {f"videos/{key}/chunk_index": 0, f"videos/{key}/file_index": k,
                   f"videos/{key}/from_timestamp": 0.0, f"videos/{key}/to_timestamp": n / fps}  # fmt: skip
        # LeRobot's per-episode statistics, as its writer keeps them: a column each (its split and delete
        # remake the dataset's from these)
        ep |= {f"stats/{name}/{stat}": value for name, st in stats.items() for stat, value in st.items()}
        episodes.append(ep)
        index += n
    pq.write_table(pa.Table.from_pylist(episodes), out / "meta" / "episodes" / CHUNK / "file-000.parquet")
    tasks = pa.table({"task_index": pa.array([0], pa.int64()), "task": pa.array([meta["task"]], pa.string())})
    pq.write_table(tasks.replace_schema_metadata({"pandas": json.dumps(TASKS_PANDAS)}), out / "meta" / "tasks.parquet")
    write_atomic(out / "meta" / "stats.json", json.dumps(aggregate_stats(per_episode), indent=1) + "\n")
    write_atomic(out / "meta" / "info.json", json.dumps(_info(meta, len(kept), index, sim_size), indent=2) + "\n")
    write_atomic(out / "meta" / "pickdemo.json", json.dumps(meta, indent=2) + "\n")
    return len(kept)


def _info(meta: dict, episodes: int, frames: int, sim_size: int) -> dict:
    fps = int(round(meta["fps"]))
    S, A = len(meta["state_names"]), len(meta["action_names"])
    features: dict[str, Any] = {
        "observation.state": {"dtype": "float32", "shape": [S], "names": meta["state_names"]},
        "action": {"dtype": "float32", "shape": [A], "names": meta["action_names"]},
        SIM_STATE: {"dtype": "float64", "shape": [sim_size], "names": None},
        ACTION_TICKS: {"dtype": "float64", "shape": [meta["stride"] * A], "names": None},
        TICK_COUNTS: {"dtype": "int64", "shape": [1], "names": None},
    }
    for cam, (w, h) in meta["cameras"].items():
        features[IMAGE_KEY.format(cam)] = {
            "dtype": "video",
            "shape": [h, w, 3],
            "names": ["height", "width", "channels"],
            "info": {"video.height": h, "video.width": w, "video.codec": "h264", "video.pix_fmt": "yuv420p",
                     "video.fps": fps, "video.channels": 3, "has_audio": False, "is_depth_map": False},
        }  # fmt: skip
    for name, dtype in (("timestamp", "float32"), ("frame_index", "int64"), ("episode_index", "int64"),
                        ("index", "int64"), ("task_index", "int64")):  # fmt: skip
        features[name] = {"dtype": dtype, "shape": [1], "names": None}
    features["next.reward"] = {"dtype": "float32", "shape": [1], "names": None}
    features["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
    features["next.success"] = {"dtype": "bool", "shape": [1], "names": None}
    return {
        "codebase_version": "v3.0",
        "robot_type": meta["robot_name"],
        "total_episodes": episodes,
        "total_frames": frames,
        "total_tasks": 1,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500,
        "fps": fps,
        "splits": {"train": f"0:{episodes}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": features,
    }


def read_lerobot(out: Path, episode: int) -> tuple[dict, np.ndarray, np.ndarray | None, np.ndarray]:
    """(the episode's attributes, every tick's action (T, stride x A), how many each frame acted (None:
    written before the counts), the states (T, Z)) from its table, as written (float64: LeRobot's loader
    gives float32)."""
    import pyarrow.parquet as pq

    eps_path = out / "meta" / "episodes" / CHUNK / "file-000.parquet"
    if not eps_path.is_file():
        raise DatasetError(f"{eps_path}: no such file (record with `pickdemo demos ... --format lerobot`)")
    eps = pq.read_table(eps_path).to_pylist()
    if not 0 <= episode < len(eps):
        raise DatasetError(f"{eps_path}: no episode {episode} (it has {len(eps)})")
    ep = eps[episode]
    table = pq.read_table(out / "data" / CHUNK / f"file-{ep['data/file_index']:03d}.parquet")
    old = "action.ticks" in table.column_names  # (written before the simulator's columns left LeRobot's names)
    ticks = _column(table, "action.ticks" if old else ACTION_TICKS)
    states = _column(table, "observation.sim_state" if old else SIM_STATE)
    counts = None if old else _column(table, TICK_COUNTS)
    attrs = {"seed": ep["pickdemo/seed"], "success": ep["pickdemo/success"], "failure": ep["pickdemo/failure"]}
    return attrs, ticks, counts, states


# ================================================================================ by format
def open_episode(fmt: str, out: Path, seed: int, stride: int, meta: dict) -> Hdf5Episode | LeRobotEpisode:
    if fmt == "hdf5":
        return Hdf5Episode(out, seed, stride, meta.get("far_m"))
    return LeRobotEpisode(out, seed, stride, meta["fps"])


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
