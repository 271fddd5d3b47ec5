"""The pick's routes around what is in the way (:mod:`pickdemo.skills.pick.routes`): no simulator; a
world model's objects and the task's fixtures as the robot knows them, the shipped robots' geometry."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.robot import robot_named
from pickdemo.robot.collision import TABLE, Obstacle, robot_geometry
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.skills.pick.routes import MARGIN_M, STRAIGHT, Router, held_box, nearest_turn, rise_over
from pickdemo.worldmodel import WorldModel
from pickdemo.worldmodel.objects import TrackedObject

DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])


def _box(centre, size) -> OrientedBox:  # noqa: ANN001
    half = np.asarray(size, dtype=float) / 2.0
    return OrientedBox(Pose(np.asarray(centre, dtype=float), np.eye(3)), -half, half)


TABLE_BOX = Obstacle(TABLE, _box((0.45, 0.0, -0.025), (1.4, 1.2, 0.05)))


def _object(world: WorldModel, centre, size, *, target: bool = False) -> TrackedObject:  # noqa: ANN001
    obj = TrackedObject(
        id=world.next_id, centre=np.array([centre[0], centre[1], size[2] / 2.0]), extents=(size[0], size[1]),
        yaw_rad=0.0, top_m=size[2], colour=(0.5, 0.5, 0.5), cov=np.eye(3) * 1e-6, first_seen_s=0.0,
        last_seen_s=0.0, is_target=target,
    )  # fmt: skip
    obj.by_camera = {"camera": np.array([[centre[0], centre[1], size[2]]])}
    world.objects[obj.id] = obj
    world.next_id += 1
    return obj


def _router(name: str = "panda", fixtures=(TABLE_BOX,)) -> tuple[Router, object]:  # noqa: ANN001
    kin = kinematics_of(robot_named(name))
    return Router(kin, fixtures, np.random.default_rng(0), max_checks=20000), kin


def _q(kin, xyz, rng=None) -> np.ndarray:  # noqa: ANN001
    rng = rng or np.random.default_rng(0)
    return kin.solve(Pose(np.asarray(xyz, dtype=float), DOWN), kin.robot.home_q, rng).q


def test_a_free_way_stays_straight_and_a_wall_in_it_is_planned_around_and_named() -> None:
    wall = Obstacle("fixtures.wall", _box((0.5, 0.03, 0.1), (0.4, 0.02, 0.2)))
    router, kin = _router(fixtures=(TABLE_BOX, wall))
    qa, qb = _q(kin, (0.5, -0.2, 0.12)), _q(kin, (0.5, 0.25, 0.12))
    scene = router.scene(WorldModel())
    assert router.joint(scene, qa, _q(kin, (0.5, -0.1, 0.15)), 0.04) is STRAIGHT
    route = router.joint(scene, qa, qb, 0.04)
    assert route.failure is None and route.waypoints is not None, route
    assert "fixtures.wall" in route.note
    assert np.allclose(route.waypoints[-1], qb)
    legs = [qa, *route.waypoints]
    assert all(scene.segment_free(a, b, 0.04, 0.01) for a, b in zip(legs[:-1], legs[1:], strict=True))
    assert router.plans == 1 and len(router.seconds) == 1 and router.checks[0] > 0


def test_the_world_models_objects_are_in_the_way_but_the_target_and_a_held_box_goes_with_the_hand() -> None:
    router, kin = _router()
    world = WorldModel()
    _object(world, (0.5, 0.05, 0.0), (0.06, 0.06, 0.2))
    target = _object(world, (0.5, -0.2, 0.0), (0.05, 0.05, 0.05), target=True)
    names = router.scene(world).names
    assert "object 1" in names and f"object {target.id}" not in names
    # the target's box held under the hand: it goes where the hand goes
    grasp = Pose(np.array([0.5, -0.2, 0.025]), DOWN)
    held = held_box(world, grasp)
    assert held is not None
    in_world = grasp @ held.pose
    assert np.allclose(in_world.position, [0.5, -0.2, 0.025], atol=1e-9)
    qa = _q(kin, (0.5, -0.2, 0.1))
    qb = _q(kin, (0.5, 0.25, 0.1))
    scene = router.scene(world, held=held)
    assert router.line_blocked(scene, qa, [Pose(np.array([0.5, 0.25, 0.1]), DOWN)], 0.025) is not None
    assert router.line_blocked(router.scene(world), qa, [Pose(np.array([0.5, -0.2, 0.3]), DOWN)], 0.04) is None
    route = router.joint(scene, qa, qb, 0.025)
    assert route.waypoints is not None and route.failure is None


def test_a_goals_lowering_onto_its_place_is_checked_and_the_table_under_what_it_holds_allowed() -> None:
    router, kin = _router()
    world = WorldModel()
    _object(world, (0.5, 0.1, 0.0), (0.1, 0.1, 0.06))
    place = Pose(np.array([0.5, 0.1, 0.05]), DOWN)  # (its fingers into the box)
    q_above = _q(kin, (0.5, 0.1, 0.2))
    accept = router.accepting(router.scene(world), [place], 0.04)
    assert not accept(q_above, 0)  # (down onto another object)
    accept = router.accepting(router.scene(WorldModel()), [Pose(np.array([0.5, 0.1, 0.03]), DOWN)], 0.04)
    assert accept(q_above, 0)  # (down onto the table)


def test_a_goal_a_whole_turn_off_is_the_same_posture_the_shorter_way() -> None:
    lower, upper = np.full(3, -2.0 * np.pi), np.full(3, 2.0 * np.pi)
    q = nearest_turn(np.array([5.38, -0.5, 1.0]), np.array([-1.2, 0.0, 0.0]), lower, upper)
    assert np.allclose(q, [5.38 - 2.0 * np.pi, -0.5, 1.0])
    panda = np.array([-2.9, 2.9])  # (no room for a turn: kept)
    assert np.allclose(nearest_turn(np.array([2.5]), np.array([-2.5]), panda[:1], panda[1:]), [2.5])


def test_a_path_under_way_is_stopped_once_the_world_shows_something_in_it_and_not_for_what_stood_aside() -> None:
    """The path watch (:mod:`pickdemo.skills.pick.replan`): a joint transfer's rest, checked again when a
    view changes the world model, names what stands in it now; nothing while the way is clear, nothing
    twice for the same view, nothing past the attempt's re-plans, nothing for a Cartesian motion."""
    from types import SimpleNamespace

    from pickdemo.skills.pick.params import MachineParams
    from pickdemo.skills.pick.replan import PathWatch
    from pickdemo.skills.pick.states import State

    router, kin = _router()
    world = WorldModel()
    qa, qb = _q(kin, (0.3, -0.25, 0.25)), _q(kin, (0.3, 0.25, 0.25))
    arm = SimpleNamespace(ahead=lambda: [qb], finished=False, q=qa)
    m = SimpleNamespace(
        p=MachineParams(), state=State.APPROACH, world=world, attempt=1, arm=arm, held=None, held_at=None, plan=None,
        grip=SimpleNamespace(finger_max_m=0.04), router=router, grasp_width_m=None,
    )  # fmt: skip
    obs = SimpleNamespace(opening_m=0.08)
    watch = PathWatch()
    _object(world, (0.6, -0.3), (0.05, 0.05, 0.3))  # aside
    world.views = 1
    assert watch.blocked(m, obs) is None
    post = _object(world, (0.39, 0.0), (0.06, 0.06, 0.4))  # pushed into the way
    assert watch.blocked(m, obs) is None  # (no new view: not checked again)
    world.views = 2
    said = watch.blocked(m, obs)
    assert said is not None and said[0] is State.APPROACH and f"object {post.id}" in said[1], said  # (planned again)
    arm.ahead = lambda: []  # a Cartesian motion: not watched
    world.views = 3
    assert watch.blocked(m, obs) is None
    arm.ahead = lambda: [qb]
    for views in range(4, 4 + m.p.max_replans):
        world.views = views
        watch.blocked(m, obs)
    world.views = 99
    assert watch.blocked(m, obs) is None  # (the attempt's re-plans spent)
    m.attempt, world.views = 2, 100
    assert watch.blocked(m, obs) is not None
    m.p = MachineParams(replan_on_change=False)
    world.views = 101
    assert watch.blocked(m, obs) is None


