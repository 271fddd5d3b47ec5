"""Grasps from the point cloud: top-down parallel-jaw grasps of an object nobody described, sampled
and scored on what the camera saw of it.

Pure: no simulator. A candidate is a hand angle, a place along the finger's width and a height;
GPD and Drake's clutter chapter sample the same way (hand orientations times finger placements), here
with the approach kept vertical (the skill's hand moves top-down: its motion is x, y, z and yaw).

The cloud is taken as a height map: what the camera sees of an object from above, it takes to be
solid down to the table (the fingers pass everything above the pads on their way down, so the
opening must clear all of it). For each candidate:

- **fits**: the object's span across the closing axis, within the fingers' width and above the
  pads' lower edge, leaves the open hand its clearance (``GraspParams.width_margin_m``);
- **collides with nothing**: the palm clears the object's top, the pads the table, and the open
  fingers and the palm every other object's points;
- **cost** (lowest first): how far the faces under the pads are from square to the closing axis
  (antipodal: the object's extent at either edge of the pads differs on a slanted face), the lever
  of the object's centre (the middle of its footprint, which the
  camera sees from above better than the far side's points) about the closing axis (its weight
  turns it in the grip: PyBullet's pads have little torsional friction), how far the pads would
  close past where the faces in their band are (sloped or hidden faces under the pads: they close on
  an edge, the failure the oracle found), the height away from where the pads close through the
  middle of the object (as deep as the palm allows), and a width near the opening's limit.

:class:`CloudGrasps` is the skill's :class:`~pickdemo.grasping.selection.GraspSelector` for such an
object: it plans once an attempt on the newest complete view's cloud, in the frame of the pose
tracked then, and carries the grasp with the tracked pose (a push moves the grasp with the object).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from pickdemo.core.geometry import wrap_angle
from pickdemo.grasping.top_down import (
    GraspParams,
    GraspPlan,
    GraspPlanningError,
    poses_of_pick,
    tcp_shift,
)
from pickdemo.perception import ObjectCloud
from pickdemo.robot.description import Gripper

#: An object nobody described is held at any opening the fingers touch it at above this, less the
#: grip's hold margin (m): they have not closed on nothing.
MIN_HELD_M = 0.012
#: A grasp this near one that failed (its TCP, m; its hand angle, rad) comes after every other
AVOID_RADIUS_M = 0.015
AVOID_YAW_RAD = float(np.radians(25.0))


@dataclass(frozen=True)
class CloudGraspParams:
    yaw_steps: int = 18  # hand angles over a half turn (the hand is symmetric under it)
    offsets_m: tuple[float, ...] = (0.0, -0.006, 0.006, -0.012, 0.012)  # along the finger's width
    height_step_m: float = 0.003
    clearance_m: float = 0.004  # between the hand and what it must not touch
    #: the costs' scales (m): a lever, a close past the band's faces, a height off the preferred one,
    #: and a width beyond ``wide_m``
    lever_scale_m: float = 0.005
    contact_scale_m: float = 0.004
    height_scale_m: float = 0.01
    width_scale_m: float = 0.01
    wide_m: float = 0.065
    #: the cost of a grasp whose fingers go down where the camera could not see (per this fraction of
    #: that volume unseen)
    unseen_scale: float = 0.05


@dataclass(frozen=True)
class CloudGrasp:
    """One top-down grasp in the world frame: the TCP's point, the hand angle and the span closed on."""

    position: np.ndarray  # (3,) m
    hand_yaw_rad: float
    width_m: float
    above_surface_m: float  # the TCP's height over what the object rests on
    cost: float

    @property
    def held_width_m(self) -> float:
        """The width the skill checks its hold against: the fingers touch where the object is at the pads,
        which the camera sees only in part (its far side hidden), and it may turn in the grip; so a hold
        is both fingers on it, less than ``MIN_HELD_M`` apart (with the hold margin) meaning closed on nothing."""
        return MIN_HELD_M


