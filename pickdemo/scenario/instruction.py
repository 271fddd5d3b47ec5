"""A scenario's task as an instruction a language-conditioned policy takes ("pick up the red cube and put
it at x 0.45 m, y 0.30 m"): the scenario's ``instruction`` where it sets one, else made from its target
(its colour's nearest plain name, its shape, its size where the seeds do not change it) and its place.
Pure: what the scenario file says, nothing drawn per seed."""

from __future__ import annotations

import numpy as np

from pickdemo.scenario.objects import ObjectSpec
from pickdemo.scenario.schema import Scenario

#: Plain colour names and their RGB (0-1): an object's colour is called by the nearest.
COLOURS = {
    "red": (0.85, 0.1, 0.1),
    "green": (0.1, 0.7, 0.2),
    "blue": (0.1, 0.2, 0.85),
    "yellow": (0.9, 0.85, 0.1),
    "orange": (0.95, 0.5, 0.1),
    "purple": (0.5, 0.15, 0.6),
    "pink": (0.95, 0.5, 0.7),
    "cyan": (0.1, 0.8, 0.85),
    "brown": (0.5, 0.3, 0.15),
    "white": (0.95, 0.95, 0.95),
    "grey": (0.5, 0.5, 0.5),
    "black": (0.08, 0.08, 0.08),
}


def colour_name(rgb: tuple[float, float, float]) -> str:
    """The plain name nearest to ``rgb`` (0-1 each)."""
    c = np.asarray(rgb, dtype=float)
    return min(COLOURS, key=lambda name: float(np.sum((np.asarray(COLOURS[name]) - c) ** 2)))


def _thing(o: ObjectSpec) -> str:
    """What the object is called: its colour, its size where fixed, its shape's word."""
    words = [colour_name(o.color)] if o.color is not None else []
    if o.shape == "box":
        cube = o.size is not None and max(o.size) - min(o.size) < 1e-9
        if cube:
            words.append(f"{o.size[0] * 100:g} cm")
        words.append("cube" if cube else "box")
    elif o.shape == "cylinder":
        words.append("cylinder")
    else:
        words.append("object")
    return " ".join(words)


def instruction(sc: Scenario) -> str:
    """The scenario's task as an instruction (see the module)."""
    if sc.instruction:
        return sc.instruction
    place = sc.place
    if place.tray is not None:
        where = "in the tray"
    elif place.position is not None:
        where = f"at x {place.position[0]:.2f} m, y {place.position[1]:.2f} m"
    else:
        where = "at its place"
    if sc.task == "clear":
        return f"pick up every object on the table and put it {where}"
    target = next((o for o in sc.objects if o.target), sc.objects[0] if sc.objects else None)
    thing = "the object" if target is None else f"the {_thing(target)}"
    return f"pick up {thing} and put it {where}"
