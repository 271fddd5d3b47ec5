"""Reading a scenario table into the schema: :func:`parse_scenario`, and every validation error said
in one line that names the key (an object by its name), the closest valid key, and what was wrong."""

from __future__ import annotations

import difflib
import re
from pathlib import Path

from pydantic import BaseModel, ValidationError

from pickdemo.scenario.base import MAX_NESTING, NAME_PATTERN, RESERVED_NAMES, ScenarioError, printable
from pickdemo.scenario.schema import Scenario

_NAME_RE = re.compile(NAME_PATTERN)


def _item_name(items: object, index: int) -> str | None:
    """The name of ``items[index]`` when it names the item on its own: a valid, unreserved name that
    no other item of the list has."""
    if not isinstance(items, (list, tuple)) or not 0 <= index < len(items) or not isinstance(items[index], dict):
        return None
    name = items[index].get("name")
    if not isinstance(name, str) or not _NAME_RE.fullmatch(name) or name.lower() in RESERVED_NAMES:
        return None
    if sum(1 for it in items if isinstance(it, dict) and it.get("name") == name) != 1:
        return None
    return name


def _format_loc(loc: tuple[int | str, ...], data: object) -> str:
    """A key's path as every scenario error writes it: ``objects.cube.color``, the way the checks of
    :mod:`pickdemo.scenario.checks` name it too (an object by its name; by its index, ``objects[0]``, only
    when it has no name of its own), and ``position_range[0][1]`` inside arrays."""
    parts: list[str] = []
    node = data
    for item in loc:
        if isinstance(item, int):
            name = _item_name(node, item)
            if name is not None and parts:
                parts.append(name)
            else:
                parts[-1:] = [f"{parts[-1]}[{item}]" if parts else f"[{item}]"]
            node = node[item] if isinstance(node, (list, tuple)) and 0 <= item < len(node) else None
        else:
            parts.append(printable(str(item)))
            node = node.get(item) if isinstance(node, dict) else None
    return ".".join(parts) or "(top level)"


