"""The house's rules, checked on the source (no simulator): modules and classes small, imports pointing
one way with no circle, imports at the top of their modules, pybullet only in ``sim/``, one robot's
constants only in ``robot/``, and the controller's packages importing nothing of the simulator, the
episode's runtime, the referee or the scoring (the honest loop; its run-time half:
``pickdemo/runtime/honest.py``)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "pickdemo"
MAX_MODULE_LINES = 600
MAX_CLASS_LINES = 400
#: The imports inside a function: the package's Episode, loaded on first use so that the pure
#: layers (the skill, perception, the schema) import without the simulator; demos, an extra's.
LAZY = {
    ("pickdemo", "pickdemo.runtime.episode"),
    ("pickdemo", "pickdemo.runtime"),
    ("pickdemo.apps.cli", "pickdemo.apps.demos"),  # (an extra's: gymnasium, pyarrow, PyAV, h5py)
    ("pickdemo.apps.cli", "pickdemo.apps.datasets"),
    ("pickdemo.robot.robot_file", "pickdemo.robot.model_check"),  # (pinocchio: only once a robot file is read)
}
#: The Panda's names and constants: in its robot file (pickdemo/robot/robots/panda.toml), no module.
PANDA_NAMES = re.compile(r"\b(HOME_Q|FINGER_MAX_M|PALM_ABOVE_TCP_M|MAX_VELOCITY_RAD_S|MAX_ACCELERATION_RAD_S2|"
                         r"MAX_JERK_RAD_S3|MIN_POSITION_RAD|MAX_POSITION_RAD|panda_hand|panda_link\d|panda_joint\d|"
                         r"panda_finger|PANDA)\b")  # fmt: skip


#: The packages the controller is built from: what the robot runs on.
CONTROLLER_PACKAGES = ("core", "robot", "perception", "tracking", "worldmodel", "grasping", "motion", "skills")
#: ... and what they may import of pickdemo: each other, and of the scenario only what its file states
#: of the cell (a tray), never a seed's draw (``scenario.layout``), the simulator (``sim``), the episode,
#: the referee and the scoring (``runtime``), the apps or the environments.
CONTROLLER_MAY_IMPORT = (*(f"pickdemo.{p}" for p in CONTROLLER_PACKAGES), "pickdemo.scenario.tray")


def _modules() -> dict[str, tuple[Path, ast.Module]]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = (path, ast.parse(path.read_text()))
    return out


def _type_checking_nodes(tree: ast.Module) -> set[int]:
    skip = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            skip.update(id(n) for n in ast.walk(node))
    return skip


def _imports(tree: ast.Module) -> list[tuple[ast.AST, str]]:
    """(node, module) of every import of pickdemo, outside ``if TYPE_CHECKING:``."""
    skip = _type_checking_nodes(tree)
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("pickdemo"):
            out += [(node, f"{node.module}.{a.name}") for a in node.names]
        elif isinstance(node, ast.Import):
            out += [(node, a.name) for a in node.names if a.name.startswith("pickdemo")]
    return out


def test_modules_and_classes_are_small() -> None:
    big = []
    for name, (path, tree) in _modules().items():
        lines = len(path.read_text().splitlines())
        if lines > MAX_MODULE_LINES:
            big.append(f"{name}: {lines} lines")
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef) and node.end_lineno - node.lineno + 1 > MAX_CLASS_LINES:
                big.append(f"{name}.{node.name}: {node.end_lineno - node.lineno + 1} lines")
    assert not big, big


def test_imports_form_no_circle_and_sit_at_the_top() -> None:
    modules = _modules()
    graph: dict[str, set[str]] = {}
    inside = []
    for name, (_path, tree) in modules.items():
        deps = set()
        for node, target in _imports(tree):
            while target not in modules and "." in target:
                target = target.rsplit(".", 1)[0]
            if target != name:
                deps.add(target)
            if node.col_offset > 0 and (name, target) not in LAZY:
                inside.append(f"{name}:{node.lineno} imports {target}")
        graph[name] = deps
    assert not inside, inside
    # Tarjan's strongly connected components: any with more than one module is a circle
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                circles.append(sorted(comp))

    for v in graph:
        if v not in index:
            visit(v)
    assert not circles, circles


def test_only_sim_imports_pybullet_and_no_module_names_the_panda() -> None:
    for name, (path, tree) in _modules().items():
        text = path.read_text()
        simulator = {"pybullet", "pybullet_utils"}  # (pybullet_data is a data folder, no simulator)
        uses_bullet = any(
            (isinstance(n, ast.Import) and any(a.name.split(".")[0] in simulator for a in n.names))
            or (isinstance(n, ast.ImportFrom) and (n.module or "").split(".")[0] in simulator)
            for n in ast.walk(tree)
        )
        assert not uses_bullet or name.startswith("pickdemo.sim"), name
        assert not PANDA_NAMES.search(text), (name, PANDA_NAMES.search(text).group(0))


def controller_import_breaches(modules: dict[str, ast.Module]) -> list[str]:
    """Every import by a controller package's module of a pickdemo module outside what it may import."""
    out = []
    for name, tree in modules.items():
        if not name.startswith(tuple(f"pickdemo.{p}" for p in CONTROLLER_PACKAGES)):
            continue
        for node, target in _imports(tree):
            if not any(target == m or target.startswith(m + ".") for m in CONTROLLER_MAY_IMPORT):
                out.append(f"{name}:{node.lineno} imports {target}")
    return out


def test_the_controller_imports_nothing_of_the_simulator_the_runtime_or_the_scoring() -> None:
    assert not controller_import_breaches({n: t for n, (_, t) in _modules().items()})


def test_the_controller_import_rule_catches_a_planted_import() -> None:
    """The rule fails on what it forbids, however it is written (a from-import, a plain import, inside a
    function), and lets through what the controller may import."""
    planted = {
        "pickdemo.skills.pick.cheat": "from pickdemo.runtime.world import World",
        "pickdemo.perception.cheat": "import pickdemo.sim.scene",
        "pickdemo.grasping.cheat": "def f():\n    from pickdemo.scenario.layout import Placement",
        "pickdemo.tracking.cheat": "from pickdemo import run_episode",
        "pickdemo.motion.cheat": "from pickdemo.runtime import referee",
    }
    found = controller_import_breaches({n: ast.parse(src) for n, src in planted.items()})
    assert [b.split(":")[0] for b in found] == list(planted), found
    allowed = {"pickdemo.skills.ok": "from pickdemo.scenario.tray import Tray\nfrom pickdemo.core.shapes import Box"}
    assert not controller_import_breaches({n: ast.parse(src) for n, src in allowed.items()})