def sample_grasps(
    cloud: ObjectCloud,
    surface_z: float,
    gripper: Gripper,
    grasp: GraspParams | None = None,
    params: CloudGraspParams | None = None,
) -> list[CloudGrasp]:
    """Every feasible top-down grasp of the cloud by this ``gripper``, best (lowest cost) first; see the
    module docstring."""
    grasp = grasp or GraspParams()
    p = params or CloudGraspParams()
    pts = cloud.points[cloud.points[:, 2] - surface_z > 0.002]
    if len(pts) < 10:
        return []
    obs = cloud.obstacles[cloud.obstacles[:, 2] - surface_z > 0.002] if len(cloud.obstacles) else np.zeros((0, 3))
    h = pts[:, 2] - surface_z
    oh = obs[:, 2] - surface_z
    top = float(h.max())
    widest = gripper.max_opening_m - grasp.width_margin_m
    palm = gripper.palm_above_tcp_m - grasp.palm_clearance_m
    # The pads close through the middle of the object, or as deep as the palm allows.
    z_pref = max(top - min(top / 2.0, palm), grasp.min_tcp_height_m)
    levels = np.arange(grasp.min_tcp_height_m, top - 0.002 + 1e-9, p.height_step_m)
    if len(levels) == 0:
        levels = np.array([grasp.min_tcp_height_m])
    found: list[np.ndarray] = []  # rows of psi, mid, cb, z, w, cost
    for psi in np.arange(p.yaw_steps) * (np.pi / p.yaw_steps):
        with np.errstate(invalid="ignore"):  # (a height with nothing above its pads: inf - inf, never kept)
            found.extend(_at_angle(float(psi), pts, h, obs, oh, levels, z_pref, widest, palm, p, gripper))
    if not found:
        return []
    c = np.vstack(found)
    # Where the open fingers go down, what the camera did not see free (behind the object's far side,
    # or behind something else) may be the object: a finger there may land on it.
    c[:, 5] += _unseen_fraction(cloud, c, surface_z, top, gripper) / p.unseen_scale
    out = [
        CloudGrasp(np.array([*(mid * _axis_a(psi) + cb * _axis_b(psi)), surface_z + z]), psi, w, z, cost)
        for psi, mid, cb, z, w, cost in c
    ]
    out.sort(key=lambda g: g.cost)
    return out


