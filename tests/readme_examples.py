"""The example outputs of the README and the docs come from real runs: this makes them, and checks them.

Every ```console block of README.md and of docs/**/*.md starts with ``$ python -m pickdemo ...``; the
lines after it are that command's standard output. ``python tests/readme_examples.py --write`` runs
each command in an empty directory and writes what it printed into its page; ``tests/test_readme.py``
runs them again and fails when a page has drifted from what the code prints:

- every line must be there, in order, with the same words (numbers aside): the states entered, the
  files written, the summary's parts;
- a line noticed *within* a state (``the target moved ...``, a repeated state's name) may be there
  or not: another machine's last bits may see a push a frame later, or twice;
- the simulated figures must be close: a state entered within 0.3 s (or 10 %), the frames and the
  simulated time of the summary within 15 %, a bench's successes within one episode. Wall-clock
  figures are never compared (nor their unit: ``850 us`` here may be ``1.20 ms`` there).

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
SUMMARY = re.compile(r"\| (?P<frames>\d+) frames \| (?P<sim>[\d.]+) s simulated in")
#: Lines a bench prints only when there is something to say, whose count is one machine's: a run may show
#: them where the page does not, or not show them where it does.
OPTIONAL = re.compile(r"^\s+estimates > 5 mm off the truth: ")
SUCCEEDED = re.compile(r"^(?P<name>\S+): (?P<ok>\d+)/(?P<n>\d+) succeeded")
ELIDED = "..."


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
    return abs(a - b) <= max(abs_, rel * abs(b))


def _figures_agree(expected: str, actual: str) -> str | None:
    """None when the simulated figures of two lines with the same words agree; else what differs."""
    pe, pa = PHASE.match(expected), PHASE.match(actual)
    if pe and pa and not _close(float(pa["sim"]), float(pe["sim"]), rel=0.10, abs_=0.3):
        return f"{pe['state']} entered at {pa['sim']} s, the README says {pe['sim']} s"
    se, sa = SUMMARY.search(expected), SUMMARY.search(actual)
    if se and sa:
        if not _close(float(sa["frames"]), float(se["frames"]), rel=0.15, abs_=2):
            return f"{sa['frames']} frames, the README says {se['frames']}"
        if not _close(float(sa["sim"]), float(se["sim"]), rel=0.15, abs_=0.3):
            return f"{sa['sim']} s simulated, the README says {se['sim']}"
    be, ba = SUCCEEDED.match(expected), SUCCEEDED.match(actual)
    if be and ba and (be["n"] != ba["n"] or abs(int(be["ok"]) - int(ba["ok"])) > 1):
        return f"{ba['name']}: {ba['ok']}/{ba['n']} succeeded, the README says {be['ok']}/{be['n']}"
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
