"""Episodes for the tests, run once per test session and shared, and assertions over several seeds.

A closed loop amplifies the last bits of floating point, and those differ between CPUs and library
builds: the same seed is the same episode on one machine with one lock, not on every machine. So a
test of an outcome asserts a property of several seeds (a rate with a bound, a maximum, "none fails
in ``trajectory``"), never one seed's fate. Exact comparisons are kept for two runs on the same
machine (determinism, worker counts, recording on and off).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence

from pickdemo.core.result import EpisodeResult


@functools.cache
def episodes(
    scenario: str,
    seeds: tuple[int, ...],
    *,
    open_loop: bool = False,
    method: str = "paper",
    record_trace: bool = False,
) -> tuple[EpisodeResult, ...]:
    """The episodes of a shipped scenario (or a path) over ``seeds``; cached for the session."""
    from pickdemo import load_scenario, run_episode
    from pickdemo.runtime.episode import EpisodeOptions

    sc = load_scenario(scenario)
    options = EpisodeOptions(open_loop=open_loop, perception_method=method, record_trace=record_trace)
    return tuple(run_episode(sc, s, options=options) for s in seeds)


def describe(r: EpisodeResult) -> str:
    if r.success:
        return f"seed {r.seed}: success ({len(r.attempts)} attempt(s))"
    return f"seed {r.seed}: {r.failure.stage.value}: {r.failure.reason}"  # type: ignore[union-attr]


def at_least(
    results: Sequence[EpisodeResult], k: int, pred: Callable[[EpisodeResult], bool] | None = None, what: str = "succeed"
) -> list[EpisodeResult]:
    """Assert that at least ``k`` of ``results`` satisfy ``pred`` (default: success); return those."""
    pred = pred or (lambda r: r.success)
    good = [r for r in results if pred(r)]
    assert len(good) >= k, f"only {len(good)} of {len(results)} {what} (need {k}): " + "; ".join(
        describe(r) for r in results
    )
    return good


def none_fails_in(results: Iterable[EpisodeResult], *stages: str) -> None:
    bad = [r for r in results if r.failure is not None and r.failure.stage.value in stages]
    assert not bad, "; ".join(describe(r) for r in bad)
