"""The Gymnasium and demonstrations pages' examples run as written."""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("pyarrow")

from pickdemo.apps.cli import main  # noqa: E402

DOCS = Path(__file__).resolve().parent.parent.parent / "docs"
pytestmark = pytest.mark.sim


def _blocks(page: str, lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", (DOCS / page).read_text(), re.S)


def test_the_gymnasium_pages_examples_run(capsys: pytest.CaptureFixture[str]) -> None:
    blocks = _blocks("gymnasium.md", "python")
    assert len(blocks) == 2
    for block in blocks:
        exec(compile(block, "docs/gymnasium.md", "exec"), {})  # noqa: S102 - the docs' own example
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("['finger_contacts', 'fingers', 'joint_pos'")
    assert out[1].startswith("True ")  # the expert picked the cube


@pytest.mark.slow
def test_the_demonstrations_pages_commands_and_example_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    shown = _blocks("demonstrations.md", "console")[0] + _blocks("demonstrations.md", "text")[0]
    commands = [line[2:].split() for line in shown.splitlines() if line.startswith("$ python -m pickdemo ")]
    assert [c[3] for c in commands] == ["demos", "replay"]
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        for argv in commands:
            assert main(argv[3:] + (["--no-progress"] if argv[3] == "demos" else [])) == 0
        printed = capsys.readouterr().out
        for line in shown.splitlines():
            if line.startswith(("pick_cube:", "episode ")):  # the same words, another machine's seconds
                assert re.sub(r"[\d.]+ s\)", "", line) in re.sub(r"[\d.]+ s\)", "", printed)
        exec(compile(_blocks("demonstrations.md", "python")[0], "docs/demonstrations.md", "exec"), {})  # noqa: S102
    finally:
        os.chdir(cwd)
