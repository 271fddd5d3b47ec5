"""The example outputs of the README and the docs come from real runs: this makes them, and checks them.

Every ```console block of README.md and of docs/**/*.md starts with ``$ python -m pickdemo ...``; the
lines after it are that command's standard output. ``python tests/readme_examples.py --write`` runs
each command in an empty directory and writes what it printed into its page; ``tests/test_readme.py``
runs them again and fails when a page has drifted from what the code prints:

- every line must be there, in order, with the same words (numbers aside): the states entered, the
  files written, the summary's parts;
- a line noticed *within* a state (``the target moved ...``, a repeated state's name) may be there
  or not: another machine's last bits may see a push a frame later, or twice; so may a bench's lines
  said only when there is something to say (failures, estimates off the truth), whose figures are
  then not compared;
- every number is compared with the page's, within the tolerance of its kind (:data:`FIGURES` says
  which number is of which kind; a number no rule names is compared exactly: the scenario's own
  figures, seeds, counts of one episode's discrete events). Wall-clock figures (wall time, ms a
  tick, us a step, real-time factors, the profile's shares and durations, a bench's worker count,
  which is the machine's cores) are never compared, nor their unit (``850 us`` here may be
  ``1.20 ms`` there).

The tolerances hold across machines, not only on this one (where a run gives the same figures bit for
bit, see docs/reproducible.md): another CPU or build changes the last bits of floating point, and a
closed loop amplifies them once the hand touches something. So what is measured of a resting scene
(the first look's errors and NEES, the ``perceive`` tables) stays far below its printed digits, and is
given 25 % or its spread over a set's seeds; what comes after contact (the place error, the hand's
opening, the later states' times and frames) is another draw of its spread over seeds, and its
tolerance covers that spread (each kind's, with the figures behind it, at its constant below). A
set's counts (successes, first attempts, the episodes behind a median) may differ by one episode; a
success rate and its Wilson interval, computed from the counts on their line, are compared when the
counts are the same.

A command that appears on several pages is run once.

An elided stretch is written ``...`` on a line of its own.
"""

from __future__ import annotations

import argparse
import functools
import re
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
#: Every page whose console examples are run: the README and the docs.
PAGES = (README, *sorted((ROOT / "docs").rglob("*.md")))
BLOCK = re.compile(r"```console\n\$ (?P<command>[^\n]+)\n(?P<output>.*?)```", re.S)
PHASE = re.compile(r"^\[sim\s+(?P<sim>[\d.]+) s \| wall\s+[\d.]+ s\] (?P<state>\S+)\s*(?P<message>.*)$")
NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?")
WALL_UNIT = re.compile(r"# (?:us|ms)\b")
#: Lines a bench prints only when there is something to say, whose figures are one machine's: a run may
#: show them where the page does not, or not show them where it does (their figures are not compared).
OPTIONAL = re.compile(
    r"^\s+(?:estimates > 5 mm off the truth: |failures: |failures by diagnosis |failed episodes that left )"
)
ELIDED = "..."


@dataclass(frozen=True)
class Tolerance:
    """How near a run's figure must be to the page's: within ``max(abs_, rel * |page's|)``. ``rel`` None:
    never compared. ``follows_counts``: computed from the counts on its line (a rate, its interval),
    compared exactly when every other figure on the line is the same, else not at all."""

    what: str
    rel: float | None
    abs_: float = 0.0
    follows_counts: bool = False


