"""Suction grasps from a cloud (no simulator): a seal where the face is under the rim all round, none
over an edge or on a face narrower than the cup, a tilted face approached along its normal, a hidden
side offered after the faces seen all round, and the weight's load judged."""

from __future__ import annotations

import numpy as np

from pickdemo.grasping.suction import SuctionParams, sample_suction, suction_plan
from pickdemo.grasping.top_down import GraspParams
from pickdemo.robot.suction import Cup

CUP = Cup(diameter_m=0.016, stroke_m=0.008, bellows_force_n=6.0, vacuum_kpa=60.0)


def _top(width: float, depth: float, z: float, step: float = 0.002, tilt_deg: float = 0.0) -> np.ndarray:
    """A box's top face as a camera samples it: a grid of points, tilted about y."""
    xs, ys = np.meshgrid(np.arange(-width / 2, width / 2 + 1e-9, step), np.arange(-depth / 2, depth / 2 + 1e-9, step))
    pts = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    t = np.radians(tilt_deg)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    return pts @ rot.T + [0.5, 0.0, z]


def test_a_flat_top_seals_near_its_middle() -> None:
    seals = sample_suction(_top(0.05, 0.04, 0.03), np.zeros((0, 3)), 0.0, CUP)
    assert seals and np.hypot(*(seals[0].position[:2] - [0.5, 0.0])) < 0.006
    assert seals[0].tilt_rad < np.radians(2.0) and seals[0].load < 1.0


def test_no_seal_on_a_face_narrower_than_the_cup_or_over_its_edge() -> None:
    assert not sample_suction(_top(0.01, 0.05, 0.03), np.zeros((0, 3)), 0.0, CUP)  # a 10 mm strip
    # none whose rim overhangs more than the planner allows: its slack, and a sector's farthest point off
    # its middle (8 sectors: up to 45 deg off an edge's normal)
    reach = (CUP.radius_m - SuctionParams().rim_slack_m) * np.cos(np.pi / 4)
    over = CUP.radius_m - reach
    for g in sample_suction(_top(0.05, 0.04, 0.03), np.zeros((0, 3)), 0.0, CUP):
        assert abs(g.position[0] - 0.5) <= 0.025 - CUP.radius_m + over + 1e-9
        assert abs(g.position[1]) <= 0.02 - CUP.radius_m + over + 1e-9


def test_a_tilted_face_is_approached_along_its_normal() -> None:
    seals = sample_suction(_top(0.05, 0.05, 0.03, tilt_deg=30.0), np.zeros((0, 3)), 0.0, CUP)
    assert seals and abs(np.degrees(seals[0].tilt_rad) - 30.0) < 2.0
    plan = suction_plan(seals[0], np.array([0.5, 0.0, 0.02]), 0.0, (0.3, 0.3), GraspParams(), SuctionParams())
    approach = plan.grasp.rotation[:, 2]
    assert np.dot(approach, -seals[0].normal) > 0.999  # into the face
    assert np.allclose(plan.place.rotation[:, 2], [0, 0, -1])  # put down with the cup level again
    steep = sample_suction(_top(0.05, 0.05, 0.03, tilt_deg=60.0), np.zeros((0, 3)), 0.0, CUP)
    assert not steep  # beyond the 45 deg the cup comes at


def test_something_in_the_cups_way_down_is_no_seal() -> None:
    top = _top(0.05, 0.04, 0.03)
    post = np.column_stack([np.full(30, 0.5), np.full(30, 0.0), np.linspace(0.05, 0.2, 30)])  # over the middle
    seals = sample_suction(top, post, 0.0, CUP)
    assert all(np.hypot(*(g.position[:2] - [0.5, 0.0])) > CUP.radius_m for g in seals)


def test_a_side_hidden_from_the_camera_is_offered_after_those_seen_all_round() -> None:
    top = _top(0.05, 0.04, 0.03)
    strip = top[top[:, 0] < 0.486]  # a 10 mm strip of the face seen, narrower than the cup; the rest ...
    seen_free = sample_suction(strip, np.zeros((0, 3)), 0.0, CUP, unknown=lambda p: np.zeros(len(p), bool))
    assert not seen_free  # ... seen to be free: over the edge, no seal
    hidden = sample_suction(strip, np.zeros((0, 3)), 0.0, CUP, unknown=lambda p: p[:, 0] > 0.486)
    assert hidden  # ... hidden from the camera: the face may go on, a seal offered
    assert min(g.cost for g in hidden) > min(g.cost for g in sample_suction(top, np.zeros((0, 3)), 0.0, CUP))


def test_a_part_too_heavy_for_the_vacuum_has_no_seal() -> None:
    tall = _top(0.06, 0.06, 0.40)  # 6 x 6 cm, 40 cm tall: 1.4 kg at water's density, over the 12 N cup
    assert not sample_suction(tall, np.zeros((0, 3)), 0.0, CUP)
