"""What can be checked of a scenario without running it: geometry, reach, the camera's view.

Pure: no simulator (reach is checked with the arm's kinematics). :func:`check_scenario` raises
:class:`~pickdemo.scenario.schema.ScenarioError` naming the key and what is impossible, so that a task that
could never succeed is refused before any simulation starts (exit 2), not failed after it (exit 1).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from pickdemo.core.camera import look_at_pose, project, rendered_intrinsics
from pickdemo.core.meshes import MeshFileError, expand, read_urdf
from pickdemo.core.shapes import Mesh
from pickdemo.core.streams import spawn_rngs
from pickdemo.grasping.top_down import GraspParams
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.robot.self_geometry import hidden_by_the_base
from pickdemo.scenario.base import ScenarioError
from pickdemo.scenario.belt import ConveyorSpec
from pickdemo.scenario.fixture_checks import check_fixtures
from pickdemo.scenario.layout import LayoutError, sample_layout, sample_place, sample_round
from pickdemo.scenario.objects import ObjectSpec, PlaceSpec
from pickdemo.scenario.reach import grasp_params, reach_from_above
from pickdemo.scenario.schema import SUPPORT_TOLERANCE_M, Scenario
from pickdemo.scenario.tasks import TASK_RULES
from pickdemo.scenario.tray import Tray
from pickdemo.scenario.twins import check_twins

#: Clearance the open gripper needs around the target's narrower side (m): the grasp planner's.
GRIPPER_CLEARANCE_M = GraspParams().width_margin_m
#: Seeds whose layouts must be possible (a range that leaves no room fails on most seeds).
LAYOUT_SEEDS = range(3)
#: A clear round's pile is at most this many objects deep (their footprints over its region's).
PILE_LAYERS = 3
#: The reach checks try an object's region on this many points a side.
REACH_GRID = 5
#: Pixels the pick region keeps from the image's edges.
VIEW_MARGIN_PX = 2.0


def _region(obj: ObjectSpec) -> list[tuple[float, float]]:
    """Corners of where the object's centre may be (one point for a fixed position)."""
    if obj.position is not None:
        return [(obj.position[0], obj.position[1])]
    (x0, x1), (y0, y1) = obj.region_range  # type: ignore[misc]
    return [(x0, y0), (x0, y1), (x1, y0), (x1, y1)]


def _grid(position, position_range, n: int) -> list[tuple[float, float]]:  # noqa: ANN001
    """A fixed position, or an n x n grid over a region ((x0, x1), (y0, y1)), corners included."""
    if position is not None:
        return [(float(position[0]), float(position[1]))]
    (x0, x1), (y0, y1) = position_range
    return [(float(x), float(y)) for x in np.linspace(x0, x1, n) for y in np.linspace(y0, y1, n)]


def _reach_points(obj: ObjectSpec) -> list[tuple[float, float]]:
    """Where the object's centre may be, as the reach checks try it: a grid over its region (its
    corners alone missed a region near the base whose middle is out of reach)."""
    return _grid(obj.position, obj.region_range, REACH_GRID)


def _footprint_mm(obj: ObjectSpec) -> np.ndarray:
    """The outline (mm, float32 polygon) of an object at a fixed position seen from above, untilted."""
    x, y = obj.position[:2]  # type: ignore[index]
    pts = obj.largest_shape.outline_xy(np.radians(obj.yaw_deg or 0.0))
    return ((pts + [x, y]) * 1e3).astype(np.float32)


def check_scenario(sc: Scenario) -> None:
    """Raise :class:`ScenarioError` (``key: what is impossible``) for a scenario that cannot run."""
    _check_mesh_files(sc)
    _check_objects(sc)
    _check_place_free(sc)
    check_twins(sc)
    _check_conveyor(sc)
    check_fixtures(sc)
    TASK_CHECKS[sc.task](sc)
    _check_camera(sc)
    _check_behind_the_base(sc)
    _check_layout(sc)


def _robot(sc: Scenario) -> RobotDescription:
    """The robot a scenario runs."""
    return sc.robot_description


