"""Record the episodes the house issue compares, and compare two recordings key by key.

A refactor that claims "behaviour unchanged" shows it here: every scenario family run on fixed seeds
before and after, on the same machine, and every key of every result compared except the wall-clock
ones (``wall_time_s``, ``stage_wall_times_s``, ``control_tick_wall_ms``).

    python tests/same_episodes.py record DIR      # about 25 min on 2 cores
    python tests/same_episodes.py diff DIR_A DIR_B
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

WALL_KEYS = {"wall_time_s", "stage_wall_times_s", "control_tick_wall_ms"}

RUNS: dict[str, list[str]] = {
    "suite": ["--seeds", "0-19"],
    "sensors": [
        "pick_cube_d435",
        "pick_box_d435",
        "pick_cylinder_d435",
        "pick_cluttered_d435",
        "pick_cube_rgb10",
        "--seeds",
        "0-9",
    ],
    "conveyors": [
        "pick_conveyor",
        "pick_conveyor_fast",
        "pick_conveyor_rush",
        "pick_conveyor_speed_change",
        "pick_conveyor_cylinder",
        "pick_conveyor_1cms",
        "pick_conveyor_2cms",
        "pick_conveyor_3cms",
        "--seeds",
        "0-9",
    ],
    "pushes": [
        "pick_pushed",
        "pick_slippery",
        "pick_pushed_descent",
        "pick_pushed_close",
        "pick_pushed_closing",
        "--seeds",
        "0-9",
    ],
    "wrist": [
        "pick_cube_wrist",
        "pick_pushed_descent_wrist",
        "pick_pushed_close_wrist",
        "pick_pushed_closing_wrist",
        "pick_miscalibrated_wrist",
        "--seeds",
        "0-9",
    ],
    "clear": ["clear_pile", "clear_packed", "--seeds", "0-4"],
    "mesh_test": ["pick_mesh_test", "--seeds", "0-9"],
    "open_loop": ["pick_cube", "pick_pushed", "--seeds", "0-9", "--open-loop"],
    "icp": ["pick_cube", "--seeds", "0-9", "--perception", "icp"],
}


def record(out: Path) -> None:
    for name, args in RUNS.items():
        cmd = [
            sys.executable,
            "-m",
            "pickdemo",
            "bench",
            *args,
            "--workers",
            "2",
            "--min-success",
            "0",
            "--no-progress",
            "--out",
            str(out / name),
        ]
        print(" ".join(cmd), flush=True)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def _strip(value):
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if k not in WALL_KEYS}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def _load(run: Path) -> dict:
    episodes = {}
    for line in (run / "episodes.jsonl").read_text().splitlines():
        result = json.loads(line)
        key = (result.get("scenario"), result.get("seed"), result.get("perception_method"), result.get("open_loop"))
        episodes[key] = _strip(result)
    return episodes


def diff(a: Path, b: Path) -> int:
    compared = differ = 0
    for name in RUNS:
        left, right = _load(a / name), _load(b / name)
        if left.keys() != right.keys():
            print(f"{name}: different episodes: {sorted(set(left) ^ set(right))}")
            differ += len(set(left) ^ set(right))
        for key in sorted(left.keys() & right.keys(), key=str):
            compared += 1
            if left[key] != right[key]:
                differ += 1
                keys = sorted(k for k in left[key].keys() | right[key].keys() if left[key].get(k) != right[key].get(k))
                print(f"{name} {key}: differs in {keys}")
    print(f"{compared} episodes compared, {differ} differ")
    return 1 if differ else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["record"]:
        record(Path(sys.argv[2]))
    elif sys.argv[1:2] == ["diff"]:
        sys.exit(diff(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        sys.exit(__doc__)
