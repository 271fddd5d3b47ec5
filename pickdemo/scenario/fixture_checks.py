"""What ``validate`` checks of a scenario's fixtures (:mod:`pickdemo.scenario.fixtures`) before it runs:
each stands clear of the robot's base, of the other fixtures and of the tray; a bin stands on the
table, the arm reaches into it from above, and no place spot and no object at a fixed position is on
its walls; a model (a shelf) is not inside the table's slab, and no place spot or object at a fixed
position is inside it.

Pure: no simulator (reach is checked with the arm's kinematics). Each check raises
:class:`~pickdemo.scenario.base.ScenarioError` naming the fixture's key.
"""

from __future__ import annotations

import cv2
import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, boxes_meet
from pickdemo.robot.collision import CollisionScene, Obstacle, robot_geometry
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.scenario.base import ScenarioError
from pickdemo.scenario.fixtures import BinSpec, ModelSpec
from pickdemo.scenario.objects import TABLE_THICKNESS_M
from pickdemo.scenario.reach import grasp_params, reach_from_above
from pickdemo.scenario.schema import SUPPORT_TOLERANCE_M, Scenario
from pickdemo.scenario.tasks import TASK_RULES
from pickdemo.scenario.tray import Tray

#: The arm must reach into a bin this far inside its walls, at each corner and the middle (m).
REACH_INSET_M = 0.03


def _mm(poly: np.ndarray) -> np.ndarray:
    return (np.asarray(poly, dtype=float) * 1e3).astype(np.float32)


def _overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether two convex footprints (m, (4, 2)) share area."""
    area, _ = cv2.intersectConvexConvex(_mm(a), _mm(b))
    return area > 1.0  # mm^2: touching edges are not an overlap


def _tray_footprint(tray: Tray) -> np.ndarray:
    hx, hy = tray.half_extents
    local = np.array([[-hx, -hy, 0.0], [hx, -hy, 0.0], [hx, hy, 0.0], [-hx, hy, 0.0]])
    return tray.pose.transform_points(local)[:, :2]


def check_fixtures(sc: Scenario) -> None:
    """Raise :class:`ScenarioError` for a fixture that cannot stand where the scenario puts it."""
    if not sc.fixtures:
        return
    robot = sc.robot_description
    tray = Tray.of(sc)
    for i, f in enumerate(sc.fixtures):
        key = f"fixtures.{f.name}"
        corners = f.footprint()
        if f.kind == "bin" and not all(sc.table.holds(float(x), float(y)) for x, y in corners):
            raise ScenarioError(f"{key}.position: the {f.kind} at {_xy(f)} reaches past the table's edge")
        base = cv2.pointPolygonTest(_mm(corners), (0.0, 0.0), True) * 1e-3  # > 0: the base inside it
        if base > -robot.base_radius_m:
            raise ScenarioError(
                f"{key}.position: the {f.kind} at {_xy(f)} stands on the robot's base (keep its walls "
                f"{robot.base_radius_m * 1e3:.0f} mm from the origin)"
            )
        for other in sc.fixtures[:i]:
            if _overlap(corners, other.footprint()):
                raise ScenarioError(f"{key}.position: the {f.kind} at {_xy(f)} overlaps fixtures.{other.name}")
        if tray is not None and _overlap(corners, _tray_footprint(tray)):
            raise ScenarioError(f"{key}.position: the {f.kind} at {_xy(f)} overlaps the tray (place.tray)")
        if f.kind == "bin":
            _check_reach(sc, f, key)
            _check_walls_free(sc, f, key)
        else:
            _check_model(sc, f, key)
        _check_home_clear(sc, f, key)
    _check_not_enclosed(sc)


def _xy(f: BinSpec | ModelSpec) -> str:
    return f"({f.position[0]:.3f}, {f.position[1]:.3f})"


def _check_reach(sc: Scenario, f: BinSpec, key: str) -> None:
    """The hand, pointing down, reaches the bin's floor at its corners (``REACH_INSET_M`` inside the
    walls) and its middle, at some hand angle."""
    robot = sc.robot_description
    kin = kinematics_of(robot)
    ix, iy = (max(s / 2.0 - REACH_INSET_M, 0.0) for s in f.inner_size)
    z = f.floor_z + grasp_params(robot).min_tcp_height_m
    rng = np.random.default_rng(0)
    for lx, ly in ((-ix, -iy), (ix, -iy), (ix, iy), (-ix, iy), (0.0, 0.0)):
        at = f.pose.transform_points(np.array([[lx, ly, z]]))[0]
        reach_from_above(kin, at, rng, f"{key}: its floor at ({at[0]:.2f}, {at[1]:.2f})")


def _standing(sc: Scenario) -> list[tuple[str, float, float, float, float | None]]:
    """What will stand at a fixed spot, for the fixtures to keep clear of: the place's spots (where the
    target is put down on the table, not into a tray) and every object at a fixed position, on the
    table or on a fixture's top (a mesh's size is its file's: the layout's check). Each as (its key,
    x, y, its footprint's radius, its ``level_m``: None on the table)."""
    spots: list[tuple[str, float, float, float, float | None]] = []
    if sc.place.tray is None and TASK_RULES[sc.task].places_target:
        r = sc.target.largest_shape.footprint_radius_m
        spots += [(sc.place.key, x, y, r, None) for x, y in sc.place.spots]
    spots += [
        (f"objects.{o.name}.position", o.position[0], o.position[1], o.largest_shape.footprint_radius_m, o.level_m)
        for o in sc.objects
        if o.position is not None and o.shape != "mesh"
    ]
    return spots


def _check_walls_free(sc: Scenario, f: BinSpec, key: str) -> None:
    """No place spot and no object standing at a fixed position is on the bin's walls or against them:
    the target put down there, or the object, would stand on a wall (inside the bin clear of them, or
    outside clear of them, is fine)."""
    outer = _mm(f.footprint())
    for what, x, y, r, _level in _standing(sc):
        off = cv2.pointPolygonTest(outer, (float(x) * 1e3, float(y) * 1e3), True) * 1e-3  # > 0: inside
        if off > -r and not f.inside(float(x), float(y), margin=r):
            raise ScenarioError(
                f"{what}: ({x:.3f}, {y:.3f}) m is on or against the walls of {key} (what stands there needs "
                f"{r * 1e3:.0f} mm clear around it)"
            )


#: A model may stand on the table's top: only this far into the slab is an overlap (m).
TABLE_TOUCH_M = 0.001


def _check_model(sc: Scenario, f: ModelSpec, key: str) -> None:
    """A model is not inside the table's slab (it may stand on the table, or beside it), and no place
    spot and no object standing at a fixed position is inside it or against it, on the table or on a
    fixture's top (``level_m``: a shelf's board; the model's boxes no higher than that top are under
    it, holding it up, not against it)."""
    boxes = f.boxes()
    t = sc.table
    slab = OrientedBox(
        Pose(np.array([t.center[0], t.center[1], 0.0]), np.eye(3)),
        np.array([-t.size[0] / 2.0, -t.size[1] / 2.0, -TABLE_THICKNESS_M]),
        np.array([t.size[0] / 2.0, t.size[1] / 2.0, -TABLE_TOUCH_M]),
    )
    if boxes_meet(boxes, [slab]):
        raise ScenarioError(f"{key}.position: the model at {_xy(f)} reaches into the table (raise it or move it aside)")
    for what, x, y, r, level in _standing(sc):
        base = 0.0 if level is None else sc.surface_z(x, y, level)
        grown = f.boxes(grown_m=r)
        if level is not None:  # on a top: the boxes no higher than it are under it
            grown = tuple(
                g for g, b in zip(grown, boxes, strict=True) if b.corners()[:, 2].max() > base + SUPPORT_TOLERANCE_M
            )
        column = np.array([[x, y, base + dz] for dz in (0.005, 0.02, 0.05, 0.1)])  # what stands there, up its height
        if any(b.contains(column).any() for b in grown):
            raise ScenarioError(
                f"{what}: ({x:.3f}, {y:.3f}) m is inside or against {key} (what stands there needs "
                f"{r * 1e3:.0f} mm clear around it)"
            )


def _check_home_clear(sc: Scenario, f: BinSpec | ModelSpec, key: str) -> None:
    """The robot at its home posture (where every episode starts) stands clear of the fixture, by its
    links' collision geometry."""
    robot = sc.robot_description
    scene = CollisionScene(robot_geometry(robot), [Obstacle(key, b) for b in f.boxes()])
    hit = scene.contact(robot.home_q, robot.gripper.finger_max_m)
    if hit is not None:
        raise ScenarioError(f"{key}.position: the {f.kind} at {_xy(f)} meets the robot's {hit[0]} at its home posture")


#: The ways a hand can come to a target: from above, and from each side across the table.
APPROACHES = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, -1.0, 0.0))
#: A way is closed when a fixture stands in it within this far (m) ...
CLOSED_WITHIN_M = 0.6
#: ... looked for every this far along it (m).
CLOSED_STEP_M = 0.005


