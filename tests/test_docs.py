"""The docs tell the truth about the code: every scenario key with its default, every key and failure
stage of ``result.json``, every shipped scenario, links that resolve, and examples that run."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import BaseModel

from pickdemo.core.result import EpisodeResult, Stage
from pickdemo.scenario import load as schema  # (it names every section of the schema)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
EXAMPLES = DOCS / "examples"

#: The reference's sections of docs/scenarios.md and the schema's model each documents.
SECTIONS = {
    "Top level": schema.Scenario,
    "[camera]": schema.CameraSpec,
    "[wrist_camera]": schema.WristCameraSpec,
    "[table]": schema.TableSpec,
    "[[objects]]": schema.ObjectSpec,
    "[objects.reference]": schema.ReferenceSpec,
    "[place]": schema.PlaceSpec,
    "[success]": schema.SuccessSpec,
    "[control]": schema.ControlSpec,
    "[motion]": schema.MotionSpec,
    "[layout]": schema.LayoutSpec,
    "[sim]": schema.SimSpec,
    "[[disturbances]]": schema.DisturbanceSpec,
    "[conveyor]": schema.ConveyorSpec,
    "[clear]": schema.ClearSpec,
}
ROW = re.compile(r"^\| `(?P<key>[a-z_]+)` \|(?P<unit>[^|]*)\|(?P<default>[^|]*)\|", re.M)


def _reference_tables() -> dict[str, dict[str, str]]:
    """Each section's rows of docs/scenarios.md: key -> its default's cell."""
    text = (DOCS / "scenarios.md").read_text()
    text = text[text.index("## Every key") :]
    parts = re.split(r"^#{3,4} (.+)$", text, flags=re.M)
    tables = {}
    for title, body in zip(parts[1::2], parts[2::2], strict=True):
        if title in SECTIONS:
            body = body.split("\n\nThe presets")[0]  # the preset table is not a section's keys
            tables[title] = {m["key"]: m["default"].strip() for m in ROW.finditer(body)}
    return tables


def _is_table(annotation: object) -> bool:
    """A table or an array of tables (of one model, or of several told apart by a key: ``[[fixtures]]``)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return True
    inner = list(getattr(annotation, "__args__", ()) or ())
    if hasattr(annotation, "__metadata__"):  # Annotated[X, ...]
        inner.append(annotation.__origin__)
    return any(_is_table(a) for a in inner if a is not Ellipsis)


def _plain(value: object) -> object:
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    return value


def _same(documented: object, default: object) -> bool:
    if isinstance(default, list):
        return (
            isinstance(documented, list)
            and len(documented) == len(default)
            and all(_same(d, v) for d, v in zip(documented, default, strict=True))
        )
    if isinstance(default, float) and isinstance(documented, int | float) and not isinstance(documented, bool):
        return math.isclose(documented, default, rel_tol=1e-4)
    return documented == default and type(documented) is type(default)


def test_the_scenario_reference_names_every_key_with_its_default() -> None:
    tables = _reference_tables()
    assert set(tables) == set(SECTIONS), set(SECTIONS) ^ set(tables)
    problems = []
    for title, model in SECTIONS.items():
        fields = {k: f for k, f in model.model_fields.items() if not (title == "Top level" and _is_table(f.annotation))}
        rows = tables[title]
        problems += [f"{title}: `{k}` is not documented" for k in fields.keys() - rows.keys()]
        problems += [f"{title}: `{k}` is documented but is no key" for k in rows.keys() - fields.keys()]
        for key in fields.keys() & rows.keys():
            field, cell = fields[key], rows[key]
            if field.is_required():
                ok = cell == "required"
            elif field.default is None:
                ok = cell == "-"
            else:
                value = re.sub(r"\s*\(.*\)$", "", cell).strip("`")
                ok = _same(tomllib.loads(f"v = {value}")["v"], _plain(field.default))
            if not ok:
                problems.append(f"{title}: `{key}` documented with default {cell!r}, the schema's is {field.default!r}")
    assert not problems, "docs/scenarios.md: " + "; ".join(problems)


