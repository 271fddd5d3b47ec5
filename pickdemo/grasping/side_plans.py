"""A grasp from any side as a pick and place: how the hand takes the object out from among the fixtures
(:func:`way_out`: lifted under a shelf's board, then back out the way it came in) and the plan's TCP
poses (:func:`tilted_pick`). Pure: no simulator.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, boxes_meet
from pickdemo.grasping.clearance import hand_boxes
from pickdemo.grasping.top_down import GraspParams, GraspPlan
from pickdemo.robot.description import Gripper

if TYPE_CHECKING:  # (antipodal.py imports this module)
    from pickdemo.grasping.antipodal import AntipodalGrasp

#: A lift that would meet a fixture (a shelf's board above) is tried this much lower, step by step (m) ...
LIFT_STEP_M = 0.005
#: ... down to this (m): enough to clear a shelf's lip (1 cm on the kiva shelf) as it comes out
LEAST_LIFT_M = 0.02
#: Taken out, the hand goes back along the approach this much at a time (m) ...
OUT_STEP_M = 0.025
#: ... at most this far (m)
MAX_OUT_M = 0.4
#: ... until the object, this much larger every way (m), meets nothing as it rises
OUT_MARGIN_M = 0.02


def out_direction(rotation: np.ndarray) -> np.ndarray:
    """Where a hand with this orientation goes in, level: the approach's part across the table (the hand
    takes an object out of a shelf level, whatever its tilt: back along a tilted approach it would rise
    into the board above), or the approach itself if it is near vertical."""
    a = rotation[:, 2]
    across = np.array([a[0], a[1], 0.0])
    n = float(np.linalg.norm(across))
    return across / n if n > 0.3 else a


def way_out(
    g: AntipodalGrasp,
    held: tuple[np.ndarray, np.ndarray],
    gripper: Gripper,
    params: GraspParams,
    fixtures: tuple[OrientedBox, ...],
) -> tuple[float, float] | None:
    """How the hand takes the object out from among the fixtures: (the lift, m; how far it then goes
    back along the approach, m): straight up ``transport_height_m`` where the hand and the object
    (``held``: its lowest and highest corners in the world) meet no fixture there; else as high as they
    clear what is above (a shelf's board), then back out the way the hand came in, raised so, until the
    hand and the object are clear of every fixture with room to rise (``OUT_STEP_M`` at a time, from
    the pregrasp's distance); None if neither."""
    opening = gripper.finger_max_m if g.open_m is None else g.open_m
    approach = out_direction(g.rotation)

    def clear(h: float, back: float) -> bool:  # lifted h, and on the way back so far (the hand every 5 cm)
        up = np.array([0.0, 0.0, h])
        lo, hi = held[0] + up, held[1] + up
        ends = np.array([lo, hi, lo - approach * back, hi - approach * back])
        obj = OrientedBox(Pose.identity(), ends.min(axis=0), ends.max(axis=0))
        hands = [
            b
            for s in np.linspace(0.0, back, max(int(np.ceil(back / 0.05)), 0) + 1)
            for b in hand_boxes(Pose(g.position + up - approach * s, g.rotation), gripper, opening, 0.0)
        ]
        return not boxes_meet([*hands, obj], fixtures)

    def out_at(h: float, back: float) -> bool:  # drawn back so far, the hand and the object may rise freely
        up = np.array([0.0, 0.0, h])
        lo, hi = held[0] + up - approach * back, held[1] + up - approach * back
        rise = np.array([0.0, 0.0, params.transport_height_m])
        obj = OrientedBox(Pose.identity(), lo - OUT_MARGIN_M, hi + rise + OUT_MARGIN_M)
        at = Pose(g.position + up - approach * back, g.rotation)
        raised = Pose(at.position + rise, g.rotation)
        return not boxes_meet(
            [*hand_boxes(at, gripper, opening, 0.0), *hand_boxes(raised, gripper, opening, 0.0), obj], fixtures
        )

    top = params.transport_height_m
    # (lifted straight up, still with room to rise: under a shelf's board, the arm would have to find
    # its own way out between the boards, and a planner in joint space rarely does)
    if not fixtures or (clear(top, 0.0) and clear(top / 2.0, 0.0) and out_at(top, 0.0)):
        return top, 0.0
    h = top
    while h >= LEAST_LIFT_M:
        if clear(h / 2.0, 0.0) and clear(h, 0.0):
            back = params.pregrasp_height_m
            while back <= MAX_OUT_M:
                if clear(h, back) and out_at(h, back):
                    return h, back
                back += OUT_STEP_M
        h -= LIFT_STEP_M
    return None


def tilted_pick(
    g: AntipodalGrasp,
    centre: np.ndarray,
    surface_z: float,
    place_xy: tuple[float, float],
    params: GraspParams,
    out: tuple[float, float] | None = None,
) -> GraspPlan:
    """Every TCP pose of a pick and place from a grasp from any side: in along its approach axis from
    ``pregrasp_height_m`` back, lifted straight up (``out``: as :func:`way_out` says, and back out along
    the approach), and put down as it stood (the same orientation, the same height over the table) with
    the object's ``centre`` (x, y) over ``place_xy``; out again along the approach. The hand keeps its
    orientation throughout (the motion near the object turns it about the vertical only)."""
    R, tcp = g.rotation, g.position
    approach = R[:, 2]
    lift_m, back_m = out if out is not None else (params.transport_height_m, 0.0)
    offset = tcp[:2] - centre[:2]  # the TCP from the object's centre, held so
    place_p = np.array(
        [place_xy[0] + offset[0], place_xy[1] + offset[1], tcp[2] - surface_z + params.place_clearance_m]
    )
    carry_z = tcp[2] + params.transport_height_m
    pose = lambda p: Pose(np.asarray(p, dtype=float), R)  # noqa: E731
    lift = np.array([tcp[0], tcp[1], tcp[2] + lift_m])
    return GraspPlan(
        pregrasp=pose(tcp - approach * params.pregrasp_height_m),
        grasp=pose(tcp),
        lift=pose(lift),
        withdraw=pose(lift - out_direction(R) * back_m) if back_m > 0.0 else None,
        place_above=pose([place_p[0], place_p[1], max(carry_z, place_p[2] + 0.05)]),
        place=pose(place_p),
        retreat=pose(place_p - approach * params.retreat_height_m),
        object_width_m=float(g.width_m),
        hand_yaw_rad=float(np.arctan2(approach[1], approach[0]))
        if g.tilt_rad > 1e-3
        else float(np.arctan2(R[0, 1], R[0, 0])),
        place_offset_xy=(float(offset[0]), float(offset[1])),
        open_m=g.open_m,
    )
