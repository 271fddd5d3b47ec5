"""Benchmark (not a test): the wall time of a clear round's pick against a single-object episode's,
measured in the same run on the same machine (one process, one core).

    python tests/clear_speed.py [--seeds 8] [--scenario clear_packed]

The reference: ``pick_mesh_test`` (one test-split object a seed, the same cell) at the round's scale.
Prints each one's median wall time per pick and per episode, the real-time factors, and the ratio.
"""

from __future__ import annotations

import argparse
import statistics

from pickdemo.runtime.episode import run_episode
from pickdemo.scenario.load import load_scenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--scenario", default="clear_packed")
    args = ap.parse_args()
    clear = load_scenario(args.scenario)
    single = load_scenario("pick_mesh_test")
    lo, hi = clear.clear.scale_range
    thing = single.objects[0].model_copy(update={"scale": (lo + hi) / 2.0})
    single = single.model_copy(update={"objects": (thing,)})
    per_pick, per_single, sim_c, wall_c, sim_s, wall_s = [], [], 0.0, 0.0, 0.0, 0.0
    for seed in range(args.seeds):
        r = run_episode(single, seed)
        per_single.append(r.wall_time_s)
        sim_s, wall_s = sim_s + r.sim_time_s, wall_s + r.wall_time_s
        c = run_episode(clear, seed)
        picks = max(len(c.clear["picks"]), 1) if c.clear else 1
        per_pick.append(c.wall_time_s / picks)
        sim_c, wall_c = sim_c + c.sim_time_s, wall_c + c.wall_time_s
        print(f"seed {seed}: single {r.wall_time_s:.2f} s ({'ok' if r.success else 'failed'}); "
              f"round {c.wall_time_s:.2f} s for {picks} pick(s), {c.clear['cleared']}/{c.clear['total']} cleared",
              flush=True)  # fmt: skip
    a, b = statistics.median(per_pick), statistics.median(per_single)
    print(
        f"single-object episode ({single.name} at scale {thing.scale:g}): median {b:.2f} s wall, "
        f"real-time factor {sim_s / wall_s:.1f}x"
    )
    print(f"{clear.name}: median {a:.2f} s wall a pick, real-time factor {sim_c / wall_c:.1f}x")
    print(f"ratio (a pick of a round / a single-object episode): {a / b:.2f}")


if __name__ == "__main__":
    main()
