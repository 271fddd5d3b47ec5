"""Many seeded episodes: run them in parallel, stream each result as it finishes, summarise, gate.

``python -m pickdemo bench [SCENARIO ...] --seeds 0-199 [--workers N] [--out DIR] [--resume]``

- Each scenario x seed is one job; a job runs one episode in a worker process (an executor of
  :mod:`pickdemo.apps.executors`: a process pool, or Ray tasks with ``--executor ray``). An episode
  is self-contained and seeded, so the results are the same whatever the number of workers or the
  executor.
- Each finished episode is appended to ``DIR/episodes.jsonl`` at once (the same object as its
  ``result.json``); ``--resume`` skips the episodes already there, so an interrupted run loses
  nothing and none is run twice. Every output of a run (``episodes.jsonl``, ``summary.json``,
  ``bench.png``, ``report.html``, the JUnit XML, the printed summary) describes the same episodes:
  the ones asked for. So ``--resume`` may ask for more than the file holds (it runs the rest), never
  for less (refused before anything runs, naming the file and an episode it would leave out).
- A job that raises, kills its worker or overruns the wall-clock guard becomes a failed result with
  stage ``error`` or ``timeout``; the batch goes on. (An episode that overruns its *simulated*
  time budget ends itself with stage ``timeout``.)
"""

from __future__ import annotations

import json
import math
import os
import re
import time
import xml.etree.ElementTree as ET
from collections import Counter
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TypeAlias

from pickdemo.apps.compare import write_run_file
from pickdemo.apps.files import write_atomic
from pickdemo.core.result import EpisodeRecord, EpisodeResult, Stage, result_key, summary_name
from pickdemo.core.stats import describe
from pickdemo.runtime.episode import EpisodeOptions, run_episode
from pickdemo.scenario.load import load_scenario

DEFAULT_GUARD_S = 300.0  # wall-clock guard of one episode (a typical one takes 1-2 s)
MAX_EPISODES = 100_000  # in one bench run (a day on a 2-core machine); more is split into several runs
MAX_SEED = 2**63 - 1
#: The default gate of ``pickdemo bench``: exit 1 when a scenario succeeds less often than this.
DEFAULT_MIN_SUCCESS = 0.95

JobFn = Callable[["Job"], EpisodeRecord]
#: One scenario's statistics in ``summary.json`` (:func:`summarise` writes every key): ``episodes``,
#: ``successes``, ``success_rate``, ``success_rate_wilson95`` ([lo, hi]), ``seeds`` and ``failed_seeds``
#: (sorted lists), ``failures_by_stage`` and ``failures_by_diagnosis`` ({name: count}), counts
#: (``first_attempt_successes``, ``estimates_rejected``, ``target_moves_detected``, ``estimates_off``,
#: ``estimates_off_accepted``, ``estimates_off_fit_rejected``, ``failed_off_table``), ``real_time_factor``
#: (or None) and, for the measured quantities, :func:`pickdemo.core.stats.describe` of them (a dict of n, mean,
#: median, p95, max ..., or None when nothing was measured). A dict, as read back from the JSON file.
ScenarioSummary: TypeAlias = dict[str, Any]


class Executor(Protocol):
    """Where the jobs run (:mod:`pickdemo.apps.executors`): one result per job, as each finishes."""

    def run(self, jobs: list[Job]) -> Iterator[EpisodeRecord]: ...


class BenchError(ValueError):
    """Bad bench input (a one-line message)."""


@dataclass(frozen=True)
class Job:
    """One episode to run: which scenario file (and its name), which seed."""

    scenario_path: str
    scenario_name: str
    seed: int
    open_loop: bool = False
    perception: str = "paper"  # the perception method in the loop (pickdemo.perception.estimators)

    @property
    def key(self) -> tuple[str, int, bool, str]:
        return (self.scenario_name, self.seed, self.open_loop, self.perception)


# ------------------------------------------------------------------------------------ small pieces
_SEED_ITEM = re.compile(r"([0-9]+)(?:-([0-9]+))?")