def _check_mesh_files(sc: Scenario) -> None:
    """Every mesh's files exist and are URDFs pickdemo can read (one line for the first bad one); a
    mesh to pick, some top-down grasp can hold."""
    robot = _robot(sc)

    for obj in sc.objects:
        if obj.shape != "mesh":
            continue
        if obj.urdf is not None:
            try:
                read_urdf(obj.urdf)
            except MeshFileError as exc:
                raise ScenarioError(f"objects.{obj.name}.urdf: {exc}") from None
        elif not obj.urdf_files:  # urdf_choice: its readable matches (a broken one is left out)
            _no_usable_file(f"objects.{obj.name}.urdf_choice", obj.urdf_choice or "")
        if obj.name in _picked(sc) and not robot.gripper.suction:  # (a cup's seal: judged on the faces seen)
            _check_mesh_holdable(obj, f"objects.{obj.name}", robot.gripper.max_opening_m - GRIPPER_CLEARANCE_M, robot)


def _no_usable_file(key: str, pattern: str) -> None:
    """Raise for a glob none of whose matches can be used: it matches nothing, or the first can't be read."""
    matched = expand(pattern, None)
    if not matched:
        raise ScenarioError(f"{key}: {pattern!r} matches no file")
    try:
        read_urdf(matched[0])
    except MeshFileError as exc:
        raise ScenarioError(f"{key}: none of its {len(matched)} matches can be read; {exc}") from None
    raise ScenarioError(f"{key}: none of its {len(matched)} matches can be read")


def _check_on_fixture(sc: Scenario, obj: ObjectSpec, key: str, r: float) -> None:
    """An object at a ``level_m`` stands wholly on one top of a fixture (a shelf's board) wherever it may
    stand: the same top under its footprint's corners."""
    for x, y in _region(obj):
        tops = {
            round(sc.surface_z(x + dx, y + dy, obj.level_m), 4)
            if _under_fixture(sc, x + dx, y + dy, obj.level_m)
            else None
            for dx in (-r, 0.0, r)
            for dy in (-r, 0.0, r)
        }
        if len(tops) != 1 or None in tops:
            raise ScenarioError(
                f"{key}.level_m: at ({x:.3f}, {y:.3f}) m its footprint ({r * 1e3:.0f} mm radius) is not wholly on "
                f"one top of a fixture at or below {obj.level_m:.3f} m"
            )


def _under_fixture(sc: Scenario, x: float, y: float, level: float) -> bool:
    return any(f.support_z(x, y, level + SUPPORT_TOLERANCE_M) is not None for f in sc.fixtures)


def _check_objects(sc: Scenario) -> None:
    table = sc.table
    fixed: list[tuple[str, np.ndarray]] = []
    for obj in sc.objects:
        key = f"objects.{obj.name}"
        r = obj.largest_shape.footprint_radius_m
        if obj.level_m is not None:
            _check_on_fixture(sc, obj, key, r)
        for x, y in _region(obj) if obj.level_m is None else ():
            if not table.holds(x, y, margin=r):
                raise ScenarioError(
                    f"{key}: at ({x:.3f}, {y:.3f}) m its footprint ({r * 1e3:.0f} mm radius) is off the table "
                    f"(x {table.center[0] - table.size[0] / 2:.2f}..{table.center[0] + table.size[0] / 2:.2f}, "
                    f"y {table.center[1] - table.size[1] / 2:.2f}..{table.center[1] + table.size[1] / 2:.2f} m)"
                )
        for x, y in _reach_points(obj):  # (a region's corners may clear the base while its middle does not)
            if np.hypot(x, y) < _robot(sc).base_radius_m + r:
                raise ScenarioError(
                    f"{key}: at ({x:.3f}, {y:.3f}) m it stands inside the robot's base "
                    f"(keep {(_robot(sc).base_radius_m + r) * 1e3:.0f} mm from the origin)"
                )
        if obj.position is not None and len(obj.position) == 3:
            h = obj.largest_shape.height_m
            if obj.position[2] < h / 2.0 - 1e-3 and not any((obj.pitch_deg, obj.roll_deg)):
                raise ScenarioError(f"{key}.position: centre z {obj.position[2]:.3f} m sinks it into the table")
        if obj.position is not None:
            mine = _footprint_mm(obj)
            for other, theirs in fixed:
                area, _ = cv2.intersectConvexConvex(mine, theirs)
                if area > 1.0:  # mm^2
                    raise ScenarioError(f"{key}: overlaps objects.{other} on the table ({area:.0f} mm^2 in common)")
            fixed.append((obj.name, mine))
    for px, py in place_points(sc.place):
        if not table.holds(px, py):
            where = "" if sc.place.position is not None else "the region reaches off the table: "
            raise ScenarioError(f"{sc.place.key}: {where}({px:.3f}, {py:.3f}) m is off the table")


