"""LeRobot's v3 format: ``data/chunk-000/file-K.parquet`` and ``videos/observation.images.<camera>/chunk-000/
file-K.mp4`` per episode, ``meta/info.json``, ``meta/stats.json``, ``meta/tasks.parquet``,
``meta/episodes/chunk-000/file-000.parquet`` (each episode's statistics in its row, LeRobot's writer's
``stats/<feature>/<stat>``), and ``meta/pickdemo.json``. Written episode by episode into the staging
(:mod:`pickdemo.apps.staging`), made from it, and read back for replay. Two layouts:

- **pickdemo's** (H.264): ``observation.state`` the environment's state, ``action`` its action;
  pickdemo's own columns beside them, outside LeRobot's ``observation.*`` and ``action*`` names, which
  its policies take as inputs and outputs (``pickdemo.sim_state``, ``pickdemo.action_ticks``,
  ``pickdemo.tick_count``), ``next.reward``, ``next.done`` and ``next.success``; the episodes' seeds and
  outcomes in ``meta/episodes/`` (``pickdemo/seed`` ...).
- **a follower's** (a robot file's ``[lerobot]``, :mod:`pickdemo.envs.follower`): the features a real
  recording of that arm has and nothing else (its channels, its cameras' names, its codec, its
  ``robot_type``), so that LeRobot's tools take both together (its ``merge_datasets`` asks for the same
  features); what pickdemo keeps for replay (the environment's state and action, the simulator's state,
  every tick's action, the rewards, the seeds) lies beside them in ``pickdemo/``, which LeRobot does not
  read.
"""

from __future__ import annotations

import json
import os
from fractions import Fraction
from pathlib import Path
from typing import Any

import numpy as np

from pickdemo.apps.files import write_atomic
from pickdemo.apps.staging import STAGING, DatasetError, hold_ticks, remove_tree
from pickdemo.envs.record import Row

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


#: Each codec's encoder and options. A key frame every other (LeRobot seeks by time), one thread (the
#: same bytes on any number of cores; for H.264, also faster for frames this small: evidence in
#: docs/decisions.md#gymnasium-and-demonstrations). AV1: LeRobot's recorder's own encoder and settings
#: (``encode_video_frames``: libsvtav1, g 2, crf 30).
CODECS = {
    "h264": ("libx264", {"crf": "23", "g": "2", "bf": "0", "preset": "veryfast", "threads": "1"}),
    "av1": ("libsvtav1", {"g": "2", "crf": "30", "svtav1-params": "lp=1"}),
}
#: The staged columns of a follower's channels (:class:`~pickdemo.envs.follower.FollowerChannels`)
FOLLOWER_STATE, FOLLOWER_ACTION = "follower.state", "follower.action"


class LeRobotEpisode:
    """One episode into ``.staging/seed-N/``: its rows' table and an MP4 per camera (``codec``);
    ``follower``: the follower's channels, staged beside the environment's state and action."""

    def __init__(
        self, out: Path, seed: int, stride: int, fps: float, codec: str = "h264", follower: Any = None
    ) -> None:
        self.dir = out / STAGING / f"seed-{seed}"
        self.tmp = out / STAGING / f"seed-{seed}.tmp"
        if self.tmp.exists():
            remove_tree(self.tmp)
        self.tmp.mkdir(parents=True)
        self.stride, self.fps, self.codec, self.follower = stride, fps, codec, follower
        self.rows: dict[str, list] = {"state": [], "action": [], "ticks": [], "counts": [], "sim_state": []}
        self.rows |= {FOLLOWER_STATE: [], FOLLOWER_ACTION: []} if follower is not None else {}
        self.videos: dict[str, Any] = {}
        self.pixels: dict[str, list[np.ndarray]] = {}  # every fourth frame's every 16th pixel, for the statistics

    def _video(self, cam: str, rgb: np.ndarray) -> Any:
        if cam not in self.videos:
            import av  # the demos extra (PyAV)

            if self.codec == "av1":  # (SVT-AV1 prints its settings to stderr at every video; errors only)
                os.environ.setdefault("SVT_LOG", "1")
            encoder, options = CODECS[self.codec]
            container = av.open(str(self.tmp / f"{cam}.mp4"), "w")
            stream = container.add_stream(encoder, rate=int(round(self.fps)), options=dict(options))
            stream.width, stream.height = rgb.shape[1], rgb.shape[0]
            stream.pix_fmt = "yuv420p"
            self.videos[cam] = (container, stream)
        return self.videos[cam]

    def row(self, row: Row) -> None:
        import av

        self.rows["state"].append(row.state.astype(np.float32))
        self.rows["action"].append(row.action.astype(np.float32))
        self.rows["ticks"].append(hold_ticks(row.ticks, self.stride).ravel())
        self.rows["counts"].append(len(row.ticks))
        self.rows["sim_state"].append(row.sim_state)
        if self.follower is not None:
            self.rows[FOLLOWER_STATE].append(self.follower.state(row.state).astype(np.float32))
            self.rows[FOLLOWER_ACTION].append(self.follower.action(row.action).astype(np.float32))
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
                | {k: vectors(self.rows[k], pa.float32()) for k in (FOLLOWER_STATE, FOLLOWER_ACTION) if k in self.rows}
            )
            pq.write_table(table, self.tmp / "frames.parquet")
            # the episode's own statistics, once (the dataset's are made of them: LeRobot's way)
            stats = {name: _stats(_column(table, name)) for name in table.column_names if name != "frame_index"}
            stats |= {IMAGE_KEY.format(cam): _pixel_stats(px) for cam, px in self.pixels.items()}
            write_atomic(self.tmp / "stats.json", json.dumps(stats) + "\n")
            if self.dir.exists():
                remove_tree(self.dir)
            os.replace(self.tmp, self.dir)
        else:
            remove_tree(self.tmp)


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