def parse_seeds(text: str, *, limit: int = MAX_EPISODES) -> list[int]:
    """``"0-49"``, ``"3"``, ``"0-9,20,30-31"`` -> a sorted list of distinct seeds.

    Items are separated by commas (spaces around an item are allowed); each is a seed ``N`` or a
    range ``N-M`` with ``N <= M``, in ASCII digits. Anything else is an error, never a guess: an
    open range (``0-``, ``-3``), a negative seed (``0--1``), a reversed range (``3-1``) or an empty
    item (``0,,1``, ``,``). The ranges are counted before any is expanded: more than ``limit`` seeds
    is an error, not a list that fills the memory.
    """
    if len(text) > 10_000:
        raise BenchError("seed list longer than 10000 characters")
    if not text.strip():
        raise BenchError("no seeds given (use e.g. 0-49 or 0-9,20)")
    ranges: list[tuple[int, int]] = []
    for part in text.split(","):
        item = part.strip()
        m = _SEED_ITEM.fullmatch(item)
        why = ""
        if not item:
            why = "an empty item between commas"
        elif m is None:
            why = "an item is a seed N or a range N-M, whole numbers from 0"
        elif max(len(g) for g in m.groups("")) > 19 or int(m.group(2) or m.group(1)) > MAX_SEED:
            why = f"a seed is at most {MAX_SEED}"
        else:
            a, b = int(m.group(1)), int(m.group(2) or m.group(1))
            if a > b:
                why = f"the range runs down ({a} > {b}); write {b}-{a}"
        if why:
            shown = item or text  # the bad item, or the whole list when the item is empty
            shown = shown if shown.isascii() and shown.isprintable() else shown.encode("unicode_escape").decode("ascii")
            shown = shown if len(shown) <= 40 else shown[:37] + "..."
            raise BenchError(f"bad seeds {shown!r}: {why} (use e.g. 0-49 or 0-9,20)")
        ranges.append((a, b))
    count = sum(b - a + 1 for a, b in ranges)
    if count > limit:
        raise BenchError(f"{count} seeds; at most {limit} in one run")
    seeds: set[int] = set()
    for a, b in ranges:
        seeds.update(range(a, b + 1))
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


def failed_result(
    job: Job, stage: Stage, reason: str, wall_time_s: float, traceback: str | None = None
) -> EpisodeRecord:
    """The record of a job that produced none (it raised, crashed or hung): :meth:`EpisodeResult.failed`
    (``traceback``: where it raised, for a bug)."""
    return EpisodeResult.failed(
        job.scenario_name,
        job.seed,
        stage,
        reason,
        wall_time_s=wall_time_s,
        open_loop=job.open_loop,
        perception_method=job.perception,
        traceback=traceback,
    ).to_dict()


def run_job(job: Job) -> EpisodeRecord:
    """Run one episode (in a worker) and return its result dict."""
    t0 = time.perf_counter()
    try:
        scenario = load_scenario(job.scenario_path, check=False)  # checked once, before the batch started
    except Exception as exc:  # noqa: BLE001 - a job must always come back with a result
        return failed_result(job, Stage.ERROR, f"{type(exc).__name__}: {exc}", time.perf_counter() - t0)

    options = EpisodeOptions(open_loop=job.open_loop, perception_method=job.perception)
    return run_episode(scenario, job.seed, options=options).to_dict()


# ----------------------------------------------------------------------------------- result files
def load_episodes(path: Path) -> list[EpisodeRecord]:
    """Results already in ``episodes.jsonl``, each (scenario, seed, open loop or not) once.

    A line cut short by a kill (or a repeated episode) is dropped, and the file is rewritten with the
    good lines only, so that appending after it keeps one object per line. The rewrite is atomic
    (:func:`~pickdemo.apps.files.write_atomic`): a kill during it leaves the file as it was, every
    finished result in it.
    """
    if not path.exists():
        return []
    text = path.read_text()
    good: dict[tuple[str, int], EpisodeRecord] = {}
    for line in text.splitlines():
        if not line.strip():
            continue
        try:
            r = json.loads(line)
            key = (r["scenario"], int(r["seed"]), bool(r.get("open_loop", False)), r.get("perception_method", "paper"))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError):
            continue
        good.setdefault(key, r)
    clean = "".join(json.dumps(r, allow_nan=False) + "\n" for r in good.values())
    if clean != text:
        write_atomic(path, clean)
    return list(good.values())