def _at_angle(
    psi: float,
    pts: np.ndarray,
    h: np.ndarray,
    obs: np.ndarray,
    oh: np.ndarray,
    levels: np.ndarray,
    z_pref: float,
    widest: float,
    palm: float,
    p: CloudGraspParams,
    gripper: Gripper,
) -> Iterator[np.ndarray]:
    """The feasible grasps at one hand angle: for each place along the finger's width, rows of (psi, mid,
    cb, z, w, cost), one a height (every height at once)."""
    pad_lows = levels - gripper.pad_half_height_m  # (L,)
    pad_highs = levels + gripper.pad_half_height_m
    palm_tops = levels + palm
    a = np.array([np.sin(psi), -np.cos(psi)])  # the closing axis: the hand's y
    b = np.array([np.cos(psi), np.sin(psi)])  # along the finger's width: the hand's x
    pa, pb = pts[:, :2] @ a, pts[:, :2] @ b
    oa, ob = obs[:, :2] @ a, obs[:, :2] @ b
    centre_b = 0.5 * float(pb.min() + pb.max())  # the middle of its footprint across the fingers' width
    for db in p.offsets_m:
        cb = centre_b + db
        in_slab = np.abs(pb - cb) < gripper.pad_half_width_m + p.clearance_m
        if in_slab.sum() < 5:
            continue
        sa, sh, sb = pa[in_slab], h[in_slab], pb[in_slab] - cb
        above = sh[None, :] >= pad_lows[:, None]  # (L, N)
        ok = above.sum(axis=1) >= 5
        s_min = np.where(above, sa, np.inf).min(axis=1)
        s_max = np.where(above, sa, -np.inf).max(axis=1)
        w = s_max - s_min
        ok &= ~(w > widest)
        if not ok.any():
            continue
        mid = 0.5 * (s_min + s_max)
        # The palm above the object's top under it.
        in_palm = np.abs(pb - cb) < gripper.palm_half_width_m
        ha, hh = pa[in_palm], h[in_palm]
        under_palm = np.abs(ha[None, :] - mid[:, None]) < gripper.palm_half_length_m
        ok &= ~np.any(under_palm & (hh[None, :] > palm_tops[:, None]), axis=1)
        if len(obs):
            ok &= ~_hits_obstacles(oa, ob, oh, mid, cb, palm_tops, pad_lows, p.clearance_m, gripper)
        if not ok.any():
            continue
        above, sa_l = above[ok], sa
        s_min, s_max, mid, w, z = s_min[ok], s_max[ok], mid[ok], w[ok], levels[ok]
        band = above & (sh[None, :] <= pad_highs[ok][:, None])
        has_band = band.any(axis=1)
        b_min = np.where(has_band, np.where(band, sa_l, np.inf).min(axis=1), mid)
        b_max = np.where(has_band, np.where(band, sa_l, -np.inf).max(axis=1), mid)
        contact = (b_min - s_min) + (s_max - b_max)
        # Antipodal, seen from above: a face square to the closing axis reaches as far at both
        # edges of the pad; a slanted one (its normal off the axis) does not.
        left = above & (sb < 0.0)[None, :]
        right = above & (sb >= 0.0)[None, :]
        both = left.any(axis=1) & right.any(axis=1)
        slant = np.abs(np.where(left, sa_l, -np.inf).max(axis=1) - np.where(right, sa_l, -np.inf).max(axis=1))
        slant = slant + np.abs(np.where(left, sa_l, np.inf).min(axis=1) - np.where(right, sa_l, np.inf).min(axis=1))
        slant = np.where(both, slant, 0.0)
        cost = (
            abs(db) / p.lever_scale_m
            + (contact + slant) / p.contact_scale_m
            + np.abs(z - z_pref) / p.height_scale_m
            + np.maximum(0.0, w - p.wide_m) / p.width_scale_m
        )
        yield np.column_stack([np.full(len(z), psi), mid, np.full(len(z), cb), z, w, cost])


def _axis_a(psi: float) -> np.ndarray:
    return np.array([np.sin(psi), -np.cos(psi)])


def _axis_b(psi: float) -> np.ndarray:
    return np.array([np.cos(psi), np.sin(psi)])


def _unseen_fraction(cloud: ObjectCloud, c: np.ndarray, surface_z: float, top: float, gripper: Gripper) -> np.ndarray:
    """For each candidate (rows of psi, mid, cb, z, ...), the fraction of points in the volume its open
    fingers sweep on the way down (from the pads' lower edge to the object's top) that the camera did
    not see to be free."""
    psi, mid, cb, z = c[:, 0], c[:, 1], c[:, 2], c[:, 3]
    a = np.stack([np.sin(psi), -np.cos(psi)], axis=1)  # (C, 2)
    b = np.stack([np.cos(psi), np.sin(psi)], axis=1)
    side = np.array([-1.0, 1.0])[:, None, None, None]  # (2, 1, 1, 1): each finger
    out_a = gripper.finger_max_m + np.array([0.002, 0.008])[None, :, None, None]  # into each finger's body
    across_b = np.array([-0.8, 0.0, 0.8])[None, None, :, None] * gripper.pad_half_width_m
    t = np.linspace(0.0, 1.0, 5)[None, None, None, :]
    n = len(c)
    pts = np.empty((n, 2, 2, 3, 5, 3))
    k = (slice(None), None, None, None, None)  # each candidate along the first axis
    lo = surface_z + z - gripper.pad_half_height_m  # (C,)
    hi = np.maximum(surface_z + top, lo)
    along = mid[k] + side * out_a  # (C, 2, 2, 1, 1)
    xy = (
        along[..., None] * a[:, None, None, None, None, :]
        + (cb[k] + across_b)[..., None] * b[:, None, None, None, None, :]
    )
    pts[..., :2] = np.broadcast_to(xy, (n, 2, 2, 3, 5, 2))
    pts[..., 2] = np.broadcast_to(lo[k] + t * (hi - lo)[k], (n, 2, 2, 3, 5))
    unknown = cloud.unknown(pts)
    return unknown.reshape(n, -1).mean(axis=1)


