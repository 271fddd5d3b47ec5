"""`pickdemo compare BASE NEW`: two `bench` runs paired by seed, per scenario (issue 62).

Every episode is determined by its scenario, seed, machine and lock, so two runs on the same seeds
are paired: a change that flips three seeds from success to failure and none back is evidence a
difference of rates hides. Per scenario:

- the table of pairs: both succeeded, both failed, only BASE, only NEW (the seeds that flipped, with
  their failure stage and reason);
- McNemar's exact test on the discordant pairs (a binomial test of the "only BASE" count among them
  at 1/2): one-sided for "worse" (more seeds lost than gained) and for "better", two-sided reported;
  the one-sided p-values over the scenarios adjusted by Holm's step-down method (the family-wise
  error at ``alpha`` however many scenarios are compared), and the verdict: worse, better, or no
  evidence;
- the continuous figures (pose error, place error, attempts, wall time; picks an hour of a clear round)
  as paired differences NEW - BASE, their mean with a seeded bootstrap 95 % interval.

Exit 0 when no scenario is worse, 1 when one is, 2 on input that does not pair (:class:`CompareError`).
Pure: files in, a report out; no simulator.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

#: The bootstrap's resamples and its seed (the interval is the same for the same runs).
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 0
#: The file beside episodes.jsonl that says where a run ran (one machine and lock give one episode).
RUN_FILE = "run.json"


#: The packages whose versions make an episode what it is (with the machine and Python).
LOCKED = ("numpy", "pybullet", "pin", "coal", "ruckig", "ompl", "opencv-python-headless", "example-robot-data")


def machine() -> dict[str, Any]:
    """Where a run runs: the CPU, the platform, Python and the versions of :data:`LOCKED` (one seed
    gives one episode bit for bit on one machine and lock)."""
    import platform
    from importlib.metadata import PackageNotFoundError, version

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), cpu)
    except OSError:
        pass
    packages = {}
    for name in LOCKED:
        try:
            packages[name] = version(name)
        except PackageNotFoundError:
            packages[name] = None
    return {"cpu": cpu, "platform": platform.platform(), "python": platform.python_version(), "packages": packages}


def write_run_file(out_dir: Path) -> None:
    """``run.json`` beside a bench's episodes: the machine it ran on (:func:`machine`)."""
    (out_dir / RUN_FILE).write_text(json.dumps({"machine": machine()}, indent=1) + "\n", encoding="utf-8")


class CompareError(Exception):
    """Input that cannot be compared (one line: which file or key, and why)."""


def binom_tail_ge(k: int, n: int) -> float:
    """P(X >= k) for X ~ Binomial(n, 1/2), exactly (integer arithmetic)."""
    if k <= 0:
        return 1.0
    if k > n:
        return 0.0
    return math.fsum(math.comb(n, i) for i in range(k, n + 1)) / 2.0**n


def mcnemar_exact(only_base: int, only_new: int) -> tuple[float, float, float]:
    """McNemar's exact test on the discordant pairs: (p worse, p better, p two-sided). "Worse" is the
    one-sided test that NEW loses more seeds than it gains (``only_base`` large); the two-sided p
    is twice the smaller tail, at most 1 (the binomial at 1/2 is symmetric: scipy's ``binomtest``)."""
    n = only_base + only_new
    worse, better = binom_tail_ge(only_base, n), binom_tail_ge(only_new, n)
    return worse, better, min(1.0, 2.0 * min(worse, better))


def holm(p: list[float]) -> list[float]:
    """Holm's step-down adjustment of ``p`` (each adjusted p-value, monotone, at most 1)."""
    order = sorted(range(len(p)), key=lambda i: p[i])
    out = [1.0] * len(p)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(p) - rank) * p[i]))
        out[i] = running
    return out


def bootstrap_mean(diff: np.ndarray, seed: int = BOOTSTRAP_SEED) -> tuple[float, float, float]:
    """The mean of paired differences and its percentile bootstrap 95 % interval (seeded)."""
    rng = np.random.default_rng(seed)
    means = diff[rng.integers(0, len(diff), size=(BOOTSTRAP_RESAMPLES, len(diff)))].mean(axis=1)
    lo, hi = np.quantile(means, [0.025, 0.975])
    return float(diff.mean()), float(lo), float(hi)


def _pose_error(r: dict) -> float | None:
    p = r.get("perception") or {}
    return p.get("position_error_mm")


def _picks_per_hour(r: dict) -> float | None:
    c = r.get("clear") or {}
    t = c.get("round_time_s")
    return None if not t else 3600.0 * c.get("successful_grasps", 0) / t


