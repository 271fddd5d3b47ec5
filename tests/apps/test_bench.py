"""The bench: parsing, statistics, JUnit, resume, fault isolation, parallel determinism, Ray."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from pickdemo.apps.bench import (
    BenchError,
    Job,
    failed_result,
    format_summary,
    junit_xml,
    load_episodes,
    parse_seeds,
    run_bench,
    run_job,
    summarise,
    wilson_interval,
)
from pickdemo.apps.executors import LocalExecutor
from pickdemo.core.result import WALL_CLOCK_KEYS, Stage


def _result(scenario: str, seed: int, ok: bool, stage: str = "grasp") -> dict:
    return {
        "scenario": scenario, "seed": seed, "success": ok,
        "failure": None if ok else {"stage": stage, "reason": "fingers closed <to> 0 mm & \"nothing\""},
        "perception": {"position_error_mm": 0.1 * seed, "yaw_error_deg": 0.2, "estimated_pose": {}, "true_pose": {}},
        "place_error_mm": 1.0 if ok else None, "lift_height_mm": 100.0, "grasp_width_mm": 50.0,
        "sim_time_s": 10.0, "wall_time_s": 1.0, "stage_wall_times_s": {}, "phases": [],
    }  # fmt: skip


def test_parse_seeds() -> None:
    assert parse_seeds("0-4") == [0, 1, 2, 3, 4]
    assert parse_seeds("3, 0-1,3") == [0, 1, 3]
    assert parse_seeds(" 7 ") == [7] and parse_seeds("0-0") == [0]
    for bad in ("", "5-2", "-1", "a", "1-b"):
        with pytest.raises(BenchError):
            parse_seeds(bad)


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ("0-", "a seed N or a range N-M"),  # issue 17: read as seed 0
        ("-3", "a seed N or a range N-M"),
        ("0--1", "a seed N or a range N-M"),
        ("3-1", "the range runs down (3 > 1); write 1-3"),
        (",", "an empty item"),
        ("0,,1", "an empty item"),
        ("0,", "an empty item"),
        ("   ", "no seeds given"),
        ("1 2", "a seed N or a range N-M"),
        ("0 - 3", "a seed N or a range N-M"),
        ("+3", "a seed N or a range N-M"),
        ("\u00b2", "a seed N or a range N-M"),  # a digit to str.isdigit, not a seed
        ("0-9223372036854775808", "a seed is at most 9223372036854775807"),
        ("9" * 5000, "a seed is at most"),  # longer than int() reads: still one line
    ],
)
def test_parse_seeds_refuses_what_is_not_a_seed_list(text: str, why: str) -> None:
    with pytest.raises(BenchError) as err:
        parse_seeds(text)
    msg = str(err.value)
    assert why in msg and "\n" not in msg and len(msg) < 200 and msg.isascii(), msg


def test_wilson_interval() -> None:
    lo, hi = wilson_interval(50, 50)
    assert lo == pytest.approx(0.92865, abs=1e-4) and hi == pytest.approx(1.0)
    lo, hi = wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.27753, abs=1e-4)
    lo, hi = wilson_interval(98, 100)
    assert lo == pytest.approx(0.92996, abs=1e-4) and hi == pytest.approx(0.99450, abs=1e-4)


def test_summary_counts_failures_by_stage() -> None:
    rs = [_result("a", s, s != 2, "grasp") for s in range(5)] + [_result("b", 0, False, "timeout")]
    s = summarise(rs)
    assert s["a"]["successes"] == 4 and s["a"]["failures_by_stage"] == {"grasp": 1} and s["a"]["failed_seeds"] == [2]
    assert s["b"]["failures_by_stage"] == {"timeout": 1}
    assert s["a"]["position_error_mm"]["median"] == pytest.approx(0.2)
    assert s["a"]["real_time_factor"] == pytest.approx(10.0)


def test_the_two_rejection_counts_say_what_each_counts() -> None:
    # Issue 57: "0 estimate(s) rejected" beside "rejected 24": two counters, one word.
    summary = summarise([_result("a", 0, True)])
    summary["a"] |= {"perception_rate_hz": {"median": 10.0}, "estimates_rejected": 0, "estimates_off": 30,
                     "estimates_off_accepted": 6, "estimates_off_fit_rejected": 20}  # fmt: skip
    text = format_summary(summary)
    assert "0 estimate(s) turned away by the tracker's gate" in text, text
    said = "off the truth: 30; not acted on 24 (80 %: 20 by perception's fit check, 4 by the loop's checks), acted on 6"
    assert said in text, text
    assert "rejected" not in text


def test_junit_xml_parses_and_carries_reasons() -> None:
    rs = [_result("a", 1, True), _result("a", 0, False)]
    root = ET.fromstring(junit_xml(rs))
    suite = root.find("testsuite")
    assert suite.get("name") == "a" and suite.get("tests") == "2" and suite.get("failures") == "1"
    cases = suite.findall("testcase")
    assert [c.get("name") for c in cases] == ["seed 0", "seed 1"]
    failure = cases[0].find("failure")
    assert failure.get("type") == "grasp" and "nothing" in failure.get("message")


def test_load_episodes_drops_a_cut_line_and_duplicates(tmp_path: Path) -> None:
    f = tmp_path / "episodes.jsonl"
    lines = [json.dumps(_result("a", 0, True)), json.dumps(_result("a", 1, True)), json.dumps(_result("a", 0, True))]
    f.write_text("\n".join(lines) + "\n" + json.dumps(_result("a", 2, True))[:40])
    got = load_episodes(f)
    assert sorted(r["seed"] for r in got) == [0, 1]
    assert len(f.read_text().splitlines()) == 2  # rewritten clean, ready for appending


# Jobs for the executor, at module level so that worker processes can unpickle them.
def _job_ok(job: Job) -> dict:
    return _result(job.scenario_name, job.seed, True)


def _job_raises(job: Job) -> dict:
    if job.seed == 1:
        raise RuntimeError("boom")
    return _job_ok(job)


def _job_dies(job: Job) -> dict:
    if job.seed == 1:
        os._exit(3)
    return _job_ok(job)


def _job_hangs(job: Job) -> dict:
    if job.seed == 1:
        time.sleep(60)
    return _job_ok(job)


@pytest.mark.parametrize(("fn", "stage", "reason"), [
    (_job_raises, "error", "RuntimeError: boom"),
    (_job_dies, "error", "worker died"),
    (_job_hangs, "timeout", "wall-clock guard"),
])  # fmt: skip
def test_one_bad_episode_does_not_take_the_batch_down(tmp_path: Path, fn, stage: str, reason: str) -> None:
    jobs = [Job("x.toml", "x", s) for s in range(4)]
    out = run_bench(jobs, LocalExecutor(2, guard_s=3.0, fn=fn), out_dir=tmp_path, progress=False)
    by_seed = {r["seed"]: r for r in out.results}
    assert sorted(by_seed) == [0, 1, 2, 3]
    assert by_seed[1]["failure"]["stage"] == stage and reason in by_seed[1]["failure"]["reason"]
    assert all(by_seed[s]["success"] for s in (0, 2, 3))
    assert len((tmp_path / "episodes.jsonl").read_text().splitlines()) == 4


def _job_slow_then_bad(job: Job) -> dict:
    """Seed 0 takes a second; seed 1 then raises, kills its worker or hangs (the job's scenario name says which)."""
    if job.seed == 0:
        time.sleep(1.0)
    elif job.scenario_name == "raises":
        raise RuntimeError("boom")
    elif job.scenario_name == "dies":
        os._exit(3)
    else:
        time.sleep(60)
    return _job_ok(job)


@pytest.mark.parametrize(("how", "low", "high"), [("raises", 0.0, 0.5), ("dies", 0.0, 0.5), ("hangs", 2.0, 2.9)])
def test_a_failed_episodes_wall_time_is_its_own(tmp_path: Path, how: str, low: float, high: float) -> None:
    # Issue 57: it was measured from the batch's start (here 1 s before: seed 0 ran first on the one worker).
    jobs = [Job("x.toml", how, s) for s in range(2)]
    out = run_bench(jobs, LocalExecutor(1, guard_s=2.0, fn=_job_slow_then_bad), progress=False)
    bad = next(r for r in out.results if r["seed"] == 1)
    assert bad["failure"]["stage"] == ("timeout" if how == "hangs" else "error")
    assert low <= bad["wall_time_s"] < high, bad
    # a job that raised is a bug: where it raised comes with it (a worker that died or hung has none)
    assert ("_job_slow_then_bad" in bad["failure"].get("traceback", "")) == (how == "raises"), bad["failure"]


def test_existing_results_need_resume(tmp_path: Path) -> None:
    jobs = [Job("x.toml", "x", s) for s in range(3)]
    run_bench(jobs, LocalExecutor(1, fn=_job_ok), out_dir=tmp_path, progress=False)
    with pytest.raises(BenchError, match="--resume"):
        run_bench(jobs, LocalExecutor(1, fn=_job_ok), out_dir=tmp_path, progress=False)
    more = [Job("x.toml", "x", s) for s in range(5)]
    out = run_bench(more, LocalExecutor(1, fn=_job_ok), out_dir=tmp_path, resume=True, progress=False)
    assert (out.skipped, out.ran) == (3, 2)
    lines = (tmp_path / "episodes.jsonl").read_text().splitlines()
    assert sorted(json.loads(line)["seed"] for line in lines) == [0, 1, 2, 3, 4]


def test_resume_runs_the_rest_and_every_result_is_of_the_run(tmp_path: Path) -> None:
    run_bench([Job("x.toml", "x", s) for s in range(3)], LocalExecutor(1, fn=_job_ok), out_dir=tmp_path, progress=False)
    for name in ("summary.json", "bench.png", "report.html"):  # a summary of these 3, as a finished run leaves
        (tmp_path / name).write_text("old")
    more = [Job("x.toml", "x", s) for s in range(5)]
    out = run_bench(more, LocalExecutor(1, fn=_job_ok), out_dir=tmp_path, resume=True, progress=False)
    assert sorted(r["seed"] for r in out.results) == [0, 1, 2, 3, 4] and out.summary["x"]["episodes"] == 5
    assert not any((tmp_path / n).exists() for n in ("summary.json", "bench.png", "report.html"))  # never stale


def test_resume_refuses_a_file_holding_episodes_outside_the_run(tmp_path: Path) -> None:
    run_bench([Job("x.toml", "x", s) for s in range(20)], LocalExecutor(2, fn=_job_ok), out_dir=tmp_path,
              progress=False)  # fmt: skip
    jsonl = tmp_path / "episodes.jsonl"
    before = jsonl.read_text()
    ran: list[int] = []
    with pytest.raises(BenchError) as err:
        run_bench([Job("x.toml", "x", s) for s in range(2)], LocalExecutor(1, fn=_job_ok), out_dir=tmp_path,
                  resume=True, progress=False, on_result=lambda r: ran.append(r["seed"]))  # fmt: skip
    msg = str(err.value)
    assert str(jsonl) in msg and "18 episode(s)" in msg and "x seed 2" in msg and "x seeds 0-19" in msg, msg
    assert "\n" not in msg and ran == [] and jsonl.read_text() == before
    # Another perception method, or open loop, is another episode: refused the same way.
    with pytest.raises(BenchError, match="x seed 0"):
        run_bench([Job("x.toml", "x", s, open_loop=True) for s in range(20)], LocalExecutor(1, fn=_job_ok),
                  out_dir=tmp_path, resume=True, progress=False)  # fmt: skip


def test_a_fresh_run_removes_an_old_runs_summary(tmp_path: Path) -> None:
    (tmp_path / "episodes.jsonl").write_text("")
    (tmp_path / "summary.json").write_text("{}")
    out = run_bench([Job("x.toml", "x", 0)], LocalExecutor(1, fn=_job_ok), out_dir=tmp_path, progress=False)
    assert out.ran == 1 and not (tmp_path / "summary.json").exists()


#: ``python -c`` this, LIMIT, ARGS...: the command line, in a process whose files may grow to LIMIT bytes. A
#: write past it kills the process at once (SIGXFSZ, whose default action Python turns off): the kill lands
#: inside the first write of a file longer than LIMIT, whatever the code that writes it.
KILLED_MID_WRITE = """
import resource, signal, sys
from pickdemo.apps.cli import main
signal.signal(signal.SIGXFSZ, signal.SIG_DFL)
resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[1]), resource.RLIM_INFINITY))
sys.exit(main(sys.argv[2:]))
"""


def _whole_lines(path: Path) -> list[dict]:
    """The results a file holds (a line cut short holds none)."""
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="a POSIX file-size limit")
def test_a_kill_during_the_resumes_rewrite_loses_no_finished_result(tmp_path: Path) -> None:
    # Issue 57: --resume rewrote episodes.jsonl in place (truncate, then write): a kill then emptied it.
    out = tmp_path / "gate"
    out.mkdir()
    jsonl = out / "episodes.jsonl"
    finished = [  # 9 finished episodes, 200 kB each (so that no other file the process writes is as long)
        json.dumps(failed_result(Job("x.toml", "pick_cube", s), Stage.ERROR, "x" * 200_000, 1.0)) + "\n"
        for s in range(9)
    ]
    jsonl.write_text("".join(finished) + finished[0][:1000])  # and a line a kill cut short: resume rewrites
    limit = len("".join(finished)) // 2  # killed halfway through the rewrite
    args = ["bench", "pick_cube", "--seeds", "0-8", "--out", str(out), "--resume", "--no-progress"]
    proc = subprocess.run([sys.executable, "-c", KILLED_MID_WRITE, str(limit), *args], capture_output=True,
                          text=True, timeout=300, env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})  # fmt: skip
    assert proc.returncode == -signal.SIGXFSZ, proc.stdout + proc.stderr  # killed, not finished
    seeds = {r["seed"] for r in _whole_lines(jsonl)}
    assert seeds == set(range(9)), f"{len(seeds)} of 9 finished results left"
    partial = [p for p in out.iterdir() if p.name.startswith(".episodes.jsonl.")]
    assert [p.stat().st_size for p in partial] == [limit]  # the kill was in the rewrite: of its temporary file
    again = _cli(*args, "--workers", "1", "--min-success", "0")
    assert again.returncode == 0 and "ran 0 episode(s)" in again.stdout and "9 already done" in again.stdout
    assert jsonl.read_text() == "".join(finished)  # rewritten clean


