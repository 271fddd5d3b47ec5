"""Pictures: the episode's video decodes and changes nothing, the motion plot is drawn, and the report
page loads in a real headless browser (Debian's chromium) with its images rendered."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from pickdemo.apps.cli import main
from pickdemo.core.result import WALL_CLOCK_KEYS
from pickdemo.robot import robot_named

ROBOT = robot_named()

pytestmark = pytest.mark.sim
av = pytest.importorskip("av")
cv2 = pytest.importorskip("cv2")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("run")
    # The pictures are the point here, not this seed's fate (exit 1: it failed on this machine).
    assert main(["run", "pick_pushed", "--seed", "1", "--out", str(out), "--video", "--quiet"]) in (0, 1)
    return out


@pytest.fixture(scope="module")
def bench_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bench")
    args = ["bench", "pick_cube", "--seeds", "0-1", "--workers", "2", "--out", str(out), "--no-progress"]
    assert main([*args, "--min-success", "0"]) == 0
    return out


@pytest.fixture(scope="module")
def perceive_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("perceive")
    assert main(["perceive", "perceive_boxes", "--seeds", "0-3", "--out", str(out)]) == 0
    return out


def _not_blank(path: Path, min_colours: int = 100) -> None:
    img = cv2.imread(str(path))
    assert img is not None and img.shape[0] > 300 and img.shape[1] > 600, path
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > min_colours and (img < 200).mean() > 0.01, path


def _strip(d: dict) -> dict:
    return {k: v for k, v in d.items() if k not in WALL_CLOCK_KEYS}


@pytest.mark.slow
def test_video_decodes_and_recording_changes_nothing(run_dir: Path, tmp_path: Path) -> None:
    with_video = json.loads((run_dir / "result.json").read_text())
    assert main(["run", "pick_pushed", "--seed", "1", "--out", str(tmp_path), "--quiet"]) in (0, 1)
    without = json.loads((tmp_path / "result.json").read_text())
    assert _strip(with_video) == _strip(without)
    assert not (tmp_path / "episode.mp4").exists()

    with av.open(str(run_dir / "episode.mp4")) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264"
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
        duration = float(stream.duration * stream.time_base)
    assert frames[0].shape == (288, 640, 3)  # two 320x240 views, the caption and the legend
    expected = with_video["sim_time_s"] * 10  # 10 frames a simulated second
    assert abs(len(frames) - expected) <= 2, (len(frames), expected)
    assert duration == pytest.approx(len(frames) / 10, abs=0.15)
    middle = frames[len(frames) // 2]
    assert middle.std() > 20 and len(np.unique(middle.reshape(-1, 3), axis=0)) > 200  # not blank


def test_plots_are_drawn(run_dir: Path, bench_dir: Path, perceive_dir: Path) -> None:
    for path in (run_dir / "motion.png", bench_dir / "bench.png", perceive_dir / "perception.png"):
        _not_blank(path)  # curves, axes and text, not a blank page


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.mark.parametrize("which", ["run", "bench", "perceive"])
@pytest.mark.slow
def test_report_loads_in_a_headless_browser(which: str, request: pytest.FixtureRequest, tmp_path: Path) -> None:
    browser = _chromium()
    if browser is None:
        if os.environ.get("CI"):
            pytest.fail("chromium is not installed (.ci/run installs Debian's chromium)")
        pytest.skip("no chromium on this machine (apt-get install chromium)")
    page = request.getfixturevalue(f"{which}_dir") / "report.html"
    shot = tmp_path / "report.png"
    proc = subprocess.run(
        [browser, "--headless=new", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
         "--window-size=1100,2600", f"--screenshot={shot}", page.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    console = [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
    assert console == [], console  # the page logs nothing: no errors
    img = cv2.imread(str(shot))
    assert img is not None, proc.stderr[-2000:]
    # The embedded plot (below the summary, and the video for a run): its many colours mean it was
    # decoded and drawn; a page without it is text on white.
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 200
    assert (img < 128).mean() > 0.002  # text and lines on white
    html = page.read_text()
    assert "data:image/png;base64," in html and "http" not in html.split("<body>")[1]  # no network
    if which == "run":
        assert 'src="episode.mp4"' in html and (page.parent / "episode.mp4").exists()


def test_a_browser_test_would_catch_a_console_error(tmp_path: Path) -> None:
    """The check above is real: a page with a script error shows up in the browser's log."""
    browser = _chromium()
    if browser is None:
        pytest.skip("no chromium on this machine")
    bad = tmp_path / "bad.html"
    bad.write_text("<!DOCTYPE html><html><body><script>undefinedFunction();</script></body></html>")
    proc = subprocess.run(
        [browser, "--headless=new", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
         f"--screenshot={tmp_path / 'bad.png'}", bad.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert any(":CONSOLE" in line and "undefinedFunction" in line for line in proc.stderr.splitlines())


def test_debug_lines_change_nothing() -> None:
    """`--gui` draws the overlays as debug lines; drawing them (here in DIRECT mode) changes nothing."""
    from pickdemo import load_scenario, run_episode
    from pickdemo.runtime.episode import EpisodeOptions

    sc = load_scenario("pick_cube")
    plain = run_episode(sc, 3).to_dict()
    drawn = run_episode(sc, 3, options=EpisodeOptions(debug_draw=True)).to_dict()
    assert _strip(plain) == _strip(drawn)


def test_bench_plot_of_a_batch_where_every_episode_failed(tmp_path: Path) -> None:
    """No place errors at all (every episode failed): the plot is still drawn (it once raised on a
    log scale with nothing to scale)."""
    pytest.importorskip("matplotlib")
    from pickdemo.apps.bench import Job, failed_result, summarise
    from pickdemo.apps.report import write_bench_plots
    from pickdemo.core.result import Stage

    results = [failed_result(Job("x.toml", "ghost", s), Stage.GRASP, "missed", 1.0) for s in range(3)]
    path = write_bench_plots(summarise(results), results, tmp_path / "bench.png")
    _not_blank(path, min_colours=20)


# ------------------------------------------------------------------- joint limits (issue 17, 9)
def _kinked(dt: float = 0.125, n: int = 40, kink: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """A joint command whose finite differences are known exactly (dt a power of two): joint 1 moves
    at 1 rad/s, then 3 rad/s from sample ``kink`` on (np.gradient gives 2 at the kink itself and an
    acceleration of 4, 8, 4 around it); joint 3 moves at exactly 2 rad/s throughout."""
    t = np.arange(n) * dt
    q = np.zeros((n, 7))
    q[:, 0] = np.where(np.arange(n) <= kink, t, t[kink] + 3.0 * (t - t[kink]))
    q[:, 2] = 2.0 * t
    return t, q


def test_limit_exceedances_flag_exactly_the_samples_over_the_limit() -> None:
    from pickdemo.core.result import joint_derivatives, limit_exceedances

    t, q = _kinked()
    m = joint_derivatives(t, q)
    assert m["velocity"][19, 0] == 1.0 and m["velocity"][20, 0] == 2.0 and m["velocity"][21, 0] == 3.0
    lim_v = np.full(7, 2.5)
    lim_v[2] = 2.0  # joint 3 runs exactly at its limit: not over it
    found = limit_exceedances(t, q, {"velocity": (lim_v, "rad/s"), "acceleration": (np.full(7, 6.0), "rad/s^2")})
    assert [(e.quantity, e.joint) for e in found] == [("velocity", 1), ("acceleration", 1)]
    vel, acc = found
    assert vel.samples == 19 and vel.first_time_s == t[21] and vel.peak == 3.0 and vel.limit == 2.5
    np.testing.assert_array_equal(vel.times_s, t[21:])
    assert acc.samples == 1 and acc.first_time_s == acc.peak_time_s == t[20] and acc.peak == 8.0
    assert acc.to_dict() == {"joint": 1, "quantity": "acceleration", "unit": "rad/s^2", "peak": 8.0, "limit": 6.0,
                             "samples": 1, "first_time_s": t[20], "peak_time_s": t[20]}  # fmt: skip
    assert "joint 1" in acc.note() and "> 6" in acc.note()
    # A lower limit takes in the kink too; backwards, the same ticks, their values signed for the plot.
    (slow,) = limit_exceedances(t, -q, {"velocity": (np.full(7, 2.1), "rad/s")})[:1]
    assert slow.joint == 1 and slow.samples == 19 and slow.peak == 3.0 and np.all(slow.values == -3.0)
    (slow,) = limit_exceedances(t, -q, {"velocity": (np.full(7, 1.5), "rad/s")})[:1]
    assert slow.samples == 20 and slow.first_time_s == t[20]
    # The datasheet's limits: this slow motion is well inside them; too short a command: nothing.
    assert limit_exceedances(t, q * 0.1, ROBOT.limits.rates()) == []
    assert limit_exceedances(t[:3], q[:3], ROBOT.limits.rates()) == []


def _trace(t: np.ndarray, q: np.ndarray):
    from pickdemo.core.result import EpisodeTrace

    n = len(t)
    z4 = np.zeros((n, 4))
    states = tuple("approach" if k < n // 2 else "lift" for k in range(n))
    return EpisodeTrace(t, states, z4, z4, z4, z4, z4, z4, z4, np.zeros(n, bool), q, np.zeros((n, 3)), z4)


def _red_pixels(path: Path) -> int:
    img = cv2.imread(str(path))  # BGR
    return int(((img[:, :, 2] > 235) & (img[:, :, 1] < 40) & (img[:, :, 0] < 40)).sum())


def test_motion_plot_marks_the_ticks_over_a_limit(tmp_path: Path) -> None:
    """Red rings and a red note where the command goes beyond the datasheet; none where it stays inside."""
    pytest.importorskip("matplotlib")
    from pickdemo.apps.report import phase_changes, write_motion_plot

    t = np.arange(400) / 120.0
    acc = np.where((t >= 1.0) & (t < 1.1), 1.2, 0.0) - np.where((t >= 1.1) & (t < 1.2), 1.2, 0.0)
    vel = np.concatenate([[0.0], np.cumsum(acc[:-1])]) / 120.0 * ROBOT.limits.max_acceleration_rad_s2[1]
    q = np.zeros((400, 7))
    q[:, 1] = np.concatenate([[0.0], np.cumsum(vel[:-1])]) / 120.0  # joint 2 speeds up and slows at 120 % of its limit
    over = write_motion_plot(_trace(t, q), tmp_path / "over.png", "over")
    inside = write_motion_plot(_trace(t, q * 0.5), tmp_path / "inside.png", "inside")
    assert _red_pixels(over) > 200 and _red_pixels(inside) < 20
    assert phase_changes(_trace(t, q)) == [(0.0, "approach"), (t[200], "lift")]


def test_result_json_carries_the_limit_check_with_or_without_a_trace(run_dir: Path) -> None:
    """The limit check is in result.json whether or not a trace was kept for the plot (a bench
    episode keeps none), the same both ways, and equal to the plot's check of the recorded trace."""
    from pickdemo import load_scenario, run_episode
    from pickdemo.core.result import limit_exceedances
    from pickdemo.runtime.episode import EpisodeOptions

    with_trace = run_episode(load_scenario("pick_pushed"), 1, options=EpisodeOptions(record_trace=True))
    plain = run_episode(load_scenario("pick_pushed"), 1).to_dict()
    saved = json.loads((run_dir / "result.json").read_text())
    assert isinstance(plain["limit_exceedances"], list)
    assert _strip(plain) == _strip(saved) == _strip(with_trace.to_dict())
    trace = with_trace.trace
    over = limit_exceedances(trace.time_s, trace.q, ROBOT.limits.rates())
    assert plain["limit_exceedances"] == [e.to_dict() for e in over]
    for e in plain["limit_exceedances"]:
        assert e["peak"] > e["limit"] > 0 and e["samples"] >= 1 and 0 <= e["first_time_s"] <= e["peak_time_s"]
        assert e["quantity"] in ("velocity", "acceleration", "jerk") and 1 <= e["joint"] <= 7


def test_a_bench_failure_has_the_keys_of_a_result() -> None:
    from pickdemo.apps.bench import Job, failed_result
    from pickdemo.core.result import EpisodeResult, Stage

    made = failed_result(Job("x.toml", "ghost", 0), Stage.ERROR, "boom", 1.0)
    real = EpisodeResult("ghost", 0, False, None, None, None, None, None, 0.0, 1.0).to_dict()
    assert set(made) == set(real) and made["limit_exceedances"] == []


# --------------------------------------------------------------------------- the video (issue 17, 10)
def test_the_camera_view_follows_the_target_then_the_hand_then_the_place() -> None:
    from pickdemo.runtime.video import panel_centre

    tracked, hand, place = np.array([0.5, 0.0, 0.025]), np.array([0.5, 0.1, 0.2]), np.array([0.45, 0.3, 0.025])
    for state in ("look", "approach", "descend", "close", "back_off"):
        assert panel_centre(state, tracked=tracked, hand=hand, place=place) is tracked
    for state in ("lift", "transport", "lower", "release"):
        assert panel_centre(state, tracked=tracked, hand=hand, place=place) is hand
    for state in ("retreat", "home", "verify", "done"):
        assert panel_centre(state, tracked=tracked, hand=hand, place=place) is place
    assert panel_centre("look", tracked=None, hand=hand, place=place) is None  # the image's middle


def test_video_frames_have_a_legend_and_no_stale_features(run_dir: Path) -> None:
    """Below the caption, a legend in the overlays' colours; once the target is lifted (no frames
    are taken while carrying) no feature ellipses are drawn, while the truth's white axes still are;
    the last frame shows how it ended."""
    from pickdemo.runtime.video import CAPTION_BAR_PX, ELLIPSE_COLOUR, GRASP_COLOUR, LEGEND_BAR_PX, PATH_COLOUR

    result = json.loads((run_dir / "result.json").read_text())
    with av.open(str(run_dir / "episode.mp4")) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    legend = frames[0][-LEGEND_BAR_PX:]
    for colour in (ELLIPSE_COLOUR, GRASP_COLOUR, PATH_COLOUR, (255, 255, 255)):
        near = np.abs(legend.astype(int) - np.array(colour)).max(axis=2) < 80  # after x264's chroma subsampling
        assert near.sum() >= 3, colour
    view_h = frames[0].shape[0] - CAPTION_BAR_PX - LEGEND_BAR_PX

    def ellipse_pixels(frame: np.ndarray) -> int:
        right = frame[:view_h, frame.shape[1] // 2 :].astype(int)
        return int((np.abs(right - np.array(ELLIPSE_COLOUR)).max(axis=2) < 40).sum())

    t = {p["phase"]: p["sim_time_s"] for p in result["phases"]}
    carrying = [f for k, f in enumerate(frames) if t["lift"] + 0.3 < k / 10 < t["lower"]]
    tracking = [f for k, f in enumerate(frames) if t["approach"] + 0.3 < k / 10 < t["close"]]
    assert carrying and tracking
    assert max(ellipse_pixels(f) for f in carrying) < 5
    assert np.median([ellipse_pixels(f) for f in tracking]) > 50
    assert ellipse_pixels(frames[-1]) > 50  # done: the verifying look's estimate at the place


def test_third_person_view_holds_the_whole_arm() -> None:
    """Every link frame the arm reaches in a pick (home, over the pick region, over the place) and
    8 cm around it projects inside the third-person view."""
    import itertools

    from pickdemo.core.camera import project
    from pickdemo.motion.online import top_down_pose
    from pickdemo.robot.kinematics import kinematics_of
    from pickdemo.runtime.episode import THIRD_PERSON_K, THIRD_PERSON_POSE

    pin = pytest.importorskip("pinocchio")
    kin = kinematics_of(ROBOT)
    data = kin.model.createData()
    qs = [ROBOT.home_q]
    rng = np.random.default_rng(0)
    for x, y, z in [(0.4, -0.15, 0.02), (0.6, 0.15, 0.02), (0.6, -0.15, 0.3), (0.45, 0.3, 0.02), (0.45, 0.3, 0.3)]:
        res = kin.solve(top_down_pose(np.array([x, y, z, 0.0])), ROBOT.home_q, rng=rng)
        assert res.success
        qs.append(res.q)
    cube = np.array(list(itertools.product((-0.08, 0.08), repeat=3)))
    pts = []
    for q in qs:
        pin.forwardKinematics(kin.model, data, q)
        pin.updateFramePlacements(kin.model, data)
        pts += [data.oMf[i].translation + cube for i in range(kin.model.nframes)]
    pts = np.vstack(pts)
    pts[:, 2] = np.maximum(pts[:, 2], 0.0)
    uv = project(THIRD_PERSON_POSE.inverse().transform_points(pts), THIRD_PERSON_K)
    K = THIRD_PERSON_K
    assert uv[:, 0].min() > 0 and uv[:, 1].min() > 0 and uv[:, 0].max() < K.width and uv[:, 1].max() < K.height


# ------------------------------------------------------------------- report pages (issue 17, 11)
def test_run_report_has_the_attempts_reasons_and_the_limit_check(run_dir: Path) -> None:
    html = (run_dir / "report.html").read_text()
    result = json.loads((run_dir / "result.json").read_text())
    table = html.split("<h2>Attempts</h2>")[1].split("</table>")[0]
    rows = table.split("<tr>")[2:]
    assert len(rows) == len(result["attempts"]) >= 1
    for row in rows:
        reason = row.split("<td>")[-1].split("</td>")[0]
        assert reason.strip(), row  # never an empty reason
    assert "released at" in rows[-1]  # a placed attempt: what ended it
    assert "joint command beyond the datasheet limits" in html


def test_run_report_reason_of_a_failed_attempt(tmp_path: Path) -> None:
    from pickdemo.apps.report import write_run_report
    from pickdemo.core.result import AttemptRecord, EpisodeResult, Failure, PhaseRecord, Stage

    attempts = (AttemptRecord(1, "missed", "fingers closed on nothing", 0.1, 3.0, 20.0, None, 1.0),
                AttemptRecord(2, "placed", "", 3.0, 8.0, 20.0, None, 1.0))  # fmt: skip
    phases = (PhaseRecord("retreat", 8.0, "released at (0.450, 0.300)"),)
    over = {"joint": 2, "quantity": "acceleration", "unit": "rad/s^2", "peak": 7.6, "limit": 7.5, "samples": 2,
            "first_time_s": 1.5, "peak_time_s": 1.5}  # fmt: skip
    r = EpisodeResult("x", 0, False, Failure(Stage.PLACE, "off"), None, None, None, None, 9.0, 1.0,
                      phases=phases, attempts=attempts, limit_exceedances=(over,))  # fmt: skip
    html = write_run_report(r, tmp_path, video=None, images=[]).read_text()
    assert "fingers closed on nothing" in html and "released at (0.450, 0.300)" in html
    assert "acceleration of joint 2: 7.6 rad/s^2 &gt; 7.5 at 1.50 s (2 ticks)" in html


def test_bench_page_has_a_table_row_per_scenario(bench_dir: Path) -> None:
    html = (bench_dir / "report.html").read_text()
    summary = json.loads((bench_dir / "summary.json").read_text())
    table = html.split('<table class="bench">')[1].split("</table>")[0]
    rows = table.split("<tr>")[2:]
    assert len(rows) == len(summary) >= 1
    for name, row in zip(summary, rows, strict=True):
        assert f"<td>{name}</td>" in row and "Wilson" not in row and "%" in row
    assert "data:image/png;base64," in html and html.index('<table class="bench">') < html.index("<pre>")
    for line in (bench_dir / "episodes.jsonl").read_text().splitlines():
        assert "limit_exceedances" in json.loads(line)


def test_bench_table_and_plot_of_several_scenarios(tmp_path: Path) -> None:
    """A table row per scenario with its successes, interval and failures by stage; the plot has no
    failures panel when nothing failed, and plain tick labels on its log axes."""
    pytest.importorskip("matplotlib")
    from pickdemo.apps.bench import Job, failed_result, summarise
    from pickdemo.apps.report import bench_table, plain_number, write_bench_plots
    from pickdemo.core.result import Stage

    ok = {"success": True, "failure": None, "perception": {"position_error_mm": 0.5, "yaw_error_deg": 0.1},
          "place_error_mm": 1.5, "tracking_error_mm": 2.0, "wall_time_s": 1.0, "sim_time_s": 10.0,
          "attempts": [{}], "limit_exceedances": []}  # fmt: skip
    results = [dict(ok, scenario="a_long_scenario_name", seed=s, place_error_mm=0.01 * 10**s) for s in range(4)]
    results += [dict(ok, scenario="b", seed=s) for s in range(3)]
    results.append(failed_result(Job("x.toml", "b", 9), Stage.GRASP, "missed", 1.0))
    html = bench_table(summarise(results), results)
    rows = html.split("<tr>")[2:]
    assert len(rows) == 2 and "4/4 (100.0 %)" in rows[0] and "3/4 (75.0 %)" in rows[1] and "grasp 1" in rows[1]
    assert [plain_number(v) for v in (0.01, 0.1, 1.0, 10.0, 100.0)] == ["0.01", "0.1", "1", "10", "100"]
    _not_blank(write_bench_plots(summarise(results), results, tmp_path / "some_failed.png"), min_colours=20)
    all_ok = [r for r in results if r["success"]]
    _not_blank(write_bench_plots(summarise(all_ok), all_ok, tmp_path / "all_ok.png"), min_colours=20)
    assert cv2.imread(str(tmp_path / "all_ok.png")).shape[1] < cv2.imread(str(tmp_path / "some_failed.png")).shape[1]


def test_the_video_draws_a_planned_path_in_its_colour() -> None:
    from pickdemo.core.camera import Intrinsics
    from pickdemo.core.geometry import Pose
    from pickdemo.runtime.video import PLANNED_COLOUR, Overlay, draw_overlay

    K = Intrinsics(fx=500.0, fy=500.0, cx=320.0, cy=240.0, width=640, height=480)
    down = Pose(np.array([0.5, 0.0, 1.0]), np.diag([1.0, -1.0, -1.0]))  # a camera 1 m above, looking down
    path = np.array([[0.4, -0.1, 0.1], [0.5, 0.0, 0.3], [0.6, 0.1, 0.1]])
    img = np.zeros((480, 640, 3), np.uint8)
    drawn = draw_overlay(img, K, down, Overlay(caption="", planned_path=path))
    assert np.all(drawn.reshape(-1, 3) == PLANNED_COLOUR, axis=1).sum() > 50
    assert not np.any(draw_overlay(img, K, down, Overlay(caption="")))
