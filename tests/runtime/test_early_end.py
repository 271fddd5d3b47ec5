"""An episode that ends early (a tiny budget, before its first frame or tick, or stopped from outside)
still gives a result and its files, never a traceback: a property over budgets and ends."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pickdemo.apps.cli import main
from pickdemo.runtime.tasks import TASKS
from pickdemo.scenario.load import builtin_scenario_dirs

#: a scenario of each kind of loop: a fixed camera, a hand camera, a belt, a clear round
KINDS = ("pick_cube", "pick_cube_wrist", "pick_conveyor", "clear_pile")


def _with_budget(tmp: Path, name: str, budget_s: float) -> Path:
    text = next(d / f"{name}.toml" for d in builtin_scenario_dirs()).read_text()
    base = next(d for d in builtin_scenario_dirs())
    text = text.replace('"../assets/', f'"{base.parent}/assets/')  # (the copy lives elsewhere)
    f = tmp / f"{name}_{budget_s:g}.toml"
    if "max_sim_time_s" in text:
        text = re.sub(r"max_sim_time_s = .*", f"max_sim_time_s = {budget_s!r}", text)
    elif "[sim]" in text:
        text = text.replace("[sim]", f"[sim]\nmax_sim_time_s = {budget_s!r}", 1)
    else:
        text += f"\n[sim]\nmax_sim_time_s = {budget_s!r}\n"
    f.write_text(text)
    return f


@pytest.mark.sim
@settings(max_examples=8, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(KINDS), budget_s=st.floats(min_value=0.001, max_value=0.4))
def test_a_tiny_budget_gives_a_result_and_its_files(
    tmp_path_factory: pytest.TempPathFactory, name: str, budget_s: float
) -> None:
    tmp = tmp_path_factory.mktemp("early")
    f = _with_budget(tmp, name, budget_s)
    out = tmp / "out"
    code = main(["run", str(f), "--out", str(out), "--quiet", "--video"])
    assert code == 1  # a failure, not a crash (exit 2 is bad input; an exception would raise here)
    result = json.loads((out / "result.json").read_text())
    assert result["failure"]["stage"] == "timeout" and "traceback" not in result["failure"], result["failure"]
    assert " 0.0 s " not in result["failure"]["reason"]  # (a tiny budget said as it is)
    settle_s = TASKS["clear" if name.startswith("clear") else "pick"].settle_max_s  # (before the budget's first tick)
    assert result["sim_time_s"] <= budget_s + settle_s + 0.05
    assert (out / "report.html").exists() and (out / "episode.mp4").exists()


@pytest.mark.sim
@pytest.mark.parametrize(
    ("args", "stage"),
    [
        (["pick_mesh", "--perception", "icp"], "perception"),  # a method that cannot see this target
        (["clear_pile", "--open-loop"], "error"),  # a task that cannot run so
    ],
)
def test_an_episode_that_ends_while_it_is_built_gives_a_result(tmp_path: Path, args: list[str], stage: str) -> None:
    out = tmp_path / "out"
    assert main(["run", *args, "--out", str(out), "--quiet"]) == 1
    result = json.loads((out / "result.json").read_text())
    assert result["failure"]["stage"] == stage and "traceback" not in result["failure"], result["failure"]
    assert result["sim_time_s"] == 0.0 and (out / "report.html").exists()


def test_the_trace_skips_a_tick_with_no_motion_yet() -> None:
    """A clear round between its picks has no motion sample: the trace (``run --out``) skips the tick
    (it raised in ``error`` before)."""
    from types import SimpleNamespace

    from pickdemo.runtime.observers import TraceRecorder

    trace = TraceRecorder()
    controller = SimpleNamespace(last_sample=None)
    trace.tick(SimpleNamespace(controller=controller), 1.0)
    assert trace.ticks == []