def _hits_obstacles(
    oa: np.ndarray,
    ob: np.ndarray,
    oh: np.ndarray,
    mid: np.ndarray,
    cb: float,
    palm_tops: np.ndarray,
    pad_lows: np.ndarray,
    gap: float,
    gripper: Gripper,
) -> np.ndarray:
    """For each height (rows of ``mid``, the palm's underside ``palm_tops`` and the pads' lower edge
    ``pad_lows``), whether another object's points lie where the open fingers go down or under the palm."""
    return _hit_counts(oa, ob, oh, mid, cb, palm_tops, pad_lows, gap, gripper, gripper.finger_max_m) > 0


def _hit_counts(
    oa: np.ndarray,
    ob: np.ndarray,
    oh: np.ndarray,
    mid: np.ndarray,
    cb: float,
    palm_tops: np.ndarray,
    pad_lows: np.ndarray,
    gap: float,
    gripper: Gripper,
    finger_m: float,
) -> np.ndarray:
    """For each height, how many of the points lie where the fingers, open ``finger_m`` each from the
    middle, go down or under the palm."""
    finger_reach = finger_m + gripper.finger_thickness_m + gap
    across = np.abs(ob - cb)
    da = np.abs(oa[None, :] - mid[:, None])  # (L, O)
    f = across < gripper.pad_half_width_m + gap
    in_fingers = f[None, :] & (da < finger_reach) & (oh[None, :] >= (pad_lows - gap)[:, None])
    u = across < gripper.palm_half_width_m
    under_palm = u[None, :] & (da < gripper.palm_half_length_m) & (oh[None, :] > palm_tops[:, None])
    return np.sum(in_fingers | under_palm, axis=1)


def hand_hits(
    obstacles: np.ndarray, tcp: np.ndarray, hand_yaw_rad: float, surface_z: float, palm_m: float, gap_m: float,
    gripper: Gripper, min_points: int = 1, finger_m: float | None = None,
) -> bool:  # fmt: skip
    """Whether ``min_points`` of the ``obstacles`` (M, 3) lie where the open fingers (``finger_m`` each
    from the middle; None: wide open) go down to a top-down grasp with the TCP at ``tcp`` and the hand
    angle ``hand_yaw_rad``, or under the palm (``palm_m`` above the TCP), ``gap_m`` to spare; what
    rests on the surface (within 2 mm of it) is the surface."""
    obs = obstacles[obstacles[:, 2] - surface_z > 0.002]
    if len(obs) == 0:
        return False
    a, b = _axis_a(hand_yaw_rad), _axis_b(hand_yaw_rad)
    level = float(tcp[2]) - surface_z
    hits = _hit_counts(
        obs[:, :2] @ a, obs[:, :2] @ b, obs[:, 2] - surface_z, np.array([float(tcp[:2] @ a)]), float(tcp[:2] @ b),
        np.array([level + palm_m - gap_m]), np.array([level - gripper.pad_half_height_m]), gap_m, gripper,
        gripper.finger_max_m if finger_m is None else finger_m,
    )  # fmt: skip
    return bool(hits[0] >= min_points)


