"""docs/robot-file.md names every key the robot-file reader takes, with its default, section by
section (as tests/test_docs.py holds docs/scenarios.md to the scenario schema): a key added to the
reader without a row there fails here."""

from __future__ import annotations

import math
import re
from pathlib import Path

import tomllib
from pydantic import BaseModel

from pickdemo.robot.robot_file import SECTIONS

PAGE = Path(__file__).resolve().parents[2] / "docs" / "robot-file.md"
ROW = re.compile(r"^\| `(?P<key>[a-z_]+)` \|(?P<unit>[^|]*)\|(?P<default>[^|]*)\|", re.M)


def _tables() -> dict[str, dict[str, str]]:
    text = PAGE.read_text()
    text = text[text.index("## Every key") :]
    parts = re.split(r"^### (.+)$", text, flags=re.M)
    return {title: {m["key"]: m["default"].strip() for m in ROW.finditer(body)}
            for title, body in zip(parts[1::2], parts[2::2], strict=True)}  # fmt: skip


def _is_table(annotation: object) -> bool:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return True
    return any(_is_table(a) for a in getattr(annotation, "__args__", ()) or ())


def _same(documented: object, default: object) -> bool:
    if isinstance(default, list):
        return isinstance(documented, list) and len(documented) == len(default) and all(
            _same(d, v) for d, v in zip(documented, default, strict=True))  # fmt: skip
    if isinstance(default, float) and isinstance(documented, int | float) and not isinstance(documented, bool):
        return math.isclose(documented, default, rel_tol=1e-9)
    return documented == default and type(documented) is type(default)


def test_the_robot_file_reference_names_every_key_with_its_default() -> None:
    tables = _tables()
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
                value = cell.strip("`")
                ok = _same(tomllib.loads(f"v = {value}")["v"], field.default)
            if not ok:
                problems.append(f"{title}: `{key}` documented with default {cell!r}, the reader's is {field.default!r}")
    assert not problems, "docs/robot-file.md: " + "; ".join(problems)


def test_the_page_is_in_the_site_nav() -> None:
    assert "robot-file.md" in (PAGE.parents[1] / "mkdocs.yml").read_text()
