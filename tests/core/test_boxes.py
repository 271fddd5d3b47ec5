"""Oriented boxes: the separating axis test agrees with points sampled inside them, and a vertical
line finds the top of what stands under a point."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, boxes_meet, top_below


def _box(rng: np.random.Generator) -> OrientedBox:
    pose = Pose.from_xyz_rpy(
        rng.uniform(-0.4, 0.4, 3), roll=rng.uniform(-3, 3), pitch=rng.uniform(-3, 3), yaw=rng.uniform(-3, 3)
    )
    return OrientedBox(pose, -rng.uniform(0.05, 0.3, 3), rng.uniform(0.05, 0.3, 3))


def test_overlap_agrees_with_points_inside() -> None:
    rng = np.random.default_rng(3)
    meets = 0
    for _ in range(300):
        a, b = _box(rng), _box(rng)
        u = rng.uniform(0.0, 1.0, (5000, 3))
        inside = b.contains(a.pose.transform_points(a.lo + u * (a.hi - a.lo))).any()
        met = boxes_meet([a], [b])
        meets += met
        assert met or not inside  # a point of one inside the other: they meet
        assert met == boxes_meet([b], [a])
    assert 50 < meets < 250  # (both outcomes were tried)


def test_apart_along_an_edge_cross_axis() -> None:
    a = OrientedBox(Pose.from_xyz_rpy(np.zeros(3), roll=np.pi / 4), np.array([-1, -0.1, -0.1]), np.array([1, 0.1, 0.1]))
    b = OrientedBox(
        Pose.from_xyz_rpy(np.array([0, 0, 0.3]), pitch=np.pi / 4), np.array([-0.1, -1, -0.1]), np.array([0.1, 1, 0.1])
    )
    assert not boxes_meet([a], [b])
    b2 = OrientedBox(Pose.from_xyz_rpy(np.array([0, 0, 0.25]), pitch=np.pi / 4), b.lo, b.hi)
    assert boxes_meet([a], [b2])


def test_the_top_under_a_point() -> None:
    board = OrientedBox(
        Pose.from_xyz_rpy(np.array([0.0, 0.0, 0.3]), yaw=0.4), np.array([-0.2, -0.2, -0.01]), np.array([0.2, 0.2, 0.01])
    )
    floor = OrientedBox(Pose.identity(), np.array([-0.5, -0.5, -0.02]), np.array([0.5, 0.5, 0.0]))
    assert np.isclose(top_below([board, floor], 0.05, 0.05, 1.0), 0.31)
    assert np.isclose(top_below([board, floor], 0.05, 0.05, 0.2), 0.0)  # under the board: the floor
    assert top_below([board, floor], 0.9, 0.0, 1.0) is None
