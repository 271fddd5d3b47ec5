"""The world model's cost a frame: whole 640 x 480 frames of the fixed camera (the robot at home, its
body and the fixtures told to the frame, as the loop takes them), split into instances and taken into
a world model, timed one after the other, beside the same frame's pose estimate by the paper's method.

    python tests/world_speed.py [--seeds 0-4] [scenario ...]
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from pickdemo import load_scenario
from pickdemo.core.interfaces import Observation
from pickdemo.perception import PerceptionError, PerceptionParams, estimate_pose
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.runtime.frames import take_frame
from pickdemo.runtime.tasks import episode_task
from pickdemo.runtime.world import World
from pickdemo.skills.pick import FrameRequest
from pickdemo.worldmodel import WorldModel, split_view

SCENARIOS = ("pick_cube", "pick_cluttered", "world_ring_of_six", "world_far_d415", "world_flat_box_d435")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*", default=list(SCENARIOS))
    ap.add_argument("--seeds", default="0-4")
    args = ap.parse_args()
    lo, hi = (int(v) for v in args.seeds.split("-"))
    every: list[float] = []
    for name in args.scenarios:
        sc = load_scenario(name)
        world_ms, estimate_ms, objects = [], [], []
        for seed in range(lo, hi + 1):
            world = World(sc, seed)
            world.open(gui=False)
            try:
                world.scene.settle(300)
                q = np.asarray(world.robot.home_q, dtype=float)
                obs = Observation(0.0, q, np.zeros_like(q), np.full(2, world.robot.gripper.finger_max_m), (0, 0))
                frame = take_frame(world, sc, FrameRequest(None), obs, kinematics_of(world.robot))
                model = episode_task(sc.task).told(sc, world, "paper", PerceptionParams(), False).model
                for _ in range(5):
                    t0 = time.perf_counter()
                    wm = WorldModel()
                    wm.update(split_view(frame))
                    world_ms.append((time.perf_counter() - t0) * 1e3)
                    t0 = time.perf_counter()
                    try:
                        estimate_pose(frame, model)
                    except PerceptionError:
                        pass
                    estimate_ms.append((time.perf_counter() - t0) * 1e3)
                objects.append(len(wm.objects))
            finally:
                world.close()
        every += world_ms
        print(f"{name}: world model {statistics.median(world_ms):.2f} ms a frame (median of {len(world_ms)}), "
              f"the paper's estimate {statistics.median(estimate_ms):.2f} ms; objects {objects}")  # fmt: skip
    print(f"all: world model {statistics.median(every):.2f} ms a frame (median of {len(every)})")


if __name__ == "__main__":
    main()
