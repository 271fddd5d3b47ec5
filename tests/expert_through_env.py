"""The expert through the Gymnasium environment against ``bench``, on the same scenarios and seeds.

    python tests/expert_through_env.py --seeds 0-99 --workers 2 --out DIR [SCENARIO ...]

Runs :class:`~pickdemo.envs.ExpertPolicy` in ``pickdemo/Pick-v0`` (``joint_pos``, one action a control
tick, ``state`` observations, ``--gripper opening`` or ``opening_force``) for every scenario x seed in
worker processes, writes ``DIR/env.jsonl``, and prints each scenario's successes with their Wilson 95 %
interval. With ``--bench DIR2`` (a ``bench``
run's directory on the same seeds) it prints bench's beside them.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

DEFAULT = ["pick_cube", "pick_mesh", "pick_conveyor", "so101_pick_cube"]


def one(job: tuple[str, int, str]) -> dict:
    import warnings

    import gymnasium as gym

    import pickdemo.envs  # noqa: F401
    from pickdemo.envs import ExpertPolicy

    warnings.simplefilter("ignore")
    scenario, seed, gripper = job
    t0 = time.perf_counter()
    env = gym.make("pickdemo/Pick-v0", scenario=scenario, agent_rate_hz=None, gripper=gripper)
    expert = ExpertPolicy(env)
    obs, info = env.reset(seed=seed)
    steps = 0
    while True:
        obs, reward, terminated, truncated, info = env.step(expert(obs))
        steps += 1
        if terminated or truncated:
            break
    env.close()
    r = info["result"]
    return {
        "scenario": scenario,
        "seed": seed,
        "success": r.success,
        "failure": None if r.failure is None else r.failure.stage.value,
        "reason": None if r.failure is None else r.failure.reason,
        "place_error_mm": r.place_error_mm,
        "steps": steps,
        "sim_time_s": r.sim_time_s,
        "wall_s": time.perf_counter() - t0,
    }


def main() -> int:
    from pickdemo.apps.bench import parse_seeds, wilson_interval

    ap = argparse.ArgumentParser()
    ap.add_argument("scenarios", nargs="*", default=DEFAULT)
    ap.add_argument("--seeds", default="0-99")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--bench", type=Path)
    ap.add_argument("--gripper", default="opening", help="opening (one number) or opening_force")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    jobs = [(s, seed, args.gripper) for s in args.scenarios for seed in parse_seeds(args.seeds)]
    results = []
    with ProcessPoolExecutor(args.workers) as pool, (args.out / "env.jsonl").open("w") as fh:
        for r in pool.map(one, jobs):
            fh.write(json.dumps(r) + "\n")
            fh.flush()
            results.append(r)
    bench = {}
    if args.bench is not None:
        for line in (args.bench / "episodes.jsonl").read_text().splitlines():
            b = json.loads(line)
            bench.setdefault(b["scenario"], []).append(b["success"])
    for s in args.scenarios:
        ok = [r["success"] for r in results if r["scenario"] == s]
        lo, hi = wilson_interval(sum(ok), len(ok))
        line = f"{s}: through the env {sum(ok)}/{len(ok)} [{100 * lo:.1f}, {100 * hi:.1f}]"
        if s in bench:
            b = bench[s]
            blo, bhi = wilson_interval(sum(b), len(b))
            line += f"; bench {sum(b)}/{len(b)} [{100 * blo:.1f}, {100 * bhi:.1f}]"
        failed = [(r["seed"], r["failure"]) for r in results if r["scenario"] == s and not r["success"]]
        print(line, "failed:", failed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
