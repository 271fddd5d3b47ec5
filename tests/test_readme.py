"""The README and the docs tell the truth: their example outputs are what the code prints
(``readme_examples``), and the README's two first commands are the ones a newcomer should type."""

from __future__ import annotations

import re

import pytest
from readme_examples import (
    FIGURES,
    NUMBER,
    PAGES,
    README,
    ROOT,
    Tolerance,
    claims,
    differences,
    examples,
    figure_kinds,
    run,
)

LOG = """\
pickdemo: pick_pushed seed 1 (closed loop): a pushed cube
[sim   0.05 s | wall  0.08 s] look      looking for the target
[sim   0.20 s | wall  0.23 s] approach  target at (0.5200, -0.0651, 0.0250) m
[sim   1.39 s | wall  0.45 s] approach  the target moved 48 mm from the plan: tracking it again
[sim   3.45 s | wall  0.80 s] descend   above the target
SUCCESS: pick_pushed seed 1 | 1 attempt(s) | 52 frames | 14.5 s simulated in 1.83 s
wrote out/result.json, out/motion.png
"""


def test_a_real_run_with_other_wall_times_and_positions_reads_true() -> None:
    other = LOG.replace("wall  0.80", "wall  3.10").replace("0.5200", "0.5193").replace("3.45 s", "3.50 s")
    assert differences(LOG, other) == []


def test_a_push_noticed_once_more_or_not_at_all_reads_true() -> None:
    lines = LOG.splitlines()
    twice = "\n".join([*lines[:4], lines[3].replace("1.39", "1.52"), *lines[4:]])
    assert differences(LOG, twice) == []
    assert differences(LOG, "\n".join(lines[:3] + lines[4:])) == []


@pytest.mark.parametrize(
    ("edit", "complaint"),
    [
        (("wrote out/result.json, out/motion.png", "wrote out/result.json, out/motion.png, out/report.html"), "says"),
        (("3.45 s | wall", "2.06 s | wall"), "a state entered (s simulated): the run printed 2.06, the page says 3.45"),
        (("52 frames", "39 frames"), "frames or calls: the run printed 39, the page says 52"),
        (("14.5 s simulated", "11.8 s simulated"), "simulated time (s): the run printed 11.8, the page says 14.5"),
        (("descend   above the target", "descend   over the target"), "says"),
    ],
)
def test_a_drifted_example_is_caught(edit: tuple[str, str], complaint: str) -> None:
    problems = differences(LOG, LOG.replace(*edit))
    assert problems and complaint in problems[0], problems


def test_a_line_the_readme_does_not_show_is_caught() -> None:
    assert differences(LOG, LOG + "[sim  14.48 s | wall  1.83 s] done      placed\n")


def test_elided_lines() -> None:
    bench = "pickdemo bench: 2 scenarios\n...\ngate passed: every scenario at or above 0.95\n"
    real = "pickdemo bench: 2 scenarios\na: 20/20 succeeded\n  pose error 1\n"
    real += "gate passed: every scenario at or above 0.95\n"
    assert differences(bench, real) == []


def test_the_readme_starts_with_the_two_commands_from_the_lock() -> None:
    text = README.read_text()
    first = re.search(r"```bash\n(.*?)```", text, re.S)
    assert first and text.index(first.group(0)) < text.index("\n## ")
    install, tests = first.group(1).strip().splitlines()
    assert "-c .ci/constraints.txt" in install and install.endswith("python -m pickdemo run pick_cube")
    assert "-c .ci/constraints.txt" in tests and tests.endswith("python -m pytest -q -n auto")


def test_a_bench_line_said_only_when_there_is_something_to_say_reads_true() -> None:
    bench = "a: 20/20 succeeded\n  pose error 1\n  wall time per episode: 3 s\n"
    said = bench.replace("  wall", "  estimates > 5 mm off the truth: 9; rejected 9\n  wall")
    assert differences(bench, said) == [] and differences(said, bench) == []


def test_a_wall_time_in_another_unit_reads_true() -> None:
    here = "physics      37.8%    1.754     2634     666 us     209 us  PyBullet's steps\n"
    there = "physics      41.0%    3.100     2634    1.18 ms     0.41 ms  PyBullet's steps\n"
    assert differences(here, there) == []


EXAMPLES = [(page, ex) for page in PAGES for ex in examples(page.read_text())]
#: Each command's output as its page shows it (a command on several pages, once).
OUTPUTS = list({ex.command: ex.output for _, ex in EXAMPLES}.values())


def _allowance(value: float, kind: Tolerance) -> float:
    return max(kind.abs_, kind.rel * abs(value))


