"""pickdemo: a simulated Franka Panda picks an object it has only seen, headless and reproducible.

One episode from Python::

    from pickdemo import load_scenario, run_episode

    result = run_episode(load_scenario("pick_cube"), seed=0)
    assert result.success, result.failure
"""

from pickdemo.result import EpisodeResult, Failure, Stage
from pickdemo.scenario import Scenario, ScenarioError, load_scenario

__all__ = ["EpisodeResult", "Failure", "Scenario", "ScenarioError", "Stage", "load_scenario", "run_episode"]
__version__ = "0.1.0"


def run_episode(scenario: Scenario, seed: int, **kwargs):  # type: ignore[no-untyped-def]
    """Run one seeded episode and return its :class:`EpisodeResult` (see :func:`pickdemo.episode.run_episode`)."""
    from pickdemo.episode import run_episode as _run

    return _run(scenario, seed, **kwargs)