def append_episode(path: Path, result: EpisodeRecord) -> None:
    with path.open("a") as fh:
        fh.write(json.dumps(result, allow_nan=False) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def summarise(results: Iterable[EpisodeRecord]) -> dict[str, ScenarioSummary]:
    """Per-scenario statistics of result dicts (as in ``episodes.jsonl``)."""
    by_scenario: dict[str, list[EpisodeRecord]] = {}
    for r in results:
        by_scenario.setdefault(summary_name(r), []).append(r)
    out: dict[str, ScenarioSummary] = {}
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
            "seeds": sorted(r["seed"] for r in rs),
            "failures_by_stage": {s.value: stages[s.value] for s in Stage if stages.get(s.value)},
            "failures_by_diagnosis": dict(
                Counter(r.get("diagnosis") or "not_committed" for r in rs if not r["success"])
            ),
            "failed_seeds": sorted(r["seed"] for r in rs if not r["success"]),
            "position_error_mm": describe([p["position_error_mm"] for p in perc]),
            "yaw_error_deg": describe([p["yaw_error_deg"] for p in perc if p["yaw_error_deg"] is not None]),
            "place_error_mm": describe([r["place_error_mm"] for r in rs if r["place_error_mm"] is not None]),
            "wall_time_s": describe([r["wall_time_s"] for r in rs]),
            "real_time_factor": sim / wall if wall > 0 else None,
            "first_attempt_successes": sum(1 for r in rs if r["success"] and len(r.get("attempts") or ()) == 1),
            "attempts_per_episode": describe([len(r.get("attempts") or ()) for r in rs]),
            "perception_rate_hz": describe([r.get("perception_rate_hz") for r in rs]),
            "estimates_rejected": sum(r.get("estimates_rejected") or 0 for r in rs),
            "target_moves_detected": sum(r.get("target_moves_detected") or 0 for r in rs),
            "tracking_error_mm": describe([r.get("tracking_error_mm") for r in rs]),
            "control_tick_wall_ms": describe([(r.get("control_tick_wall_ms") or {}).get("median") for r in rs]),
            "estimates_off": sum(r.get("estimates_off") or 0 for r in rs),
            "estimates_off_accepted": sum(r.get("estimates_off_accepted") or 0 for r in rs),
            "estimates_off_fit_rejected": sum(r.get("estimates_off_fit_rejected") or 0 for r in rs),
            "failed_off_table": sum(1 for r in rs if not r["success"] and r.get("target_off_table")),
        }
        rounds = [r["clear"] for r in rs if r.get("clear")]
        if rounds:
            out[name]["clear"] = clear_summary(rounds)
        worlds = [r["world"] for r in rs if r.get("world")]
        if worlds:
            out[name]["world"] = world_summary(worlds)
    return out


def world_summary(worlds: list[dict]) -> dict:
    """The world models' scores over a scenario's episodes: the objects found of those in view (recall,
    with its Wilson 95 % interval), the phantoms and the id switches, each per 100 episodes."""
    in_view, found = sum(w["in_view"] for w in worlds), sum(w["found"] for w in worlds)
    lo, hi = wilson_interval(found, in_view) if in_view else (0.0, 1.0)
    n = len(worlds)
    return {
        "episodes": n,
        "in_view": in_view,
        "found": found,
        "recall": found / in_view if in_view else None,
        "recall_wilson95": [lo, hi],
        "phantoms": sum(w["phantoms"] for w in worlds),
        "phantoms_per_100": 100.0 * sum(w["phantoms"] for w in worlds) / n,
        "id_switches": sum(w["id_switches"] for w in worlds),
        "id_switches_per_100": 100.0 * sum(w["id_switches"] for w in worlds) / n,
    }


