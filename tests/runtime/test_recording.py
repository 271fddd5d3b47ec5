"""``run ... --rerun FILE.rrd``: a recording rerun's own reader loads, with the camera, perception, the
poses, the truth and the time series in it, on simulated time; recording changes nothing in the result."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from pickdemo import load_scenario, run_episode
from pickdemo.apps.cli import main
from pickdemo.core.result import WALL_CLOCK_KEYS

pytestmark = pytest.mark.sim

#: entity -> the archetype it must hold
ARCHETYPES = {
    "/world/camera": "Transform3D",
    "/world/camera/image": "Pinhole",
    "/world/camera/image/rgb": "Image",
    "/world/camera/image/depth": "DepthImage",
    "/world/target/points": "Points3D",
    "/world/target/features": "Ellipsoids3D",
    "/world/estimate": "Transform3D",
    "/world/tracker": "Transform3D",
    "/world/truth": "Transform3D",
    "/world/tcp": "Points3D",
    "/world/tcp/path": "LineStrips3D",
    "/tcp/setpoint/x": "Scalars",
    "/tcp/true/z": "Scalars",
    "/joints/command/q1": "Scalars",
    "/joints/command/q7": "Scalars",
    "/phases": "TextLog",
}


def _strip_wall(d: dict) -> dict:
    return {k: v for k, v in d.items() if k not in WALL_CLOCK_KEYS}


def test_run_writes_a_recording_that_rerun_reads(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    from pickdemo.runtime.recording import ENTITIES

    out = tmp_path / "out"
    rrd = out / "episode.rrd"
    code = main(["run", "pick_pushed", "--seed", "1", "--out", str(out), "--rerun", str(rrd)])
    assert code in (0, 1)
    assert str(rrd) in capsys.readouterr().out  # named among what was written
    result = json.loads((out / "result.json").read_text())

    store = RrdReader(rrd).store()
    schema = store.schema()
    paths = set(schema.entity_paths())
    assert set(ENTITIES) <= paths and set(ARCHETYPES) <= paths, sorted(set(ARCHETYPES) - paths)
    for entity, archetype in ARCHETYPES.items():
        held = {c.archetype for c in schema.columns_for(entity_path=entity)}
        assert f"rerun.archetypes.{archetype}" in held, (entity, held)
    assert [str(i) for i in schema.index_columns()] == ["Index(timeline:sim)"]  # simulated time, only

    rows: dict[str, int] = {}
    for chunk in store.stream().to_chunks():
        rows[chunk.entity_path] = rows.get(chunk.entity_path, 0) + chunk.num_rows
    # Every frame perception got, and no other; the TCP and the joint command on every control tick.
    assert rows["/world/camera/image/rgb"] == rows["/world/camera/image/depth"] == result["perception_frames"]
    assert rows["/world/tcp"] == rows["/joints/command/q1"] == rows["/tcp/true/x"] > 100
    assert rows["/phases"] == len(result["phases"])

    # Recording changed nothing: the same episode without it.
    plain = json.loads(run_episode(load_scenario("pick_pushed"), 1).to_json())
    assert _strip_wall(result) == _strip_wall(plain)


def test_rerun_without_rerun_sdk_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    code = main(["run", "pick_cube", "--rerun", str(tmp_path / "x.rrd")])
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and ".[rerun]" in err and "--rerun" in err
    assert not (tmp_path / "x.rrd").exists()


@pytest.mark.slow
def test_a_path_planned_around_a_wall_is_drawn_in_the_recording_while_the_arm_is_on_it(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "so101_motion_over_a_wall.toml"
    planned = None  # (the first of a few seeds whose episode planned a path: not one seed's fate)
    for seed in (0, 1, 2):
        rrd, out = tmp_path / f"episode{seed}.rrd", tmp_path / f"out{seed}"
        main(["run", str(scenario), "--seed", str(seed), "--out", str(out), "--rerun", str(rrd)])
        if (json.loads((out / "result.json").read_text())["motion_plans"] or {}).get("count"):
            planned = rrd
            break
    assert planned is not None, "no episode of three planned a path around the wall"
    store = RrdReader(planned).store()
    assert "/world/planned_path" in set(store.schema().entity_paths())
    held = {c.archetype for c in store.schema().columns_for(entity_path="/world/planned_path")}
    assert "rerun.archetypes.LineStrips3D" in held, held
