"""Command line: ``python -m pickdemo COMMAND``.

- ``run SCENARIO [--seed N] [--out DIR [--video]] [--rerun FILE.rrd] [--gui] [--quiet] [--open-loop]
  [--perception METHOD]``: one episode; ``--out DIR`` writes ``result.json``, ``motion.png`` and
  ``report.html`` there (and ``episode.mp4`` with ``--video``); ``--rerun`` a rerun recording
  (``rerun FILE.rrd`` opens it).
- ``bench [SCENARIO ...] [--seeds 0-19] [--min-success 0.95] [--out DIR [--resume]] [--junit FILE]``:
  many episodes in parallel, gated on the success rate; ``DIR`` gets ``episodes.jsonl``,
  ``summary.json``, ``bench.png`` and ``report.html``.
- ``perceive SCENARIO [--seeds ...] [--out DIR]``: perception only; ``DIR`` gets
  ``perception.json``, ``perception.png`` and ``report.html``.
- ``profile SCENARIO [--seeds 0-2] [--json]``: where the loop's wall time goes, stage by stage, beside the
  episode's own physics replayed in the same run.
- ``validate SCENARIO ...``, ``list [--names]``.

Exit codes: 0 the episode (or every scenario of a bench) succeeded, 1 it failed, 2 bad scenario or
bad arguments (one line on stderr, no traceback).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

from pickdemo.apps import bench, executors, perceive, report
from pickdemo.apps import compare as cmp
from pickdemo.apps.files import write_atomic
from pickdemo.apps.gate import FailFast, interleaved
from pickdemo.apps.parser import UsageError, build_parser
from pickdemo.apps.profile import profile
from pickdemo.apps.summary import summary_line, yaw_modulus_deg
from pickdemo.core.result import EpisodeResult, PhaseRecord
from pickdemo.perception.estimators import EstimatorError, resolve_estimator
from pickdemo.robot.description import RobotDescription
from pickdemo.runtime.episode import EpisodeOptions, run_episode
from pickdemo.scenario.load import (
    Scenario,
    ScenarioError,
    list_scenarios,
    load_scenario,
    resolve_scenario_path,
    suite_scenarios,
)
from pickdemo.scenario.tasks import TASK_RULES

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
MAX_SEED = 2**63 - 1
MAX_WORKERS = 256
MAX_GUARD_S = 86400.0


def _check_method(name: str, flag: str = "--perception") -> None:
    try:
        resolve_estimator(name)
    except EstimatorError as exc:
        raise UsageError(f"{flag}: {exc}") from None


def _check_seed(seed: int) -> None:
    if not 0 <= seed <= MAX_SEED:
        raise UsageError(f"--seed must be in 0..{MAX_SEED}, got {seed}")


def _writable_dir(path: Path, flag: str) -> None:
    """Create ``path`` if needed and prove it writable, before any work is done."""
    if path.exists() and not path.is_dir():
        raise UsageError(f"{flag} {path}: exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".pickdemo-probe-"):
            pass
    except OSError as exc:
        raise UsageError(f"{flag} {path}: not writable ({exc.strerror or exc})") from None


def _pick_scenario(name: str) -> Scenario:
    scenario = load_scenario(name)
    if not TASK_RULES[scenario.task].runs_episodes:
        raise UsageError(f'{name}: a perception-only scenario (task = "{scenario.task}"); use `pickdemo perceive`')
    return scenario


def _save_result(result: EpisodeResult, out: Path) -> Path:
    """Write result.json; if that fails after all, write it where it can be written and say so."""
    text = result.to_json() + "\n"
    path = out / "result.json"
    try:
        return write_atomic(path, text)
    except OSError as exc:
        fd, fallback = tempfile.mkstemp(prefix="pickdemo-result-", suffix=".json")
        os.close(fd)
        write_atomic(fallback, text)
        print(f"pickdemo: error: {path}: cannot write ({exc.strerror or exc}); the result is in {fallback}",
              file=sys.stderr)  # fmt: skip
        return Path(fallback)


def _run_pictures(result: EpisodeResult, out: Path, *, video: bool, robot: RobotDescription) -> list[Path]:
    """motion.png and report.html beside result.json (the plots extra); never fails the run."""
    images: list[Path] = []
    try:
        if result.trace is not None and len(result.trace.time_s) > 3:
            title = f"{result.scenario} seed {result.seed}: commanded arm motion"
            images.append(report.write_motion_plot(result.trace, out / "motion.png", title, robot))
    except report.PlotsUnavailable as exc:
        print(f"pickdemo: note: no plots ({exc})", file=sys.stderr)
    except Exception as exc:  # noqa: BLE001 - a plot must never lose the episode's result
        print(f"pickdemo: note: motion.png not drawn ({type(exc).__name__}: {exc})", file=sys.stderr)
    mp4 = out / "episode.mp4"
    page = report.write_run_report(result, out, video=mp4 if video and mp4.exists() else None, images=images)
    return [*images, *([mp4] if video and mp4.exists() else []), page]


def _bench_pictures(outcome, out: Path, title: str, open_loop: bool) -> list[Path]:
    """bench.png and report.html beside summary.json (the plots extra); never fails the bench."""
    sections = [("Scenarios", report.bench_table(outcome.summary, outcome.results))]
    written: list[Path] = []
    try:
        plot = report.write_bench_plots(outcome.summary, outcome.results, out / "bench.png", title)
        sections.append(("Plots", report.image(plot)))
        written.append(plot)
    except report.PlotsUnavailable as exc:
        print(f"pickdemo: note: no plots ({exc})", file=sys.stderr)
    except Exception as exc:  # noqa: BLE001 - a plot must never lose what the bench measured
        print(f"pickdemo: note: bench.png not drawn ({type(exc).__name__}: {exc})", file=sys.stderr)
    sections.append(("Summary, as printed", report.pre(bench.format_summary(outcome.summary))))
    loop = " (open loop)" if open_loop else ""
    written.append(report.write_page(out, f"pickdemo bench{loop}: {title}", sections))
    return written


def _cmd_run(args: argparse.Namespace) -> int:
    _check_seed(args.seed)
    _check_method(args.perception)
    scenario = _pick_scenario(args.scenario)
    if args.gui and sys.platform.startswith("linux") and not os.environ.get("DISPLAY"):
        raise UsageError("--gui needs a display (DISPLAY is not set); run without --gui for headless")
    if args.out is not None:
        _writable_dir(args.out, "--out")
    if args.video:
        if args.out is None:
            raise UsageError("--video needs --out DIR (where episode.mp4 is written)")
        try:
            import av  # noqa: F401
        except ImportError:
            raise UsageError(
                "--video needs PyAV: pip install -c .ci/constraints.txt '.[video]' in the checkout"
            ) from None
    if args.rerun is not None:
        try:
            import rerun  # noqa: F401
        except ImportError:
            raise UsageError(
                "--rerun needs rerun-sdk: pip install -c .ci/constraints.txt '.[rerun]' in the checkout"
            ) from None
        _writable_dir(args.rerun.parent, "--rerun")

    t0 = time.perf_counter()

    def on_phase(rec: PhaseRecord) -> None:
        if not args.quiet:
            wall = time.perf_counter() - t0
            print(f"[sim {rec.sim_time_s:6.2f} s | wall {wall:5.2f} s] {rec.phase:<9} {rec.message}", flush=True)

    if not args.quiet:
        loop = "open loop: one look" if args.open_loop else "closed loop"
        print(f"pickdemo: {scenario.name} seed {args.seed} ({loop}): {scenario.description}", flush=True)
    options = EpisodeOptions(
        gui=args.gui,
        open_loop=args.open_loop,
        perception_method=args.perception,
        record_trace=args.out is not None,
        video_path=str(args.out / "episode.mp4") if args.video else None,
        rerun_path=str(args.rerun) if args.rerun is not None else None,
    )
    result = run_episode(scenario, args.seed, options=options, on_phase=on_phase)
    modulus = yaw_modulus_deg(scenario.target) if TASK_RULES[scenario.task].one_target else None
    print(summary_line(result, modulus), flush=True)
    if args.out is not None:
        path = _save_result(result, args.out)
        written = [path] + _run_pictures(result, args.out, video=args.video, robot=scenario.robot_description)
        if not args.quiet:
            print("wrote " + ", ".join(str(p) for p in [*written, *([args.rerun] if args.rerun else [])]))
    if args.rerun is not None and args.out is None and not args.quiet:
        print(f"wrote {args.rerun}")
    return EXIT_OK if result.success else EXIT_FAILED


def _cmd_bench(args: argparse.Namespace) -> int:
    try:
        seeds = bench.parse_seeds(args.seeds)
    except bench.BenchError as exc:
        raise UsageError(f"--seeds: {exc}") from None
    if not 0.0 <= args.min_success <= 1.0:
        raise UsageError(f"--min-success must be in [0, 1], got {args.min_success}")
    if not 1 <= args.workers <= MAX_WORKERS:
        raise UsageError(f"--workers must be in 1..{MAX_WORKERS}, got {args.workers}")
    if not (math.isfinite(args.episode_timeout) and 0 < args.episode_timeout <= MAX_GUARD_S):
        raise UsageError(
            f"--episode-timeout must be a number of seconds in (0, {MAX_GUARD_S:.0f}], got {args.episode_timeout}"
        )
    if args.resume and args.out is None:
        raise UsageError("--resume needs --out DIR (where episodes.jsonl is)")
    _check_method(args.perception)
    if args.out is not None:
        _writable_dir(args.out, "--out")
    if args.junit is not None:
        if args.junit.is_dir():
            raise UsageError(f"--junit {args.junit}: is a directory; give a file, e.g. {args.junit / 'junit.xml'}")
        _writable_dir(args.junit.parent if str(args.junit.parent) else Path("."), "--junit")
    names = args.scenarios or suite_scenarios()
    if not names:
        raise UsageError("no scenario given and none is tagged 'suite'")
    jobs, seen = [], {}
    if len(names) * len(seeds) > bench.MAX_EPISODES:
        raise UsageError(
            f"{len(names)} scenario(s) x {len(seeds)} seed(s) is more than {bench.MAX_EPISODES} episodes; split the run"
        )
    for name in names:
        path = resolve_scenario_path(name)
        scenario = _pick_scenario(str(path))  # validate every scenario before running anything
        if scenario.name in seen and seen[scenario.name] != path.resolve():
            raise UsageError(f"two scenarios are named {scenario.name!r}: {seen[scenario.name]} and {path}")
        seen[scenario.name] = path.resolve()
        jobs += [bench.Job(str(path.resolve()), scenario.name, seed, args.open_loop, args.perception) for seed in seeds]
    jobs = list({j.key: j for j in jobs}.values())
    if args.fail_fast:
        if args.min_success <= 0.0:
            raise UsageError("--fail-fast needs a gate: --min-success above 0")
        jobs = interleaved(jobs)  # (seed by seed across the scenarios: every answer advances together)
    done = None
    if args.out is not None:  # before an executor starts: a directory this run cannot describe is refused here
        try:
            done = bench.prepare_out_dir(args.out, jobs, resume=args.resume)
        except bench.BenchError as exc:
            raise UsageError(str(exc)) from None
    if args.junit is not None:
        try:
            args.junit.unlink(missing_ok=True)  # written at the end, for this run's episodes: never a stale one
        except OSError as exc:
            raise UsageError(f"--junit {args.junit}: cannot replace it ({exc.strerror or exc})") from None

    if args.executor == "ray":
        try:
            executor = executors.RayExecutor(args.address, args.episode_timeout, num_cpus=args.workers)
        except bench.BenchError as exc:
            raise UsageError(str(exc)) from None
    else:
        executor = executors.LocalExecutor(min(args.workers, len(jobs)), args.episode_timeout)

    gate = FailFast(jobs, args.min_success, done or []) if args.fail_fast else None

    def on_result(r: dict) -> None:
        if gate is not None:
            before = len(gate.log)
            gate.record(r)
            if len(gate.log) > before:
                from tqdm import tqdm

                tqdm.write(gate.log[-1])
        if not r["success"]:
            from tqdm import tqdm

            tqdm.write(f"FAIL {r['scenario']} seed {r['seed']}: {r['failure']['stage']}: {r['failure']['reason']}")

    print(
        f"pickdemo bench: {len(names)} scenario(s) x {len(seeds)} seed(s) = {len(jobs)} episodes, "
        f"{args.executor} executor" + (f", {executor.workers} workers" if args.executor == "local" else ""),
        flush=True,
    )
    t0 = time.perf_counter()
    try:
        outcome = bench.run_bench(
            jobs,
            executor,
            out_dir=args.out,
            resume=args.resume,
            progress=not args.no_progress,
            on_result=on_result,
            done=done,
            skip=None if gate is None else gate.skip,
        )
    except bench.BenchError as exc:
        raise UsageError(str(exc)) from None
    elapsed = time.perf_counter() - t0
    print(bench.format_summary(outcome.summary))
    print(
        f"ran {outcome.ran} episode(s) in {elapsed:.1f} s"
        + (f", {outcome.skipped} already done" if outcome.skipped else "")
    )
    if gate is not None:
        saved = len(jobs) - len(outcome.results)
        print(f"fail-fast: {len(outcome.results)} of {len(jobs)} episodes run, {saved} saved "
              f"({'every' if gate.settled else 'not every'} scenario's answer fixed)")  # fmt: skip
    if args.out is not None:
        write_atomic(args.out / "summary.json", json.dumps(outcome.summary, indent=2) + "\n")
        print(f"wrote {args.out / 'episodes.jsonl'} and {args.out / 'summary.json'}")
    if args.out is not None:
        written = _bench_pictures(outcome, args.out, f"{', '.join(names)}; seeds {args.seeds}", args.open_loop)
        print("wrote " + ", ".join(str(p) for p in written))
    if args.junit is not None:
        args.junit.parent.mkdir(parents=True, exist_ok=True)
        write_atomic(args.junit, bench.junit_xml(outcome.results))
        print(f"wrote {args.junit}")
    low = [n for n, s in outcome.summary.items() if s["success_rate"] < args.min_success]
    if low:
        print(f"GATE FAILED: success rate below {args.min_success:.2f} for {', '.join(low)}")
        return EXIT_FAILED
    if args.min_success > 0:
        print(f"gate passed: every scenario at or above {args.min_success:.2f}")
    return EXIT_OK


def _cmd_perceive(args: argparse.Namespace) -> int:
    try:
        seeds = bench.parse_seeds(args.seeds)
    except bench.BenchError as exc:
        raise UsageError(f"--seeds: {exc}") from None
    # The command says the task: a file without a `task` key is read as a perception task (a static,
    # tilted target is fine to look at); a file that says `task = "pick"` is checked as the pick it says it is.
    scenario = load_scenario(args.scenario, default_task="perceive")
    undescribed = any(t.shape == "mesh" for t in scenario.targets)  # seen as objects nobody described
    if args.methods is None:
        methods = [m for m in perceive.METHODS if not (undescribed and m in perceive.NEEDS_DESCRIPTION)]
    else:
        methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    unknown = [m for m in methods if m not in perceive.METHODS and ":" not in m]
    if unknown or not methods:
        raise UsageError(
            f"--methods: unknown {', '.join(unknown) or '(none given)'}; known: {', '.join(perceive.METHODS)}, "
            "or module:function for your own"
        )
    for m in methods:
        if m not in perceive.METHODS:
            _check_method(m, "--methods")
    blind = [m for m in methods if undescribed and m in perceive.NEEDS_DESCRIPTION]
    if blind:
        raise UsageError(
            f"--methods: {', '.join(blind)} {'needs' if len(blind) == 1 else 'need'} the target's shape and colour, "
            f"which {args.scenario} does not give (a mesh is seen as an object nobody described)"
        )
    print(f"pickdemo perceive: {scenario.name}, {len(scenario.targets)} target(s) x {len(seeds)} seed(s), "
          f"methods {', '.join(methods)}", flush=True)  # fmt: skip
    samples: list[perceive.PerceptionSample] = []
    from tqdm import tqdm

    if not 1 <= args.repeat <= 100:
        raise UsageError(f"--repeat must be in 1..100, got {args.repeat}")
    batches = perceive.iter_samples(scenario, seeds, methods, repeat=args.repeat)
    for batch in tqdm(batches, total=len(seeds), unit="seed", disable=not sys.stderr.isatty()):
        samples += batch
    summary = perceive.summarise(samples)
    print(perceive.format_summary(summary))
    rows = perceive.format_reference_rows(samples)
    if rows:
        print("\nThe reference's errors beside ours (paper method, the top face's centre as the main feature point):")
        print(rows)
    if args.out is not None:
        written = perceive.write_outputs(args.out, samples, summary, f"{scenario.name}, seeds {args.seeds}")

        sections = [("Summary", report.pre(perceive.format_summary(summary) + ("\n\n" + rows if rows else "")))]
        sections += [("Plots", report.image(p)) for p in written if p.suffix == ".png"]
        written.append(report.write_page(args.out, f"pickdemo perceive: {scenario.name}, seeds {args.seeds}", sections))
        print("wrote " + ", ".join(str(p) for p in written))
        if len(written) == 1:
            print("(no plot: matplotlib is missing; it is a dependency of pickdemo: pip install matplotlib)")
    return EXIT_OK


def _cmd_profile(args: argparse.Namespace) -> int:
    try:
        seeds = bench.parse_seeds(args.seeds)
    except bench.BenchError as exc:
        raise UsageError(f"--seeds: {exc}") from None
    scenario = _pick_scenario(args.scenario)
    if not args.json:
        mode = ", open loop" if args.open_loop else ""
        print(f"pickdemo profile: {scenario.name}, seeds {args.seeds}{mode}, one process", flush=True)

    def on_episode(e) -> None:
        if not args.json:
            outcome = "ok" if e.success else f"FAILED ({e.failure})"
            print(f"  seed {e.seed}: {outcome}, {e.loop_sim_s:.1f} s simulated in {e.loop_s:.2f} s "
                  f"({e.real_time_factor:.1f}x real time)", flush=True)  # fmt: skip

    report = profile(scenario, seeds, on_episode, open_loop=args.open_loop)
    print(json.dumps(report.to_dict(), indent=1) if args.json else "\n" + report.format())
    return EXIT_OK


def _cmd_list(args: argparse.Namespace) -> int:
    names = list_scenarios()
    if args.names:
        print("\n".join(names))
        return EXIT_OK
    width = max((len(n) for n in names), default=0)
    for name in names:
        try:
            text = load_scenario(name, check=False).description or "(no description)"
        except ScenarioError as exc:
            text = f"(does not load: {str(exc).split(': ', 1)[-1]})"
        print(f"{name:<{width}}  {text}")
    return EXIT_OK


def _cmd_validate(args: argparse.Namespace) -> int:
    bad = 0
    for name in args.scenarios:
        try:
            scenario = load_scenario(name)
        except ScenarioError as exc:
            print(f"error {exc}")
            bad += 1
        else:
            print(f"ok {scenario.name}")
            robot = scenario.robot_description
            if robot.home_proposed:  # (a robot file without a home: say the one it runs with, to paste in)
                home = ", ".join(f"{q if abs(q) >= 5e-5 else 0.0:.4f}" for q in robot.home_q)  # (no "-0.0000")
                print(f"  {scenario.robot}: no home given; proposed (the hand down over the table), "
                      f"to write in its [arm]: home = [{home}]")  # fmt: skip
    return EXIT_BAD_INPUT if bad else EXIT_OK


def _replay(demos, args: argparse.Namespace) -> int:  # noqa: ANN001 - the module pickdemo.apps.demos
    """Each episode asked for, replayed: a line each, then how many succeeded again."""
    episodes = demos.episodes_in(args.dir, args.episode)
    again = recorded = 0
    env = demos.replay_env(args.dir)
    for k in episodes:
        r = demos.run_replay(args.dir, k, env)
        s, a = r["from_states"], r["from_actions"]
        was = "success" if r["recorded_success"] else "failure"
        print(f"episode {k} (seed {r['seed']}, recorded {was}):"
              f" from states {'SUCCESS' if s['success'] else 'FAILED ' + str(s['failure'])},"
              f" from actions {'SUCCESS' if a['success'] else 'FAILED ' + str(a['failure'])}"
              f" ({'identical states' if a['identical'] else 'states differ'})", flush=True)  # fmt: skip
        recorded += r["recorded_success"]
        again += r["recorded_success"] and s["success"] and a["success"] and bool(a["identical"])
    if len(episodes) > 1:
        print(f"{again} of {recorded} successful episodes succeed again from their states and their actions, "
              "through the recorded states")  # fmt: skip
    return EXIT_OK if again == recorded else EXIT_FAILED


def _cmd_demos(args: argparse.Namespace) -> int:
    """``demos`` and ``replay``: the extra's modules imported only here."""
    try:
        from pickdemo.apps import demos
        from pickdemo.apps.datasets import DatasetError
    except ImportError as exc:
        raise UsageError(
            f"`pickdemo {args.command}` needs the demos extra ({exc.name} is missing): "
            "pip install -c .ci/constraints.txt '.[demos]'"
        ) from None
    try:
        if args.command == "replay":
            return _replay(demos, args)
        seeds = bench.parse_seeds(args.seeds)
        _writable_dir(args.out, "--out")
        _pick_scenario(args.scenario)
        r = demos.run_demos(
            args.scenario, seeds, args.out, fmt=args.format, fps=args.fps, only_success=args.only_success,
            resume=args.resume, progress=not args.no_progress, robot=args.robot, image_width=args.image_width,
            task=args.task, features=args.features,
        )  # fmt: skip
    except (DatasetError, bench.BenchError, ValueError) as exc:
        raise UsageError(str(exc)) from None
    print(f"{args.scenario}: {r['successes']}/{r['episodes']} episodes succeeded; {r['kept']} in the {args.format} "
          f"dataset {args.out} ({r['recorded']} recorded in {r['wall_s']:.1f} s)")  # fmt: skip
    return EXIT_OK