#: The continuous figures compared: (name, unit, how to read it off an episode's record).
FIGURES: tuple[tuple[str, str, Callable[[dict], float | None]], ...] = (
    ("pose error", "mm", _pose_error),
    ("place error", "mm", lambda r: r.get("place_error_mm")),
    ("attempts", "", lambda r: float(len(r.get("attempts") or []))),
    ("wall time", "s", lambda r: r.get("wall_time_s")),
    ("picks an hour", "", _picks_per_hour),
)


@dataclass
class ScenarioComparison:
    """One scenario's paired runs."""

    scenario: str
    pairs: int
    both_ok: int
    both_failed: int
    only_base: list[dict] = field(default_factory=list)  # {seed, stage, reason}: NEW failed where BASE did not
    only_new: list[dict] = field(default_factory=list)  # BASE failed where NEW did not
    p_worse: float = 1.0
    p_better: float = 1.0
    p_two_sided: float = 1.0
    p_worse_adjusted: float = 1.0
    p_better_adjusted: float = 1.0
    verdict: str = "no evidence"
    figures: dict[str, dict[str, Any]] = field(default_factory=dict)


def _failure(r: dict) -> tuple[str, str]:
    f = r.get("failure") or {}
    return str(f.get("stage", "")), str(f.get("reason", ""))


def read_run(folder: Path) -> dict[tuple[str, int], dict]:
    """A bench folder's episodes by (scenario, seed); a :class:`CompareError` naming the file and line
    when it is not one."""
    if not folder.is_dir():
        raise CompareError(f"{folder}: not a directory (give a bench --out folder)")
    path = folder / "episodes.jsonl"
    if not path.is_file():
        raise CompareError(f"{path}: missing (not a bench --out folder, or its run wrote nothing)")
    out: dict[tuple[str, int], dict] = {}
    with path.open(encoding="utf-8") as f:
        for n, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                r = json.loads(line)
                key = (str(r["scenario"]), int(r["seed"]))
                bool(r["success"])
            except (json.JSONDecodeError, KeyError, TypeError, ValueError):
                raise CompareError(f"{path}:{n}: not a whole episode record (a truncated file?)") from None
            if key in out:
                raise CompareError(f"{path}:{n}: {key[0]} seed {key[1]} appears twice")
            out[key] = r
    if not out:
        raise CompareError(f"{path}: no episodes")
    return out


def _machine(folder: Path) -> dict | None:
    try:
        return json.loads((folder / RUN_FILE).read_text(encoding="utf-8")).get("machine")
    except (OSError, json.JSONDecodeError, AttributeError):
        return None


def pair_runs(base: Path, new: Path) -> tuple[dict, dict]:
    """Both runs read and checked to pair: the same scenarios, each on the same seeds, on one machine."""
    a, b = read_run(base), read_run(new)
    sa, sb = {k[0] for k in a}, {k[0] for k in b}
    if sa != sb:
        only = sorted(sa ^ sb)
        raise CompareError(f"{base} and {new} ran other scenarios: {', '.join(only[:5])} in one of them only")
    for s in sorted(sa):
        seeds_a = {k[1] for k in a if k[0] == s}
        seeds_b = {k[1] for k in b if k[0] == s}
        if seeds_a != seeds_b:
            diff = sorted(seeds_a ^ seeds_b)
            raise CompareError(f"{base} and {new} ran {s} on other seeds: {diff[:8]} in one of them only")
    ma, mb = _machine(base), _machine(new)
    if ma is not None and mb is not None and ma != mb:
        keys = sorted(k for k in set(ma) | set(mb) if ma.get(k) != mb.get(k))
        raise CompareError(f"{base} and {new} ran on other machines or locks ({', '.join(keys)} differ): "
                           "their seeds do not pair")  # fmt: skip
    return a, b


def compare(base: Path, new: Path, alpha: float = 0.05) -> list[ScenarioComparison]:
    """Every scenario of the two runs, paired by seed (see the module docstring)."""
    if not 0.0 < alpha < 1.0:
        raise CompareError(f"--alpha must be in (0, 1), got {alpha}")
    a, b = pair_runs(base, new)
    out = []
    for s in sorted({k[0] for k in a}):
        keys = sorted(k for k in a if k[0] == s)
        c = ScenarioComparison(s, len(keys), 0, 0)
        for k in keys:
            ok_a, ok_b = bool(a[k]["success"]), bool(b[k]["success"])
            if ok_a and ok_b:
                c.both_ok += 1
            elif not ok_a and not ok_b:
                c.both_failed += 1
            elif ok_a:
                stage, reason = _failure(b[k])
                c.only_base.append({"seed": k[1], "stage": stage, "reason": reason})
            else:
                stage, reason = _failure(a[k])
                c.only_new.append({"seed": k[1], "stage": stage, "reason": reason})
        c.p_worse, c.p_better, c.p_two_sided = mcnemar_exact(len(c.only_base), len(c.only_new))
        for name, unit, read in FIGURES:
            both = [(read(a[k]), read(b[k])) for k in keys]
            d = np.array([y - x for x, y in both if x is not None and y is not None], dtype=float)
            if len(d):
                mean, lo, hi = bootstrap_mean(d)
                c.figures[name] = {"unit": unit, "pairs": len(d), "mean_difference": mean, "ci95": [lo, hi]}
        out.append(c)
    worse = holm([c.p_worse for c in out])
    better = holm([c.p_better for c in out])
    for c, w, bt in zip(out, worse, better, strict=True):
        c.p_worse_adjusted, c.p_better_adjusted = w, bt
        c.verdict = "worse" if w < alpha else "better" if bt < alpha else "no evidence"
    return out


