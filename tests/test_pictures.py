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

from pickdemo.cli import main
from pickdemo.result import WALL_CLOCK_KEYS

pytestmark = pytest.mark.sim
av = pytest.importorskip("av")
cv2 = pytest.importorskip("cv2")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("run")
    assert main(["run", "pick_pushed", "--seed", "1", "--out", str(out), "--video", "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def bench_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bench")
    assert main(["bench", "pick_cube", "--seeds", "0-1", "--workers", "2", "--out", str(out), "--no-progress"]) == 0
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


def test_video_decodes_and_recording_changes_nothing(run_dir: Path, tmp_path: Path) -> None:
    with_video = json.loads((run_dir / "result.json").read_text())
    assert main(["run", "pick_pushed", "--seed", "1", "--out", str(tmp_path), "--quiet"]) == 0
    without = json.loads((tmp_path / "result.json").read_text())
    assert _strip(with_video) == _strip(without)
    assert not (tmp_path / "episode.mp4").exists()

    with av.open(str(run_dir / "episode.mp4")) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == "h264"
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
        duration = float(stream.duration * stream.time_base)
    assert frames[0].shape == (268, 640, 3)
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
    from pickdemo.episode import EpisodeOptions

    sc = load_scenario("pick_cube")
    plain = run_episode(sc, 3).to_dict()
    drawn = run_episode(sc, 3, options=EpisodeOptions(debug_draw=True)).to_dict()
    assert _strip(plain) == _strip(drawn)


def test_bench_plot_of_a_batch_where_every_episode_failed(tmp_path: Path) -> None:
    """No place errors at all (every episode failed): the plot is still drawn (it once raised on a
    log scale with nothing to scale)."""
    pytest.importorskip("matplotlib")
    from pickdemo.bench import Job, failed_result, summarise
    from pickdemo.report import write_bench_plots
    from pickdemo.result import Stage

    results = [failed_result(Job("x.toml", "ghost", s), Stage.GRASP, "missed", 1.0) for s in range(3)]
    path = write_bench_plots(summarise(results), results, tmp_path / "bench.png")
    _not_blank(path, min_colours=20)