def _check_place_free(sc: Scenario) -> None:
    """A fixed place spot that an object standing at a fixed position takes (the target, put down
    there, would land on it or against it) is refused: the object's footprint comes nearer the spot
    than the target's footprint radius. (A spot drawn per seed is drawn clear of the objects.)"""
    if not TASK_RULES[sc.task].places_target or sc.place.position is None:
        return
    px, py = (float(v) for v in sc.place.position[:2])
    r_mm = sc.target.largest_shape.footprint_radius_m * 1e3
    for obj in sc.objects:
        if obj.target or obj.position is None:
            continue
        inside_mm = cv2.pointPolygonTest(_footprint_mm(obj), (px * 1e3, py * 1e3), True)  # > 0: inside it
        if inside_mm > -r_mm:
            raise ScenarioError(
                f"{sc.place.key}: ({px:.3f}, {py:.3f}) m is taken: objects.{obj.name} stands there (the target "
                f"needs {r_mm:.0f} mm clear around it); put the place elsewhere or move the object"
            )


def place_points(place: PlaceSpec, n: int = 5) -> list[tuple[float, float]]:
    """The place spot, or an n x n grid over its region (corners included): where the target may be put."""
    return _grid(place.position, place.position_range, n)


def belt_sweep_mm(belt: ConveyorSpec) -> np.ndarray:
    """The footprint (mm, float32 convex polygon) the belt's slab sweeps on the table: its strip, plus
    the overhang and the overhang's travel along the belt's direction (:meth:`ConveyorSpec.slab`,
    the geometry the simulator builds the slab from)."""
    pts = np.array(belt.slab().swept_corners(), dtype=np.float64) * 1e3
    return cv2.convexHull(pts.astype(np.float32))


def _sweep_distance_mm(sweep: np.ndarray, x: float, y: float) -> float:
    """How far (mm) the point (x, y) m lies outside the swept footprint (negative: inside it)."""
    return -float(cv2.pointPolygonTest(sweep, (float(x) * 1e3, float(y) * 1e3), True))


def _sweep_text(sweep: np.ndarray) -> str:
    lo, hi = sweep.reshape(-1, 2).min(axis=0) / 1e3, sweep.reshape(-1, 2).max(axis=0) / 1e3
    return f"x {lo[0]:.2f}..{hi[0]:.2f}, y {lo[1]:.2f}..{hi[1]:.2f} m"


def _region_mm(obj: ObjectSpec, pad_mm: float = 0.5) -> np.ndarray:
    """Where the object's centre may be (mm, float32 rectangle), padded so that a fixed position or a
    range of zero width still has an area."""
    xs, ys = zip(*_region(obj), strict=True)
    x0, x1, y0, y1 = min(xs) * 1e3 - pad_mm, max(xs) * 1e3 + pad_mm, min(ys) * 1e3 - pad_mm, max(ys) * 1e3 + pad_mm
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float32)


def _grown_mm(poly: np.ndarray, radius_mm: float) -> np.ndarray:
    """A convex polygon grown by ``radius_mm`` (its Minkowski sum with a 32-gon around that circle)."""
    a = np.linspace(0.0, 2.0 * np.pi, 32, endpoint=False)
    disc = radius_mm / np.cos(np.pi / 32) * np.column_stack([np.cos(a), np.sin(a)])  # the circle fits inside
    pts = (poly.reshape(-1, 1, 2).astype(np.float64) + disc[None, :, :]).reshape(-1, 2)
    return cv2.convexHull(pts.astype(np.float32))