def clear_summary(rounds: list[dict]) -> dict:
    """A clear scenario's rounds together: objects cleared over objects laid out (percent cleared) and
    successful grasps over attempts (grasp success rate), each with its Wilson 95 % interval (objects
    and attempts counted as trials), and picks per hour of simulated time."""
    cleared, total = sum(c["cleared"] for c in rounds), sum(c["total"] for c in rounds)
    ok, attempts = sum(c["successful_grasps"] for c in rounds), sum(c["grasp_attempts"] for c in rounds)
    time_s = sum(c["round_time_s"] for c in rounds)
    return {
        "rounds": len(rounds),
        "objects": total,
        "cleared": cleared,
        "percent_cleared": 100.0 * cleared / total if total else None,
        "percent_cleared_wilson95": [100.0 * v for v in wilson_interval(cleared, total)] if total else None,
        "grasp_attempts": attempts,
        "successful_grasps": ok,
        "grasp_success_rate": ok / attempts if attempts else None,
        "grasp_success_rate_wilson95": list(wilson_interval(ok, attempts)) if attempts else None,
        "picks_per_hour": 3600.0 * cleared / time_s if time_s > 0 else None,
        "seconds_per_pick": time_s / cleared if cleared else None,
        "fully_cleared_rounds": sum(1 for c in rounds if c["cleared"] == c["total"]),
    }


def _seed_ranges(seeds: list[int]) -> str:
    parts, i = [], 0
    while i < len(seeds):
        j = i
        while j + 1 < len(seeds) and seeds[j + 1] == seeds[j] + 1:
            j += 1
        parts.append(str(seeds[i]) if i == j else f"{seeds[i]}-{seeds[j]}")
        i = j + 1
    return ",".join(parts)


def format_summary(summary: dict[str, ScenarioSummary]) -> str:
    lines = []
    for name, s in summary.items():
        lo, hi = s["success_rate_wilson95"]
        lines.append(
            f"{name}: {s['successes']}/{s['episodes']} succeeded ({100 * s['success_rate']:.1f} %, "
            f"Wilson 95 % [{100 * lo:.1f}, {100 * hi:.1f}]) over seeds {_seed_ranges(s['seeds'])}"
        )
        if s["failures_by_stage"]:
            by_stage = ", ".join(f"{k} {v}" for k, v in s["failures_by_stage"].items())
            lines.append(f"  failures: {by_stage} (seeds {s['failed_seeds']})")
            by_diag = ", ".join(f"{k} {v}" for k, v in sorted(s["failures_by_diagnosis"].items()))
            lines.append(f"  failures by diagnosis (perception > 5 mm off at the grasp?): {by_diag}")
        for key, label, unit in (
            ("position_error_mm", "pose error", "mm"),
            ("yaw_error_deg", "yaw error (modulo the target's symmetry)", "deg"),
            ("place_error_mm", "place error", "mm"),
        ):
            st = s[key]
            if st:
                med, p95, mx = st["median"], st["p95"], st["max"]
                lines.append(f"  {label}: median {med:.3f} {unit}, p95 {p95:.3f}, max {mx:.3f} (n={st['n']})")
        att = s["attempts_per_episode"]
        if att and not s.get("clear"):
            lines.append(
                f"  first attempt: {s['first_attempt_successes']}/{s['episodes']}; attempts per episode: "
                f"mean {att['mean']:.2f}, max {att['max']:.0f}"
            )
        if s["perception_rate_hz"] and s["perception_rate_hz"]["median"] > 0:
            trk = s["tracking_error_mm"]
            lines.append(
                f"  closed loop: perception {s['perception_rate_hz']['median']:.1f} Hz, "
                f"{s['estimates_rejected']} estimate(s) turned away by the tracker's gate, "
                f"{s['target_moves_detected']} target move(s) "
                f"detected" + (f", tracking error at the grasp median {trk['median']:.2f} mm" if trk else "")
            )
        if s["estimates_off"]:
            off, acc, fit = s["estimates_off"], s["estimates_off_accepted"], s.get("estimates_off_fit_rejected", 0)
            lines.append(
                f"  estimates > 5 mm off the truth: {off}; not acted on {off - acc} ({100 * (off - acc) / off:.0f} %: "
                f"{fit} by perception's fit check, {off - acc - fit} by the loop's checks), acted on {acc}"
            )
        if s.get("failed_off_table"):
            lines.append(f"  failed episodes that left the target off the table: {s['failed_off_table']}")
        w = s.get("world")
        if w and w["in_view"]:
            lines.append(
                f"  world model: found {w['found']}/{w['in_view']} objects in view (recall {w['recall']:.3f}), "
                f"{w['phantoms']} phantom(s), {w['id_switches']} id switch(es) over {w['episodes']} episodes"
            )
        c = s.get("clear")
        if c and c["objects"]:
            clo, chi = c["percent_cleared_wilson95"]
            lines.append(
                f"  cleared {c['cleared']}/{c['objects']} objects ({c['percent_cleared']:.1f} %, Wilson 95 % "
                f"[{clo:.1f}, {chi:.1f}]); {c['fully_cleared_rounds']}/{c['rounds']} rounds cleared whole"
            )
            if c["grasp_attempts"]:
                glo, ghi = c["grasp_success_rate_wilson95"]
                lines.append(
                    f"  grasps: {c['successful_grasps']}/{c['grasp_attempts']} succeeded "
                    f"({100 * c['grasp_success_rate']:.1f} %, Wilson 95 % [{100 * glo:.1f}, {100 * ghi:.1f}]); "
                    f"{c['picks_per_hour']:.0f} picks per simulated hour ({c['seconds_per_pick']:.2f} s a pick)"
                )
        wt, rtf = s["wall_time_s"], s["real_time_factor"]
        rtf_text = f"{rtf:.1f}x" if rtf is not None else "n/a"
        tick = s["control_tick_wall_ms"]
        tick_text = f"; control decision {tick['median']:.3f} ms a tick (median)" if tick else ""
        lines.append(f"  wall time per episode: median {wt['median']:.2f} s; real-time factor {rtf_text}{tick_text}")
    return "\n".join(lines)