@dataclass
class CloudGrasps:
    """Grasps of an object nobody described from its cloud (a
    :class:`~pickdemo.grasping.selection.GraspSelector`): sampled on the request's cloud once per plan
    (the request's ``plan_id``: a new attempt plans afresh), in the frame of the target's pose as
    tracked then, and carried with the tracked pose after (a push moves the grasp with the object;
    the views that come while the hand goes down do not re-plan it)."""

    params: GraspParams = GraspParams()
    cloud_params: CloudGraspParams = CloudGraspParams()
    #: grasps tried and failed (TCP position in the world, hand angle): one near either comes after the others
    avoid: tuple[tuple[np.ndarray, float], ...] = ()
    _planned: tuple[int, list[tuple[np.ndarray, float, float, float, float]]] | None = field(default=None, repr=False)

    def _local(self, request) -> list[tuple[np.ndarray, float, float, float, float]]:  # noqa: ANN001 - a GraspRequest
        """The cloud's grasps in the tracked pose's frame: (xy offset, hand angle, TCP height over the
        surface, the least width it is held at, the span the fingers close on), best first."""
        if self._planned is not None and self._planned[0] == request.plan_id:
            return self._planned[1]
        cloud = request.cloud
        if cloud is None:
            raise GraspPlanningError("no view of the object to plan a grasp from")
        grasps = sample_grasps(cloud, request.surface_z, request.gripper, self.params, self.cloud_params)
        if not grasps:
            widest = request.gripper.max_opening_m - self.params.width_margin_m
            raise GraspPlanningError(
                "no top-down grasp fits what was seen: wherever the fingers could close, the object is wider "
                f"than the open hand ({widest * 1e3:.0f} mm)"
            )
        if self.avoid:
            grasps.sort(key=lambda g: (self._tried(g), g.cost))
        at = request.pose
        yaw0 = float(at.rpy[2])
        c, s = np.cos(-yaw0), np.sin(-yaw0)
        rot = np.array([[c, -s], [s, c]])
        local = [
            (
                rot @ (g.position[:2] - at.position[:2]),
                g.hand_yaw_rad - yaw0,
                g.above_surface_m,
                g.held_width_m,
                g.width_m,
            )
            for g in grasps
        ]
        self._planned = (request.plan_id, local)
        return local

    def _tried(self, g: CloudGrasp) -> bool:
        """Whether a grasp is near one that was tried and failed (its TCP within ``AVOID_RADIUS_M``, its
        hand angle within ``AVOID_YAW_RAD``, the hand the same after a half turn)."""
        return any(
            np.linalg.norm(g.position[:2] - p[:2]) < AVOID_RADIUS_M
            and abs(wrap_angle(g.hand_yaw_rad - yaw, np.pi)) < AVOID_YAW_RAD
            for p, yaw in self.avoid
        )

    def hand_yaws(self, request) -> list[float]:  # noqa: ANN001 - a GraspRequest
        """The best grasp's two hand angles (the hand is the same after a half turn), at the tracked pose."""
        _, psi, _, _, _ = self._local(request)[0]
        yaw = float(request.pose.rpy[2]) + psi
        return [float(wrap_angle(yaw)), float(wrap_angle(yaw + np.pi))]

    def candidates(self, request) -> Iterator[GraspPlan]:  # noqa: ANN001 - a GraspRequest
        offset, psi, z, width, span = self._local(request)[0]
        yaw = float(request.pose.rpy[2])
        c, s = np.cos(yaw), np.sin(yaw)
        held = np.array([[c, -s], [s, c]]) @ offset  # the TCP from the object's centre
        xy = request.pose.position[:2] + held
        grasp_p = np.array([xy[0], xy[1], request.surface_z + z])
        for near in request.hand_yaws:
            hand = float(wrap_angle(yaw + psi)) if near is None else float(near + wrap_angle(yaw + psi - near, np.pi))
            shift = tcp_shift(request.gripper, span, hand)
            if shift is None:
                yield poses_of_pick(grasp_p, hand, z, width, request.place_xy, self.params, (held[0], held[1]))
            else:  # a jaw: its fixed face beside the span it closes on; closed, the object is pressed to it
                pressed = tcp_shift(request.gripper, span, hand, held=True)
                at = (held[0] + pressed[0], held[1] + pressed[1])
                yield poses_of_pick(grasp_p + shift, hand, z, width, request.place_xy, self.params, at)
