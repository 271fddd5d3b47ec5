"""Scenarios by name or path: where the shipped ones are, reading a file, and checking it.

:func:`load_scenario` reads a TOML file (a path, or the name of a shipped scenario), validates it
against the schema (:mod:`pickdemo.scenario.schema`) and, unless told not to, checks what can be checked
without running it (:mod:`pickdemo.scenario.checks`). A bad file raises :class:`ScenarioError` whose message
is one line naming the file and the offending key.

This is the scenario API the rest of pickdemo imports: the schema's types are re-exported here
(``from pickdemo.scenario.load import Scenario, ObjectSpec``), so that a caller needs one module. The
imports run one way: shapes <- schema <- layout <- checks <- scenario (none of the lower modules
imports this one). :mod:`pickdemo.scenario.checks` is imported when a check is asked for, not with this
module: it needs the geometry (pinocchio), and ``import pickdemo`` stays light.
"""

from __future__ import annotations

import codecs
import difflib
import sys
from importlib import resources
from pathlib import Path

from pickdemo.scenario.base import NAME_PATTERN, RESERVED_NAMES, ScenarioError, printable
from pickdemo.scenario.belt import BELT_ACCELERATION_M_S2, BELT_REWIND_M, MAX_TIME_STEP_S, BeltSlab, ConveyorSpec
from pickdemo.scenario.checks import check_scenario
from pickdemo.scenario.objects import ObjectSpec, PlaceSpec, ReferenceSpec, TableSpec
from pickdemo.scenario.parse import parse_scenario
from pickdemo.scenario.schema import (
    ClearSpec,
    ControlSpec,
    DisturbanceSpec,
    LayoutSpec,
    MotionSpec,
    Scenario,
    SimSpec,
    SuccessSpec,
)
from pickdemo.scenario.sensors import SENSOR_PRESETS, CameraSpec, WristCameraSpec

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on Python 3.10 only
    import tomli as tomllib

__all__ = [
    "BELT_ACCELERATION_M_S2", "BELT_REWIND_M", "MAX_FILE_BYTES", "MAX_TIME_STEP_S", "NAME_PATTERN", "RESERVED_NAMES",
    "SENSOR_PRESETS", "BeltSlab", "CameraSpec", "ClearSpec", "ControlSpec", "ConveyorSpec", "DisturbanceSpec",
    "LayoutSpec", "MotionSpec", "ObjectSpec", "PlaceSpec", "ReferenceSpec", "Scenario", "ScenarioError", "SimSpec",
    "SuccessSpec", "TableSpec", "WristCameraSpec", "builtin_scenario_dirs", "list_scenarios", "load_scenario",
    "parse_scenario", "resolve_scenario_path", "suite_scenarios",
]  # fmt: skip

MAX_FILE_BYTES = 1 << 20


def builtin_scenario_dirs() -> list[Path]:
    """Where scenario names are looked up: the installed package first, then a source checkout."""
    dirs = []
    try:
        packaged = resources.files("pickdemo") / "scenarios"
        dirs.append(Path(str(packaged)))
    except (ModuleNotFoundError, TypeError):  # pragma: no cover
        pass
    dirs.append(Path(__file__).resolve().parents[2] / "scenarios")
    return [d for d in dirs if d.is_dir()]


def list_scenarios() -> list[str]:
    names: set[str] = set()
    for d in builtin_scenario_dirs():
        names.update(p.stem for p in d.glob("*.toml"))
    return sorted(names)


def suite_scenarios() -> list[str]:
    """Names of the shipped scenarios tagged ``suite`` (what ``pickdemo bench`` runs by default).

    A shipped scenario that does not load raises :class:`ScenarioError` naming it: whether it is of
    the suite cannot be told, and a suite run without it would gate fewer scenarios than it says.
    """
    out = []
    for name in list_scenarios():
        try:
            scenario = load_scenario(name, check=False)
        except ScenarioError as exc:
            raise ScenarioError(f"shipped scenario {name!r} does not load, so the suite is unknown: {exc}") from None
        if "suite" in scenario.tags:
            out.append(name)
    return out


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """A path to a ``.toml`` file, or the name of a shipped scenario (``pick_cube``)."""
    text = str(name_or_path)
    if not text or not text.isprintable():
        raise ScenarioError(f"{printable(text) or '(empty)'}: not a scenario name or path")
    path = Path(text)
    if path.suffix == ".toml" or path.exists() or len(path.parts) > 1:
        if path.is_dir():
            raise ScenarioError(f"{path}: is a directory, not a scenario file")
        if not path.is_file():
            raise ScenarioError(f"{path}: no such scenario file")
        if path.suffix != ".toml":
            raise ScenarioError(f"{path}: not a .toml file")
        return path
    for d in builtin_scenario_dirs():
        candidate = d / f"{path.name}.toml"
        if candidate.is_file():
            return candidate
    known = list_scenarios()
    close = difflib.get_close_matches(text, known, n=1)
    hint = f"did you mean {close[0]!r}? " if close else ""
    raise ScenarioError(f"{text}: unknown scenario ({hint}known: {', '.join(known) or 'none found'})")


def load_scenario(
    name_or_path: str | Path, *, check: bool = True, default_task: str = "pick", robot: str | None = None
) -> Scenario:
    """Load and validate a scenario by name or path; raises :class:`ScenarioError` on bad input.

    With ``check`` (the default) it also runs what can be checked without running it
    (:func:`pickdemo.scenario.checks.check_scenario`: geometry, reach, the camera's view). ``default_task``:
    the task of a file that has no ``task`` key (see :func:`parse_scenario`); ``robot``: another robot
    than the file's (its ``robot`` key: a shipped robot's name or a robot file), checked as the file's.
    """
    path = resolve_scenario_path(name_or_path)
    try:
        if path.stat().st_size > MAX_FILE_BYTES:
            raise ScenarioError(f"{path}: {path.stat().st_size} bytes; a scenario file is at most {MAX_FILE_BYTES}")
        raw = path.read_bytes()
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read: {exc.strerror or exc}") from None
    for bom, enc in ((codecs.BOM_UTF32_LE, "UTF-32"), (codecs.BOM_UTF32_BE, "UTF-32"), (codecs.BOM_UTF16_LE, "UTF-16"),
                     (codecs.BOM_UTF16_BE, "UTF-16")):  # fmt: skip
        if raw.startswith(bom):
            raise ScenarioError(f"{path}: {enc} text; TOML files are UTF-8 (save it as UTF-8)")
    if b"\x00" in raw:
        raise ScenarioError(f"{path}: a binary file, not TOML text")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"{path}: not UTF-8 text (byte {exc.start}); TOML files are UTF-8") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{path}: invalid TOML: {printable(str(exc), 120)}") from None
    except RecursionError:
        raise ScenarioError(f"{path}: invalid TOML: nested too deeply") from None
    if robot is not None:
        data["robot"] = robot
    scenario = parse_scenario(data, source=str(path), default_task=default_task)
    if check:
        try:
            check_scenario(scenario)
        except ScenarioError as exc:
            raise ScenarioError(f"{path}: {exc}") from None
    return scenario
