"""`bench --min-success P --fail-fast`: a gate that stops when its answer can no longer change (issue 62).

The gate passes a scenario when its success rate over the seeds asked is at least P. After each
episode, a scenario's answer is fixed when no outcome of its episodes still to run could change it:
failed when even all of them succeeding would leave the rate below P, passed when even all of them
failing would leave it at P or above. A scenario whose answer is fixed as failed runs no more
episodes (those not started are dropped, those under way stopped); the whole run stops when every
scenario's answer is fixed. The decision is the full run's, always: the comparison is the gate's own
(successes over the seeds asked, against P), made on counts that can only move one way.
Pure: results in, decisions out.
"""

from __future__ import annotations

from collections import Counter

from pickdemo.apps.bench import Job
from pickdemo.core.result import EpisodeRecord


def _group(scenario: str, open_loop: bool, perception: str) -> tuple[str, bool, str]:
    return scenario, bool(open_loop), perception


class FailFast:
    """The gate's answer per scenario as results come in (see the module docstring)."""

    def __init__(self, jobs: list[Job], min_success: float, done: list[EpisodeRecord] = ()) -> None:
        self.p = min_success
        self.asked = Counter(_group(j.scenario_name, j.open_loop, j.perception) for j in jobs)
        self.ok: Counter = Counter()
        self.ran: Counter = Counter()
        self.verdict: dict[tuple, str] = {}  # "failed" or "passed", once fixed
        self.log: list[str] = []  # what it decided, in order
        for r in done:
            self.record(r)

    def record(self, r: EpisodeRecord) -> None:
        g = _group(r["scenario"], r.get("open_loop", False), r.get("perception_method") or "paper")
        if g not in self.asked:
            return
        self.ran[g] += 1
        self.ok[g] += bool(r["success"])
        if g in self.verdict:
            return
        n, left = self.asked[g], self.asked[g] - self.ran[g]
        if (self.ok[g] + left) / n < self.p:
            self.verdict[g] = "failed"
            fails = self.ran[g] - self.ok[g]
            self.log.append(f"fail-fast: {g[0]} FAILED after {self.ran[g]} of {n} episodes: {fails} failure(s), "
                            f"more than a success rate of {self.p:g} allows over {n} seeds")  # fmt: skip
        elif self.ok[g] / n >= self.p:
            self.verdict[g] = "passed"

    def skip(self, job: Job) -> bool:
        """Whether a job is no longer needed: its scenario failed, or every scenario's answer is fixed."""
        return self.verdict.get(_group(job.scenario_name, job.open_loop, job.perception)) == "failed" or self.settled

    @property
    def settled(self) -> bool:
        return len(self.verdict) == len(self.asked)


def interleaved(jobs: list[Job]) -> list[Job]:
    """The jobs seed by seed across the scenarios (every scenario's answer advances together)."""
    order = {j.key: k for k, j in enumerate(jobs)}
    rank: Counter = Counter()
    keyed = []
    for j in jobs:
        g = _group(j.scenario_name, j.open_loop, j.perception)
        keyed.append((rank[g], order[j.key], j))
        rank[g] += 1
    return [j for _, _, j in sorted(keyed, key=lambda t: (t[0], t[1]))]