def _model_at(loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """The schema model that the location ``loc`` (without its last key) points into."""
    model: type[BaseModel] | None = Scenario
    for item in loc[:-1]:
        if isinstance(item, int) or model is None:
            continue
        field = model.model_fields.get(str(item))
        if field is None:
            return None
        model = next((t for t in _types_in(field.annotation) if isinstance(t, type) and issubclass(t, BaseModel)), None)
    return model


def _types_in(annotation: object) -> list[object]:
    args = getattr(annotation, "__args__", None)
    if not args:
        return [annotation]
    return [t for a in args for t in _types_in(a)]


def _tuples(value: object, depth: int = 0) -> object:
    """TOML arrays as tuples (the strict schema takes tuples), and a bound on nesting."""
    if depth > MAX_NESTING:
        raise ScenarioError(f"nested more than {MAX_NESTING} levels deep")
    if isinstance(value, list):
        return tuple(_tuples(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return {k: _tuples(v, depth + 1) for k, v in value.items()}
    return value


def _data_loc(loc: tuple, data: object) -> tuple[int | str, ...]:
    """Pydantic's error location less the parts it adds (union branches, validator names): only keys
    and indices that exist in the document are kept, plus a last key that is missing or unknown."""
    out: list[int | str] = []
    node = data
    for i, item in enumerate(loc):
        if isinstance(node, dict) and isinstance(item, str) and item in node:
            out.append(item)
            node = node[item]
        elif isinstance(node, (list, tuple)) and isinstance(item, int) and 0 <= item < len(node):
            out.append(item)
            node = node[item]
        elif i == len(loc) - 1 and isinstance(item, str) and isinstance(node, dict):
            out.append(item)  # a missing key (or an unknown one) at the end
    return tuple(out)


def _close_key(loc: tuple[int | str, ...]) -> str | None:
    """The valid key an unknown key at ``loc`` most likely meant (None if none is close)."""
    model = _model_at(loc)
    valid = sorted(model.model_fields) if model is not None else []
    close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.6)
    return close[0] if close else None


def _message(err: dict, data: object, listed: set[tuple[int | str, ...]] | None = None) -> str:
    """One problem as ``path: what``. ``listed``: where the valid keys were listed already (a second
    unknown key there does not list them again)."""
    loc = _data_loc(err["loc"], data)
    where = _format_loc(loc, data)
    if err["type"] == "extra_forbidden" and loc:
        model = _model_at(loc)
        valid = sorted(model.model_fields) if model is not None else []
        close = _close_key(loc)
        if close:
            return f"{where}: unknown key (did you mean {close!r}?)"
        if not valid or (listed is not None and loc[:-1] in listed):
            return f"{where}: unknown key"
        if listed is not None:
            listed.add(loc[:-1])
        return f"{where}: unknown key (valid keys: {', '.join(valid)})"
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] == "union_tag_invalid":  # a tagged table (a fixture's kind) of no known kind
        ctx = err.get("ctx", {})
        key = ctx.get("discriminator", "kind").strip("'")
        return f"{where}.{key}: {printable(repr(ctx.get('tag')), 40)} is not one of {ctx.get('expected_tags')}"
    if not loc:
        return msg
    if err["type"] in ("float_type", "int_type", "bool_type", "string_type", "tuple_type"):
        got = err.get("input")
        shown = printable(repr(got), 40)
        hint = ' (values are not converted: write 0.1, not "0.1")' if isinstance(got, str) else ""
        if err["type"] == "int_type" and isinstance(got, float):
            hint = " (a whole number: write 640, not 640.5)"
        msg = f"{msg}, got {type(got).__name__} {shown}{hint}"
    return f"{where}: {msg}"


#: Problems of one file spelt out in its error line; any more are named by their keys only.
SHOWN_PROBLEMS = 3


def _problems(exc: ValidationError, data: object) -> str:
    """Every problem pydantic found, on one line: unknown keys first, then the rest in file order; a
    key reported missing only because a misspelling of it is there (``colour`` for ``color``) is left
    out, the misspelling's "did you mean" says it. Past :data:`SHOWN_PROBLEMS`, the others are named."""
    errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
    meant = set()
    for e in errors:
        loc = _data_loc(e["loc"], data)
        if e["type"] == "extra_forbidden" and loc:
            close = _close_key(loc)
            if close is not None:
                meant.add((*loc[:-1], close))
    kept = [e for e in errors if not (e["type"] == "missing" and _data_loc(e["loc"], data) in meant)] or errors[:1]
    listed: set[tuple[int | str, ...]] = set()
    messages = list(dict.fromkeys(_message(e, data, listed) for e in kept))
    text = "; ".join(messages[:SHOWN_PROBLEMS])
    rest = messages[SHOWN_PROBLEMS:]
    if rest:
        where = [m.split(": ", 1)[0] for m in rest]
        text += f"; {len(rest)} more at {printable(', '.join(where), 120)}"
    return text


def parse_scenario(data: dict, *, source: str = "<scenario>", default_task: str = "pick") -> Scenario:
    """Validate a scenario given as a parsed TOML table. ``default_task``: the task of a file without a
    ``task`` key ("pick"; ``pickdemo perceive`` reads such a file as "perceive")."""
    if not isinstance(data, dict):
        raise ScenarioError(f"{source}: a scenario is a TOML table, got {type(data).__name__}")
    try:
        tupled = _tuples(data)
    except ScenarioError as exc:
        raise ScenarioError(f"{source}: {exc}") from None
    if "task" not in tupled:
        tupled["task"] = default_task
    base_dir = Path(source).parent if source and not source.startswith("<") else None
    try:
        return Scenario.model_validate(tupled, context={"base_dir": base_dir})
    except ValidationError as exc:
        raise ScenarioError(f"{source}: {_problems(exc, data)}") from None