def test_bad_scenario_in_a_job_is_an_error_result() -> None:
    r = run_job(Job("/no/such/scenario.toml", "ghost", 0))
    assert r["success"] is False and r["failure"]["stage"] == "error" and "no such scenario" in r["failure"]["reason"]


def _strip(rs: list[dict]) -> dict:
    return {(r["scenario"], r["seed"]): {k: v for k, v in r.items() if k not in WALL_CLOCK_KEYS}
            for r in rs}  # fmt: skip


@pytest.mark.sim
@pytest.mark.slow
def test_same_results_whatever_the_worker_count(cube_scenario) -> None:
    from pickdemo.scenario.load import resolve_scenario_path

    jobs = [Job(str(resolve_scenario_path("pick_cube")), "pick_cube", s) for s in range(3)]
    one = run_bench(jobs, LocalExecutor(1), progress=False).results
    two = run_bench(jobs, LocalExecutor(2), progress=False).results
    assert _strip(one) == _strip(two)


def _cli(*args: str, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pickdemo", *args], capture_output=True, text=True, timeout=600, **kw)


@pytest.mark.sim
@pytest.mark.slow
def test_cli_bench_gate_and_files(tmp_path: Path) -> None:
    out = tmp_path / "b"
    proc = _cli("bench", "pick_cube", "pick_cylinder", "--seeds", "0-1", "--workers", "2", "--out", str(out),
                "--junit", str(tmp_path / "j.xml"), "--min-success", "0.5", "--no-progress")  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "gate passed" in proc.stdout
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 4
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pick_cube"]["episodes"] == 2 and summary["pick_cylinder"]["success_rate"] >= 0.5
    assert len(ET.parse(tmp_path / "j.xml").getroot().findall("testsuite/testcase")) == 4
    # Resumed: nothing to run again.
    again = _cli(
        "bench",
        "pick_cube",
        "pick_cylinder",
        "--seeds",
        "0-1",
        "--out",
        str(out),
        "--resume",
        "--no-progress",
        "--min-success",
        "0.5",
    )
    assert again.returncode == 0 and "ran 0 episode(s)" in again.stdout and "4 already done" in again.stdout
    # Without --resume the results are not overwritten.
    clash = _cli("bench", "pick_cube", "--seeds", "0-1", "--out", str(out), "--no-progress")
    assert clash.returncode == 2 and "--resume" in clash.stderr


def test_cli_bench_refuses_to_resume_on_part_of_a_run(tmp_path: Path) -> None:
    # Issue 17: 20 episodes there, 2 asked for: refused before anything runs, every file left as it was.
    out = tmp_path / "gate"
    out.mkdir()
    jsonl = out / "episodes.jsonl"
    jsonl.write_text("".join(json.dumps(_result("pick_cube", s, True)) + "\n" for s in range(20)))
    (out / "junit.xml").write_text("<old/>")
    proc = _cli("bench", "pick_cube", "--seeds", "0-1", "--out", str(out), "--resume", "--junit",
                str(out / "junit.xml"), "--no-progress")  # fmt: skip
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stdout + proc.stderr
    assert str(jsonl) in proc.stderr and "pick_cube seed 2" in proc.stderr and "Traceback" not in proc.stderr
    assert len(jsonl.read_text().splitlines()) == 20 and (out / "junit.xml").read_text() == "<old/>"
    assert not (out / "summary.json").exists()


def test_bench_gate_has_a_real_default() -> None:
    from pickdemo.apps.bench import DEFAULT_MIN_SUCCESS
    from pickdemo.apps.cli import build_parser

    assert build_parser().parse_args(["bench"]).min_success == DEFAULT_MIN_SUCCESS == 0.95
    help_text = " ".join(_cli("bench", "--help").stdout.split())
    assert "exit 1 if a scenario's success rate is below RATE (default 0.95; 0: no gate)" in help_text


@pytest.mark.sim
def test_bench_gates_without_min_success_and_zero_turns_it_off(tmp_path: Path) -> None:
    bad = tmp_path / "too_short.toml"  # possible, but given too little simulated time: it fails when it runs
    bad.write_text('name = "too_short"\n[[objects]]\nname = "c"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\n'
                   'color = [0.85, 0.1, 0.1]\nposition = [0.5, 0.0]\ntarget = true\n[sim]\nmax_sim_time_s = 2.0\n'
                   '[place]\nposition = [0.4, 0.3]\n')  # fmt: skip
    out = tmp_path / "o"
    gated = _cli("bench", str(bad), "--seeds", "0", "--workers", "1", "--out", str(out), "--no-progress")
    assert gated.returncode == 1 and "GATE FAILED: success rate below 0.95" in gated.stdout, gated.stdout
    off = _cli("bench", str(bad), "--seeds", "0", "--out", str(out), "--resume", "--min-success", "0", "--no-progress")
    assert off.returncode == 0 and "ran 0 episode(s)" in off.stdout and "GATE" not in off.stdout, off.stdout


@pytest.mark.sim
@pytest.mark.slow
def test_resumed_bench_outputs_all_describe_the_whole_run(tmp_path: Path) -> None:
    out = tmp_path / "gate"
    junit = out / "junit.xml"
    first = _cli("bench", "pick_cube", "--seeds", "0", "--workers", "1", "--out", str(out), "--junit", str(junit),
                 "--no-progress", "--min-success", "0")  # fmt: skip
    assert first.returncode == 0, first.stdout + first.stderr
    more = _cli("bench", "pick_cube", "--seeds", "0-1", "--workers", "1", "--out", str(out), "--resume", "--junit",
                str(junit), "--no-progress", "--min-success", "0")  # fmt: skip
    assert more.returncode == 0 and "ran 1 episode(s)" in more.stdout and "1 already done" in more.stdout, more.stdout
    assert re.search(r"pick_cube: \d/2 succeeded .* over seeds 0-1", more.stdout), more.stdout
    assert [json.loads(line)["seed"] for line in (out / "episodes.jsonl").read_text().splitlines()] == [0, 1]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pick_cube"]["seeds"] == [0, 1]
    cases = ET.parse(junit).getroot().findall("testsuite/testcase")
    assert sorted(c.get("name") for c in cases) == ["seed 0", "seed 1"]
    assert "seeds 0-1" in (out / "report.html").read_text()  # the page of this run, not of the first


def test_cli_bench_bad_input() -> None:
    for args in (("--seeds", "9-1"), ("--seeds", "0-"), ("--workers", "0"), ("--resume",), ("--min-success", "2")):
        proc = _cli("bench", "pick_cube", *args)
        assert proc.returncode == 2 and proc.stderr.count("\n") == 1, (args, proc.stderr)


@pytest.mark.sim
def test_gate_fails_below_min_success(tmp_path: Path) -> None:
    # Well-formed and possible, but given too little simulated time: it fails when it runs.
    bad = tmp_path / "too_short.toml"
    bad.write_text('name = "too_short"\n[[objects]]\nname = "c"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\n'
                   'color = [0.85, 0.1, 0.1]\nposition = [0.5, 0.0]\ntarget = true\n[sim]\nmax_sim_time_s = 2.0\n'
                   '[place]\nposition = [0.4, 0.3]\n')  # fmt: skip
    proc = _cli(
        "bench", str(bad), "--seeds", "0", "--min-success", "0.5", "--no-progress", "--junit", str(tmp_path / "j.xml")
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "GATE FAILED" in proc.stdout and "FAIL too_short seed 0: timeout" in proc.stdout + proc.stderr


@pytest.mark.sim
@pytest.mark.slow
def test_killed_bench_resumes_with_every_episode_once(tmp_path: Path) -> None:
    out = tmp_path / "k"
    args = [sys.executable, "-m", "pickdemo", "bench", "pick_cube", "--seeds", "0-7", "--workers", "2",
            "--out", str(out), "--no-progress"]  # fmt: skip
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    jsonl = out / "episodes.jsonl"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if jsonl.exists() and len(jsonl.read_text().splitlines()) >= 3:
            break
        time.sleep(0.1)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    done_before = len(jsonl.read_text().splitlines())
    assert 3 <= done_before < 8
    resumed = _cli(
        "bench",
        "pick_cube",
        "--seeds",
        "0-7",
        "--workers",
        "2",
        "--out",
        str(out),
        "--resume",
        "--no-progress",
        "--min-success",
        "0",
    )
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    seeds = [json.loads(line)["seed"] for line in jsonl.read_text().splitlines()]
    assert sorted(seeds) == list(range(8))  # every episode exactly once


@pytest.mark.sim
def test_ray_executor_gives_the_same_results() -> None:
    pytest.importorskip("ray")
    import ray

    from pickdemo.apps.executors import RayExecutor
    from pickdemo.scenario.load import resolve_scenario_path

    jobs = [Job(str(resolve_scenario_path("pick_cube")), "pick_cube", s) for s in range(2)]
    try:
        on_ray = run_bench(jobs, RayExecutor(None, num_cpus=2), progress=False).results
    finally:
        ray.shutdown()
    local = run_bench(jobs, LocalExecutor(2), progress=False).results
    assert _strip(on_ray) == _strip(local)


@pytest.mark.slow
def test_a_ray_task_whose_worker_died_is_run_again_and_the_run_completes(tmp_path: Path) -> None:
    """As when a node is lost mid-run: Ray runs the task again elsewhere, and nothing is lost or doubled."""
    ray = pytest.importorskip("ray")
    from ray import cloudpickle

    from pickdemo.apps.executors import RayExecutor

    died = tmp_path / "died-once"

    def dies_once(job: Job) -> dict:
        if job.seed == 1 and not died.exists():
            died.touch()
            os._exit(3)
        return _job_ok(job)

    module = sys.modules[__name__]
    cloudpickle.register_pickle_by_value(module)  # (Ray's workers cannot import this test module)
    try:
        jobs = [Job("x.toml", "x", s) for s in range(3)]
        out = run_bench(jobs, RayExecutor(None, fn=dies_once, num_cpus=2), out_dir=tmp_path, progress=False)
    finally:
        ray.shutdown()
        cloudpickle.unregister_pickle_by_value(module)
    assert died.exists()  # its first run died
    assert sorted(r["seed"] for r in out.results) == [0, 1, 2] and all(r["success"] for r in out.results)
    assert len((tmp_path / "episodes.jsonl").read_text().splitlines()) == 3


def _job_takes_a_moment(job: Job) -> dict:
    time.sleep(0.5)  # (so that some are on the node when it goes)
    return _job_ok(job)


@pytest.mark.slow
def test_a_ray_node_lost_mid_run_loses_no_episode(tmp_path: Path) -> None:
    """A cluster of two nodes; one is killed after the first results: every job still ends, once, well."""
    ray = pytest.importorskip("ray")
    from ray import cloudpickle
    from ray.cluster_utils import Cluster

    from pickdemo.apps.executors import RayExecutor

    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    node = cluster.add_node(num_cpus=1)
    module = sys.modules[__name__]
    cloudpickle.register_pickle_by_value(module)  # (Ray's workers cannot import this test module)
    results = []
    try:
        executor = RayExecutor(cluster.address, fn=_job_takes_a_moment)
        for r in executor.run([Job("x.toml", "x", s) for s in range(10)]):
            results.append(r)
            if len(results) == 2:
                cluster.remove_node(node, allow_graceful=False)
    finally:
        ray.shutdown()
        cluster.shutdown()
        cloudpickle.unregister_pickle_by_value(module)
    assert sorted(r["seed"] for r in results) == list(range(10))
    assert all(r["success"] for r in results), [r["failure"] for r in results if not r["success"]]


def test_a_failed_job_is_an_episode_result() -> None:
    """A job that produced no result becomes :meth:`EpisodeResult.failed`, serialised by its ``to_dict``:
    the keys of every other result, in their order, nothing measured."""
    from pickdemo.apps.bench import Job, failed_result
    from pickdemo.core.result import EpisodeResult, Stage

    made = failed_result(Job("x.toml", "ghost", 3, open_loop=True, perception="icp"), Stage.TIMEOUT, "hung", 300.0)
    real = EpisodeResult("ghost", 3, False, None, None, None, None, None, 0.0, 1.0).to_dict()
    assert list(made) == list(real)
    assert made["failure"] == {"stage": "timeout", "reason": "hung"} and made["wall_time_s"] == 300.0
    assert made["open_loop"] is True and made["perception_method"] == "icp" and made["diagnosis"] == "not_committed"
    assert made["sim_time_s"] == 0.0 and made["phases"] == [] and made["perception"] is None


def test_resuming_in_another_mode_says_which_mode_it_asks_for(tmp_path: Path) -> None:
    out = tmp_path / "gate"
    out.mkdir()
    (out / "episodes.jsonl").write_text(json.dumps(_result("pick_cube", 0, True)) + "\n")
    proc = _cli("bench", "pick_cube", "--seeds", "0", "--open-loop", "--out", str(out), "--resume", "--no-progress")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "this run asks for pick_cube [open loop] seeds 0" in proc.stderr


def test_a_ray_address_nobody_answers_is_a_one_line_error_not_a_hang() -> None:
    pytest.importorskip("ray")
    # (a hang would end in _cli's own subprocess timeout)
    proc = _cli("bench", "pick_cube", "--seeds", "0", "--executor", "ray", "--address", "127.0.0.1:1", "--no-progress")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "no Ray cluster answers" in proc.stderr and "Traceback" not in proc.stderr