def test_result_json_explains_every_key_and_failure_stage() -> None:
    text = (DOCS / "result-json.md").read_text()
    stages = set(re.findall(r"^\| `([a-z_]+)` \|", text[text.index("## Failure stages") : text.index("## Keys")], re.M))
    assert stages == {s.value for s in Stage}
    keys = text[text.index("## Keys") :]
    documented = set(re.findall(r"`([a-z_]+)`", keys))
    result = EpisodeResult.failed("pick_cube", 0, Stage.ERROR, "x", wall_time_s=0.0).to_dict()
    assert not set(result) - documented, sorted(set(result) - documented)


def test_every_shipped_scenario_is_listed() -> None:
    text = (DOCS / "shipped-scenarios.md").read_text()
    named = set(re.findall(r"`([a-z0-9_]+)`", text))
    named |= {f"pick_conveyor{suffix}" for suffix in re.findall(r"`(_\dcms)`", text)}
    missing = sorted(p.stem for p in (ROOT / "scenarios").glob("*.toml") if p.stem not in named)
    assert not missing, f"docs/shipped-scenarios.md does not list {missing}"


def _anchors(page: Path) -> set[str]:
    """The anchors MkDocs gives a page's headings (its default slugify: lower case, words joined by -)."""
    out = set()
    for title in re.findall(r"^#+ (.+)$", page.read_text(), re.M):
        slug = re.sub(r"[^\w\s-]", "", title.lower()).strip()
        out.add(re.sub(r"[\s]+", "-", slug))
    return out


def test_every_relative_link_of_the_readme_resolves() -> None:
    """The docs' own links are checked by ``mkdocs build --strict``; the README is not part of the site."""
    text = (ROOT / "README.md").read_text()
    problems = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+://", target):
            continue
        path, _, anchor = target.partition("#")
        page = ROOT / path if path else ROOT / "README.md"
        if not page.exists():
            problems.append(f"{target}: no such file")
        elif anchor and page.suffix == ".md" and anchor not in _anchors(page):
            problems.append(f"{target}: no heading #{anchor}")
    assert not problems, problems


def test_every_code_fence_is_closed() -> None:
    """An unclosed fence turns the rest of a page into code, which no link check sees."""
    pages = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]
    odd = [str(p.relative_to(ROOT)) for p in pages if len(re.findall(r"^```", p.read_text(), re.M)) % 2]
    assert not odd, odd


def test_the_scenario_example_is_the_file_the_tests_run() -> None:
    text = (DOCS / "scenarios.md").read_text()
    assert f"```toml\n{(EXAMPLES / 'my_part.toml').read_text()}```" in text


def _pickdemo(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "pickdemo", *args], capture_output=True, text=True, cwd=cwd,
                          timeout=600, check=False)  # fmt: skip


def test_the_example_scenarios_are_valid() -> None:
    proc = _pickdemo("validate", *(str(p) for p in sorted(EXAMPLES.glob("*.toml"))))
    assert proc.returncode == 0, proc.stdout + proc.stderr


@pytest.mark.sim
def test_the_example_estimator_sees_the_cube_beside_the_papers_method() -> None:
    proc = _pickdemo(
        "perceive", "pick_cube", "--seeds", "0-2", "--methods", "paper,my_estimator:estimate", cwd=EXAMPLES
    )
    assert proc.returncode == 0, proc.stderr
    row = next(line for line in proc.stdout.splitlines() if line.startswith("my_estimator:estimate "))
    median_mm = float(row.split()[1])
    assert median_mm < 2.0, row


@pytest.mark.sim
@pytest.mark.slow
def test_the_python_examples_of_getting_started_run(capsys: pytest.CaptureFixture[str]) -> None:
    blocks = re.findall(r"```python\n(.*?)```", (DOCS / "getting-started.md").read_text(), re.S)
    assert len(blocks) == 2
    for block in blocks:
        exec(compile(block, "docs/getting-started.md", "exec"), {})  # noqa: S102 - the docs' own example
    assert " s: " in capsys.readouterr().out  # the observer saw frames


@pytest.mark.sim
@pytest.mark.slow
def test_the_example_scenario_with_its_own_mesh_is_picked() -> None:
    """Measured 20/20 over seeds 0-19 (docs/measurements/hand-camera.md): two of three seeds at least."""
    proc = _pickdemo("bench", str(EXAMPLES / "my_part.toml"), "--seeds", "0-2", "--min-success", "0.6", "--no-progress")
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
