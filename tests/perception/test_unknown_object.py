"""An object nobody described: segmentation by geometry, its pose from the paper's point model, and
top-down grasps sampled on its cloud, on frames ray-cast here (boxes on a table, no simulator)."""

from __future__ import annotations

import numpy as np
import pytest
from raycast import Block, render

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import Pose
from pickdemo.core.shapes import Unknown
from pickdemo.grasping.cloud import CloudGrasps, sample_grasps
from pickdemo.grasping.selection import GraspRequest
from pickdemo.grasping.top_down import GraspParams, GraspPlanningError
from pickdemo.perception import ObjectCloud, PerceptionError, PerceptionParams, TargetModel
from pickdemo.perception.unknown import (
    Clusters,
    choose_cluster,
    estimate_unknown,
    hidden_in_part,
    principal_yaw,
    segment_objects,
)
from pickdemo.robot import robot_named

ROBOT = robot_named()

MODEL = TargetModel(Unknown(), None)
MODEL_PARAMS = PerceptionParams()


def test_objects_apart_are_two_clusters_and_one_hiding_part_of_itself_is_one() -> None:
    frame = render([Block((0.45, -0.08), (0.05, 0.05, 0.04)), Block((0.55, 0.08), (0.04, 0.06, 0.03))])
    clusters = segment_objects(frame, MODEL_PARAMS)
    assert sorted(a > 30 for a in clusters.areas).count(True) == 2
    # Two parts of one object with a gap of 6 mm seen between them (a duck's head and body, the neck
    # hidden) are one; 40 mm apart, two.
    parts = [Block((0.5, 0.0), (0.03, 0.03, 0.06)), Block((0.5, 0.036), (0.04, 0.04, 0.03))]
    assert len(segment_objects(render(parts), MODEL_PARAMS).areas) == 1
    parts[1] = Block((0.5, 0.075), (0.04, 0.04, 0.03))
    assert len(segment_objects(render(parts), MODEL_PARAMS).areas) == 2


def test_the_pose_of_an_unknown_box_is_its_centre_and_its_long_axis() -> None:
    for seed, (x, y, yaw) in enumerate([(0.45, -0.05, 20.0), (0.55, 0.1, -60.0), (0.5, 0.0, 75.0)]):
        size = (0.07, 0.035, 0.04)
        est = estimate_unknown(render([Block((x, y), size, yaw)], noise=1.45e-3, seed=seed), MODEL)
        np.testing.assert_allclose(est.pose.position[:2], [x, y], atol=0.004)
        assert est.pose.position[2] == pytest.approx(0.02, abs=0.002)  # half its height
        turn = (float(np.degrees(est.pose.rpy[2])) - yaw + 90.0) % 180.0 - 90.0
        assert abs(turn) < 3.0
        assert sorted(est.top_face_size_m, reverse=True) == pytest.approx([0.07, 0.035], abs=0.004)
        assert est.cloud is not None and len(est.cloud.points) > 100 and not est.occluded
        sd = np.sqrt(np.diag(est.position_cov))  # what its view hides of its shape included: a few mm
        assert np.all(sd > 0.001) and np.all(sd < 0.005)
        frame_sd = np.sqrt(np.diag(est.frame_cov))  # from one frame to the next: a fraction of a mm
        assert np.all(frame_sd > 0.0) and np.all(frame_sd < 0.001)


def test_a_colour_named_by_the_task_is_a_cue_among_clusters() -> None:
    dark, light = (20, 20, 20), (235, 235, 235)
    frame = render(
        [Block((0.45, -0.1), (0.05, 0.05, 0.05), rgb=dark), Block((0.55, 0.1), (0.05, 0.05, 0.05), rgb=light)]
    )
    black = estimate_unknown(frame, TargetModel(Unknown(), (0.1, 0.1, 0.1)))
    white = estimate_unknown(frame, TargetModel(Unknown(), (0.9, 0.9, 0.9)))
    assert black.pose.position[1] == pytest.approx(-0.1, abs=0.005)
    assert white.pose.position[1] == pytest.approx(0.1, abs=0.005)