def _moved(text: str, move, only_first: bool = False) -> str:
    """``text`` with each number that ``move(value, kind)`` turns into a float moved so (None: left as it
    is); with ``only_first``, only the first it moves."""
    out, done = [], False
    for line in text.splitlines(keepends=True):
        pieces, at = [], 0
        for m, kind in figure_kinds(line):
            new = None if done else move(float(m.group()), kind)
            if new is None:
                continue
            pieces += [line[at : m.start()], f"{new:.6f}"]
            at, done = m.end(), only_first
        out.append("".join(pieces) + line[at:])
    return "".join(out)


def test_every_rule_names_numbers_with_a_tolerance_each() -> None:
    for pattern, kinds in FIGURES:
        assert pattern.groups == len(kinds), pattern.pattern
    for output in OUTPUTS:
        for line in output.splitlines():
            spans = {m.span() for m in NUMBER.finditer(line)}
            assert set(claims(line)) <= spans, line  # a rule's number is a whole number of the line


def test_the_wall_clock_and_the_machine_are_never_compared() -> None:
    """Every wall-clock figure of every example three times as long (and a machine with 6 cores)."""
    for output in OUTPUTS:
        slower = _moved(output, lambda v, kind: 3.0 * v if kind.rel is None else None)
        assert slower != output
        assert differences(output, slower) == []


def test_figures_within_their_tolerance_read_true() -> None:
    for output in OUTPUTS:
        near = _moved(output, lambda v, kind: v + 0.9 * _allowance(v, kind) if kind.rel else None)
        assert differences(output, near) == []


KINDS = list(
    {kind.what: kind for output in OUTPUTS for line in output.splitlines() for _, kind in figure_kinds(line)}.values()
)


@pytest.mark.parametrize("kind", [k for k in KINDS if k.rel is not None], ids=lambda k: k.what)
def test_a_figure_beyond_its_tolerance_is_caught(kind: Tolerance) -> None:
    """For each kind of figure the pages show, one figure moved past its tolerance is named."""
    output = next(o for o in OUTPUTS if any(k is kind for line in o.splitlines() for _, k in figure_kinds(line)))
    off = _moved(output, lambda v, k: v + 1.5 * _allowance(v, k) + 1e-3 if k is kind else None, only_first=True)
    problems = differences(output, off)
    assert problems and problems[0].startswith(kind.what + ":"), problems


def test_a_success_rate_follows_its_counts() -> None:
    """One episode fewer on another machine: the rate and its interval follow; the same counts with
    another rate: caught."""
    page = "pick_cube: 10/10 succeeded (100.0 %, Wilson 95 % [72.2, 100.0]) over seeds 0-9\n"
    one_fewer = page.replace(
        "10/10 succeeded (100.0 %, Wilson 95 % [72.2, 100.0]", "9/10 succeeded (90.0 %, Wilson 95 % [59.6, 98.2]"
    )
    assert one_fewer != page and differences(page, one_fewer) == []
    assert differences(page, page.replace("[72.2", "[59.6")), "the same counts, another interval"
    assert differences(page, page.replace("10/10 succeeded (100.0 %", "8/10 succeeded (80.0 %"))


def test_a_bench_failure_said_on_one_machine_only_reads_true() -> None:
    page = "a: 10/10 succeeded (100.0 %, Wilson 95 % [72.2, 100.0]) over seeds 0-9\n  pose error: median 1 mm\n"
    there = page.replace("10/10 succeeded (100.0 %", "9/10 succeeded (90.0 %").replace(
        "  pose",
        "  failures: place 1 (seeds [3])\n  failures by diagnosis (perception > 5 mm off at the grasp?): "
        "perception_ok 1\n  pose",
    )
    assert differences(page, there) == []


def test_the_readme_shows_run_bench_perceive_and_profile() -> None:
    commands = [ex.command.split()[3] for page, ex in EXAMPLES if page == README]
    assert {"run", "bench", "perceive", "profile"} <= set(commands), commands


@pytest.mark.sim
@pytest.mark.parametrize(
    ("page", "example"), EXAMPLES, ids=[f"{p.relative_to(ROOT)}:{e.command.split(' --')[0]}" for p, e in EXAMPLES]
)
@pytest.mark.slow
def test_example_is_what_the_code_prints(page, example) -> None:
    problems = differences(example.output, run(example.command))
    assert not problems, f"{page.relative_to(ROOT)}'s example `{example.command}` has drifted (python " \
        f"tests/readme_examples.py --write makes it anew): " + "; ".join(problems)  # fmt: skip