def _check_conveyor(sc: Scenario) -> None:
    """The belt lies on the table; an object stands wholly on it or wholly off where its slab goes; the
    place is off where its slab goes (the strip and the overhang that slides past it)."""
    belt = sc.conveyor
    if belt is None:
        return
    (x0, x1), (y0, y1) = belt.x_range_m, belt.y_range_m
    for x, y in ((x0, y0), (x1, y1)):
        if not sc.table.holds(x, y, margin=-1e-9):
            raise ScenarioError(f"conveyor: its strip x {x0:.2f}..{x1:.2f}, y {y0:.2f}..{y1:.2f} m runs off the table")
    if np.hypot(max(0.0, x0, -x1), max(0.0, y0, -y1)) < _robot(sc).base_radius_m:
        raise ScenarioError("conveyor: its strip runs through the robot's base")
    sweep = belt_sweep_mm(belt)
    slab = belt.slab()
    moves = slab.travel_m[1] > slab.travel_m[0]
    overhang = (
        f"its body is {slab.rewind_m:.2f} m longer than the strip "
        + ("and slides along it, over " if moves else "(it stands still), over ")
        + _sweep_text(sweep)
    )
    if _sweep_distance_mm(sweep, 0.0, 0.0) < _robot(sc).base_radius_m * 1e3:
        raise ScenarioError(f"conveyor: the belt runs through the robot's base ({overhang})")
    for obj in sc.objects:
        r = obj.largest_shape.footprint_radius_m
        region = _region(obj)
        on = [belt.holds(x, y, margin=r) for x, y in region]
        touching = [belt.touches(x, y, r) for x, y in region]
        if any(touching) and not all(on):
            raise ScenarioError(
                f"objects.{obj.name}: where it may stand, its footprint ({r * 1e3:.0f} mm radius) straddles the "
                "belt's edge; keep it wholly on the belt or wholly off it"
            )
        if not any(on):
            area, _ = cv2.intersectConvexConvex(_grown_mm(sweep, r * 1e3), _region_mm(obj))
            if area > 0.0:
                raise ScenarioError(
                    f"objects.{obj.name}: where it may stand, its footprint ({r * 1e3:.0f} mm radius) reaches onto "
                    f"the belt's overhang ({overhang}); keep it wholly on the strip or off that"
                )
    if TASK_RULES[sc.task].places_target:
        target = sc.target
        r = target.largest_shape.footprint_radius_m
        for px, py in place_points(sc.place):
            if belt.touches(px, py, r):
                raise ScenarioError(
                    f"{sc.place.key}: ({px:.3f}, {py:.3f}) m is on the belt (the target would ride away); place it "
                    f"at least {r * 1e3:.0f} mm off the strip"
                )
            if _sweep_distance_mm(sweep, px, py) < r * 1e3:
                raise ScenarioError(
                    f"{sc.place.key}: ({px:.3f}, {py:.3f}) m is on the belt's overhang ({overhang}): the target "
                    + ("would ride away" if moves else "would rest on it, not on the table")
                    + f"; place it at least {r * 1e3:.0f} mm off that"
                )


def _check_camera(sc: Scenario) -> None:
    cam = sc.camera
    if cam.sampled:
        return  # placed per seed around look_at, above the table by construction (elevation > 0)
    if cam.position[2] <= 0.05:
        raise ScenarioError(f"camera.position: z = {cam.position[2]:.3f} m; the camera must be above the table")
    K = rendered_intrinsics(cam.width, cam.height, cam.fov_deg[0], cam.fov_deg[1])
    T_cam_world = look_at_pose(np.array(cam.position), np.array(cam.look_at)).inverse()
    for obj in sc.objects:
        if obj.name not in {t.name for t in sc.targets}:  # (a clear round's targets: every object it lists)
            continue
        shape = obj.largest_shape
        h, r = shape.height_m, shape.footprint_radius_m
        pts = np.array([[x + dx, y + dy, sc.surface_z(x, y, obj.level_m) + z] for x, y in _region(obj) for dx in (-r, r)
                        for dy in (-r, r) for z in (0.0, h)])  # fmt: skip
        p_cam = T_cam_world.transform_points(pts)
        if np.any(p_cam[:, 2] <= cam.near_m) or np.any(p_cam[:, 2] >= cam.far_m):
            raise ScenarioError(
                f"camera: objects.{obj.name} is not in front of the camera (within near_m..far_m) everywhere "
                "it may stand"
            )
        uv = project(p_cam, K)
        m = VIEW_MARGIN_PX
        inside = (uv[:, 0] >= m) & (uv[:, 0] <= K.width - 1 - m) & (uv[:, 1] >= m) & (uv[:, 1] <= K.height - 1 - m)
        if not inside.all():
            u, v = uv[~inside][0]
            raise ScenarioError(
                f"camera: objects.{obj.name} can stand out of the camera's view (a corner of its region projects "
                f"to pixel ({u:.0f}, {v:.0f}) of {K.width}x{K.height}); aim look_at at it or widen fov_deg"
            )