def test_a_size_named_by_the_task_is_a_cue_among_clusters() -> None:
    brick, bear = Block((0.45, 0.1), (0.03, 0.02, 0.03)), Block((0.55, -0.1), (0.07, 0.06, 0.09))
    frame = render([brick, bear])
    assert estimate_unknown(frame, MODEL).pose.position[1] == pytest.approx(-0.1, abs=0.01)  # no cue: the largest
    cued = TargetModel(Unknown(size_cue_m=(0.03, 0.03, 0.02)), None)
    assert estimate_unknown(frame, cued).pose.position[1] == pytest.approx(0.1, abs=0.01)


def test_a_sliver_at_the_centre_too_small_to_measure_is_passed_over_for_the_part_beside_it() -> None:
    # A heap's split left a sliver of a part nearest the region's centre: 54 pixels, 24 of them off its
    # silhouette, too few to measure a pose from; the part beside it is what the robot came to look at.
    labels = np.zeros((100, 100), dtype=np.int32)
    labels[60:84, 40:64] = 1  # the part, 576 pixels
    labels[48:54, 48:57] = 2  # the sliver, 54 pixels, over the centre (50, 50)
    clusters = Clusters(labels, np.bincount(labels.ravel())[1:])
    off_edges = labels == 1
    off_edges[49:53, 49:55] = True  # 24 of the sliver's pixels
    frame, centre = render([]), np.array([50.0, 50.0])
    assert choose_cluster(frame, clusters, MODEL, 30, centre_uv=centre) == 2  # (nearest the centre, as before)
    assert choose_cluster(frame, clusters, MODEL, 30, centre_uv=centre, measurable=off_edges) == 1
    # nothing else measurable: the sliver is still the one (its estimate then fails, naming why)
    off_edges[labels == 1] = False
    assert choose_cluster(frame, clusters, MODEL, 30, centre_uv=centre, measurable=off_edges) == 2


def test_a_part_hidden_by_something_nearer_is_a_partial_view() -> None:
    depth = np.full((60, 80), 1.2)
    mask = np.zeros(depth.shape, dtype=bool)
    mask[20:40, 20:50] = True
    depth[mask] = 1.0
    assert not hidden_in_part(depth, mask)  # the table behind it all round
    depth[25:35, 50:56] = 0.9  # something nearer beside it: the hand over it
    assert hidden_in_part(depth, mask)
    depth[25:35, 50:56] = 1.1  # something beside it but farther: it hides nothing
    assert not hidden_in_part(depth, mask)


def test_nothing_in_view_is_a_perception_error() -> None:
    with pytest.raises(PerceptionError, match="nothing stands on the table"):
        estimate_unknown(render([]), MODEL)


def test_a_principal_axis_of_a_round_spread_has_no_direction_to_speak_of() -> None:
    _, var_round = principal_yaw(np.eye(2), 1000)
    assert var_round == pytest.approx(np.pi**2 / 12.0)
    yaw, var_long = principal_yaw(np.diag([4.0, 1.0]), 1000)
    assert abs(np.sin(yaw)) < 1e-9 and var_long < 1e-3


def _cloud(block: Block, *, obstacles: list[Block] = (), frame: RGBDFrame | None = None) -> ObjectCloud:
    """The points a camera right above would see of a block (its top), and of the obstacles'."""

    def top(b: Block) -> np.ndarray:
        g = np.stack(np.meshgrid(np.linspace(-0.5, 0.5, 25), np.linspace(-0.5, 0.5, 25)), axis=-1).reshape(-1, 2)
        c, s = np.cos(np.radians(b.yaw_deg)), np.sin(np.radians(b.yaw_deg))
        xy = (g * np.array(b.size[:2])) @ np.array([[c, s], [-s, c]]) + np.array(b.centre_xy)
        return np.column_stack([xy, np.full(len(xy), b.size[2])])

    obs = np.vstack([top(o) for o in obstacles]) if obstacles else np.zeros((0, 3))
    if frame is None:
        return ObjectCloud(points=top(block), obstacles=obs, time_s=0.0)
    return ObjectCloud(top(block), obs, 0.0, frame.depth_m, frame.intrinsics, frame.T_world_cam)


