"""Suction grasps from what was seen: where a vacuum cup, coming along a face's normal, seals and holds.

Pure: no simulator. Dex-Net 3.0's ring model (Mahler et al. 2018) on the points. A candidate is a point
of the target's cloud. The face the cup meets there: the plane through the cloud's points within 1.1 cup
radii of it (its least principal axis, facing up), tilted at most 45 deg, and the points within the
depth's noise of that plane; a few points above it are a bump in the cup's way. It seals where that face
reaches under the rim all round: in each of 8 sectors, to the cup's radius less 1.5 mm (the last point
seen short of an edge). As a sector's farthest point may lie off its middle, a 16 mm cup may still
overhang a straight edge by up to 3.4 mm (r - (r - 1.5 mm) cos 45 deg): the simulator's rim, 1 mm inside
the cup's edge, then leaks, and the pick tries elsewhere. A sector short of it is an edge (it leaks)
where the camera saw past the rim's point there, and may be a face the camera could not see where it did
not: up to 3 such sectors are offered, after the seals seen all round. It holds where the weight,
hanging from the cup at the cloud's centroid, asks less than the vacuum gives
(:func:`pickdemo.robot.suction.hanging_load`), the mass estimated from what was seen (its footprint
times its height, at :data:`DENSITY_KG_M3`). The cup and its tube must go in clear: no point of anything
else, or of the target itself, within the cup's radius of its axis up the tool's length. Ranked by the
weight's arm about the cup's axis, the tilt, and the load. A described target (a known box or can) is
sealed on the middle of its top face. A level seal is taken from straight above at any hand angle; a
tilted one along its normal, the hand level across the tilt, and put down level.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from pickdemo.core.geometry import Pose, about_vertical, wrap_angle
from pickdemo.core.shapes import Unknown
from pickdemo.grasping.top_down import GraspParams, GraspPlan, GraspPlanningError, poses_of_pick, top_down
from pickdemo.robot.suction import Cup, hanging_load

#: What an object nobody described is taken to weigh per volume seen (kg/m^3): water's, more than most
#: of what is picked from bins (cartons, plastics), so that a seal judged to hold holds the real one.
DENSITY_KG_M3 = 1000.0
#: The rim's sectors (seen from above) under each of which the face must reach.
SECTORS = 8
#: The best seals offered to the skill (it takes the first the arm reaches): the best few of a small
#: part in a bin may all face away from the arm (its wrist then out of reach)
BEST_SEALS = 10
#: At most so many of the rim's sectors may be hidden from the camera (and the seal's cost for each).
UNSEEN_SECTORS = 3
UNSEEN_COST = 0.5
#: A seal this near one that failed is tried after the others (m).
AVOID_RADIUS_M = 0.02
#: So many points in the cup's way at least are something there (fewer: a speck of the depth's noise).
STRAY_POINTS = 3


@dataclass(frozen=True)
class SuctionParams:
    """How suction grasps are sampled and judged; SI units."""

    candidates: int = 300  # cloud points tried, spread evenly over the cloud
    #: the face seen must reach the cup's radius less this from its centre in every sector (the last
    #: point seen short of a face's edge: about one point's spacing) ...
    rim_slack_m: float = 0.0015
    ring_outer: float = 1.1  # ... and is looked for within this share of the radius
    press_m: float = 0.004  # the cup is pressed this far past the face (into the bellows' stroke)
    noise_m: float = 0.003  # a point this near the face's plane is on it (the depth's noise)
    #: the cup comes along a face's normal tilted at most this far from the vertical (rad): the arm's
    #: wrist over a bin's walls, and the held part's weight peeling a tilted cup
    max_tilt_rad: float = np.radians(45.0)
    #: below this tilt the cup comes straight down (a top-down pick, as the fingers' are)
    level_rad: float = np.radians(5.0)
    #: no point of anything (the target too) within the cup's radius and this margin of its axis, from
    #: this far above the lip up the tool's length
    clear_margin_m: float = 0.004
    clear_above_m: float = 0.004
    tool_length_m: float = 0.3
    hand_yaws: int = 8  # the hand's angles offered about a vertical cup's axis (a round cup holds the same)


@dataclass(frozen=True)
class SuctionGrasp:
    """A seal on a cloud: the cup's centre on the face (world), the face's outward normal, its cost
    (lower is better)."""

    position: np.ndarray
    normal: np.ndarray
    cost: float
    tilt_rad: float
    load: float  # the worst share of the hold the weight asks


def _thin(points: np.ndarray, n: int) -> np.ndarray:
    if len(points) <= n:
        return points
    idx = np.linspace(0, len(points) - 1, n).round().astype(int)
    return points[idx]


def _basis(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors across ``n`` (a face's plane)."""
    e1 = np.cross(n, [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def sample_suction(
    points: np.ndarray,
    obstacles: np.ndarray,
    surface_z: float,
    cup: Cup,
    params: SuctionParams = SuctionParams(),
    unknown: Callable[[np.ndarray], np.ndarray] | None = None,
) -> list[SuctionGrasp]:
    """The cloud's seals that hold, best first (see the module's rule). ``unknown``: which of some world
    points the camera did not see to be free (:meth:`~pickdemo.perception.model.ObjectCloud.unknown`):
    where the face is not seen to reach under the rim and the rim's point there is hidden, the face may
    go on (a side the camera could not see): such a seal is offered, after those seen all round, with
    at most :data:`UNSEEN_SECTORS` sectors so; where the camera saw past the rim, it leaks."""
    pts = np.asarray(points, dtype=float)
    if len(pts) < 10:
        return []
    r = cup.radius_m
    centroid = pts.mean(axis=0)
    top = float(pts[:, 2].max())
    footprint = np.ptp(pts[:, 0]) * np.ptp(pts[:, 1])
    mass = DENSITY_KG_M3 * footprint * max(top - surface_z, 0.005)
    others = np.asarray(obstacles, dtype=float).reshape(-1, 3)
    everything = np.vstack([pts, others])
    out = []
    for c in _thin(pts[np.argsort(-pts[:, 2], kind="stable")], params.candidates):
        patch = pts[np.linalg.norm(pts - c, axis=1) <= params.ring_outer * r]
        if len(patch) < SECTORS:
            continue
        # the face: the plane through the patch (its least principal axis, facing up), and the points
        # within the depth's noise of it; a point farther, above it, is a bump in the cup's way
        mid = patch.mean(axis=0)
        n = np.linalg.eigh(np.cov((patch - mid).T))[1][:, 0]
        n = n if n[2] >= 0.0 else -n
        tilt = float(np.arccos(np.clip(n[2], -1.0, 1.0)))
        if tilt > params.max_tilt_rad:
            continue
        lip = c - n * float((c - mid) @ n)  # the candidate on the plane
        res = (patch - lip) @ n
        face = patch[np.abs(res) <= params.noise_m]
        if np.count_nonzero(res > params.noise_m) >= STRAY_POINTS:
            continue  # something of the target stands up within the rim
        e1, e2 = _basis(n)
        u, v = (face - lip) @ e1, (face - lip) @ e2
        sector = ((np.arctan2(v, u) + np.pi) / (2 * np.pi) * SECTORS).astype(int) % SECTORS
        reach = np.zeros(SECTORS)
        np.maximum.at(reach, sector, np.hypot(u, v))
        short = np.flatnonzero(reach < r - params.rim_slack_m)
        if len(short):  # the face not seen under the rim there: hidden from the camera, or past an edge
            if unknown is None or len(short) > UNSEEN_SECTORS:
                continue
            angle = (short + 0.5) * (2 * np.pi / SECTORS) - np.pi
            rim = lip + r * (np.outer(np.cos(angle), e1) + np.outer(np.sin(angle), e2))
            if not np.all(unknown(rim)):
                continue  # seen past the rim: over an edge, it leaks
        # the cup's and the tube's way in along the normal: nothing within the radius of its axis
        rel = everything - lip
        along = rel @ n
        across = np.linalg.norm(rel - np.outer(along, n), axis=1)
        way = (along > params.clear_above_m) & (along < params.tool_length_m) & (across <= r + params.clear_margin_m)
        if np.count_nonzero(way) >= STRAY_POINTS:
            continue
        held = hanging_load(cup, mass, centroid - lip, n)
        if not held.holds:
            continue
        lever = float(np.linalg.norm(np.cross(centroid - lip, n)))  # the weight's arm about the cup's axis
        cost = lever / r + tilt / params.max_tilt_rad + 0.5 * held.worst + UNSEEN_COST * len(short)
        out.append(SuctionGrasp(lip, n, cost, tilt, held.worst))
    out.sort(key=lambda g: g.cost)
    return out


def suction_plan(
    g: SuctionGrasp, centre: np.ndarray, surface_z: float, place_xy: tuple[float, float], params: GraspParams,
    suction: SuctionParams, hand_yaw: float = 0.0,
) -> GraspPlan:  # fmt: skip
    """Every TCP pose of a pick and place on a seal: a level face's from straight above at
    ``hand_yaw`` (as a top-down pick's); a tilted face's in along its normal, pressed ``press_m`` into it,
    lifted straight up, and put down with the cup level (the object's ``centre`` over ``place_xy``)."""
    if g.tilt_rad <= suction.level_rad:
        z = float(g.position[2]) - surface_z - suction.press_m
        grasp_p = np.array([g.position[0], g.position[1], surface_z + z])
        held = grasp_p[:2] - centre[:2]
        # (no width: nothing closes on it; the estimate may be off by up to the cup's radius)
        return poses_of_pick(grasp_p, hand_yaw, z, 0.0, place_xy, params, (float(held[0]), float(held[1])))
    approach = -g.normal
    level_x = np.cross([0.0, 0.0, 1.0], approach)  # the hand's x level, across the tilt ...
    level_x /= np.linalg.norm(level_x)
    # ... turned ``hand_yaw`` about the cup's axis (a round cup seals the same at any turn)
    x = np.cos(hand_yaw) * level_x + np.sin(hand_yaw) * np.cross(approach, level_x)
    rot = np.column_stack([x, np.cross(approach, x), approach])
    tcp = g.position + approach * suction.press_m
    offset = tcp[:2] - centre[:2]
    place_p = np.array(
        [place_xy[0] + offset[0], place_xy[1] + offset[1], tcp[2] - surface_z + params.place_clearance_m]
    )
    carry_z = tcp[2] + params.transport_height_m
    pose = lambda p: Pose(np.asarray(p, dtype=float), rot)  # noqa: E731
    yaw = float(np.arctan2(x[1], x[0]))  # (top_down's x along the tilted hand's, seen from above)
    return GraspPlan(
        pregrasp=pose(tcp - approach * params.pregrasp_height_m),
        grasp=pose(tcp),
        lift=pose([tcp[0], tcp[1], carry_z]),
        # put down with the cup level again (the part turned with it; what it rests on takes it as it
        # comes): a tilted hand over the place, as it was held, put the UR5's wrist near its singularity
        place_above=top_down(np.array([place_p[0], place_p[1], max(carry_z, place_p[2] + 0.05)]), yaw),
        place=top_down(place_p, yaw),
        retreat=top_down(place_p + np.array([0.0, 0.0, params.retreat_height_m]), yaw),
        object_width_m=0.0,
        hand_yaw_rad=float(wrap_angle(yaw)),
        place_offset_xy=(float(offset[0]), float(offset[1])),
    )


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
    _planned: tuple[int, list[SuctionGrasp]] | None = field(default=None, repr=False)

    def _local(self, request) -> list[SuctionGrasp]:  # noqa: ANN001 - a GraspRequest
        """The seals in the tracked pose's frame (its centre the origin, turned by its yaw), best first."""
        if self._planned is not None and self._planned[0] == request.plan_id:
            return self._planned[1]
        cup = request.gripper.cup
        at = request.pose
        # (a described shape stands on its known top face: its middle; the cloud of an upright box's
        # sides had no face under the rim all round in 3 of 100 episodes, measured)
        if isinstance(request.model.geometry, Unknown):
            if request.cloud is None:
                raise GraspPlanningError("no view of the object to plan a suction grasp from")
            cloud = request.cloud
            seen = sample_suction(cloud.points, cloud.obstacles, request.surface_z, cup, self.suction, cloud.unknown)
            if not seen:
                raise GraspPlanningError(
                    f"no face seen where a {cup.diameter_m * 1e3:.0f} mm cup seals and holds (a face at least as "
                    f"wide as the cup, seen all round, tilted at most {np.degrees(self.suction.max_tilt_rad):.0f} deg, "
                    "its way in clear)"
                )
            if self.avoid:
                seen.sort(key=lambda g: (self._tried(g.position), g.cost))
            turn = about_vertical(-float(at.rpy[2]))
            local = [
                SuctionGrasp(turn @ (g.position - at.position), turn @ g.normal, g.cost, g.tilt_rad, g.load)
                for g in seen
            ]
        else:
            top = np.array([0.0, 0.0, request.surface_z + request.model.geometry.height_m]) - at.position * [0, 0, 1]
            local = [SuctionGrasp(top, np.array([0.0, 0.0, 1.0]), 0.0, 0.0, 0.0)]
        self._planned = (request.plan_id, local)
        return local

    def _tried(self, position: np.ndarray) -> bool:
        return any(np.hypot(*(position[:2] - p[:2])) < AVOID_RADIUS_M for p, _ in self.avoid)

    def _world(self, request) -> list[SuctionGrasp]:  # noqa: ANN001 - a GraspRequest
        """The best seals where the tracked pose has the target now; after a miss (a leak), the seals a
        cup's radius away from those tried first: tried elsewhere."""
        at = request.pose
        turn = about_vertical(float(at.rpy[2]))
        local = list(self._local(request))
        r = request.gripper.cup.radius_m
        for _ in range(min(request.misses, len(local) - 1)):  # each miss: the best seal, and those near it, last
            tried = local[0].position
            far = [g for g in local if np.linalg.norm(g.position - tried) > r]
            local = far + [g for g in local if np.linalg.norm(g.position - tried) <= r]
        return [
            SuctionGrasp(at.position + turn @ g.position, turn @ g.normal, g.cost, g.tilt_rad, g.load)
            for g in local[:BEST_SEALS]
        ]

    def _level(self, g: SuctionGrasp) -> bool:
        return g.tilt_rad <= self.suction.level_rad

    def hand_yaws(self, request) -> list[float]:  # noqa: ANN001 - a GraspRequest
        """The hand's angles the best seals are taken at (the skill ranks them by the IK, and so takes
        the best seal the arm reaches): a level cup holds the same at any angle about its axis, a few
        evenly round; a tilted one comes with its hand level across the tilt (turned about a tilted
        axis, the UR5's wrist came near its singularities: 2 of 10 rounds stopped so, measured), one
        angle a seal."""
        yaws: list[float] = []
        for g in self._world(request):
            if self._level(g):
                n = self.suction.hand_yaws
                even = [float(wrap_angle(-np.pi + 2.0 * np.pi * k / n)) for k in range(n)]
                yaws += [y for y in even if y not in yaws]
            else:
                yaws.append(_tilted_yaw(g))
        return yaws

    def candidates(self, request) -> Iterator[GraspPlan]:  # noqa: ANN001 - a GraspRequest
        """One plan for each hand angle asked: the tilted seal taken at that angle, else the best level
        seal turned to it, else the best seal."""
        seals = self._world(request)
        level = next((g for g in seals if self._level(g)), None)
        for near in request.hand_yaws:
            tilted = None if near is None else next(
                (g for g in seals if not self._level(g) and abs(wrap_angle(_tilted_yaw(g) - near)) < 1e-6), None
            )  # fmt: skip
            g = tilted or level or seals[0]
            hand = float(near) if g is level and near is not None else 0.0
            yield suction_plan(
                g, request.pose.position, request.surface_z, request.place_xy, self.params, self.suction, hand
            )


def _tilted_yaw(g: SuctionGrasp) -> float:
    """The hand's angle of a tilted seal's plan (its x level, across the tilt)."""
    x = np.cross([0.0, 0.0, 1.0], -g.normal)
    return float(np.arctan2(x[1], x[0]))