def to_json(rows: list[ScenarioComparison], base: Path, new: Path, alpha: float) -> dict:
    return {
        "base": str(base),
        "new": str(new),
        "alpha": alpha,
        "correction": "holm",
        "test": "McNemar exact (binomial on the discordant pairs at 1/2)",
        "scenarios": [c.__dict__ for c in rows],
        "worse": [c.scenario for c in rows if c.verdict == "worse"],
    }


def _fmt_p(p: float) -> str:
    return f"{p:.2g}" if p < 0.001 else f"{p:.3f}"


def format_text(rows: list[ScenarioComparison], alpha: float) -> str:
    """The console report: a line per scenario, the flipped seeds under it."""
    lines = [f"paired by seed; McNemar exact, Holm-adjusted over {len(rows)} scenario(s), alpha {alpha:g}"]
    for c in rows:
        lines.append(
            f"{c.scenario}: {c.verdict.upper() if c.verdict != 'no evidence' else 'no evidence'} | {c.pairs} seeds: "
            f"both ok {c.both_ok}, both failed {c.both_failed}, only BASE {len(c.only_base)}, only NEW "
            f"{len(c.only_new)} | p worse {_fmt_p(c.p_worse_adjusted)} (raw {_fmt_p(c.p_worse)}), p better "
            f"{_fmt_p(c.p_better_adjusted)}"
        )
        for tag, flips in (("lost by NEW", c.only_base), ("gained by NEW", c.only_new)):
            for f in flips:
                lines.append(f"  {tag}: seed {f['seed']} ({f['stage']}: {f['reason'][:100]})")
        for name, fig in c.figures.items():
            lo, hi = fig["ci95"]
            if fig["pairs"] and (lo != 0.0 or hi != 0.0):
                u = f" {fig['unit']}" if fig["unit"] else ""
                lines.append(
                    f"  {name}: {fig['mean_difference']:+.3g}{u} [{lo:+.3g}, {hi:+.3g}] over {fig['pairs']} pairs"
                )
    worse = [c.scenario for c in rows if c.verdict == "worse"]
    lines.append(f"WORSE: {', '.join(worse)}" if worse else "nothing significantly worse")
    return "\n".join(lines)


def format_markdown(rows: list[ScenarioComparison], base: Path, new: Path, alpha: float) -> str:
    """A CI job's summary page."""
    worse = [c.scenario for c in rows if c.verdict == "worse"]
    out = [
        "## pickdemo compare",
        "",
        f"`{base}` (BASE) against `{new}` (NEW), paired by seed. McNemar's exact test on the seeds that "
        f"flipped, Holm-adjusted over {len(rows)} scenario(s), alpha {alpha:g}.",
        "",
        f"**{'Worse: ' + ', '.join(worse) if worse else 'Nothing significantly worse.'}**",
        "",
        "| scenario | verdict | seeds | both ok | both failed | only BASE | only NEW | p worse (Holm) "
        "| p better (Holm) |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for c in rows:
        out.append(
            f"| `{c.scenario}` | {c.verdict} | {c.pairs} | {c.both_ok} | {c.both_failed} | {len(c.only_base)} | "
            f"{len(c.only_new)} | {_fmt_p(c.p_worse_adjusted)} | {_fmt_p(c.p_better_adjusted)} |"
        )
    flips = [
        (c.scenario, tag, f) for c in rows for tag, fl in (("lost", c.only_base), ("gained", c.only_new)) for f in fl
    ]
    if flips:
        out += ["", "| scenario | seed | NEW | the failure |", "| --- | --- | --- | --- |"]
        out += [f"| `{s}` | {f['seed']} | {tag} | {f['stage']}: {f['reason'][:120]} |" for s, tag, f in flips]
    out += [
        "",
        "| scenario | figure | pairs | mean NEW - BASE | 95 % interval (bootstrap) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for c in rows:
        for name, fig in c.figures.items():
            lo, hi = fig["ci95"]
            out.append(f"| `{c.scenario}` | {name} {fig['unit']} | {fig['pairs']} | {fig['mean_difference']:+.3g} | "
                       f"[{lo:+.3g}, {hi:+.3g}] |")  # fmt: skip
    return "\n".join(out) + "\n"