def test_a_grasp_closes_across_the_narrow_side_through_the_middle() -> None:
    for yaw in (0.0, 30.0, -70.0):
        block = Block((0.5, 0.05), (0.09, 0.04, 0.05), yaw)
        best = sample_grasps(_cloud(block), 0.0, ROBOT.gripper)[0]
        np.testing.assert_allclose(best.position[:2], block.centre_xy, atol=0.004)
        closing = np.array([np.sin(best.hand_yaw_rad), -np.cos(best.hand_yaw_rad)])
        narrow = np.array([-np.sin(np.radians(yaw)), np.cos(np.radians(yaw))])  # the block's y axis
        assert abs(float(closing @ narrow)) > 0.98
        assert best.width_m == pytest.approx(0.04, abs=0.004)
        assert 0.012 <= best.above_surface_m <= 0.05 - 0.002  # between the table and its top


def test_no_grasp_of_an_object_wider_than_the_hand_every_way() -> None:
    assert sample_grasps(_cloud(Block((0.5, 0.0), (0.09, 0.09, 0.05))), 0.0, ROBOT.gripper) == []
    selector = CloudGrasps(GraspParams())
    request = GraspRequest(Pose.from_xyz_rpy(np.array([0.5, 0.0, 0.025])), MODEL, (0.45, 0.3),
                           cloud=_cloud(Block((0.5, 0.0), (0.09, 0.09, 0.05))), gripper=ROBOT.gripper)  # fmt: skip
    with pytest.raises(GraspPlanningError, match="wider than the open hand"):
        selector.hand_yaws(request)


def test_a_grasp_keeps_its_fingers_off_a_neighbour() -> None:
    block = Block((0.5, 0.0), (0.04, 0.04, 0.05))
    alone = sample_grasps(_cloud(block), 0.0, ROBOT.gripper)
    beside = sample_grasps(_cloud(block, obstacles=[Block((0.5, 0.055), (0.06, 0.03, 0.05))]), 0.0, ROBOT.gripper)
    assert len(beside) < len(alone)
    closing = np.array([[np.sin(g.hand_yaw_rad), -np.cos(g.hand_yaw_rad)] for g in beside])
    assert abs(closing[0, 1]) < 0.2  # the best closes along x, its fingers clear of the neighbour
    assert np.all(np.abs(closing[:, 1]) < 0.9)  # none closes towards it


def test_fingers_go_down_where_the_camera_saw_free_space_first() -> None:
    """Seen from the side (the camera at +x), an object's far side is hidden: the grasp that puts no
    finger behind it (closing across the line of sight) is preferred to one as good that does."""
    block = Block((0.5, 0.0), (0.045, 0.045, 0.05))
    frame = render([block])
    best = sample_grasps(_cloud(block, frame=frame), 0.0, ROBOT.gripper)[0]
    closing = np.array([np.sin(best.hand_yaw_rad), -np.cos(best.hand_yaw_rad)])
    assert abs(closing[1]) > 0.9  # across the camera's line of sight (which runs along x)


def test_the_grasp_is_planned_once_and_carried_with_the_tracked_pose() -> None:
    block = Block((0.5, 0.0), (0.08, 0.04, 0.05))
    selector = CloudGrasps(GraspParams())
    pose = Pose.from_xyz_rpy(np.array([0.5, 0.0, 0.025]))
    request = GraspRequest(pose, MODEL, (0.45, 0.3), cloud=_cloud(block), plan_id=1, gripper=ROBOT.gripper)
    first = next(selector.candidates(request))
    moved = Pose.from_xyz_rpy(np.array([0.52, 0.01, 0.025]), yaw=np.radians(90.0))
    # The same plan, carried: a newer cloud (here: none) does not re-plan it.
    request = GraspRequest(moved, MODEL, (0.45, 0.3), cloud=None, plan_id=1, gripper=ROBOT.gripper)
    carried = next(selector.candidates(request))
    dx, dy = first.grasp.position[:2] - pose.position[:2]
    np.testing.assert_allclose(carried.grasp.position[:2] - moved.position[:2], [-dy, dx], atol=1e-9)  # turned 90 deg
    turn = (np.degrees(carried.hand_yaw_rad - first.hand_yaw_rad) + 90.0) % 180.0 - 90.0  # modulo the hand's half turn
    assert abs(turn) == pytest.approx(90.0, abs=1e-6)
    assert carried.place.position[2] == pytest.approx(first.place.position[2])


