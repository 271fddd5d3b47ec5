"""Property tests of the scenario loader: random and mutated documents give a valid scenario or the
project's :class:`ScenarioError`, nothing else; and a valid one runs an episode without an internal
error."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pickdemo.scenario.checks import check_scenario
from pickdemo.scenario.load import ScenarioError, load_scenario, parse_scenario, resolve_scenario_path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

BASE: dict = tomllib.loads(resolve_scenario_path("pick_cube").read_text())  # the default scenario, as a document

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)),
    max_leaves=12,
)


def _paths(doc: object, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += _paths(v, (*prefix, i))
    return out


def _copy(doc: object) -> object:
    if isinstance(doc, dict):
        return {k: _copy(v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [_copy(v) for v in doc]
    return doc


@st.composite
def mutated(draw: st.DrawFn) -> object:
    """The default scenario with a few of its parts replaced, removed or added to."""
    doc = _copy(BASE)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(doc) if p]
        path = draw(st.sampled_from(paths))
        parent = doc
        for key in path[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "delete", "add"]))
        if action == "replace":
            parent[path[-1]] = draw(values)
        elif action == "delete":
            del parent[path[-1]]
        elif isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=8))] = draw(values)
        else:
            parent.append(draw(values))
    return doc


def _load(doc: object) -> None:
    """What `load_scenario` does once the file is parsed: the schema, then the checks."""
    scenario = parse_scenario(doc, source="doc")  # type: ignore[arg-type]
    check_scenario(scenario)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(mutated(), values))
def test_loader_gives_a_scenario_or_a_scenario_error(doc: object) -> None:
    try:
        _load(doc)
    except ScenarioError as exc:
        message = str(exc)
        assert "\n" not in message and message.isprintable(), message


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=300))
def test_any_bytes_in_a_file_give_a_scenario_or_a_scenario_error(tmp_path_factory, data: bytes) -> None:
    f = Path(tmp_path_factory.mktemp("b")) / "s.toml"
    f.write_bytes(data)
    try:
        load_scenario(f)
    except ScenarioError as exc:
        assert "\n" not in str(exc)


@st.composite
def valid_variants(draw: st.DrawFn) -> dict:
    """The default scenario with its numbers moved within the ranges a user might write."""
    doc = _copy(BASE)
    obj = doc["objects"][0]
    side = draw(st.floats(0.03, 0.07))
    obj["size"] = [side, side, draw(st.floats(0.03, 0.08))]
    x0 = draw(st.floats(0.35, 0.6))
    y0 = draw(st.floats(-0.2, 0.15))
    obj["position_range"] = [[x0, x0 + draw(st.floats(0.0, 0.1))], [y0, y0 + draw(st.floats(0.0, 0.1))]]
    obj["mass"] = draw(st.floats(0.02, 0.5))
    doc["place"]["position"] = [draw(st.floats(0.35, 0.55)), draw(st.floats(0.2, 0.35))]
    doc["sim"] = {"max_sim_time_s": 40.0}
    return doc


@pytest.mark.sim
@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(valid_variants(), st.integers(0, 2**31))
@pytest.mark.slow
def test_a_valid_scenario_runs_without_an_internal_error(doc: dict, seed: int) -> None:
    from pickdemo import Stage, run_episode

    try:
        scenario = parse_scenario(doc, source="doc")
        check_scenario(scenario)
    except ScenarioError:
        assume(False)
    result = run_episode(scenario, seed)
    assert result.failure is None or result.failure.stage is not Stage.ERROR, result.failure
    assert math.isfinite(result.sim_time_s)