#: Never compared: the wall clock, and the machine's own (its cores).
WALL = Tolerance("wall clock", None)
EXACT = Tolerance("exact", 0.0)
#: Simulated time, when a state was entered and a whole episode's: a later state adds up what an
#: earlier one took longer (a retry's look, a frame more to settle).
ENTERED = Tolerance("a state entered (s simulated)", 0.10, 0.3)
SIMULATED = Tolerance("simulated time (s)", 0.15, 0.3)
#: Frames, stage calls, picks an hour: they follow the simulated time.
TICKS = Tolerance("frames or calls", 0.15, 2.0)
PER_SIM_HOUR = Tolerance("per simulated hour", 0.15)
#: Frames a simulated second: the scenario's rate, kept within 5 % (tests/runtime/test_episode.py).
RATE_HZ = Tolerance("Hz (simulated time)", 0.05)
#: Measured of a resting scene (an object's settle damps what differs): 25 %, or a figure's spread over
#: a set's seeds (pick_cube's first look, seeds 10-17: 0.02-0.13 mm, 0.002-0.36 deg), so that a median or a maximum
#: over a set with an episode more or less stays within.
POSE_MM = Tolerance("position error (mm)", 0.25, 0.05)
ANGLE_DEG = Tolerance("angle error (deg)", 0.25, 0.05)
NEES = Tolerance("NEES", 0.25, 0.1)
#: Where a target was seen and how large (in a clear round after the first pick: objects a pick may
#: have nudged), where the hand let go, the yaw seen and the grasp's.
POSITION_M = Tolerance("position (m)", 0.0, 0.002)
YAW_DEG = Tolerance("yaw (deg)", 0.0, 0.5)
SIZE_MM = Tolerance("size seen (mm)", 0.0, 2.0)
GRASP_COST = Tolerance("grasp cost", 0.0, 0.05)
#: After contact, another draw of the figure's spread over seeds: pick_cube's place error over 50 seeds,
#: median 0.40 mm, largest 2.3 (2 mm, or half a larger one); the tracker's error when the gripper
#: closes, 0.04-0.15 mm a seed (seeds 10-17; one 5.4: a median over a set); a push seen a frame later
#: has gone farther (pushes of 30-60 mm); the fingers close on where the grasp met the object; the
#: wrist weighs while the arm accelerates.
PLACE_MM = Tolerance("place error (mm)", 0.5, 2.0)
TRACKING_MM = Tolerance("tracking error at the grasp (mm)", 0.5, 0.1)
PUSH_MM = Tolerance("move seen (mm)", 0.3, 10.0)
FINGERS_MM = Tolerance("fingers (mm)", 0.0, 1.0)
WEIGHT_KG = Tolerance("weighed (kg)", 0.2, 0.02)
#: A set's counts: one episode either way; a mean of attempts, one more in ten episodes; what the tracker
#: rejected or saw move over a set, 25 % or 2.
SET_COUNT = Tolerance("a count over the set", 0.0, 1.0)
MEAN_PER_EPISODE = Tolerance("attempts per episode (mean)", 0.0, 0.1)
SET_EVENTS = Tolerance("events over the set", 0.25, 2.0)
FOLLOWS = Tolerance("computed from the line's counts", 0.0, follows_counts=True)