def _cmd_compare(args: argparse.Namespace) -> int:
    try:
        rows = cmp.compare(args.base, args.new, args.alpha)
    except cmp.CompareError as exc:
        raise UsageError(str(exc)) from None
    print(cmp.format_text(rows, args.alpha))
    for path, text in (
        (args.markdown, lambda: cmp.format_markdown(rows, args.base, args.new, args.alpha)),
        (args.json, lambda: json.dumps(cmp.to_json(rows, args.base, args.new, args.alpha), indent=1) + "\n"),
    ):
        if path is not None:
            try:
                path.write_text(text(), encoding="utf-8")
            except OSError as exc:
                raise UsageError(f"{path}: not writable ({exc.strerror or exc})") from None
    return EXIT_FAILED if any(r.verdict == "worse" for r in rows) else EXIT_OK


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "bench":
            return _cmd_bench(args)
        if args.command == "perceive":
            return _cmd_perceive(args)
        if args.command == "profile":
            return _cmd_profile(args)
        if args.command == "validate":
            return _cmd_validate(args)
        if args.command == "list":
            return _cmd_list(args)
        if args.command in ("demos", "replay"):
            return _cmd_demos(args)
        if args.command == "compare":
            return _cmd_compare(args)
        parser.print_help()
        return EXIT_BAD_INPUT
    except (ScenarioError, UsageError) as exc:
        print(f"pickdemo: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("pickdemo: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (`| head`): stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
