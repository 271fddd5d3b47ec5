"""Perception only, in the simulator: a regression on fixed seeds, the paper's rows, the command."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pickdemo.apps.perceive import perceive_seed
from pickdemo.core.geometry import Pose
from pickdemo.scenario.load import load_scenario

pytestmark = pytest.mark.sim


def test_random_boxes() -> None:
    """Over six seeds (boxes of 3-8 cm, any yaw, tilted up to 10 deg, camera 0.5-1.0 m): measured over
    100 seeds, the paper's method has a median of 0.023 mm and a maximum of 0.38 mm."""
    sc = load_scenario("perceive_boxes")
    runs = [{s["method"]: s for s in perceive_seed(sc, seed, ["paper", "pixel"])} for seed in range(6)]
    paper = [r["paper"] for r in runs]
    assert all(p["failure"] is None for p in paper)
    errors = [p["position_error_mm"] for p in paper]
    assert max(errors) < 1.0 and float(np.median(errors)) < 0.1, errors
    assert max(max(p["yaw_error_deg"], p["pitch_error_deg"], p["roll_error_deg"]) for p in paper) < 1.0
    assert float(np.median([p["nees"] for p in paper])) < 20.0  # honest: not wildly over-confident
    assert all(r["paper"]["position_error_mm"] < r["pixel"]["position_error_mm"] for r in runs)


def test_paper_table_rows_beat_the_paper() -> None:
    samples = [s for s in perceive_seed(load_scenario("paper_table"), 0, ["paper"])]
    assert len(samples) == 6
    for s in samples:
        ref = s["reference"]
        assert s["feature_point_error_mm"] < ref["position_error_mm"], s["target"]
        assert s["yaw_error_deg"] < ref["yaw_error_deg"], s["target"]


def test_perceive_command_writes_json_and_plot(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    proc = subprocess.run(
        [sys.executable, "-m", "pickdemo", "perceive", "perceive_cylinders", "--seeds", "0-1", "--out", str(tmp_path)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for method in ("paper", "pixel", "centroid", "icp"):
        assert f"\n{method} " in proc.stdout
    data = json.loads((tmp_path / "perception.json").read_text())
    assert len(data["samples"]) == 8  # 4 methods x 2 seeds x 1 target
    for key in ("method", "seed", "position_error_mm", "yaw_error_deg", "pitch_error_deg", "roll_error_deg", "nees"):
        assert key in data["samples"][0]
    assert data["samples"][0]["yaw_error_deg"] is None  # a cylinder has no yaw
    assert set(data["summary"]) == {"paper", "pixel", "centroid", "icp"}
    assert (tmp_path / "perception.png").stat().st_size > 10_000


def test_perceive_rejects_unknown_method() -> None:
    proc = subprocess.run([sys.executable, "-m", "pickdemo", "perceive", "pick_cube", "--methods", "magic"],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert proc.returncode == 2 and "magic" in proc.stderr and proc.stderr.count("\n") == 1


def test_the_fit_is_unbiased_beside_edges_under_depth_noise() -> None:
    """Readings are matched to the face their ray meets, not the nearest face: beside an edge, noise
    pushes a top-face reading nearer a side face, and matching it there dragged the top up (boxes
    estimated 0.06 mm too high on average with the D435's noise; 0.000 mm over seeds 100-199 since)."""
    sc = load_scenario("perceive_boxes_d435")
    heights = []
    for seed in range(24):
        (s,) = perceive_seed(sc, seed, ["paper"])
        assert s["failure"] is None
        t = s["true_pose"]
        up = Pose.from_xyz_rpy(
            np.zeros(3), roll=np.radians(t["roll_deg"]), pitch=np.radians(t["pitch_deg"]), yaw=np.radians(t["yaw_deg"])
        ).rotation[:, 2]
        heights.append(1e3 * float(up @ (np.subtract(s["estimated_pose"]["position_m"], t["position_m"]))))
    assert abs(float(np.mean(heights))) < 0.03, heights


def test_perceive_on_objects_nobody_described_runs_what_applies(tmp_path: Path) -> None:
    """The baselines need a shape and a colour: by default they are left out for a mesh, and asking
    for one is a one-line error."""
    run = [sys.executable, "-m", "pickdemo", "perceive", "perceive_meshes", "--seeds", "0"]
    proc = subprocess.run(run, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "\npaper " in proc.stdout and "\nicp " not in proc.stdout
    proc = subprocess.run([*run, "--methods", "paper,icp"], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "icp needs" in proc.stderr and proc.stderr.count("\n") == 1