def test_a_held_object_that_stood_on_a_board_is_held_as_tall_as_it_is_not_from_the_table_up() -> None:
    world = WorldModel()
    _object(world, (0.0, 0.57, 0.0), (0.05, 0.09, 0.14), target=True)  # (a world model's box: from the table)
    board = _box((0.0, 0.7, 0.05), (0.9, 0.9, 0.03))  # (its top 6.5 cm up)
    tcp = Pose(np.array([0.0, 0.57, 0.12]), DOWN)
    on_table, on_board = held_box(world, tcp), held_box(world, tcp, [board])
    assert on_table is not None and on_board is not None
    assert abs((on_table.hi[2] - on_table.lo[2]) - (0.14 + 0.02)) < 1e-9
    assert abs((on_board.hi[2] - on_board.lo[2]) - (0.14 - 0.065 + 0.02)) < 1e-9
    centre = (tcp @ on_board.pose).position[2]
    bottom = centre - (on_board.hi[2] - on_board.lo[2]) / 2.0
    assert abs(bottom - (0.065 - 0.01)) < 1e-9  # (grown by its margin below the board's top)


def test_a_goal_none_keeps_clear_of_by_the_margin_is_one_clear_within_the_tight_margins_before_any_other() -> None:
    from pickdemo.skills.pick import MachineParams
    from pickdemo.skills.pick.arm import ArmDriver

    kin = kinematics_of(robot_named("panda"))
    arm = ArmDriver(kin, kin.robot.home_q, 0.1, MachineParams(), np.random.default_rng(0))
    above, grasp = Pose(np.array([0.5, 0.1, 0.2]), DOWN), Pose(np.array([0.5, 0.1, 0.1]), DOWN)
    seen: list[np.ndarray] = []

    def near(q: np.ndarray, i: int) -> bool:  # (one posture of those offered: the last one asked of)
        seen.append(q)
        return len(seen) == 3

    q, _ = arm.goal(above, grasp, accept=lambda q, i: False, near=near)
    assert len(seen) >= 3 and q is not None and np.array_equal(q, seen[2])