def _check_behind_the_base(sc: Scenario) -> None:
    """A target that may stand where the robot's base hides its top from a fixed camera whatever the
    arm does is refused: the base's links (those no joint but the first moves) hide it at every turn
    of the first joint: no posture can show it, so the task could not succeed in those seeds."""
    cam = sc.camera
    if cam.sampled or not TASK_RULES[sc.task].one_target:
        return
    target = sc.target
    h = target.largest_shape.height_m
    tops = np.array([[x, y, sc.surface_z(x, y, target.level_m) + h] for x, y in _reach_points(target)])
    hidden = hidden_by_the_base(_robot(sc), np.array(cam.position, dtype=float), tops)
    if hidden.any():
        x, y, _ = tops[np.argmax(hidden)]
        raise ScenarioError(
            f"camera: objects.{target.name} may stand at ({x:.2f}, {y:.2f}) m, where the robot's base hides it "
            "from the camera whatever the arm does; move the camera or the region"
        )


def _check_pick(sc: Scenario) -> None:
    robot = _robot(sc)

    target = sc.target
    key = f"objects.{target.name}"
    narrow = _check_holdable(target, key, robot)
    grasp = grasp_params(robot)
    carried = grasp.transport_height_m
    if sc.success.lift_height >= carried - 0.005:
        raise ScenarioError(
            f"success.lift_height: {sc.success.lift_height:.3f} m; the arm lifts the target {carried:.3f} m, so "
            f"lift_height must stay below {carried - 0.005:.3f} m"
        )
    kin = kinematics_of(robot)
    rng = np.random.default_rng(0)
    spots = [(f"{key} at ({x:.2f}, {y:.2f})", x, y, target.level_m) for x, y in _reach_points(target)]
    spots += [(f"{sc.place.key} at ({x:.2f}, {y:.2f})" if sc.place.position is None else sc.place.key, x, y, None)
              for x, y in sc.place.spots]  # fmt: skip
    for what, x, y, level in spots:
        z = max(target.largest_shape.height_m / 2.0, grasp.min_tcp_height_m) + sc.surface_z(x, y, level)
        for dz in (0.0, grasp.pregrasp_height_m):
            reach_from_above(kin, np.array([x, y, z + dz]), rng, what, narrow)


def _check_holdable(obj: ObjectSpec, key: str, robot: RobotDescription) -> float:
    """An object the robot picks fits its open hand with the clearance the grasp planner keeps, across
    its narrower side (a mesh's: :func:`_check_mesh_holdable`, from its files), and weighs no more than
    the arm carries. Returns that side's width (0 for a mesh)."""
    opening = robot.gripper.max_opening_m
    narrow = 0.0 if obj.shape == "mesh" else obj.largest_shape.grasp_width_m
    cup = robot.gripper.cup
    smallest = obj.size or (None if obj.size_range is None else tuple(lo for lo, _ in obj.size_range))
    if cup is not None and obj.shape != "mesh" and smallest is not None:
        # a suction cup seals on a face at least as wide as it: a box's narrower side, at its smallest
        face = obj.shape_of_size(tuple(smallest)).grasp_width_m
        if face < cup.diameter_m:
            raise ScenarioError(
                f"{key}.size: its narrower side is {face * 1e3:.0f} mm; the {robot.label}'s "
                f"{cup.diameter_m * 1e3:.0f} mm cup seals only on a face at least as wide"
            )
    if cup is None and narrow > opening - GRIPPER_CLEARANCE_M:
        raise ScenarioError(
            f"{key}.size: its narrower side is {narrow * 1e3:.0f} mm; the gripper opens to {opening * 1e3:.0f} mm "
            f"and needs {GRIPPER_CLEARANCE_M * 1e3:.0f} mm of clearance, so at most "
            f"{(opening - GRIPPER_CLEARANCE_M) * 1e3:.0f} mm"
        )
    if obj.mass > robot.payload_kg:
        carries = f"the {robot.label} carries ({robot.payload_kg} kg)"
        raise ScenarioError(f"{key}.mass: {obj.mass} kg is more than {carries}")
    return narrow


