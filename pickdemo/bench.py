"""Many seeded episodes: run them, stream each result as it finishes, summarise.

``python -m pickdemo bench SCENARIO [...] --seeds 0-49 [--out DIR] [--min-success 0.95]``

Each finished episode is appended to ``DIR/episodes.jsonl`` at once (the same object as its
``result.json``), so an interrupted run loses nothing; ``DIR/summary.json`` holds the statistics.
"""

from __future__ import annotations

import json
import math
import statistics
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pickdemo.result import Stage


def parse_seeds(text: str) -> list[int]:
    """``"0-49"``, ``"3"``, ``"0-9,20,30-31"`` -> a sorted list of distinct seeds."""
    seeds: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        if "-" in part:
            lo, hi = part.split("-", 1)
            a, b = int(lo), int(hi)
            if a < 0 or b < a:
                raise ValueError(f"bad seed range {part!r}")
            seeds.update(range(a, b + 1))
        else:
            s = int(part)
            if s < 0:
                raise ValueError(f"bad seed {part!r}")
            seeds.add(s)
    if not seeds:
        raise ValueError("no seeds given")
    return sorted(seeds)


def wilson_interval(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score 95 % interval of a success rate."""
    if n == 0:
        return 0.0, 1.0
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return max(0.0, centre - half), min(1.0, centre + half)


def _stats(values: list[float]) -> dict[str, float] | None:
    if not values:
        return None
    v = sorted(values)

    def q(f: float) -> float:
        k = (len(v) - 1) * f
        lo, hi = math.floor(k), math.ceil(k)
        return v[lo] + (v[hi] - v[lo]) * (k - lo)

    return {"median": q(0.5), "p95": q(0.95), "max": v[-1], "mean": statistics.fmean(v), "n": len(v)}


def summarise(results: Iterable[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per-scenario statistics of result dicts (as in ``episodes.jsonl``)."""
    by_scenario: dict[str, list[dict[str, Any]]] = {}
    for r in results:
        by_scenario.setdefault(r["scenario"], []).append(r)
    out: dict[str, dict[str, Any]] = {}
    for name, rs in sorted(by_scenario.items()):
        n = len(rs)
        ok = sum(1 for r in rs if r["success"])
        lo, hi = wilson_interval(ok, n)
        stages = Counter(r["failure"]["stage"] for r in rs if r["failure"])
        perc = [r["perception"] for r in rs if r.get("perception")]
        sim = sum(r["sim_time_s"] for r in rs)
        wall = sum(r["wall_time_s"] for r in rs)
        out[name] = {
            "episodes": n,
            "successes": ok,
            "success_rate": ok / n,
            "success_rate_wilson95": [lo, hi],
            "failures_by_stage": {s.value: stages.get(s.value, 0) for s in Stage if stages.get(s.value, 0)},
            "failed_seeds": sorted(r["seed"] for r in rs if not r["success"]),
            "position_error_mm": _stats([p["position_error_mm"] for p in perc]),
            "yaw_error_deg": _stats([p["yaw_error_deg"] for p in perc if p["yaw_error_deg"] is not None]),
            "place_error_mm": _stats([r["place_error_mm"] for r in rs if r["place_error_mm"] is not None]),
            "wall_time_s": _stats([r["wall_time_s"] for r in rs]),
            "real_time_factor": sim / wall if wall > 0 else None,
        }
    return out


@dataclass(frozen=True)
class Job:
    scenario_path: str
    seed: int


def run_job(job: Job) -> dict[str, Any]:
    """Run one episode and return its result dict. Never raises for a bad episode."""
    from pickdemo.episode import run_episode
    from pickdemo.scenario import load_scenario

    return run_episode(load_scenario(job.scenario_path), job.seed).to_dict()


def run_jobs(jobs: list[Job]) -> Iterator[dict[str, Any]]:
    """Results in the order they finish (sequential here)."""
    for job in jobs:
        yield run_job(job)


def format_summary(summary: dict[str, dict[str, Any]]) -> str:
    lines = []
    for name, s in summary.items():
        lo, hi = s["success_rate_wilson95"]
        lines.append(
            f"{name}: {s['successes']}/{s['episodes']} succeeded "
            f"({100 * s['success_rate']:.1f} %, Wilson 95 % [{100 * lo:.1f}, {100 * hi:.1f}])"
        )
        if s["failures_by_stage"]:
            lines.append(
                "  failures: "
                + ", ".join(f"{k} {v}" for k, v in s["failures_by_stage"].items())
                + f" (seeds {s['failed_seeds']})"
            )
        for key, unit in (("position_error_mm", "mm"), ("yaw_error_deg", "deg"), ("place_error_mm", "mm")):
            st = s[key]
            if st:
                lines.append(
                    f"  {key[:-3].replace('_', ' ')}: median {st['median']:.3f} {unit}, "
                    f"p95 {st['p95']:.3f}, max {st['max']:.3f} (n={st['n']})"
                )
        wt = s["wall_time_s"]
        rtf = s["real_time_factor"]
        lines.append(f"  wall time per episode: median {wt['median']:.2f} s; real-time factor {rtf:.1f}x")
    return "\n".join(lines)


def write_jsonl_line(path: Path, result: dict[str, Any]) -> None:
    with path.open("a") as fh:
        fh.write(json.dumps(result, allow_nan=False) + "\n")
        fh.flush()