_N = r"([-+]?\d+(?:\.\d+)?)"
_T = r"(?:# / # / #|-)"  # a perceive table's median / p95 / max, or a dash
#: (pattern, the tolerance of each of its groups in order): ``#`` stands for a number. A number takes the
#: first rule that names it; a number no rule names is compared exactly.
FIGURES: list[tuple[re.Pattern[str], tuple[Tolerance, ...]]] = [
    (re.compile(p.replace("_T", _T).replace("#", _N)), kinds)
    for p, kinds in [
        # the wall clock and the machine
        (r"wall\s+# s", (WALL,)),
        (r"\bin # s\b", (WALL,)),
        (r"#x real time", (WALL,)),
        (r"real-time factor #x", (WALL,)),
        (r"median # s; real-time", (WALL,)),
        (r"# (?:us|ms) a (?:tick|step)", (WALL,)),
        (r"decision\): # s", (WALL,)),
        (r"the loop:? # of", (WALL,)),
        (r"# workers", (WALL,)),
        # the profile's table: share, wall s, calls, per call, median
        (r"^[a-z][a-zA-Z/ ]*? +#% +#(?: +#(?: +# [um]s(?: +# [um]s)?)?)?", (WALL, WALL, TICKS, WALL, WALL)),
        # perceive's table: 3-D mm, x / y / z mm, yaw, pitch, roll deg, NEES, ms, fail
        (
            r"^\S+ +_T +(?:#|-) / (?:#|-) / (?:#|-) +_T +_T +_T +(?:#|-) +# +#$",
            (*[POSE_MM] * 6, *[ANGLE_DEG] * 9, NEES, WALL, SET_COUNT),
        ),
        # the paper's errors beside ours: ref / ours
        (r"# / # +# / # +# / # +# / #\s*$", (EXACT, POSE_MM, EXACT, ANGLE_DEG, EXACT, ANGLE_DEG, EXACT, ANGLE_DEG)),
        # an episode's states
        (r"^\[sim\s+# s", (ENTERED,)),
        (r"frame of t = # s", (ENTERED,)),
        (r"\bat \(#, #(?:, #)?\)", (POSITION_M,) * 3),
        (r"yaw # deg", (YAW_DEG,)),
        (r"the target moved # mm", (PUSH_MM,)),
        (r"fingers at # mm", (FINGERS_MM,)),
        (r"weighed # kg", (WEIGHT_KG,)),
        (r"sees the target # mm from the place", (PLACE_MM,)),
        (r"# mm tall, # x # mm \(grasp cost #\)", (SIZE_MM, SIZE_MM, SIZE_MM, GRASP_COST)),
        # an episode's summary
        (r"pose error # mm", (POSE_MM,)),
        (r"yaw error # deg", (ANGLE_DEG,)),
        (r"place error # mm", (PLACE_MM,)),
        (r"# picks/h", (PER_SIM_HOUR,)),
        (r"# frames", (TICKS,)),
        (r"# s simulated", (SIMULATED,)),
        # a set's summary (bench, demos, profile)
        (r"^\S+: #/# succeeded \(# %, Wilson 95 % \[#, #\]\)", (SET_COUNT, EXACT, FOLLOWS, FOLLOWS, FOLLOWS)),
        (r"^\S+: #/# episodes succeeded; # in the", (SET_COUNT, EXACT, SET_COUNT)),
        (r"^episodes: # \(# succeeded\)", (EXACT, SET_COUNT)),
        (r"pose error: median # mm, p95 #, max # \(n=#\)", (POSE_MM, POSE_MM, POSE_MM, SET_COUNT)),
        (r"yaw error \(.*\): median # deg, p95 #, max # \(n=#\)", (ANGLE_DEG, ANGLE_DEG, ANGLE_DEG, SET_COUNT)),
        (r"place error: median # mm, p95 #, max # \(n=#\)", (PLACE_MM, PLACE_MM, PLACE_MM, SET_COUNT)),
        (r"first attempt: #/#; attempts per episode: mean #, max #", (SET_COUNT, EXACT, MEAN_PER_EPISODE, SET_COUNT)),
        (
            r"perception # Hz, # estimate\(s\) rejected, # target move\(s\) detected"
            r"(?:, tracking error at the grasp median # mm)?",
            (RATE_HZ, SET_EVENTS, SET_EVENTS, TRACKING_MM),
        ),
    ]
]


@dataclass(frozen=True)
class Example:
    command: str
    output: str
    start: int  # the output's span in the README's text
    end: int


def examples(text: str) -> list[Example]:
    return [Example(m["command"], m["output"], m.start("output"), m.end("output")) for m in BLOCK.finditer(text)]


@functools.cache
def run(command: str, timeout_s: float = 900.0) -> str:
    """Run a README command (``python -m pickdemo ...``) in an empty directory; its standard output."""
    argv = shlex.split(command)
    if argv[:3] != ["python", "-m", "pickdemo"]:
        raise ValueError(f"a README example must run `python -m pickdemo ...`, not {command!r}")
    with tempfile.TemporaryDirectory(prefix="pickdemo-readme-") as cwd:
        proc = subprocess.run(
            [sys.executable, *argv[1:]], cwd=cwd, capture_output=True, text=True, timeout=timeout_s, check=False
        )
    if proc.returncode not in (0, 1):
        raise RuntimeError(f"{command}: exit {proc.returncode}\n{proc.stderr}")
    return proc.stdout


def _masked(line: str) -> str:
    return " ".join(WALL_UNIT.sub("# t", NUMBER.sub("#", line)).split())


def _close(a: float, b: float, *, rel: float, abs_: float) -> bool:
    return abs(a - b) <= max(abs_, rel * abs(b)) + 1e-9  # (floating point aside: 1.10 - 1.00 > 0.10)