_XML_INVALID = dict.fromkeys([*range(0, 9), 11, 12, *range(14, 32), 0xFFFE, 0xFFFF])


def xml_text(text: object) -> str:
    """Text XML 1.0 can hold: characters it forbids (control characters) written as ``\\xNN``."""
    s = str(text)
    if not any(ord(c) in _XML_INVALID or 0xD800 <= ord(c) <= 0xDFFF for c in s):
        return s
    return "".join(f"\\x{ord(c):02x}" if (ord(c) in _XML_INVALID or 0xD800 <= ord(c) <= 0xDFFF) else c for c in s)


def junit_xml(results: Iterable[EpisodeRecord]) -> str:
    """JUnit XML: one test suite per scenario, one test case per episode, the failure as message."""
    by_scenario: dict[str, list[EpisodeRecord]] = {}
    for r in results:
        by_scenario.setdefault(r["scenario"], []).append(r)
    root = ET.Element("testsuites", name="pickdemo bench")
    for name, rs in sorted(by_scenario.items()):
        rs = sorted(rs, key=lambda r: r["seed"])
        failures = sum(1 for r in rs if not r["success"])
        suite = ET.SubElement(
            root, "testsuite", name=xml_text(name), tests=str(len(rs)), failures=str(failures), errors="0",
            time=f"{sum(r['wall_time_s'] for r in rs):.3f}",
        )  # fmt: skip
        for r in rs:
            case = ET.SubElement(
                suite,
                "testcase",
                classname=xml_text(f"pickdemo.{name}"),
                name=f"seed {r['seed']}",
                time=f"{r['wall_time_s']:.3f}",
            )
            if not r["success"]:
                f = r["failure"] or {"stage": "unknown", "reason": ""}
                msg = xml_text(f"{f['stage']}: {f['reason']}")
                ET.SubElement(case, "failure", message=msg, type=xml_text(f["stage"])).text = msg
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


# ------------------------------------------------------------------------------------------ driver
@dataclass(frozen=True)
class BenchOutcome:
    results: list[EpisodeRecord]  # every episode of the batch, resumed ones included
    summary: dict[str, ScenarioSummary]
    ran: int  # episodes run by this call
    skipped: int  # episodes found done already (--resume)


#: What a bench writes beside ``episodes.jsonl``, all of it derived from it (rewritten at the end of a run).
DERIVED_FILES = ("summary.json", "bench.png", "report.html")


