"""Command line: ``python -m pickdemo run SCENARIO [--seed N] [--out DIR] [--gui]``.

Exit codes: 0 the episode succeeded, 1 it failed, 2 bad scenario or bad arguments (one line on
stderr, no traceback).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from pickdemo.result import EpisodeResult
from pickdemo.scenario import ScenarioError, list_scenarios, load_scenario, resolve_scenario_path

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class UsageError(Exception):
    """Bad command-line input; the message is one line."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2, instead of argparse's usage dump
        raise UsageError(message)


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="pickdemo", description="A simulated Franka Panda picks an object it has only seen.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    run = sub.add_parser("run", help="run one episode of a scenario")
    run.add_argument("scenario", help="a scenario name (see `pickdemo list`) or a path to a .toml file")
    run.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    run.add_argument("--out", type=Path, help="directory to write result.json into")
    run.add_argument("--gui", action="store_true", help="open the PyBullet window (needs a display)")
    run.add_argument("--quiet", action="store_true", help="print only the summary line")
    bench = sub.add_parser("bench", help="run many seeded episodes and summarise them")
    bench.add_argument("scenarios", nargs="+", metavar="SCENARIO", help="scenario names or paths")
    bench.add_argument("--seeds", default="0-19", help="seeds, e.g. 0-49 or 0-9,20 (default 0-19)")
    bench.add_argument("--out", type=Path, help="directory for episodes.jsonl and summary.json")
    bench.add_argument("--min-success", type=float, default=0.0, help="exit 1 if any scenario's rate is below")
    sub.add_parser("list", help="list the shipped scenarios")
    return parser


def _summary(result: EpisodeResult) -> str:
    head = "SUCCESS" if result.success else f"FAILED in {result.failure.stage.value}"  # type: ignore[union-attr]
    parts = [f"{head}: {result.scenario} seed {result.seed}"]
    if result.perception is not None:
        yaw = result.perception.yaw_error_deg
        parts.append(
            f"pose error {result.perception.position_error_mm:.2f} mm"
            + (f", yaw {yaw:.2f} deg" if yaw is not None else "")
        )
    if result.place_error_mm is not None:
        parts.append(f"place error {result.place_error_mm:.1f} mm")
    parts.append(f"{result.sim_time_s:.1f} s simulated in {result.wall_time_s:.2f} s")
    line = " | ".join(parts)
    if result.failure is not None:
        line += f"\n  reason: {result.failure.reason}"
    return line


def _cmd_run(args: argparse.Namespace) -> int:
    from pickdemo.episode import EpisodeOptions, run_episode  # heavy imports only when running

    scenario = load_scenario(args.scenario)
    if args.seed < 0:
        raise UsageError(f"--seed must be >= 0, got {args.seed}")
    if args.gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise UsageError("--gui needs a display (DISPLAY is not set); run without --gui for headless")
    if args.out is not None and args.out.exists() and not args.out.is_dir():
        raise UsageError(f"--out {args.out}: exists and is not a directory")

    t0 = time.perf_counter()

    def on_phase(phase: str, message: str) -> None:
        if not args.quiet:
            print(f"[{time.perf_counter() - t0:6.2f} s] {phase:<9} {message}", flush=True)

    if not args.quiet:
        print(f"pickdemo: {scenario.name} seed {args.seed}: {scenario.description}", flush=True)
    result = run_episode(scenario, args.seed, options=EpisodeOptions(gui=args.gui), on_phase=on_phase)
    print(_summary(result), flush=True)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        path = args.out / "result.json"
        path.write_text(result.to_json() + "\n")
        if not args.quiet:
            print(f"wrote {path}")
    return EXIT_OK if result.success else EXIT_FAILED


def _cmd_bench(args: argparse.Namespace) -> int:
    from pickdemo import bench

    try:
        seeds = bench.parse_seeds(args.seeds)
    except ValueError as exc:
        raise UsageError(f"--seeds: {exc}") from None
    if not 0.0 <= args.min_success <= 1.0:
        raise UsageError("--min-success must be in [0, 1]")
    paths = [str(resolve_scenario_path(s)) for s in args.scenarios]
    for p in paths:
        load_scenario(p)  # validate every scenario before running anything
    jobs = [bench.Job(p, seed) for p in paths for seed in seeds]
    jsonl = None
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        jsonl = args.out / "episodes.jsonl"
        jsonl.write_text("")
    results = []
    for i, r in enumerate(bench.run_jobs(jobs), 1):
        results.append(r)
        if jsonl is not None:
            bench.write_jsonl_line(jsonl, r)
        status = "ok  " if r["success"] else f"FAIL {r['failure']['stage']}: {r['failure']['reason']}"
        pe = r["perception"]["position_error_mm"] if r["perception"] else float("nan")
        print(
            f"[{i}/{len(jobs)}] {r['scenario']} seed {r['seed']}: {status} (pose {pe:.2f} mm, "
            f"{r['wall_time_s']:.2f} s)",
            flush=True,
        )
    summary = bench.summarise(results)
    print(bench.format_summary(summary))
    if args.out is not None:
        (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    low = [n for n, s in summary.items() if s["success_rate"] < args.min_success]
    if low:
        print(f"success rate below {args.min_success:.2f}: {', '.join(low)}")
        return EXIT_FAILED
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    parser = _build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "bench":
            return _cmd_bench(args)
        if args.command == "list":
            print("\n".join(list_scenarios()))
            return EXIT_OK
        parser.print_help()
        return EXIT_BAD_INPUT
    except (ScenarioError, UsageError) as exc:
        print(f"pickdemo: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("pickdemo: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
