"""``pickdemo demos`` and ``pickdemo replay``: the datasets' layouts (LeRobot v3 as its loader reads it,
HDF5), a stopped run resumed without an episode lost or doubled, replays from states and actions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")
pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")
av = pytest.importorskip("av")
h5py = pytest.importorskip("h5py")

from pickdemo.apps.cli import main  # noqa: E402

pytestmark = pytest.mark.sim


@pytest.fixture(scope="module")
def lerobot_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("lerobot")
    assert main(["demos", "pick_cube", "--seeds", "0-1", "--out", str(out), "--no-progress"]) == 0
    return out


@pytest.mark.slow
def test_the_lerobot_dataset_has_v3s_layout_as_its_loader_reads_it(lerobot_dir: Path) -> None:
    info = json.loads((lerobot_dir / "meta" / "info.json").read_text())
    assert info["codebase_version"] == "v3.0" and info["total_episodes"] == 2 and isinstance(info["fps"], int)
    features = info["features"]
    plain = [k for k, f in features.items() if f["dtype"] != "video"]
    frames = 0
    for k in range(2):
        table = pq.read_table(lerobot_dir / "data" / "chunk-000" / f"file-{k:03d}.parquet")
        assert sorted(table.column_names) == sorted(plain)  # exactly the features that are not videos
        n = table.num_rows
        assert table.column("index").to_pylist() == list(range(frames, frames + n))  # the global frame number
        assert table.column("frame_index").to_pylist() == list(range(n))
        assert np.allclose(table.column("timestamp").to_numpy(), np.arange(n) / info["fps"])
        state_type = table.schema.field("observation.state").type  # LeRobot's Sequence(length=N, float32)
        assert pa.types.is_fixed_size_list(state_type) and state_type.value_type == pa.float32()
        video = lerobot_dir / "videos" / "observation.images.camera" / "chunk-000" / f"file-{k:03d}.mp4"
        with av.open(str(video)) as c:
            times = [float(f.pts * f.time_base) for f in c.decode(video=0)]
        assert np.allclose(times, np.arange(n) / info["fps"], atol=1e-4)  # LeRobot finds a frame by its time
        frames += n
    assert info["total_frames"] == frames and info["splits"] == {"train": "0:2"}
    episodes = pq.read_table(lerobot_dir / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    assert [e["episode_index"] for e in episodes] == [0, 1]
    assert episodes[1]["dataset_from_index"] == episodes[0]["dataset_to_index"]
    assert episodes[0]["videos/observation.images.camera/from_timestamp"] == 0.0
    tasks = pq.read_table(lerobot_dir / "meta" / "tasks.parquet")
    assert json.loads(tasks.schema.metadata[b"pandas"])["index_columns"] == ["task"]  # the task strings, as an index
    assert tasks.column("task").to_pylist() == ["pick up the red 5 cm cube and put it at x 0.45 m, y 0.30 m"]
    stats = json.loads((lerobot_dir / "meta" / "stats.json").read_text())
    assert len(stats["observation.state"]["mean"]) == features["observation.state"]["shape"][0]
    assert np.shape(stats["observation.images.camera"]["mean"]) == (3, 1, 1)


@pytest.mark.slow
def test_the_lerobot_dataset_is_as_lerobots_tools_and_policies_take_it(lerobot_dir: Path) -> None:
    """No NaN anywhere (LeRobot's merge turns one into a null no frame then loads); only what a policy
    takes or gives under ``observation.*`` and ``action*`` (LeRobot's inputs and outputs); the simulator's
    state float64 beside them; a ``next.reward``; each episode's statistics in its row of the episodes'
    table, as LeRobot's writer keeps them (its split and delete remake the dataset's from those), and the
    dataset's made of them."""
    info = json.loads((lerobot_dir / "meta" / "info.json").read_text())
    features = info["features"]
    inputs = sorted(k for k in features if k.startswith(("observation.", "action")))
    assert inputs == ["action", "observation.images.camera", "observation.state"]
    assert features["pickdemo.sim_state"]["dtype"] == "float64" and features["next.reward"]["dtype"] == "float32"
    table = pq.read_table(lerobot_dir / "data")
    assert table.schema.field("pickdemo.sim_state").type.value_type == pa.float64()
    for name in table.column_names:
        values = table.column(name).to_numpy(zero_copy_only=False)
        values = np.stack(values) if values.dtype == object else values
        assert not np.isnan(values.astype(np.float64)).any(), name
    reward = table.column("next.reward").to_numpy()
    assert reward.sum() == 2 and set(reward) == {0.0, 1.0}  # the last frame of each of the two successes
    episodes = pq.read_table(lerobot_dir / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pylist()
    stats = json.loads((lerobot_dir / "meta" / "stats.json").read_text())
    for name in [k for k in features if features[k]["dtype"] != "video"] + ["observation.images.camera"]:
        for stat in ("min", "max", "mean", "std", "count", "q01", "q50", "q99"):
            assert f"stats/{name}/{stat}" in episodes[0], (name, stat)
    state = np.stack(table.column("observation.state").to_numpy(zero_copy_only=False)).astype(np.float64)
    assert np.allclose(stats["observation.state"]["mean"], state.mean(0), atol=1e-5)
    assert np.allclose(stats["observation.state"]["std"], state.std(0), atol=1e-5)
    assert stats["index"]["max"] == [table.num_rows - 1]


def test_an_episode_replays_from_its_states_and_bit_for_bit_from_its_actions(
    lerobot_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    assert main(["replay", str(lerobot_dir), "--episode", "1"]) == 0
    assert "from states SUCCESS, from actions SUCCESS (identical states)" in capsys.readouterr().out


@pytest.mark.slow
def test_a_stopped_run_resumes_without_an_episode_lost_or_doubled(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "h5"
    assert main(["demos", "pick_cube", "--seeds", "0", "--out", str(out), "--format", "hdf5", "--no-progress"]) == 0
    (out / ".staging" / "seed-1.h5.tmp").write_bytes(b"a half-written episode of a killed run")
    args = ["demos", "pick_cube", "--seeds", "0-1", "--out", str(out), "--format", "hdf5", "--no-progress"]
    assert main(args) == 2  # a recording is there: go on with it only when asked
    assert "--resume" in capsys.readouterr().err
    assert main([*args, "--resume"]) == 0
    assert "1 recorded" in capsys.readouterr().out
    with h5py.File(out / "demos.hdf5") as f:
        assert sorted(f["data"]) == ["demo_0", "demo_1"]
        assert [int(f["data"][d].attrs["seed"]) for d in ("demo_0", "demo_1")] == [0, 1]
        g = f["data"]["demo_1"]
        n = int(g.attrs["num_samples"])
        assert list(g["dones"][:]) == [0] * (n - 1) + [1] and g["rewards"][-1] == 1.0
        assert json.loads(f["data"].attrs["env_args"])["env_name"] == "pickdemo/Pick-v0"
        assert g["obs/state"].shape[0] == g["actions"].shape[0] == g["states"].shape[0] == n
        assert g["obs/camera_rgb"].shape == (n, 168, 224, 3)
    assert main(["replay", str(out), "--episode", "1"]) == 0


@pytest.mark.slow
def test_the_hdf5_is_as_robomimic_reads_it_and_its_env_args_rebuild_the_environment(tmp_path: Path) -> None:
    """robomimic's Gym type; actions in [-1, 1] on the bounds the file keeps; depth (N, H, W, 1) as a share
    of the far plane; ``next_obs``; and the environment its ``env_args`` make, stepped with demo 0's
    actions from its seed, succeeds as the demonstration did."""
    import gymnasium as gym

    import pickdemo.envs  # noqa: F401 - (registers the ids)

    out = tmp_path / "h5"
    assert main(["demos", "pick_cube", "--seeds", "0", "--out", str(out), "--format", "hdf5", "--no-progress"]) == 0
    with h5py.File(out / "demos.hdf5") as f:
        env_args = json.loads(f["data"].attrs["env_args"])
        g = f["data"]["demo_0"]
        actions = g["actions"][:]
        n = actions.shape[0]
        assert env_args["type"] == 2 and np.all(np.abs(actions) <= 1.0)
        assert g["obs/camera_depth"].shape == (n, 168, 224, 1) and g["obs/camera_depth"].attrs["scale_m"] == 3.0
        assert np.array_equal(g["next_obs/state"][: n - 1], g["obs/state"][1:])
        assert np.array_equal(g["next_obs/camera_rgb"][n - 1], g["obs/camera_rgb"][n - 1])
        seed = int(g.attrs["seed"])
    env = gym.make(env_args["env_name"], **env_args["env_kwargs"])
    env.reset(seed=seed)
    steps = 0
    for a in actions:
        _, _, terminated, truncated, info = env.step(a.astype(np.float32))
        steps += 1
        if terminated or truncated:
            break
    env.close()
    assert info["is_success"] and steps == n


def test_bad_input_is_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["replay", str(tmp_path)]) == 2
    assert "not a pickdemo demos dataset" in capsys.readouterr().err
    assert main(["demos", "pick_cube", "--out", str(tmp_path / "x"), "--fps", "7"]) == 2
    assert "--fps 7" in capsys.readouterr().err
    assert main(["demos", "pick_cube", "--out", str(tmp_path / "y"), "--features", "follower"]) == 2
    assert "--features follower: the Panda's robot file has no [lerobot] table" in capsys.readouterr().err
