"""Whether the arm stands between the fixed camera and the table, and where it could stand instead."""

from __future__ import annotations

import numpy as np

from pickdemo.core.camera import Intrinsics, look_at_pose
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.skills.pick.params import CameraModel
from pickdemo.skills.pick.sightline import Sightline

KIN = kinematics_of(robot_named())
HOME = np.asarray(KIN.robot.home_q, dtype=float)
K = Intrinsics.from_fov(640, 480, 57.0, 43.0)


def _sight(position: tuple[float, float, float]) -> Sightline:
    return Sightline(KIN, CameraModel(K, look_at_pose(np.array(position), np.array([0.5, 0.0, 0.0]))))


def test_a_camera_over_the_shoulder_is_shown_the_table_from_aside() -> None:
    sight = _sight((-0.35, 0.1, 0.85))
    aside = sight.aside([HOME], np.random.default_rng(0))
    assert aside is not None
    q, hid, still = aside
    assert hid > 0.4 and still <= 0.5  # most of what the arm hid at home (not the base), it shows from there
    table = sight.table()
    assert sight.hidden(q, table).mean() < sight.hidden(HOME, table).mean()
    assert KIN.within_limits(q)


def test_a_camera_in_front_of_the_robot_needs_no_move() -> None:
    assert _sight((1.1, 0.0, 0.75)).aside([HOME], np.random.default_rng(0)) is None


def test_a_second_look_aside_shows_what_the_first_still_hid() -> None:
    sight = _sight((-0.35, 0.1, 0.85))
    first = sight.aside([HOME], np.random.default_rng(0))
    assert first is not None
    second = sight.aside([HOME, first[0]], np.random.default_rng(1))
    if second is not None:  # (what both hid, the second shows at least half of)
        table = sight.table()
        both = sight.hidden(HOME, table) & sight.hidden(first[0], table) & ~sight.base_hides()
        assert sight.hidden(second[0], table[both]).mean() <= 0.5


def test_what_the_base_hides_whatever_the_arm_does_is_not_looked_for_from_aside() -> None:
    """A camera behind the robot: part of the table just in front of the base is hidden by it at every
    turn of the first joint; no posture is chosen to show that, and a posture is chosen that shows
    at least half of the rest."""
    sight = _sight((-0.35, 0.1, 0.85))
    base = sight.base_hides()
    assert 0 < base.sum() < len(base)
    q, _, _ = sight.aside([HOME], np.random.default_rng(0))
    table = sight.table()
    assert sight.hidden(q, table[base]).all()  # (still hidden: the base)
