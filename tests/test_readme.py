"""The README and the docs tell the truth: their example outputs are what the code prints
(``readme_examples``), and the README's two first commands are the ones a newcomer should type."""

from __future__ import annotations

import re

import pytest
from readme_examples import PAGES, README, ROOT, differences, examples, run

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
        (("3.45 s | wall", "2.06 s | wall"), "descend entered at 2.06 s"),
        (("52 frames", "39 frames"), "39 frames"),
        (("14.5 s simulated", "11.8 s simulated"), "11.8 s simulated"),
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