def test_a_jaw_comes_down_beside_the_span_it_closes_on_whatever_the_width() -> None:
    """One jaw against a fixed one (the SO-101's): the fixed jaw's face, the TCP, comes down
    ``jaw_clearance_m`` beside what the fingers close on (a 36 mm block's side, not beside a 12 mm
    one: it came down on the block's top), and the place is reckoned with the block pressed to it."""
    jaw = robot_named("so101").gripper
    for size in ((0.036, 0.05, 0.012), (0.02, 0.05, 0.012)):
        block = Block((0.18, 0.0), size)
        request = GraspRequest(Pose.from_xyz_rpy(np.array([0.18, 0.0, 0.006])), MODEL, (0.18, 0.1),
                               cloud=_cloud(block), plan_id=1, gripper=jaw)  # fmt: skip
        plan = next(CloudGrasps(GraspParams()).candidates(request))
        closing = plan.grasp.rotation[:2, 1]  # from the fixed jaw towards the moving one
        assert abs(closing[0]) > 0.98  # across the block's narrow side
        beside = (plan.grasp.position[:2] - np.array(block.centre_xy)) @ closing
        assert beside == pytest.approx(-(size[0] / 2 + jaw.jaw_clearance_m), abs=0.003)
        pressed = (plan.place.position[:2] - np.array([0.18, 0.1])) @ closing
        assert pressed == pytest.approx(-size[0] / 2, abs=0.003)


@pytest.mark.sim
@pytest.mark.slow
def test_objects_nobody_described_are_picked_and_put_down() -> None:
    """The closed loop on a duck and on held-out test-split objects: found, measured at their centre,
    carried as high as the hand rose and put down well inside the tolerance (the success rates
    themselves are measured by the bench, ``tests/mesh_split.py``).

    Bounds from seeds 0-7 (the test's are 0-3), with room for what the robot is told of such objects to
    change: the first look's error against the truth, median duck 4.9 mm (3.7-6.7), test split 2.5
    (1.4-3.7); how high it rose (its body's origin, which turns when the object turns in the hand), the
    hand 120 mm: seeds 0-3 median duck 120.2, test split 119.6, single seeds 106-134; the place error,
    seeds 0-3 median duck 3.8 mm and test split 2.2 (single seeds up to 15.7 and 8.8), the duck over 100
    seeds median 6.2 mm and its largest success 11.4: for the median of four to pass 14 mm, two must
    land farther off than any of those 97."""
    from episodes import at_least, episodes

    from pickdemo.scenario.reach import grasp_params

    rise_mm = grasp_params(ROBOT).transport_height_m * 1e3
    for name in ("pick_duck", "pick_mesh_test"):
        rs = episodes(name, (0, 1, 2, 3))
        ok = at_least(rs, 3)
        for r in ok:
            assert r.perception is not None and r.perception.yaw_error_deg is None  # principal axes: no body yaw
            assert r.perception.position_error_mm < 25.0  # the centre of what the camera sees of it
        assert float(np.median([r.perception.position_error_mm for r in ok])) < 12.0, name
        assert abs(float(np.median([r.lift_height_mm for r in ok])) - rise_mm) < 10.0, name
        assert float(np.median([r.place_error_mm for r in ok])) < 14.0, name  # the tolerance: 20 mm


@pytest.mark.sim
def test_another_perception_method_needs_a_model() -> None:
    from episodes import episodes

    (r,) = episodes("pick_duck", (0,), method="icp")
    assert r.failure is not None and r.failure.stage.value == "perception" and "needs its model" in r.failure.reason


def test_a_box_of_black_is_not_taken_for_a_larger_white_object() -> None:
    """Grey, black and white point the same way in RGB: the segmentation of a box or cylinder by its
    colour leaves out a blob far brighter (or darker) than the target's colour."""
    from pickdemo.core.shapes import Box
    from pickdemo.perception import segment_target, world_heights

    frame = render([Block((0.45, -0.1), (0.04, 0.04, 0.04), rgb=(22, 22, 22)),
                    Block((0.55, 0.1), (0.07, 0.07, 0.06), rgb=(250, 232, 232))])  # fmt: skip
    black = TargetModel(Box((0.04, 0.04, 0.04)), (0.1, 0.1, 0.1))
    mask = segment_target(frame, black, MODEL_PARAMS, world_heights(frame))
    assert np.all(frame.rgb[mask].astype(int).max(axis=1) < 60)  # the black one, not the larger white one
