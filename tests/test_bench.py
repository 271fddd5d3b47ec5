"""The bench: parsing, statistics, JUnit, resume, fault isolation, parallel determinism, Ray."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from pickdemo.bench import (
    BenchError,
    Job,
    LocalExecutor,
    junit_xml,
    load_episodes,
    parse_seeds,
    run_bench,
    run_job,
    summarise,
    wilson_interval,
)
from pickdemo.result import WALL_CLOCK_KEYS


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
    for bad in ("", "5-2", "-1", "a", "1-b"):
        with pytest.raises(BenchError):
            parse_seeds(bad)


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


def test_bad_scenario_in_a_job_is_an_error_result() -> None:
    r = run_job(Job("/no/such/scenario.toml", "ghost", 0))
    assert r["success"] is False and r["failure"]["stage"] == "error" and "no such scenario" in r["failure"]["reason"]


def _strip(rs: list[dict]) -> dict:
    return {(r["scenario"], r["seed"]): {k: v for k, v in r.items() if k not in WALL_CLOCK_KEYS}
            for r in rs}  # fmt: skip


@pytest.mark.sim
def test_same_results_whatever_the_worker_count(cube_scenario) -> None:
    from pickdemo.scenario import resolve_scenario_path

    jobs = [Job(str(resolve_scenario_path("pick_cube")), "pick_cube", s) for s in range(3)]
    one = run_bench(jobs, LocalExecutor(1), progress=False).results
    two = run_bench(jobs, LocalExecutor(2), progress=False).results
    assert _strip(one) == _strip(two)


def _cli(*args: str, **kw) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pickdemo", *args], capture_output=True, text=True, timeout=600, **kw)


@pytest.mark.sim
def test_cli_bench_gate_and_files(tmp_path: Path) -> None:
    out = tmp_path / "b"
    proc = _cli("bench", "pick_cube", "pick_cylinder", "--seeds", "0-1", "--workers", "2", "--out", str(out),
                "--junit", str(tmp_path / "j.xml"), "--min-success", "1.0", "--no-progress")  # fmt: skip
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "gate passed" in proc.stdout
    assert len((out / "episodes.jsonl").read_text().splitlines()) == 4
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pick_cube"]["episodes"] == 2 and summary["pick_cylinder"]["success_rate"] == 1.0
    assert len(ET.parse(tmp_path / "j.xml").getroot().findall("testsuite/testcase")) == 4
    # Resumed: nothing to run again.
    again = _cli(
        "bench", "pick_cube", "pick_cylinder", "--seeds", "0-1", "--out", str(out), "--resume", "--no-progress"
    )
    assert again.returncode == 0 and "ran 0 episode(s)" in again.stdout and "4 already done" in again.stdout
    # Without --resume the results are not overwritten.
    clash = _cli("bench", "pick_cube", "--seeds", "0-1", "--out", str(out), "--no-progress")
    assert clash.returncode == 2 and "--resume" in clash.stderr


def test_cli_bench_bad_input() -> None:
    for args in (("--seeds", "9-1"), ("--workers", "0"), ("--resume",), ("--min-success", "2")):
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
        "bench", "pick_cube", "--seeds", "0-7", "--workers", "2", "--out", str(out), "--resume", "--no-progress"
    )
    assert resumed.returncode == 0, resumed.stdout + resumed.stderr
    seeds = [json.loads(line)["seed"] for line in jsonl.read_text().splitlines()]
    assert sorted(seeds) == list(range(8))  # every episode exactly once


@pytest.mark.sim
def test_ray_executor_gives_the_same_results() -> None:
    pytest.importorskip("ray")
    import ray

    from pickdemo.bench import RayExecutor
    from pickdemo.scenario import resolve_scenario_path

    jobs = [Job(str(resolve_scenario_path("pick_cube")), "pick_cube", s) for s in range(2)]
    try:
        on_ray = run_bench(jobs, RayExecutor(None, num_cpus=2), progress=False).results
    finally:
        ray.shutdown()
    local = run_bench(jobs, LocalExecutor(2), progress=False).results
    assert _strip(on_ray) == _strip(local)