def _check_mesh_holdable(target: ObjectSpec, key: str, widest_m: float, robot: RobotDescription) -> None:
    """A mesh target some top-down grasp of the hand can hold at its smallest scale (of a
    ``urdf_choice``: at least one of its files; of a seed that draws one too wide, the grasp planner
    says so from what the camera sees: nothing a seed drew is told to the robot or judged before it looks)."""
    files = target.urdf_files
    widths = []
    for path in files:
        shape = target.mesh_shape(path, target.scales[0])
        assert isinstance(shape, Mesh)
        widths.append(shape.top_down_width_m())
        if widths[-1] <= widest_m:
            return
    which = f"{key}.urdf" if target.urdf is not None else f"{key}.urdf_choice"
    what = "it is" if len(files) == 1 else f"each of its {len(files)} files is, the narrowest"
    raise ScenarioError(
        f"{which}: no top-down grasp can hold it: at scale {target.scales[0]:g} {what} {min(widths) * 1e3:.0f} mm "
        f"across where the fingers would close; the gripper opens to {robot.gripper.max_opening_m * 1e3:.0f} mm and "
        "needs "
        f"{GRIPPER_CLEARANCE_M * 1e3:.0f} mm of clearance (a smaller scale?)"
    )


def _check_layout(sc: Scenario) -> None:
    for seed in LAYOUT_SEEDS:
        try:
            rngs = spawn_rngs(seed)
            layout = sample_layout(sc, rngs["layout"], rngs["objects"])
            rules = TASK_RULES[sc.task]
            if rules.places_target:
                sample_place(sc, layout, rngs["place"])
            if rules.draws_round:
                sample_round(sc, rngs["clear"], layout)
        except LayoutError as exc:
            hint = "widen the position ranges or lower clearance_m" + (", or lower clear.count" if sc.clear else "")
            raise ScenarioError(f"layout (seed {seed}): {exc}; {hint}") from None


def _corners(box: tuple[tuple[float, float], tuple[float, float]]) -> list[tuple[float, float]]:
    (x0, x1), (y0, y1) = box
    return [(x0, y0), (x0, y1), (x1, y0), (x1, y1)]


