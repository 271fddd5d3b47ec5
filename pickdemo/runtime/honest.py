"""The honest loop, checked while it runs: the controller holds nothing of the simulator or the scoring.

The controller may be told only what a real cell's would be (the docs' architecture page): images,
depth, the cameras' intrinsics and poses, joint states, finger contacts, and of its task what the
scenario file says. The import rule in ``tests/test_house.py`` keeps its modules from importing the
simulator, the episode's runtime or the referee; this check covers what the import rule cannot see:
an object handed to it at run time (a World, a Scene, a referee's bound method, a seed's layout).

:func:`truth_in` walks everything an object holds (attributes, containers, closures, bound methods'
owners, partials) and names the first object of a forbidden module it reaches. The episode calls it on
its task's controller when it is built and again when the loop ends, and on every estimate handed
to it (:class:`TruthLeak`, a bug: the episode ends in ``error`` with its traceback).
"""

from __future__ import annotations

import enum
import functools
import types
from collections import deque

import numpy as np

#: Modules whose objects carry the simulator's truth or the scoring: never reachable from the controller.
#: (An app's own objects may be: ``profile`` times the controller's parts by wrapping them, and its timers
#: hold nothing of the truth; what they hold is walked like the rest.)
FORBIDDEN_MODULES = (
    "pickdemo.sim",
    "pickdemo.runtime",
    "pickdemo.envs",
    "pickdemo.scenario.layout",  # a seed's draw: where each object stands, which mesh at which scale
    "pybullet",
)
_LEAVES = (str, bytes, bytearray, int, float, complex, bool, type(None), np.ndarray, np.generic, type,
           types.ModuleType, enum.Enum, range, memoryview)  # fmt: skip


class TruthLeak(AssertionError):
    """The controller holds an object of the simulator or the scoring: a bug of the harness."""


def _module_of(obj: object) -> str:
    return getattr(type(obj), "__module__", None) or ""


def _children(obj: object, path: str) -> list[tuple[object, str]]:
    """What ``obj`` holds, each with its path from the root."""
    if isinstance(obj, dict):
        return [(k, f"{path}.keys()") for k in obj] + [(v, f"{path}[{k!r}]") for k, v in obj.items()]
    if isinstance(obj, (list, tuple, set, frozenset, deque)):
        return [(v, f"{path}[{i}]") for i, v in enumerate(obj)]
    if isinstance(obj, functools.partial):
        return [(obj.func, f"{path}.func"), (obj.args, f"{path}.args"), (obj.keywords, f"{path}.keywords")]
    if isinstance(obj, types.MethodType):
        return [(obj.__self__, f"{path}.__self__"), (obj.__func__, f"{path}.__func__")]
    if isinstance(obj, types.FunctionType):  # its closure and defaults; not its module's globals
        cells = [(c.cell_contents, f"{path}.<closure {name}>")
                 for name, c in zip(obj.__code__.co_freevars, obj.__closure__ or (), strict=True)
                 if c.cell_contents is not c]  # fmt: skip
        return [*cells, (obj.__defaults__, f"{path}.__defaults__"), (obj.__kwdefaults__, f"{path}.__kwdefaults__")]
    if isinstance(obj, types.BuiltinMethodType):
        owner = getattr(obj, "__self__", None)
        return [] if owner is None or isinstance(owner, types.ModuleType) else [(owner, f"{path}.__self__")]
    out = []
    attrs = getattr(obj, "__dict__", None)
    if isinstance(attrs, dict):
        out += [(v, f"{path}.{k}") for k, v in attrs.items()]
    for cls in type(obj).__mro__:
        slots = getattr(cls, "__slots__", ())
        for name in (slots,) if isinstance(slots, str) else slots:  # (a single slot may be a bare string)
            if hasattr(obj, name) and name not in ("__dict__", "__weakref__"):
                out.append((getattr(obj, name), f"{path}.{name}"))
    return out


def truth_in(root: object, name: str = "controller") -> str | None:
    """The path to the first object of a :data:`FORBIDDEN_MODULES` module that ``root`` holds, with its
    type (``"controller.on_pick_end.__self__: a pickdemo.runtime.referee.ClearReferee"``); None: none."""
    seen: set[int] = set()
    todo: list[tuple[object, str]] = [(root, name)]
    while todo:
        obj, path = todo.pop()
        if id(obj) in seen:
            continue
        seen.add(id(obj))
        module = _module_of(obj)
        if module.startswith(FORBIDDEN_MODULES):
            return f"{path}: a {module}.{type(obj).__qualname__}"
        if isinstance(obj, _LEAVES):
            continue
        todo.extend(reversed(_children(obj, path)))
    return None


def check_honest(given: object) -> None:
    """Raise :class:`TruthLeak` when ``given`` (the controller, or what it is handed: an estimate, an
    observation) holds anything of the simulator or the scoring."""
    leak = truth_in(given, type(given).__name__)
    if leak is not None:
        raise TruthLeak(f"the controller holds or is handed what a real robot has not: {leak}")
