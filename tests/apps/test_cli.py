"""The command line: exit codes, one-line errors without tracebacks, result.json."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def _run(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pickdemo", *args], capture_output=True, text=True, cwd=cwd, timeout=300
    )


@pytest.mark.parametrize(
    "args",
    [
        ("run", "no_such_scenario"),
        ("run", "pick_cube", "--seed", "x"),
        ("run",),
        ("run", "pick_cube", "--seed", "-1"),
        ("frobnicate",),
        ("profile", "pick_cube", "--seeds", "x"),
        ("profile", "perceive_boxes"),
        ("perceive", "pick_cube", "--methods", "paper,no_such_module:estimate"),
        ("perceive", "pick_cube", "--methods", "nope"),
    ],
)
def test_bad_input_exits_2_with_one_line(args: tuple[str, ...]) -> None:
    proc = _run(*args)
    assert proc.returncode == 2
    assert proc.stderr.startswith("pickdemo: error:")
    assert proc.stderr.count("\n") == 1
    assert "Traceback" not in proc.stderr


def test_bad_scenario_file_names_file_and_key(tmp_path: Path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text(
        'name = "x"\n[[objects]]\nname = "c"\nshape = "box"\nsize = [1]\ncolor = [1, 0, 0]\n'
        "position = [0.5, 0]\ntarget = true\n[place]\nposition = [0.4, 0.3]\n"
    )
    proc = _run("run", str(f))
    assert proc.returncode == 2
    assert str(f) in proc.stderr and "objects.c.size" in proc.stderr


@pytest.mark.sim
def test_run_writes_result_json(tmp_path: Path) -> None:
    proc = _run("run", "pick_cube", "--seed", "1", "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert proc.returncode in (0, 1), proc.stdout + proc.stderr  # 1: this seed failed on this machine
    assert proc.stderr == ""  # nothing leaks from PyBullet's C code
    result = json.loads((tmp_path / "o" / "result.json").read_text())
    for key in (
        "scenario",
        "seed",
        "success",
        "failure",
        "perception",
        "place_error_mm",
        "sim_time_s",
        "wall_time_s",
        "stage_wall_times_s",
        "attempts",
        "perception_frames",
        "perception_rate_hz",
        "estimates_rejected",
        "tracking_error_mm",
    ):
        assert key in result
    for key in ("estimated_pose", "true_pose", "position_error_mm", "yaw_error_deg"):
        assert key in result["perception"]
    assert result["seed"] == 1 and (result["failure"] is None) == result["success"] == (proc.returncode == 0)
    # What it printed is what result.json holds: every phase in order, and the outcome.
    printed = [line.split("] ", 1)[1].split()[0] for line in proc.stdout.splitlines() if line.startswith("[sim")]
    assert printed == [p["phase"] for p in result["phases"]] and printed[0] == "look"
    assert ("SUCCESS: pick_cube seed 1" in proc.stdout) == result["success"]


def test_list() -> None:
    from pickdemo.scenario.load import list_scenarios, load_scenario

    proc = _run("list")
    assert proc.returncode == 0 and "pick_cube" in proc.stdout.split()
    lines = proc.stdout.splitlines()
    assert len(lines) == len(list_scenarios())
    cube = next(line for line in lines if line.split()[0] == "pick_cube")
    assert cube.endswith(load_scenario("pick_cube", check=False).description)
    starts = {len(line) - len(line.split(maxsplit=1)[1]) for line in lines}
    assert len(starts) == 1  # the descriptions line up


def test_list_names_is_for_scripts() -> None:
    from pickdemo.scenario.load import list_scenarios

    proc = _run("list", "--names")
    assert proc.returncode == 0 and proc.stdout.splitlines() == list_scenarios()


def _help(*args: str) -> str:
    proc = _run(*args, "--help")
    assert proc.returncode == 0, proc.stderr
    return " ".join(proc.stdout.split())  # as one line: argparse wraps where it likes


@pytest.mark.parametrize(
    ("command", "files"),
    [
        ("run", ("result.json", "motion.png", "report.html", "episode.mp4")),
        ("bench", ("episodes.jsonl", "summary.json", "bench.png", "report.html")),
        ("perceive", ("perception.json", "perception.png", "report.html")),
    ],
)
def test_help_names_every_file_written(command: str, files: tuple[str, ...]) -> None:
    import pickdemo.apps.cli

    text = _help(command)
    out_help = text.rsplit("--out DIR", 1)[-1].split(" --", 1)[0]  # the --out option's own line
    assert all(f in out_help or (f == "episode.mp4" and f in text) for f in files), (files, out_help)
    usage = " ".join(pickdemo.apps.cli.__doc__.split())
    assert all(f in usage for f in files), files  # the module's one-line usages say it too


def test_episode_options_from_the_package_and_import_stays_light() -> None:
    """``import pickdemo`` loads the scenario checks (and so the kinematics), never the simulator."""
    code = (
        "import sys, pickdemo\n"
        "assert 'pybullet' not in sys.modules\n"
        "from pickdemo import EpisodeOptions\n"
        "from pickdemo.runtime.episode import EpisodeOptions as E\n"
        "assert EpisodeOptions is E and EpisodeOptions(open_loop=True).open_loop\n"
        "assert 'EpisodeOptions' in pickdemo.__all__\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr


def test_yaw_is_said_modulo_the_targets_symmetry() -> None:
    from pickdemo.apps.summary import summary_line, yaw_modulus_deg
    from pickdemo.core.result import EpisodeResult, PerceptionScore
    from pickdemo.scenario.load import load_scenario

    assert yaw_modulus_deg(load_scenario("pick_cube", check=False).target) == 90.0
    assert yaw_modulus_deg(load_scenario("pick_box", check=False).target) == 180.0
    assert yaw_modulus_deg(load_scenario("pick_cylinder", check=False).target) is None
    score = PerceptionScore({}, {}, position_error_mm=0.5, yaw_error_deg=0.07)
    r = EpisodeResult("s", 0, True, None, score, 1.0, 50.0, 50.0, 10.0, 1.0)
    assert "pose error 0.50 mm, yaw error 0.07 deg modulo 90 deg |" in summary_line(r, 90.0)
    no_yaw = EpisodeResult("s", 0, True, None, PerceptionScore({}, {}, 0.5, None), 1.0, 50.0, 50.0, 10.0, 1.0)
    assert "yaw" not in summary_line(no_yaw, None)  # a cylinder has no yaw


@pytest.mark.sim
def test_open_loop_header_and_yaw_modulus_of_a_run() -> None:
    proc = _run("run", "pick_cube", "--seed", "0", "--open-loop")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.splitlines()[0].startswith("pickdemo: pick_cube seed 0 (open loop: one look): ")
    assert "deg modulo 90 deg" in proc.stdout.splitlines()[-1]


STATIC_TARGET = (
    'name = "tilted"\n[[objects]]\nname = "c"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.85, 0.1, 0.1]\n'
    "position = [0.5, 0.0, 0.03]\npitch_deg = 10.0\nstatic = true\ntarget = true\n[place]\nposition = [0.4, 0.3]\n"
)


@pytest.mark.sim
def test_perceive_reads_a_file_without_task_as_perception(tmp_path: Path) -> None:
    f = tmp_path / "tilted.toml"
    f.write_text(STATIC_TARGET)
    proc = _run("perceive", str(f), "--seeds", "0", "--methods", "pixel")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "pickdemo perceive: tilted, 1 target(s) x 1 seed(s)" in proc.stdout
    # `run` still refuses it (a pick's target cannot be static), and so does perceive a file that says it is a pick.
    ran = _run("run", str(f))
    assert ran.returncode == 2 and "the target of a pick cannot be static" in ran.stderr
    f.write_text('task = "pick"\n' + STATIC_TARGET)
    said = _run("perceive", str(f), "--seeds", "0", "--methods", "pixel")
    assert said.returncode == 2 and "objects.c: the target of a pick cannot be static" in said.stderr
    assert said.stderr.count("\n") == 1


def test_version_is_the_installed_distributions() -> None:
    from importlib.metadata import version

    proc = _run("--version")
    assert proc.returncode == 0 and proc.stdout == f"pickdemo {version('pickdemo')}\n", proc.stdout + proc.stderr
    assert "--version" in _help()


def test_the_description_names_every_robot_that_ships() -> None:
    from pickdemo.robot import shipped_robots

    text = _help()
    assert "Franka Panda picks" not in text
    shown = {"panda": "Panda", "so101": "SO-101", "ur5_franka_hand": "UR5", "ur5_suction": "suction cup"}
    assert set(shipped_robots()) == set(shown) and all(name in text for name in shown.values()), text


def test_a_shipped_scenario_that_does_not_load_stops_a_suite_bench(tmp_path: Path, monkeypatch, capsys) -> None:
    # Issue 57: `bench` without names dropped it and gated a smaller suite: now one line, exit 2, its name.
    from pickdemo.apps.cli import main
    from pickdemo.scenario import load

    shipped = load.builtin_scenario_dirs()[0]
    for name in ("pick_cube", "pick_cylinder"):
        (tmp_path / f"{name}.toml").write_text((shipped / f"{name}.toml").read_text())
    (tmp_path / "pick_broken.toml").write_text((shipped / "pick_cube.toml").read_text() + "\nnot_a_key = 1\n")
    monkeypatch.setattr(load, "builtin_scenario_dirs", lambda: [tmp_path])
    assert main(["bench", "--seeds", "0", "--no-progress", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pickdemo: error: ") and err.count("\n") == 1, err
    assert "'pick_broken'" in err and "not_a_key" in err and not (tmp_path / "o" / "episodes.jsonl").exists(), err
