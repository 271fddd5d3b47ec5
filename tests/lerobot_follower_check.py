"""An SO-101 dataset of pickdemo's beside a recording LeRobot's own writer makes, with LeRobot itself (0.4.4,
in an environment of its own: it is not a dependency; docs/demonstrations.md#a-dataset-beside-a-real-one):

    python tests/lerobot_follower_check.py DATASET WORKDIR

The recording has the features LeRobot's recorder makes of an SO follower's motors and two 640 x 480
cameras (front, wrist). Printed: the two datasets' features compared, every frame of ours loaded, the two
merged (``merge_datasets``) and every frame of the merge loaded, the merge split and an episode deleted,
every frame of each result loaded."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

os.environ.setdefault("HF_HUB_OFFLINE", "1")

import numpy as np  # noqa: E402
from lerobot.datasets.dataset_tools import delete_episodes, merge_datasets, split_dataset  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402
from lerobot.datasets.utils import hw_to_dataset_features  # noqa: E402

MOTORS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def load(repo_id: str, root: Path) -> LeRobotDataset:
    return LeRobotDataset(repo_id, root=root, video_backend="pyav")  # (torchcodec needs FFmpeg's libraries)


def load_all(ds: LeRobotDataset, label: str) -> None:
    bad = 0
    for i in range(len(ds)):
        try:
            ds[i]
        except Exception as exc:  # noqa: BLE001 - every frame's failure counted and shown
            bad += 1
            if bad < 3:
                print("  frame", i, type(exc).__name__, exc)
    print(f"{label}: {len(ds)} frames, {ds.num_episodes} episodes, {bad} failed to load", flush=True)


def real_recording(root: Path) -> LeRobotDataset:
    """Two episodes of 45 frames, written by LeRobot as its recorder would write an SO follower's."""
    obs = {f"{m}.pos": float for m in MOTORS} | {"front": (480, 640, 3), "wrist": (480, 640, 3)}
    act = {f"{m}.pos": float for m in MOTORS}
    features = {**hw_to_dataset_features(act, "action"), **hw_to_dataset_features(obs, "observation")}
    ds = LeRobotDataset.create("real/so101", fps=30, features=features, root=root, robot_type="so_follower",
                               use_videos=True, video_backend="pyav")  # fmt: skip
    rng = np.random.default_rng(0)
    for _episode in range(2):
        for _frame in range(45):
            image = lambda: (rng.random((480, 640, 3)) * 255).astype(np.uint8)  # noqa: E731
            ds.add_frame({"observation.state": (rng.random(6) * 90).astype(np.float32),
                          "action": (rng.random(6) * 90).astype(np.float32),
                          "observation.images.front": image(), "observation.images.wrist": image(),
                          "task": "pick up the cube"})  # fmt: skip
        ds.save_episode()
    ds.finalize()
    return ds


def main(ours_root: Path, work: Path) -> None:
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    real_recording(work / "real")
    rf = json.loads((work / "real" / "meta" / "info.json").read_text())
    of = json.loads((ours_root / "meta" / "info.json").read_text())
    print("robot_type", rf["robot_type"], "|", of["robot_type"], "fps", rf["fps"], of["fps"])
    print("features only in one:", sorted(set(rf["features"]) ^ set(of["features"])))
    for k in rf["features"]:
        if k in of["features"] and rf["features"][k] != of["features"][k]:
            print("DIFFERS", k, rf["features"][k], "|", of["features"][k])
    ours = load("pickdemo/so101", ours_root)
    load_all(ours, "ours")
    merge_datasets([load("real/so101", work / "real"), ours], output_repo_id="merged/so101", output_dir=work / "merged")
    merged = load("merged/so101", work / "merged")
    load_all(merged, "merged (real + ours)")
    print("merged stats:", sorted(merged.meta.stats))
    for name, d in split_dataset(merged, splits={"train": 0.75, "val": 0.25}, output_dir=work / "split").items():
        load_all(load(d.repo_id, d.root), f"split {name}")
    d = delete_episodes(merged, episode_indices=[0], output_dir=work / "deleted", repo_id="deleted/so101")
    load_all(load(d.repo_id, d.root), "deleted episode 0")


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))
