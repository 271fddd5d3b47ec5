"""pickdemo: a simulated robot arm (Panda, SO-101, UR5 ship) picks an object it has only seen, headless
and reproducible.

One episode from Python::

    from pickdemo import EpisodeOptions, load_scenario, run_episode

    result = run_episode(load_scenario("pick_cube"), seed=0)
    assert result.success, result.failure
    looked_once = run_episode(load_scenario("pick_cube"), seed=0, options=EpisodeOptions(open_loop=True))

Or stepped, one control tick at a time (the same result)::

    from pickdemo import Episode

    episode = Episode(load_scenario("pick_cube"), seed=0)
    episode.reset()  # the first observation
    while not episode.step():
        pass
    result = episode.result()

Importing the package stays light, so that its pure parts (the skill, perception, the scenario
schema) import without the simulator: ``run_episode``, ``Episode`` and ``EpisodeOptions``, which
live beside the simulator in :mod:`pickdemo.runtime.episode`, load it on first use (the package's
one import inside a function; everything else imports at the top).
"""

from importlib.metadata import PackageNotFoundError, version

from pickdemo.core.result import EpisodeResult, Failure, Stage
from pickdemo.scenario.load import Scenario, ScenarioError, load_scenario

__all__ = [
    "Episode",
    "EpisodeOptions",
    "EpisodeResult",
    "Failure",
    "Scenario",
    "ScenarioError",
    "Stage",
    "load_scenario",
    "run_episode",
]
try:  # the installed distribution's (pyproject.toml's): one version, stated once
    __version__ = version("pickdemo")
except PackageNotFoundError:  # pragma: no cover - a source tree on the path that was never installed
    __version__ = "0+unknown"


def run_episode(scenario: Scenario, seed: int, **kwargs):  # type: ignore[no-untyped-def]
    """Run one seeded episode and return its :class:`EpisodeResult`
    (see :func:`pickdemo.runtime.episode.run_episode`)."""
    from pickdemo.runtime.episode import run_episode as _run

    return _run(scenario, seed, **kwargs)


def __getattr__(name: str):  # type: ignore[no-untyped-def]
    """``pickdemo.EpisodeOptions`` and ``pickdemo.Episode`` on first use (PEP 562), so that
    ``import pickdemo`` stays light."""
    if name in ("EpisodeOptions", "Episode"):
        from pickdemo.runtime import episode

        return getattr(episode, name)
    raise AttributeError(f"module 'pickdemo' has no attribute {name!r}")
