"""The scenario schema's shared vocabulary: bounded number types, names, the base model (strict,
frozen, no unknown keys), :class:`ScenarioError` and how a value is shown in one line."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

PositiveFloat = Annotated[float, Field(gt=0.0)]
UnitFloat = Annotated[float, Field(ge=0.0, le=1.0)]
Coord = Annotated[float, Field(ge=-10.0, le=10.0)]  # m, a place in the world
Angle = Annotated[float, Field(ge=-720.0, le=720.0)]  # deg
Extent = Annotated[float, Field(ge=0.001, le=0.5)]  # m, an object's size: 1 mm to 50 cm
Friction = Annotated[float, Field(ge=0.0, le=5.0)]
Scale = Annotated[float, Field(gt=0.0, le=100.0)]  # a mesh's scale: positive and finite
Vec2 = tuple[Coord, Coord]
Vec3 = tuple[Coord, Coord, Coord]
#: Names: printable, no spaces or control characters (they end up in terminals, files and JUnit XML).
NAME_PATTERN = r"^[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}$"
Name = Annotated[str, Field(pattern=NAME_PATTERN)]
#: Bodies of the scene that an object may not be named after.
RESERVED_NAMES = frozenset({"robot", "table", "world", "camera", "conveyor", "tray"})
#: The names a clear round gives the objects it draws (``drawn_1``, ...): a listed object may not take one.
DRAWN_NAME = "drawn_{}"
MAX_NESTING = 16


class ScenarioError(ValueError):
    """A scenario that cannot be used; the message is one line naming the file and key."""


class Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", strict=True, allow_inf_nan=False)


def printable(text: str, limit: int = 60) -> str:
    """Text safe for one line of a terminal: control characters escaped, long text cut."""
    out = text if text.isprintable() else text.encode("unicode_escape").decode("ascii")
    return out if len(out) <= limit else out[: limit - 3] + "..."
