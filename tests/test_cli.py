"""The command line: exit codes, one-line errors without tracebacks, result.json."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def _run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pickdemo", *args], capture_output=True, text=True, cwd=cwd, timeout=300
    )


@pytest.mark.parametrize(
    "args",
    [
        ("run", "no_such_scenario"),
        ("run", "pick_cube", "--seed", "x"),
        ("run",),
        ("run", "pick_cube", "--seed", "-1"),
        ("frobnicate",),
    ],
)
def test_bad_input_exits_2_with_one_line(args: tuple[str, ...]) -> None:
    proc = _run(*args)
    assert proc.returncode == 2
    assert proc.stderr.startswith("pickdemo: error:")
    assert proc.stderr.count("\n") == 1
    assert "Traceback" not in proc.stderr


def test_bad_scenario_file_names_file_and_key(tmp_path: Path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(
        'name = "x"\n[[objects]]\nname = "c"\nshape = "box"\nsize = [1]\ncolor = [1, 0, 0]\n'
        "position = [0.5, 0]\ntarget = true\n[place]\nposition = [0.4, 0.3]\n"
    )
    proc = _run("run", str(f))
    assert proc.returncode == 2
    assert str(f) in proc.stderr and "objects[0](c).size" in proc.stderr


@pytest.mark.sim
def test_run_writes_result_json(tmp_path: Path) -> None:
    proc = _run("run", "pick_cube", "--seed", "1", "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    for phase in ("look", "approach", "descend", "close", "lift", "transport", "lower", "release", "verify", "done"):
        assert f"] {phase}" in proc.stdout
    assert "SUCCESS" in proc.stdout
    assert proc.stderr == ""  # nothing leaks from PyBullet's C code
    result = json.loads((tmp_path / "o" / "result.json").read_text())
    for key in (
        "scenario",
        "seed",
        "success",
        "failure",
        "perception",
        "place_error_mm",
        "sim_time_s",
        "wall_time_s",
        "stage_wall_times_s",
        "attempts",
        "perception_frames",
        "perception_rate_hz",
        "estimates_rejected",
        "tracking_error_mm",
    ):
        assert key in result
    for key in ("estimated_pose", "true_pose", "position_error_mm", "yaw_error_deg"):
        assert key in result["perception"]
    assert result["success"] is True and result["failure"] is None and result["seed"] == 1


def test_list() -> None:
    proc = _run("list")
    assert proc.returncode == 0 and "pick_cube" in proc.stdout.split()