def _check_not_enclosed(sc: Scenario) -> None:
    """A target that fixtures enclose on every side a hand can come from (above, and the four sides;
    a hand that grasps only from above, as a jaw's or a suction cup's: above), wherever its range puts
    it, cannot be picked: refused before it runs."""
    boxes = [b for f in sc.fixtures for b in f.boxes()]
    target = next((o for o in sc.objects if o.target), None)
    if not boxes or target is None:
        return
    rng = target.region_range
    if rng is None:
        assert target.position is not None
        spots = [tuple(target.position)]
    else:
        (x0, x1), (y0, y1) = rng
        spots = [(x0, y0), (x0, y1), (x1, y0), (x1, y1), ((x0 + x1) / 2.0, (y0 + y1) / 2.0)]
    steps = np.arange(CLOSED_STEP_M, CLOSED_WITHIN_M, CLOSED_STEP_M)[:, None]
    robot = sc.robot_description
    ways = APPROACHES if robot.grasps_any_side else APPROACHES[:1]
    for x, y in spots:
        z = (target.level_m or 0.0) + 0.02  # (about its middle, on what it stands on)
        at = np.array([x, y, z])
        if not all(any(b.contains(at + steps * np.array(d)).any() for b in boxes) for d in ways):
            return
    x, y = spots[-1]
    if len(ways) == 1:
        hand = "a suction cup" if robot.gripper.suction else "its hand"
        raise ScenarioError(
            f"objects.{target.name}: at ({x:.3f}, {y:.3f}) m a fixture stands over it, and the {robot.label} takes "
            f"a part only from above ({hand}: no grasp from the side)"
        )
    raise ScenarioError(
        f"objects.{target.name}: at ({x:.3f}, {y:.3f}) m the fixtures enclose it on every side a hand can "
        "come from (above and the four sides across the table): no approach can reach it"
    )