def _check_clear(sc: Scenario) -> None:
    """A clear round: its objects' files, its region on the table, in reach and in view, room for its
    count, and a tray on the table, in reach, apart from the region."""
    robot = _robot(sc)

    spec = sc.clear
    assert spec is not None
    files = spec.files
    if not files:
        _no_usable_file("clear.objects_from", spec.objects_from)
    table, region = sc.table, spec.region
    for x, y in _corners(region):
        if not table.holds(x, y):
            raise ScenarioError(f"clear.region: its corner ({x:.3f}, {y:.3f}) m is off the table")
        if np.hypot(x, y) < _robot(sc).base_radius_m:
            raise ScenarioError(f"clear.region: its corner ({x:.3f}, {y:.3f}) m is inside the robot's base")
    radii = np.array([Mesh(f, 1.0, read_urdf(f).vertices).footprint_radius_m for f in files])
    r_min = float(radii.min()) * spec.scale_range[0]
    r_median = float(np.median(radii)) * spec.scale_range[0]
    (tx0, tx1), (ty0, ty1) = (table.center[0] - table.size[0] / 2, table.center[0] + table.size[0] / 2), (
        table.center[1] - table.size[1] / 2, table.center[1] + table.size[1] / 2)  # fmt: skip
    table_area = (tx1 - tx0) * (ty1 - ty0)
    if spec.count * np.pi * r_min**2 > table_area:
        raise ScenarioError(
            f"clear.count: {spec.count} objects of at least {2e3 * r_min:.0f} mm across do not fit on the table "
            f"({table.size[0]:.2f} x {table.size[1]:.2f} m)"
        )
    (x0, x1), (y0, y1) = region
    room = (x1 - x0 + 2.0 * r_median) * (y1 - y0 + 2.0 * r_median)
    if spec.layout == "pile" and spec.count * np.pi * r_median**2 > PILE_LAYERS * room:
        raise ScenarioError(
            f"clear.region: a pile of {spec.count} objects of {2e3 * r_median:.0f} mm across (the median) cannot "
            f"be laid out in {1e3 * (x1 - x0):.0f} x {1e3 * (y1 - y0):.0f} mm (at most {PILE_LAYERS} deep); "
            "a larger region or fewer objects"
        )
    try:
        tray = Tray.of(sc)
    except MeshFileError as exc:
        raise ScenarioError(f"place.tray: {exc}") from None
    assert tray is not None
    corners = [tray.pose.transform_points(np.array([[sx * tray.half_extents[0], sy * tray.half_extents[1], 0.0]]))[0]
               for sx in (-1, 1) for sy in (-1, 1)]  # fmt: skip
    for c in corners:
        if not table.holds(float(c[0]), float(c[1])):
            raise ScenarioError(
                f"place.position: the tray ({2e3 * tray.half_extents[0]:.0f} x {2e3 * tray.half_extents[1]:.0f} mm) "
                f"reaches off the table at ({c[0]:.3f}, {c[1]:.3f}) m"
            )
    region_mm = (np.array(_corners(region))[[0, 1, 3, 2]] * 1e3).astype(np.float32)
    tray_mm = (np.array([c[:2] for c in corners])[[0, 1, 3, 2]] * 1e3).astype(np.float32)
    area, _ = cv2.intersectConvexConvex(region_mm, tray_mm)
    if area > 0.0:
        raise ScenarioError("place.position: the tray overlaps clear.region (where the round is laid out)")
    for obj in sc.objects:  # the listed objects join the round: each must be one the robot can pick
        key, shape = f"objects.{obj.name}", obj.largest_shape
        area, _ = cv2.intersectConvexConvex(_grown_mm(_region_mm(obj), shape.footprint_radius_m * 1e3), tray_mm)
        if area > 0.0:
            raise ScenarioError(f"{key}: where it may stand reaches under the tray (place.position)")
        _check_holdable(obj, key, robot)
    kin = kinematics_of(robot)
    rng = np.random.default_rng(0)
    grasp = grasp_params(robot)
    spots = [(f"clear.region's corner ({x:.2f}, {y:.2f})", x, y, grasp.min_tcp_height_m) for x, y in _corners(region)]
    spots += [(f"objects.{o.name} at ({x:.2f}, {y:.2f})", x, y, grasp.min_tcp_height_m)
              for o in sc.objects for x, y in _reach_points(o)]  # fmt: skip
    spots += [(f"place.position: the tray's drop spot ({x:.2f}, {y:.2f})", x, y, tray.rim_z + 0.1)
              for x, y in (tray.spot(k) for k in range(len(Tray.SPOTS)))]  # fmt: skip
    for what, x, y, z in spots:
        for dz in (0.0, grasp.pregrasp_height_m):
            reach_from_above(kin, np.array([x, y, z + dz]), rng, what)
    _check_region_in_view(sc, region)


def _check_region_in_view(sc: Scenario, region: tuple[tuple[float, float], tuple[float, float]]) -> None:
    cam = sc.camera
    if cam.sampled:
        return
    K = rendered_intrinsics(cam.width, cam.height, cam.fov_deg[0], cam.fov_deg[1])
    T_cam_world = look_at_pose(np.array(cam.position), np.array(cam.look_at)).inverse()
    pts = np.array([[x, y, z] for x, y in _corners(region) for z in (0.0, 0.1)])
    p_cam = T_cam_world.transform_points(pts)
    uv = project(p_cam, K)
    m = VIEW_MARGIN_PX
    inside = (p_cam[:, 2] > cam.near_m) & (uv[:, 0] >= m) & (uv[:, 0] <= K.width - 1 - m) & (uv[:, 1] >= m)
    inside &= uv[:, 1] <= K.height - 1 - m
    if not inside.all():
        u, v = uv[~inside][0]
        raise ScenarioError(
            f"camera: clear.region is not all in the camera's view (a corner projects to pixel ({u:.0f}, {v:.0f}) "
            f"of {K.width}x{K.height}); aim look_at at it or widen fov_deg"
        )


def _picked(sc: Scenario) -> set[str]:
    """The names of the objects the robot picks: a pick's target, every object of a clear round."""
    return {o.name for o in sc.targets} if TASK_RULES[sc.task].runs_episodes else set()


def _no_checks(sc: Scenario) -> None:
    """A task with no checks of its own (``perceive``: it only looks)."""


#: Each task's own checks, by the scenario's ``task`` (:data:`~pickdemo.scenario.tasks.TASK_RULES`).
TASK_CHECKS: dict[str, Callable[[Scenario], None]] = {
    "pick": _check_pick,
    "perceive": _no_checks,
    "clear": _check_clear,
}