def test_after_the_tight_margins_a_goal_clear_of_the_fixtures_alone_before_the_best_of_all() -> None:
    from pickdemo.skills.pick import MachineParams
    from pickdemo.skills.pick.arm import ArmDriver

    kin = kinematics_of(robot_named("panda"))
    arm = ArmDriver(kin, kin.robot.home_q, 0.1, MachineParams(), np.random.default_rng(0))
    above, grasp = Pose(np.array([0.5, 0.1, 0.2]), DOWN), Pose(np.array([0.5, 0.1, 0.1]), DOWN)
    seen: list[np.ndarray] = []

    def fixed(q: np.ndarray, i: int) -> bool:  # (one posture of those offered: the last one asked of)
        seen.append(q)
        return len(seen) == 2

    q, _ = arm.goal(above, grasp, accept=lambda q, i: False, near=lambda q, i: False, fixed=fixed)
    assert len(seen) >= 2 and q is not None and np.array_equal(q, seen[1])


def test_a_cups_tilted_way_into_a_bin_is_refused_clear_of_the_fixtures_where_the_upper_arm_ends_on_a_wall() -> None:
    """``suction_clear_bin`` seed 7: a cup's way in tilted 26 deg towards the arm. From the pregrasp with
    the elbow low, the descent ends with the upper arm on the bin's near wall (the cup stopped 16 mm short
    of the face); with the elbow high, clear. The world's objects are not asked of; a task without
    fixtures has no such test."""
    from pickdemo.runtime.tasks import cell_obstacles
    from pickdemo.scenario.load import load_scenario

    router, kin = _router("ur5_suction", cell_obstacles(load_scenario("suction_clear_bin")))
    approach = np.array([-0.35, -0.25, -0.90])
    approach /= np.linalg.norm(approach)
    x = np.cross([0.0, 0.0, 1.0], approach)
    x /= np.linalg.norm(x)
    rot = np.column_stack([x, np.cross(approach, x), approach])
    grasp = Pose(np.array([0.557, -0.0436, 0.0286]), rot)
    pregrasp = Pose(grasp.position - 0.1 * approach, rot)
    fixed = router.accepting_fixed([grasp], 0.0, lambda q, i: True)
    assert fixed is not None
    rng = np.random.default_rng(0)
    low = kin.solve(pregrasp, np.array([-0.04, -0.49, -0.25, -0.45, -1.81, 5.74]), rng)
    high = kin.solve(pregrasp, np.array([-0.04, -0.73, 0.25, -0.71, -1.81, 5.74]), rng)
    assert low.success and high.success and low.q[2] < 0.0 < high.q[2]  # (two branches: the elbow's sign)
    assert not fixed(low.q, 0) and fixed(high.q, 0)
    # (a line the arm would not follow as it makes it is no line checked: refused however clear)
    assert not router.accepting_fixed([grasp], 0.0, lambda q, i: False)(high.q, 0)
    assert _router("ur5_suction")[0].accepting_fixed([grasp], 0.0, lambda q, i: True) is None