#: A follower's layout: pickdemo's own per-frame columns and its episodes, beside LeRobot's (which it does not read)
OWN_DIR = "pickdemo"
#: ... the environment's own state and action there
OWN_STATE, OWN_ACTION = "pickdemo.state", "pickdemo.action"


def finalize_lerobot(out: Path, records: dict[int, dict], meta: dict, *, only_success: bool) -> int:
    """LeRobot v3's layout in ``out`` from the staged episodes (its tables and meta rewritten, each
    episode's MP4 linked in); how many episodes it holds. ``meta["follower"]``: a follower's layout."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    kept = [r for _, r in sorted(records.items()) if r["kept"] and (r["success"] or not only_success)]
    fps = meta["fps"]
    follower = meta.get("follower")
    names = {cam: cam for cam in meta["cameras"]} | (follower["cameras"] if follower else {})
    for sub in ("data", OWN_DIR):
        for old in (out / sub / CHUNK).glob("file-*.parquet"):
            old.unlink()
    (out / "meta" / "episodes" / CHUNK).mkdir(parents=True, exist_ok=True)
    for sub in ("data",) + ((OWN_DIR,) if follower else ()):
        (out / sub / CHUNK).mkdir(parents=True, exist_ok=True)
    episodes: list[dict] = []
    own_episodes: list[dict] = []
    per_episode: list[dict[str, dict]] = []
    index = 0
    sim_size = 0
    for k, r in enumerate(kept):
        src = out / STAGING / f"seed-{r['seed']}"
        staged_table = pq.read_table(src / "frames.parquet")
        n = staged_table.num_rows
        frame_index = np.arange(n, dtype=np.int64)
        done = np.zeros(n, dtype=bool)
        done[-1] = True
        success = done & bool(r["success"])
        place = {
            "timestamp": pa.array((frame_index / fps).astype(np.float32)),
            "frame_index": pa.array(frame_index),
            "episode_index": pa.array(np.full(n, k, dtype=np.int64)),
            "index": pa.array(np.arange(index, index + n, dtype=np.int64)),
            "task_index": pa.array(np.zeros(n, dtype=np.int64)),
        }
        outcome = {
            "next.reward": pa.array(success.astype(np.float32)),
            "next.done": pa.array(done),
            "next.success": pa.array(success),
        }
        own = {c: staged_table.column(c) for c in (SIM_STATE, ACTION_TICKS, TICK_COUNTS)}
        if follower:  # LeRobot's features only; the rest beside them
            table = pa.table(
                {
                    "observation.state": staged_table.column(FOLLOWER_STATE),
                    "action": staged_table.column(FOLLOWER_ACTION),
                }
                | place
            )
            mine = {OWN_STATE: staged_table.column("observation.state"), OWN_ACTION: staged_table.column("action")}
            mine |= own | outcome | {"frame_index": place["frame_index"], "episode_index": place["episode_index"]}
            pq.write_table(pa.table(mine), out / OWN_DIR / CHUNK / f"file-{k:03d}.parquet")
        else:
            table = pa.table(
                {"observation.state": staged_table.column("observation.state"), "action": staged_table.column("action")}
                | own
                | place
                | outcome
            )
        pq.write_table(table, out / "data" / CHUNK / f"file-{k:03d}.parquet")
        sim_size = len(staged_table.column(SIM_STATE)[0])
        # the episode's statistics: those made as it was recorded, and its place in the dataset's columns
        made = json.loads((src / "stats.json").read_text())
        if follower:
            made["observation.state"], made["action"] = made.pop(FOLLOWER_STATE), made.pop(FOLLOWER_ACTION)
        made = {IMAGE_KEY.format(names[key[len(IMAGE_KEY) - 2 :]]) if key.startswith(IMAGE_KEY[:-2]) else key: v
                for key, v in made.items()}  # fmt: skip
        stats = {name: st for name, st in made.items() if name in table.column_names or name.startswith(IMAGE_KEY[:-2])}
        stats |= {name: _stats(_column(table, name)) for name in POSITIONAL if name in table.column_names}
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
        }
        mine_ep = {
            "pickdemo/seed": r["seed"],
            "pickdemo/success": bool(r["success"]),
            "pickdemo/failure": r["failure"] or "",
        }
        if follower:
            own_episodes.append({"episode_index": k} | mine_ep)
        else:
            ep |= mine_ep
        for cam in meta["cameras"]:
            key = IMAGE_KEY.format(names[cam])
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
    if follower:
        pq.write_table(pa.Table.from_pylist(own_episodes), out / OWN_DIR / "episodes.parquet")
    tasks = pa.table({"task_index": pa.array([0], pa.int64()), "task": pa.array([meta["task"]], pa.string())})
    pq.write_table(tasks.replace_schema_metadata({"pandas": json.dumps(TASKS_PANDAS)}), out / "meta" / "tasks.parquet")
    write_atomic(out / "meta" / "stats.json", json.dumps(aggregate_stats(per_episode), indent=1) + "\n")
    write_atomic(out / "meta" / "info.json", json.dumps(_info(meta, len(kept), index, sim_size), indent=2) + "\n")
    write_atomic(out / "meta" / "pickdemo.json", json.dumps(meta, indent=2) + "\n")
    return len(kept)


def _info(meta: dict, episodes: int, frames: int, sim_size: int) -> dict:
    fps = int(round(meta["fps"]))
    follower = meta.get("follower")
    state_names = follower["names"] if follower else meta["state_names"]
    action_names = follower["names"] if follower else meta["action_names"]
    features: dict[str, Any] = {
        "observation.state": {"dtype": "float32", "shape": [len(state_names)], "names": state_names},
        "action": {"dtype": "float32", "shape": [len(action_names)], "names": action_names},
    }
    if not follower:
        features |= {
            SIM_STATE: {"dtype": "float64", "shape": [sim_size], "names": None},
            ACTION_TICKS: {"dtype": "float64", "shape": [meta["stride"] * len(action_names)], "names": None},
            TICK_COUNTS: {"dtype": "int64", "shape": [1], "names": None},
        }
    names = follower["cameras"] if follower else {}
    for cam, (w, h) in meta["cameras"].items():
        features[IMAGE_KEY.format(names.get(cam, cam))] = {
            "dtype": "video",
            "shape": [h, w, 3],
            "names": ["height", "width", "channels"],
            # (as LeRobot's get_video_info describes a video)
            "info": {"video.height": h, "video.width": w, "video.codec": meta.get("codec", "h264"),
                     "video.pix_fmt": "yuv420p", "video.is_depth_map": False, "video.fps": fps,
                     "video.channels": 3, "has_audio": False},
        }  # fmt: skip
    for name, dtype in (("timestamp", "float32"), ("frame_index", "int64"), ("episode_index", "int64"),
                        ("index", "int64"), ("task_index", "int64")):  # fmt: skip
        features[name] = {"dtype": dtype, "shape": [1], "names": None}
    if not follower:
        features["next.reward"] = {"dtype": "float32", "shape": [1], "names": None}
        features["next.done"] = {"dtype": "bool", "shape": [1], "names": None}
        features["next.success"] = {"dtype": "bool", "shape": [1], "names": None}
    return {
        "codebase_version": "v3.0",
        "robot_type": follower["robot_type"] if follower else meta["robot_name"],
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
    gives float32), or from pickdemo's own beside a follower's."""
    import pyarrow.parquet as pq

    own = (out / OWN_DIR / "episodes.parquet").is_file()
    eps_path = out / OWN_DIR / "episodes.parquet" if own else out / "meta" / "episodes" / CHUNK / "file-000.parquet"
    if not eps_path.is_file():
        raise DatasetError(f"{eps_path}: no such file (record with `pickdemo demos ... --format lerobot`)")
    eps = pq.read_table(eps_path).to_pylist()
    if not 0 <= episode < len(eps):
        raise DatasetError(f"{eps_path}: no episode {episode} (it has {len(eps)})")
    ep = eps[episode]
    if own:
        table = pq.read_table(out / OWN_DIR / CHUNK / f"file-{episode:03d}.parquet")
    else:
        table = pq.read_table(out / "data" / CHUNK / f"file-{ep['data/file_index']:03d}.parquet")
    old = "action.ticks" in table.column_names  # (written before the simulator's columns left LeRobot's names)
    ticks = _column(table, "action.ticks" if old else ACTION_TICKS)
    states = _column(table, "observation.sim_state" if old else SIM_STATE)
    counts = None if old else _column(table, TICK_COUNTS)
    attrs = {"seed": ep["pickdemo/seed"], "success": ep["pickdemo/success"], "failure": ep["pickdemo/failure"]}
    return attrs, ticks, counts, states
