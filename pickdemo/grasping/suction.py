"""Suction grasps from what was seen: where a vacuum cup, coming straight down, seals and holds.

Pure: no simulator. Dex-Net 3.0's ring model (Mahler et al. 2018) on the points. A candidate is a point
of the target's cloud. The face the cup meets there: the plane through the cloud's points within 1.1
cup radii of it (seen from above) and within the stroke of their top, and the points within the
depth's noise of that plane (points lower are another surface: a side, past an edge). It seals where
that face reaches under the rim all round (in each of 8 sectors, to 0.7 radii at least: seen this
sparsely, a farther point is seldom there; a rim over an edge leaks) and the plane rises across the
cup less than 60 % of the stroke (the rest: the depth's noise). It holds where the weight, hanging from
the cup at the cloud's centroid, asks less than the vacuum gives
(:func:`pickdemo.robot.suction.hanging_load`), the mass estimated from what was seen (its footprint
times its height, at :data:`DENSITY_KG_M3`). The cup and its tube must go down clear: no point of
anything else, or of the target itself, within the cup's radius above the lip. Ranked by how far the
cup is from the centroid (the torque), how level the face is, and the load. A described target (a
known box or cylinder) is sealed on the middle of its top face.

The approach is vertical: a face tilted more than the bellows' stroke across the cup is no candidate
(a cup on a tilted hand, along the face's normal, is not yet planned).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from pickdemo.core.geometry import wrap_angle
from pickdemo.core.shapes import Unknown
from pickdemo.grasping.top_down import GraspParams, GraspPlan, GraspPlanningError, poses_of_pick
from pickdemo.robot.suction import Cup, hanging_load

#: What an object nobody described is taken to weigh per volume seen (kg/m^3): water's, more than most
#: of what is picked from bins (cartons, plastics), so that a seal judged to hold holds the real one.
DENSITY_KG_M3 = 1000.0
#: The rim's sectors (seen from above) under each of which the face must reach.
SECTORS = 8
#: A seal this near one that failed is tried after the others (m).
AVOID_RADIUS_M = 0.02
#: So many points in the cup's way at least are something there (fewer: a speck of the depth's noise).
STRAY_POINTS = 3


@dataclass(frozen=True)
class SuctionParams:
    """How suction grasps are sampled and judged; SI units."""

    candidates: int = 300  # cloud points tried, spread evenly over the cloud
    #: the face seen must reach this share of the cup's radius from its centre in every sector ...
    ring_inner: float = 0.7
    ring_outer: float = 1.1  # ... and is looked for within this share of it
    #: the ring's heights may spread this share of the stroke (the rest: the depth's noise)
    stroke_share: float = 0.6
    press_m: float = 0.004  # the cup is pressed this far past the face (into the bellows' stroke)
    noise_m: float = 0.003  # a point this near the face's plane is on it (the depth's noise)
    #: no point of anything (the target too) this far above the lip within the cup's radius and this margin
    clear_above_m: float = 0.004
    clear_margin_m: float = 0.004
    hand_yaws: int = 8  # the hand's angles offered about the cup's axis (a round cup holds the same)


@dataclass(frozen=True)
class SuctionGrasp:
    """A seal on a cloud: the cup's centre on the face (world), and its cost (lower is better)."""

    position: np.ndarray
    cost: float
    spread_m: float
    load: float  # the worst share of the hold the weight asks


def _thin(points: np.ndarray, n: int) -> np.ndarray:
    if len(points) <= n:
        return points
    idx = np.linspace(0, len(points) - 1, n).round().astype(int)
    return points[idx]


def _plane(points: np.ndarray) -> np.ndarray:
    """(gx, gy, z0): the plane z = gx x + gy y + z0 nearest the points (least squares)."""
    a = np.column_stack([points[:, 0], points[:, 1], np.ones(len(points))])
    return np.linalg.lstsq(a, points[:, 2], rcond=None)[0]