def test_a_part_taken_from_a_bin_rises_over_its_walls_and_one_on_the_table_not_over_a_wall_beside_it() -> None:
    """A part held 3 cm from a tote's 12 cm wall (its floor 1 cm thick) must rise until its bottom clears
    the wall's top; the same part on the table beside a wall is the routes' to take around (no rise)."""
    floor = Obstacle("fixtures.tote", _box((0.5, 0.0, 0.005), (0.3, 0.3, 0.01)))
    tote = [floor, Obstacle("fixtures.tote", _box((0.5, 0.155, 0.06), (0.3, 0.01, 0.12)))]  # a wall, its top 0.12
    held = _box((0.5, 0.1, 0.03), (0.04, 0.04, 0.04))  # its bottom at 0.01, on the floor
    assert abs(rise_over(held, [TABLE_BOX, *tote], 0.05) - (0.12 + MARGIN_M - 0.01)) < 1e-9
    wall = Obstacle("fixtures.wall", _box((0.5, 0.155, 0.1), (0.3, 0.01, 0.2)))
    on_table = _box((0.5, 0.1, 0.02), (0.04, 0.04, 0.04))
    assert rise_over(on_table, [TABLE_BOX, wall], 0.05) == 0.0


def test_a_held_object_swung_into_the_forearm_meets_it_but_not_what_it_was_taken_touching() -> None:
    """The held object is checked against the arm's own links too (a part hanging from a tilted cup,
    carried in joint space, met the forearm and held the wrist back 17 cm short of the place), but not
    against the hand's, nor a link it touched where it was taken."""
    router, kin = _router("ur5_suction")
    g = robot_geometry(kin.robot)
    forearm = next(i for i, o in enumerate(g.geometry.geometryObjects) if o.name.startswith("forearm"))
    q_taken, q_swung = kin.robot.home_q, kin.robot.home_q + np.array([0.0, 0.0, 0.0, 1.2, 0.8, 0.0])
    # a 3 cm cube where the forearm's middle is, seen from the TCP, with the wrist swung
    data, gdata = g.model.createData(), pin.GeometryData(g.geometry)
    pin.updateGeometryPlacements(g.model, data, g.geometry, gdata, g.q(q_swung, 0.0))
    pin.updateFramePlacements(g.model, data)
    at = data.oMf[g.tcp_frame].actInv(gdata.oMg[forearm])
    held = OrientedBox(Pose(at.translation, np.eye(3)), np.full(3, -0.015), np.full(3, 0.015))
    world = WorldModel()
    assert router.scene(world, held=held).contact(q_swung, 0.0) is None  # (the arm's links unchecked)
    hit = router.scene(world, held=held, held_at=(q_taken, 0.0)).contact(q_swung, 0.0)
    assert hit is not None and hit[0].startswith("forearm") and hit[1] == "the held object"
    assert router.scene(world, held=held, held_at=(q_taken, 0.0)).free(q_taken, 0.0)
    # taken touching the forearm: that contact is allowed
    assert router.scene(world, held=held, held_at=(q_swung, 0.0)).contact(q_swung, 0.0) is None
    # the hand's links are never checked against it
    assert all(o.parentJoint != 0 for i, o in enumerate(g.geometry.geometryObjects) if i in g.hand)
    assert {g.geometry.geometryObjects[i].name.split("_")[0] for i in g.hand} == {"suction"}