def prepare_out_dir(out_dir: Path, jobs: list[Job], *, resume: bool) -> list[EpisodeRecord]:
    """Ready ``out_dir`` for a run of ``jobs``; the results already there (``--resume``).

    One run, one set of episodes, in every output: ``episodes.jsonl`` holds only episodes of this
    run. Without ``resume`` it must be empty (or absent); with it, every episode it holds must be one
    of ``jobs`` (a run may add episodes to a directory, never describe a part of it): an episode
    outside raises :class:`BenchError` naming the file and one such episode, before anything runs.
    The files derived from the episodes (:data:`DERIVED_FILES`) are removed, so that a run that is
    interrupted leaves no summary of another set of episodes beside ``episodes.jsonl``.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    jsonl = out_dir / "episodes.jsonl"
    done: list[EpisodeRecord] = []
    if resume:
        done = load_episodes(jsonl)
        wanted = {j.key for j in jobs}
        outside = sorted((r for r in done if result_key(r) not in wanted), key=result_key)
        if outside:
            r = outside[0]
            held = summarise(done)
            what = "; ".join(f"{name} seeds {_seed_ranges(s['seeds'])}" for name, s in held.items())
            asked: dict[str, list[int]] = {}
            for j in jobs:
                name = summary_name(
                    {"scenario": j.scenario_name, "open_loop": j.open_loop, "perception_method": j.perception}
                )
                asked.setdefault(name, []).append(j.seed)
            this = "; ".join(f"{name} seeds {_seed_ranges(sorted(seeds))}" for name, seeds in asked.items())
            raise BenchError(
                f"{jsonl}: holds {len(outside)} episode(s) this run does not ask for (e.g. {summary_name(r)} seed "
                f"{r['seed']}); it holds {_short(what, 160)}, this run asks for {_short(this, 160)}: ask for all of "
                "them, or use another --out"
            )
    elif jsonl.exists() and jsonl.stat().st_size > 0:
        raise BenchError(f"{jsonl} exists: pass --resume to continue that run, or remove it")
    else:
        write_atomic(jsonl, "")
    for name in DERIVED_FILES:
        (out_dir / name).unlink(missing_ok=True)
    write_run_file(out_dir)  # (where it ran: `compare` pairs runs of one machine and lock only)
    return done


def _short(text: str, limit: int) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."


def run_bench(
    jobs: list[Job],
    executor: Executor,
    *,
    out_dir: Path | None = None,
    resume: bool = False,
    progress: bool = True,
    on_result: Callable[[EpisodeRecord], None] | None = None,
    done: list[EpisodeRecord] | None = None,
    skip: Callable[[Job], bool] | None = None,
) -> BenchOutcome:
    """Run the jobs not done yet, streaming each result to ``out_dir/episodes.jsonl`` as it finishes.

    ``done``: what :func:`prepare_out_dir` returned, when the caller checked the directory already
    (before it started an executor); else it is checked here. ``skip``: the executor's (jobs no longer
    needed, asked after each result: ``--fail-fast``).
    """
    from tqdm import tqdm

    jsonl = None
    if out_dir is not None:
        jsonl = out_dir / "episodes.jsonl"
        if done is None:
            done = prepare_out_dir(out_dir, jobs, resume=resume)
    done = list(done or [])
    done_keys = {result_key(r) for r in done}
    todo = [j for j in jobs if j.key not in done_keys]
    results = list(done)
    ok = sum(1 for r in results if r["success"])
    bar = tqdm(total=len(jobs), initial=len(done), disable=not progress, unit="ep", dynamic_ncols=True,
               mininterval=0.5 if os.isatty(2) else 10.0)  # fmt: skip
    try:
        for r in executor.run(todo, skip) if skip is not None else executor.run(todo):
            if jsonl is not None:
                append_episode(jsonl, r)
            results.append(r)
            ok += bool(r["success"])
            bar.update(1)
            bar.set_postfix_str(f"success {100 * ok / len(results):.1f} %", refresh=False)
            if on_result is not None:
                on_result(r)
    finally:
        bar.close()
    return BenchOutcome(results=results, summary=summarise(results), ran=len(results) - len(done), skipped=len(done))
