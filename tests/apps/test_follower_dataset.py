"""A LeRobot dataset of an arm whose robot file names its LeRobot follower (``[lerobot]``): the features a
real recording of that arm has, in its units, and nothing else (LeRobot's ``merge_datasets`` asks for the
same features; checked against LeRobot 0.4.4's own writer in docs/measurements/gym.md), with pickdemo's
own columns beside them for replay."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pickdemo.envs.follower import FollowerChannels
from pickdemo.robot import robot_named

MOTORS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def _names(n: int) -> list[str]:
    return [f"joint_pos.{i}" for i in range(n)] + [f"joint_vel.{i}" for i in range(n)] + ["finger.0", "finger.1"]


def test_a_followers_channels_are_in_lerobots_units() -> None:
    """The arm's joints in degrees from their zero; the jaw 0 (its lower limit) to 100 (its upper), from
    its measured opening in the state and its commanded one in the action."""
    r = robot_named("so101")
    assert r.lerobot is not None
    ch = FollowerChannels(r.lerobot, r, _names(r.dof))
    q = np.array([0.1, -0.2, 0.3, 0.0, 1.0])
    lo, hi = r.lerobot.channels[-1].low, r.lerobot.channels[-1].high
    open_pct = 100.0 * (r.gripper.joint_targets(r.gripper.finger_max_m)[0] - lo) / (hi - lo)
    state = ch.state(np.r_[q, np.zeros(r.dof), r.gripper.finger_max_m, r.gripper.finger_max_m])
    assert state == pytest.approx([*np.degrees(q), open_pct])
    opened = ch.action(np.r_[q, 1.0, 0.0])  # (the gripper's opening +1: wide open; its force)
    closed = ch.action(np.r_[q, -1.0, 0.0])
    assert opened == pytest.approx(state)
    assert 0.0 <= closed[-1] < 1.0  # shut: the jaw at its lower limit, give or take the table's first row
    assert ch.names == [f"{m}.pos" for m in MOTORS]


@pytest.mark.sim
@pytest.mark.slow
def test_an_so101_dataset_has_a_real_followers_features_and_replays(tmp_path: Path) -> None:
    pytest.importorskip("gymnasium")
    pq = pytest.importorskip("pyarrow.parquet")
    av = pytest.importorskip("av")
    from pickdemo.apps.cli import main

    out = tmp_path / "so101"
    assert main(["demos", "so101_pick_cube", "--seeds", "0", "--out", str(out), "--no-progress"]) == 0
    info = json.loads((out / "meta" / "info.json").read_text())
    assert info["robot_type"] == "so_follower" and info["fps"] == 30
    # what LeRobot's hw_to_dataset_features makes of the follower's features (motors, front and wrist cameras)
    names = [f"{m}.pos" for m in MOTORS]
    video = {"video.height": 480, "video.width": 640, "video.codec": "av1", "video.pix_fmt": "yuv420p",
             "video.is_depth_map": False, "video.fps": 30, "video.channels": 3, "has_audio": False}  # fmt: skip
    camera = {"dtype": "video", "shape": [480, 640, 3], "names": ["height", "width", "channels"], "info": video}
    expected = {
        "action": {"dtype": "float32", "shape": [6], "names": names},
        "observation.state": {"dtype": "float32", "shape": [6], "names": names},
        "observation.images.front": camera,
        "observation.images.wrist": camera,
    } | {k: {"dtype": d, "shape": [1], "names": None} for k, d in (("timestamp", "float32"), ("frame_index", "int64"),
        ("episode_index", "int64"), ("index", "int64"), ("task_index", "int64"))}  # fmt: skip
    assert info["features"] == expected
    table = pq.read_table(out / "data" / "chunk-000" / "file-000.parquet")
    assert sorted(table.column_names) == sorted(k for k, f in expected.items() if f["dtype"] != "video")
    for cam in ("front", "wrist"):
        with av.open(str(out / "videos" / f"observation.images.{cam}" / "chunk-000" / "file-000.mp4")) as c:
            s = c.streams.video[0]  # (as LeRobot's get_video_info reads it)
            assert (s.codec.canonical_name, s.width, s.height, s.pix_fmt) == ("av1", 640, 480, "yuv420p")
    state = np.stack(table.column("observation.state").to_numpy(zero_copy_only=False))
    assert np.all(np.abs(state[:, :5]) < 180.0) and np.all((state[:, 5] >= 0.0) & (state[:, 5] <= 100.0))
    mine = pq.read_table(out / "pickdemo" / "chunk-000" / "file-000.parquet")  # beside LeRobot's: for replay
    assert {"pickdemo.sim_state", "pickdemo.action_ticks", "next.reward"} <= set(mine.column_names)
    stats = json.loads((out / "meta" / "stats.json").read_text())
    assert sorted(stats) == sorted(expected)
    assert main(["replay", str(out), "--episode", "0"]) == 0
    # another width keeps the follower's aspect, every camera's (the hand camera's own is wider)
    small = tmp_path / "small"
    assert main(["demos", "so101_pick_cube", "--seeds", "0", "--out", str(small), "--image-width", "64",
                 "--no-progress"]) == 0  # fmt: skip
    features = json.loads((small / "meta" / "info.json").read_text())["features"]
    assert [features[f"observation.images.{c}"]["shape"] for c in ("front", "wrist")] == [[48, 64, 3]] * 2