def sample_suction(
    points: np.ndarray, obstacles: np.ndarray, surface_z: float, cup: Cup, params: SuctionParams = SuctionParams()
) -> list[SuctionGrasp]:
    """The cloud's seals that hold, best first (see the module's rule)."""
    pts = np.asarray(points, dtype=float)
    if len(pts) < 10:
        return []
    r = cup.radius_m
    centroid = pts.mean(axis=0)
    top = float(pts[:, 2].max())
    footprint = np.ptp(pts[:, 0]) * np.ptp(pts[:, 1])
    mass = DENSITY_KG_M3 * footprint * max(top - surface_z, 0.005)
    others = np.asarray(obstacles, dtype=float).reshape(-1, 3)
    out = []
    for c in _thin(pts[np.argsort(-pts[:, 2], kind="stable")], params.candidates):
        d = np.hypot(pts[:, 0] - c[0], pts[:, 1] - c[1])
        disc = pts[d <= params.ring_outer * r]
        if len(disc) < SECTORS:
            continue
        # the face the lip meets: the plane through the points under the cup within the stroke of their
        # top (a speck of noise above it aside), and the points near that plane (the depth's noise);
        # points lower are another surface (a side, past an edge)
        lip = float(np.percentile(disc[:, 2], 95))
        face = disc[disc[:, 2] >= lip - cup.stroke_m]
        if len(face) < SECTORS:
            continue
        for _ in range(2):
            plane = _plane(face)
            face = face[np.abs(face[:, 2] - face[:, :2] @ plane[:2] - plane[2]) <= params.noise_m]
            if len(face) < SECTORS:
                break
        if len(face) < SECTORS:
            continue
        fd = np.hypot(face[:, 0] - c[0], face[:, 1] - c[1])
        sector = ((np.arctan2(face[:, 1] - c[1], face[:, 0] - c[0]) + np.pi) / (2 * np.pi) * SECTORS).astype(int)
        reach = np.zeros(SECTORS)
        np.maximum.at(reach, sector % SECTORS, fd)
        if np.any(reach < params.ring_inner * r):
            continue  # the face does not reach under the rim all round: over an edge, tilted, or unseen
        spread = float(np.hypot(*_plane(face)[:2])) * 2.0 * r  # one side of the rim above the other
        if spread > params.stroke_share * cup.stroke_m:
            continue
        inside = pts[d <= r + params.clear_margin_m]
        if np.count_nonzero(inside[:, 2] > lip + params.clear_above_m) >= STRAY_POINTS:
            continue  # a part of the target itself stands in the cup's way
        if len(others):
            near = np.hypot(others[:, 0] - c[0], others[:, 1] - c[1]) <= r + params.clear_margin_m
            if np.count_nonzero(others[near, 2] > lip - params.press_m) >= STRAY_POINTS:
                continue  # something else under or beside the cup's way down
        held = hanging_load(cup, mass, centroid - np.array([c[0], c[1], lip]), np.array([0.0, 0.0, 1.0]))
        if not held.holds:
            continue
        lever = float(np.hypot(*(centroid[:2] - c[:2])))
        cost = lever / r + spread / cup.stroke_m + 0.5 * held.worst
        out.append(SuctionGrasp(np.array([c[0], c[1], lip]), cost, spread, held.worst))
    out.sort(key=lambda g: g.cost)
    return out


@dataclass
class SuctionGrasps:
    """A :class:`~pickdemo.grasping.selection.GraspSelector` for a suction cup: seals sampled on the
    request's cloud once per plan, in the frame of the target's pose as tracked then (carried with the
    tracked pose after, as :class:`~pickdemo.grasping.cloud.CloudGrasps` does); a described target on the
    middle of its top face."""

    params: GraspParams = GraspParams()
    suction: SuctionParams = SuctionParams()
    #: seals tried that held nothing (the TCP's position in the world, the hand's angle): one near them
    #: comes after the others
    avoid: tuple[tuple[np.ndarray, float], ...] = ()
    _planned: tuple[int, list[tuple[np.ndarray, float]]] | None = field(default=None, repr=False)

    def _local(self, request) -> list[tuple[np.ndarray, float]]:  # noqa: ANN001 - a GraspRequest
        """The seals in the tracked pose's frame: (xy offset from its centre, the lip's height over the
        surface), best first."""
        if self._planned is not None and self._planned[0] == request.plan_id:
            return self._planned[1]
        cup = request.gripper.cup
        at = request.pose
        if isinstance(request.model.geometry, Unknown) or request.cloud is not None:
            if request.cloud is None:
                raise GraspPlanningError("no view of the object to plan a suction grasp from")
            seen = sample_suction(request.cloud.points, request.cloud.obstacles, request.surface_z, cup, self.suction)
            if not seen:
                raise GraspPlanningError(
                    f"no face seen where a {cup.diameter_m * 1e3:.0f} mm cup seals and holds (a flat patch "
                    "at least as wide as the cup, seen all round, near the object's middle)"
                )
            if self.avoid:
                seen.sort(key=lambda g: (self._tried(g.position), g.cost))
            yaw0 = float(at.rpy[2])
            c, s = np.cos(-yaw0), np.sin(-yaw0)
            rot = np.array([[c, -s], [s, c]])
            local = [(rot @ (g.position[:2] - at.position[:2]), float(g.position[2]) - request.surface_z) for g in seen]
        else:  # a described shape: the middle of its top face
            height = request.model.geometry.height_m
            local = [(np.zeros(2), float(height))]
        self._planned = (request.plan_id, local)
        return local

    def _tried(self, xy: np.ndarray) -> bool:
        return any(np.hypot(*(xy[:2] - p[:2])) < AVOID_RADIUS_M for p, _ in self.avoid)

    def hand_yaws(self, request) -> list[float]:  # noqa: ANN001 - a GraspRequest
        """A round cup holds the same at any angle about its axis: a few, evenly round (the skill ranks
        them by the IK)."""
        self._local(request)
        n = self.suction.hand_yaws
        return [float(wrap_angle(-np.pi + 2.0 * np.pi * k / n)) for k in range(n)]

    def candidates(self, request) -> Iterator[GraspPlan]:  # noqa: ANN001 - a GraspRequest
        for offset, lip in self._local(request)[:1]:
            yaw = float(request.pose.rpy[2])
            c, s = np.cos(yaw), np.sin(yaw)
            held = np.array([[c, -s], [s, c]]) @ offset  # the cup from the object's centre
            xy = request.pose.position[:2] + held
            z = lip - self.suction.press_m
            grasp_p = np.array([xy[0], xy[1], request.surface_z + z])
            for near in request.hand_yaws:
                hand = 0.0 if near is None else float(near)
                # (no width: nothing closes on it; the estimate may be off by up to the cup's radius)
                yield poses_of_pick(grasp_p, hand, z, 0.0, request.place_xy, self.params, (held[0], held[1]))