def claims(line: str) -> dict[tuple[int, int], Tolerance]:
    """The spans of a line's numbers that a rule of :data:`FIGURES` names, with their tolerance."""
    claimed: dict[tuple[int, int], Tolerance] = {}
    for pattern, kinds in FIGURES:
        for m in pattern.finditer(line):
            for group, kind in enumerate(kinds, 1):
                if m.start(group) >= 0:
                    claimed.setdefault(m.span(group), kind)
    return claimed


def figure_kinds(line: str) -> list[tuple[re.Match[str], Tolerance]]:
    """Each number of a page's line, with the tolerance of its kind (exact where no rule names it)."""
    claimed = claims(line)
    return [(n, claimed.get(n.span(), EXACT)) for n in NUMBER.finditer(line)]


def _figures_agree(expected: str, actual: str) -> str | None:
    """None when the figures of two lines with the same words agree, each within its kind's tolerance;
    else what differs."""
    if OPTIONAL.match(expected):
        return None
    pairs = zip(figure_kinds(expected), NUMBER.findall(actual), strict=True)
    figures = [(e.group(), a, kind) for (e, kind), a in pairs]
    counts_same = all(
        float(e) == float(a) for e, a, kind in figures if kind.rel is not None and not kind.follows_counts
    )
    for e, a, kind in figures:
        if kind.rel is None or (kind.follows_counts and not counts_same):
            continue
        if not _close(float(a), float(e), rel=kind.rel, abs_=kind.abs_):
            parts = [f"{kind.abs_:g}"] * (kind.abs_ > 0) + [f"{100 * kind.rel:g} %"] * (kind.rel > 0)
            within = "within " + " or ".join(parts) if parts else "exactly"
            return f"{kind.what}: the run printed {a}, the page says {e} ({within}) in {actual.strip()!r}"
    return None


def _notices(lines: list[str]) -> set[int]:
    """Indices of lines that may be there or not: noticed within a state (a phase line naming the state of
    the one before), or :data:`OPTIONAL`."""
    out, state = set(), None
    for i, line in enumerate(lines):
        m = PHASE.match(line)
        if (m and m["state"] == state) or OPTIONAL.match(line):
            out.add(i)
        state = m["state"] if m else None
    return out


def differences(expected: str, actual: str) -> list[str]:
    """What in ``actual`` (a real run's output) the README's ``expected`` does not say truly."""
    exp = [line for line in expected.splitlines() if line.strip()]
    act = [line for line in actual.splitlines() if line.strip()]
    exp_notice, act_notice = _notices(exp), _notices(act)
    problems: list[str] = []
    i = j = 0
    while i < len(exp) or j < len(act):
        if i < len(exp) and exp[i].strip() == ELIDED:
            if i + 1 == len(exp):
                return problems  # elided to the end
            nxt = _masked(exp[i + 1])
            while j < len(act) and _masked(act[j]) != nxt:
                j += 1
            i += 1
            continue
        if i < len(exp) and j < len(act) and _masked(exp[i]) == _masked(act[j]):
            why = _figures_agree(exp[i], act[j])
            if why:
                problems.append(why)
            i, j = i + 1, j + 1
        elif j < len(act) and j in act_notice:
            j += 1  # noticed here, not in the README's run: allowed
        elif i < len(exp) and i in exp_notice:
            i += 1  # noticed in the README's run, not here: allowed
        elif i < len(exp):
            problems.append(
                f"the README says {exp[i]!r}; the run printed {act[j] if j < len(act) else '(nothing more)'!r}"
            )
            return problems
        else:
            problems.append(f"the run printed {act[j]!r}, which the README does not show")
            return problems
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite the pages' example outputs from real runs")
    args = parser.parse_args(argv)
    bad = 0
    for page in PAGES:
        text = page.read_text()
        found = examples(text)
        for ex in reversed(found):  # from the end, so earlier spans stay valid
            print(f"{page.relative_to(ROOT)}: $ {ex.command}", flush=True)
            out = run(ex.command)
            if args.write:
                text = text[: ex.start] + out + text[ex.end :]
            else:
                for problem in differences(ex.output, out):
                    print(f"  drifted: {problem}")
                    bad += 1
        if args.write and found:
            page.write_text(text)
            print(f"wrote {page.relative_to(ROOT)}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
