"""`pickdemo compare`: paired by seed, McNemar's exact test as scipy computes it, Holm's correction,
the verdicts and exit codes, and bad input in one line with exit 2 (issue 62). No simulator: runs
written as `bench` writes them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pickdemo.apps.cli import main
from pickdemo.apps.compare import compare, holm, mcnemar_exact


def _run(folder: Path, outcomes: dict[str, list[bool]], *, machine: str = "m") -> Path:
    folder.mkdir(parents=True)
    lines = []
    for scenario, ok in outcomes.items():
        for seed, success in enumerate(ok):
            failure = None if success else {"stage": "grasp", "reason": "fingers closed on nothing"}
            lines.append(json.dumps({"scenario": scenario, "seed": seed, "success": success, "failure": failure,
                                     "perception": {"position_error_mm": 1.0 + 0.1 * seed}, "place_error_mm": 2.0,
                                     "attempts": [{}], "wall_time_s": 1.0}))  # fmt: skip
    (folder / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    (folder / "run.json").write_text(json.dumps({"machine": {"cpu": machine}}))
    return folder


@pytest.mark.parametrize(
    ("only_base", "only_new"), [(0, 0), (1, 0), (3, 0), (0, 3), (5, 1), (7, 2), (10, 10), (12, 3), (1, 20), (30, 4)]
)
def test_the_exact_p_values_are_scipys(only_base: int, only_new: int) -> None:
    from scipy.stats import binomtest

    worse, better, two = mcnemar_exact(only_base, only_new)
    n = only_base + only_new
    if n == 0:
        assert (worse, better, two) == (1.0, 1.0, 1.0)
        return
    assert worse == pytest.approx(binomtest(only_base, n, 0.5, alternative="greater").pvalue, rel=1e-12)
    assert better == pytest.approx(binomtest(only_new, n, 0.5, alternative="greater").pvalue, rel=1e-12)
    assert two == pytest.approx(binomtest(only_base, n, 0.5).pvalue, rel=1e-12)


def test_holm_adjusts_step_down_and_keeps_the_order() -> None:
    assert holm([0.01, 0.04, 0.03]) == pytest.approx([0.03, 0.06, 0.06])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def test_a_run_against_itself_is_no_evidence_and_lost_seeds_are_worse(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    base = _run(tmp_path / "base", {"a": [True] * 20, "b": [True] * 18 + [False] * 2})
    same = _run(tmp_path / "same", {"a": [True] * 20, "b": [True] * 18 + [False] * 2})
    assert all(c.verdict == "no evidence" for c in compare(base, same))
    assert main(["compare", str(base), str(same)]) == 0
    # seven of a's seeds lost, none gained (p = 1/128 one-sided, 2/128 after Holm over two): worse
    new = _run(tmp_path / "new", {"a": [False] * 7 + [True] * 13, "b": [True] * 20})
    rows = {c.scenario: c for c in compare(base, new)}
    assert rows["a"].verdict == "worse" and [f["seed"] for f in rows["a"].only_base] == list(range(7))
    assert rows["a"].p_worse == pytest.approx(1 / 128) and rows["a"].p_worse_adjusted == pytest.approx(2 / 128)
    assert rows["b"].verdict == "no evidence" and len(rows["b"].only_new) == 2  # (2 gained: p = 1/4)
    md, js = tmp_path / "summary.md", tmp_path / "compare.json"
    assert main(["compare", str(base), str(new), "--markdown", str(md), "--json", str(js)]) == 1
    assert "Worse: a" in md.read_text() and json.loads(js.read_text())["worse"] == ["a"]
    assert "lost by NEW: seed 0 (grasp: fingers closed on nothing)" in capsys.readouterr().out


def test_folders_that_do_not_pair_are_refused_in_one_line(tmp_path: Path, capsys) -> None:  # noqa: ANN001
    base = _run(tmp_path / "base", {"a": [True] * 5})
    cases = {
        "other seeds": _run(tmp_path / "seeds", {"a": [True] * 6}),
        "other scenarios": _run(tmp_path / "scen", {"b": [True] * 5}),
        "another machine": _run(tmp_path / "mach", {"a": [True] * 5}, machine="other"),
    }
    empty = tmp_path / "empty"
    empty.mkdir()
    cases["an empty folder"] = empty
    cut = _run(tmp_path / "cut", {"a": [True] * 5})
    text = (cut / "episodes.jsonl").read_text()
    (cut / "episodes.jsonl").write_text(text[: len(text) - 40])
    cases["a truncated file"] = cut
    for what, folder in cases.items():
        assert main(["compare", str(base), str(folder)]) == 2, what
        err = capsys.readouterr().err.strip()
        assert err.startswith("pickdemo: error: ") and "\n" not in err and "Traceback" not in err, (what, err)
    for alpha in ("0", "1", "-0.1"):
        assert main(["compare", str(base), str(base), "--alpha", alpha]) == 2
        assert "--alpha" in capsys.readouterr().err
