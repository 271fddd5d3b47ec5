"""Episodes for the tests, run once per test session and shared, and assertions over several seeds.

A closed loop amplifies the last bits of floating point, and those differ between CPUs and library
builds: the same seed is the same episode on one machine with one lock, not on every machine. So a
test of an outcome asserts a property of several seeds (a rate with a bound, a maximum, "none fails
in ``trajectory``"), never one seed's fate. Exact comparisons are kept for two runs on the same
machine (determinism, worker counts, recording on and off).
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

from pickdemo.core.result import EpisodeResult

#: Set by ``conftest.py`` for a test session: a directory its processes (pytest-xdist's workers)
#: share, so that a set of episodes runs once a session, in whichever worker asks for it first.
SHARED_DIR_ENV = "PICKDEMO_TEST_EPISODES"


@functools.cache
def episodes(
    scenario: str,
    seeds: tuple[int, ...],
    *,
    open_loop: bool = False,
    method: str = "paper",
    record_trace: bool = False,
) -> tuple[EpisodeResult, ...]:
    """The episodes of a shipped scenario (or a path) over ``seeds``; run once for the test session."""
    return no_bugs(_shared(scenario, tuple(seeds), open_loop, method, record_trace))


def no_bugs(results: Sequence[EpisodeResult]) -> tuple[EpisodeResult, ...]:
    """``results``, after asserting that none ended on a bug (an exception no stage expects): a test over
    seeds that counts successes must not read a bug as an episode that merely failed."""
    bugs = [r for r in results if r.failure is not None and r.failure.is_bug]
    assert not bugs, "\n".join(f"{r.scenario} seed {r.seed}:\n{r.failure.traceback}" for r in bugs)  # type: ignore[union-attr]
    return tuple(results)


def _shared(*key) -> tuple[EpisodeResult, ...]:  # noqa: ANN002
    shared = os.environ.get(SHARED_DIR_ENV)
    if not shared:
        return _run(*key)
    from filelock import FileLock

    path = Path(shared) / (hashlib.sha256(repr(key).encode()).hexdigest()[:24] + ".pickle")
    with FileLock(f"{path}.lock"):  # another worker asking for them waits, then reads them
        if path.exists():
            return pickle.loads(path.read_bytes())
        results = _run(*key)
        part = path.with_suffix(".part")
        part.write_bytes(pickle.dumps(results))
        part.replace(path)
        return results


def _run(
    scenario: str, seeds: tuple[int, ...], open_loop: bool, method: str, record_trace: bool
) -> tuple[EpisodeResult, ...]:
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
