"""Grasps from any side: 6-DoF antipodal parallel-jaw grasps sampled on an object's point cloud.

Pure: no simulator. As Drake's clutter chapter (``GenerateAntipodalGraspCandidate``) and GPD sample
them: a cloud point and its surface normal give the closing axis; the hand is rolled about that axis
from the most downward approach the axis allows (``rolls_deg``, within ``max_tilt_deg`` of the
vertical); the TCP goes where the pads close across the object's extent along the axis, as deep as
the palm allows. A candidate is kept when:

- **it fits**: the object's extent between the pads leaves the open hand ``width_margin_m``, and the
  faces the pads meet are within ``friction_cone_deg`` of square to the closing axis;
- **it collides with nothing**: no point of the object, of what stands near it, or of a fixture
  lies where the open fingers sweep on their way in along the approach axis (from ``approach_m``
  back), or behind the palm; the finger tips stay above the surface the object rests on; the open
  hand, from the pregrasp in, meets no fixture's box (:mod:`pickdemo.grasping.clearance`). The fingers
  open wide; where that collides, only ``open_margin_m`` past the object's extent.

Its cost (lowest first), as Drake's ``GraspCandidateCost`` weighs it: the approach's tilt from the
vertical, the far face out of square with the closing axis (``1 - |n . y|``), the lever of the
cloud's centroid about the closing axis (its weight turns it in the grip), and a width near the
opening's limit (the cloud grasps' rule: the narrower span leaves the estimate's error more room).

The checks run on the candidates together, a batch at a time (their points in every candidate's frame
by one matrix product; the open hand's boxes against the fixtures', every pair at once): one by one,
numpy's overhead a call was four fifths of a shelf item's grasp planning.

The hand frame is the TCP's: ``z`` the approach (from the palm to the finger tips), ``y`` the closing
axis, ``x = y x z`` across the pads. A top-down grasp has ``z`` straight down; it is the special case.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, meeting, top_below
from pickdemo.grasping.clearance import HAND_DEPTH_M, hand_boxes
from pickdemo.grasping.side_plans import tilted_pick, way_out
from pickdemo.grasping.top_down import GraspParams, GraspPlan, GraspPlanningError
from pickdemo.robot.description import Gripper

DOWN = np.array([0.0, 0.0, -1.0])
#: A grasp's way out (:func:`~pickdemo.grasping.side_plans.way_out`): the lift, and how far back
Out = tuple[float, float]
#: A normal with less vertical than this is a side's (the fingers close along it); more, a top's (within
#: 12 deg of level: closing axes across it are sampled instead, as the top-down grasps do)
SIDE_NORMAL_Z = float(np.sin(np.radians(78.0)))
#: An end of a grasp's band on a face this far from square to the closing axis (|n . y| below it), at the
#: edge of the view along the axis, is the edge of what the camera saw: the face the pad meets is unseen
UNSEEN_FACE_ALIGNMENT = 0.5
#: The object's points this near what it rests on are left out (m): the depth sensor's mixed pixels where
#: it meets its support (a shelf's board before it), and no pad holds there (its tips stay above)
SUPPORT_BAND_M = 0.008
#: From a top face, a hand tilted this far or more from straight down (deg) holds the object below its top:
#: a pad's height and this (m) down
SHALLOW_ROLL_DEG = 75.0
SHALLOW_PAD_MARGIN_M = 0.004
#: Candidates checked together (their points in their frames at once: the batch's memory, not its result)
BATCH = 128


@dataclass(frozen=True)
class AntipodalParams:
    samples: int = 100  # cloud points tried as a contact, drawn evenly over the cloud
    #: rolls of the hand about the closing axis, from the most downward approach it allows (Drake's
    #: +-60 deg in 7 steps) ...
    rolls_deg: tuple[float, ...] = (0.0, -20.0, 20.0, -40.0, 40.0, -60.0, 60.0)
    #: ... and on to level, where a fixture stands over the object (a shelf's board): the hand comes in level
    level_rolls_deg: tuple[float, ...] = (-75.0, 75.0, -90.0, 90.0)
    max_tilt_deg: float = 90.0  # the approach at most this far from straight down
    top_axes: int = 6  # closing axes across a top face sampled at (over a half turn)
    #: a face the pads meet more than this out of square with the closing axis is refused (GPD's 20 deg;
    #: the pads' friction of about 1 on the objects' allows 45)
    friction_cone_deg: float = 30.0
    #: where the wide-open fingers would meet something, they open this far past the object's extent on
    #: each side on the way in (m): the estimate's error and the tracking's, and twice that to spare
    open_margin_m: float = 0.012
    voxel_m: float = 0.004  # the cloud thinned to this grid before sampling (normals, checks)
    normal_neighbours: int = 12
    approach_m: float = 0.06  # the fingers come in along the approach axis from this far back
    clearance_m: float = 0.003  # the open hand keeps this far from every point not between its pads
    depth_steps: int = 4  # the TCP backed off along the approach this many steps when the palm meets the object
    tilt_weight: float = 1.0  # cost per radian of tilt
    square_weight: float = 1.0  # cost of the far face out of square with the closing axis (1 - |n . y|)
    lever_weight: float = 10.0  # cost per metre of the centroid's lever about the closing axis
    width_weight: float = 0.5  # cost of a width near the opening's limit (the width over the widest it takes)


@dataclass(frozen=True)
class AntipodalGrasp:
    """A grasp in the world: the TCP's pose (``rotation``'s columns are the hand's x, y, z), the
    object's extent between the pads, and its cost."""

    position: np.ndarray  # (3,) m, the TCP
    rotation: np.ndarray  # (3, 3)
    width_m: float
    cost: float
    open_m: float | None = None  # each finger from the middle on the way in (None: wide open)

    @property
    def tilt_rad(self) -> float:
        """The approach's angle from straight down."""
        return float(np.arccos(np.clip(self.rotation[:, 2] @ DOWN, -1.0, 1.0)))


def thinned(points: np.ndarray, voxel_m: float) -> np.ndarray:
    """One point per occupied ``voxel_m`` cube (the first, in the order given): an even cloud."""
    if len(points) == 0:
        return points
    keys = np.floor(points / voxel_m).astype(np.int64)
    _, first = np.unique(keys, axis=0, return_index=True)
    return points[np.sort(first)]


def normal_at(points: np.ndarray, i: int, k: int, centroid: np.ndarray) -> np.ndarray:
    """Point ``i``'s surface normal: the least principal axis of its ``k`` nearest neighbours, turned
    away from the cloud's ``centroid`` (what the camera sees of an object is its outside)."""
    d2 = ((points - points[i]) ** 2).sum(axis=1)
    k = min(k, len(points))
    nb = points[np.argpartition(d2, k - 1)[:k]]
    nb = nb - nb.mean(axis=0)
    _, vecs = np.linalg.eigh(nb.T @ nb)
    n = vecs[:, 0]
    return -n if n @ (points[i] - centroid) < 0.0 else n


def normals_at(points: np.ndarray, idx: np.ndarray, k: int, centroid: np.ndarray) -> np.ndarray:
    """(len(idx), 3): :func:`normal_at` of each of the points ``idx``, all at once."""
    if len(idx) == 0:
        return np.zeros((0, 3))
    k = min(k, len(points))
    d2 = ((points[idx][:, None, :] - points[None, :, :]) ** 2).sum(axis=2)
    nb = points[np.argpartition(d2, k - 1, axis=1)[:, :k]]  # (n, k, 3)
    nb = nb - nb.mean(axis=1, keepdims=True)
    _, vecs = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))
    n = vecs[:, :, 0]
    flip = np.einsum("ni,ni->n", n, points[idx] - centroid) < 0.0
    n[flip] *= -1.0
    return n


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The cross product of two 3-vectors (``np.cross`` costs ten times as much on one pair)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``v`` turned ``angle`` about the unit ``axis`` (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    return v * c + _cross(axis, v) * s + axis * (axis @ v) * (1.0 - c)


def sample_antipodal(
    points: np.ndarray,
    surface_z: float,
    gripper: Gripper,
    rng: np.random.Generator,
    *,
    obstacles: np.ndarray | None = None,
    grasp: GraspParams | None = None,
    params: AntipodalParams | None = None,
    fixtures: tuple[OrientedBox, ...] = (),
) -> list[AntipodalGrasp]:
    """Every collision-free antipodal grasp of the object whose cloud is ``points`` (world, (N, 3))
    found from ``params.samples`` contacts, best (lowest cost) first. ``obstacles``: points of what
    stands near it (other objects, a fixture's faces) the hand keeps out of; ``surface_z``: the height
    of what the object rests on; ``fixtures``: the boxes of the cell's fixtures near it, which the open
    hand coming in from the pregrasp (``grasp.pregrasp_height_m`` back) keeps out of."""
    grasp = grasp or GraspParams()
    p = params or AntipodalParams()
    pts = thinned(np.asarray(points, dtype=float), p.voxel_m)
    pts = pts[pts[:, 2] - surface_z > SUPPORT_BAND_M]
    if len(pts) < 10:
        return []
    obs = np.zeros((0, 3)) if obstacles is None or len(obstacles) == 0 else np.asarray(obstacles, dtype=float)
    obs = obs[obs[:, 2] - surface_z > 0.002]  # what rests on the surface is the surface (the finger tips' check)
    obs = thinned(obs, p.voxel_m)  # (as even as the cloud: a fixture's faces come 3 mm apart)
    centroid = pts.mean(axis=0)
    widest = gripper.max_opening_m - grasp.width_margin_m
    max_tilt = np.radians(p.max_tilt_deg)
    picks = rng.choice(len(pts), size=min(p.samples, len(pts)), replace=False)
    out: list[AntipodalGrasp] = []
    top = float(pts[:, 2].max())
    depth = min((top - surface_z) / 2.0, gripper.palm_above_tcp_m - grasp.palm_clearance_m)
    # a hand coming in level or nearly has its palm beside the object, not over it: its pads a pad's height
    # below the top (clear of the top's edge, where the faces' normals blur into one another)
    shallow = min(depth, 2.0 * gripper.pad_half_height_m + SHALLOW_PAD_MARGIN_M)
    over = top_below(fixtures, float(centroid[0]), float(centroid[1]), top + 2.0) if fixtures else None
    rolls = p.rolls_deg + (p.level_rolls_deg if over is not None and over > top else ())
    tried: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (contact, closing axis, approach)
    for i, n in zip(picks, normals_at(pts, picks, p.normal_neighbours, centroid), strict=True):
        on_top = abs(n[2]) >= SIDE_NORMAL_Z
        if not on_top:  # a side: the fingers close along its normal, at its depth
            axes, contact = [n], pts[i]
        else:  # the top (or a face near level): closing axes across it, the pads as deep as the palm allows
            psi = np.arange(p.top_axes) * (np.pi / p.top_axes)
            axes = [np.array([np.cos(a), np.sin(a), 0.0]) for a in psi]
        for y in axes:
            z0 = DOWN - y * (DOWN @ y)  # the most downward approach square to the closing axis
            z0 /= np.linalg.norm(z0)
            for roll in rolls:
                if on_top:
                    contact = pts[i] + DOWN * (shallow if abs(roll) >= SHALLOW_ROLL_DEG else depth)
                z = _rotate(z0, y, np.radians(roll))
                if np.arccos(np.clip(z @ DOWN, -1.0, 1.0)) <= max_tilt:
                    tried.append((contact, y, z))
    for s in range(0, len(tried), BATCH):  # (every candidate's checks at once, a batch at a time)
        chunk = tried[s : s + BATCH]
        found = _candidates(pts, obs, *(np.array(col) for col in zip(*chunk, strict=True)), surface_z, gripper,
                            widest, centroid, p)  # fmt: skip
        kept = [g for g in found if g is not None]
        if kept and fixtures:  # the open hand from the pregrasp in, every candidate's boxes at once
            boxes = [
                b
                for g in kept
                for b in hand_boxes(Pose(g.position, g.rotation), gripper,
                                    gripper.finger_max_m if g.open_m is None else g.open_m, grasp.pregrasp_height_m)
            ]  # fmt: skip
            meets = meeting(boxes, fixtures).reshape(len(kept), -1).any(axis=1)
            kept = [g for g, m in zip(kept, meets, strict=True) if not m]
        out.extend(kept)
    out.sort(key=lambda g: g.cost)
    return out


def _candidates(
    pts: np.ndarray,
    obs: np.ndarray,
    contacts: np.ndarray,
    ys: np.ndarray,
    zs: np.ndarray,
    surface_z: float,
    gripper: Gripper,
    widest: float,
    centroid: np.ndarray,
    p: AntipodalParams,
) -> list[AntipodalGrasp | None]:
    """Each candidate's grasp (closing along ``ys[j]``, approached along ``zs[j]``, its pads at
    ``contacts[j]``'s depth, backed off when the palm would meet the object), or None where it does not
    fit or collides: every candidate's points in its own frame at once (the checks batched)."""
    K = len(contacts)
    if K == 0:
        return []
    xs = np.cross(ys, zs)
    Rs = np.stack([xs, ys, zs], axis=2)  # (K, 3, 3): columns x, y, z
    hh, hw = gripper.pad_half_height_m, gripper.pad_half_width_m
    palm, c = gripper.palm_above_tcp_m, p.clearance_m
    step = hh / max(p.depth_steps, 1)
    level = zs @ DOWN <= np.cos(np.radians(SHALLOW_ROLL_DEG)) + 1e-9  # (K,)
    # (K, N) each: the points along each candidate's axes at depth 0, a product of the cloud with every
    # candidate's axis (BLAS), less the contact's
    # (in single precision: a tenth of a micrometre is nothing to a grasp, and half the memory is half the time)
    p32 = pts.T.astype(np.float32)
    lx, ly, lz0 = (
        (a.astype(np.float32) @ p32) - np.einsum("kd,kd->k", a, contacts).astype(np.float32)[:, None]
        for a in (xs, ys, zs)
    )
    across = np.abs(lx) < hw
    palm_across = np.abs(lx) < gripper.palm_half_width_m
    # the first depth at which the pads' band fits and the palm clears the object (-1: none; -2: rejected)
    chosen = np.full(K, -1)
    width = np.zeros(K)
    mid = np.zeros(K)
    lo_b = np.zeros(K)
    hi_b = np.zeros(K)
    bands = np.zeros((K, pts.shape[0]), dtype=bool)
    slabs = np.zeros((K, pts.shape[0]), dtype=bool)
    for k in range(p.depth_steps + 1):
        at = np.flatnonzero(chosen == -1)  # (the candidates still backing off)
        if len(at) == 0:
            break
        lz, ly_a = lz0[at] + k * step, ly[at]
        pad = np.abs(lz) < hh
        slab = across[at] & pad
        tcp_z = contacts[at, 2] - zs[at, 2] * (k * step)
        band = slab | (level[at, None] & pad & (pts[None, :, 2] > tcp_z[:, None]))
        count = band.sum(axis=1)
        with np.errstate(invalid="ignore"):  # (an empty band: refused below)
            lo = np.where(band, ly_a, np.inf).min(axis=1)
            hi = np.where(band, ly_a, -np.inf).max(axis=1)
            w, m = hi - lo, 0.5 * (lo + hi)
        bad = (count < 3) | (w > widest)
        chosen[at[bad]] = -2
        palm_hit = (
            (lz < -palm + c) & (lz > -palm - HAND_DEPTH_M) & (np.abs(ly_a - m[:, None]) < gripper.palm_half_length_m)
            & palm_across[at]
        ).any(axis=1)  # fmt: skip
        ok = ~bad & ~palm_hit
        g = at[ok]
        chosen[g] = k
        width[g], mid[g], lo_b[g], hi_b[g] = w[ok], m[ok], lo[ok], hi[ok]
        bands[g], slabs[g] = band[ok], slab[ok]
    out: list[AntipodalGrasp | None] = [None] * K
    live = np.flatnonzero(chosen >= 0)
    if len(live) == 0:
        return out
    R, z, y = Rs[live], zs[live], ys[live]
    k_at = chosen[live]
    lz = lz0[live] + (k_at * step)[:, None]
    ly_c = ly[live] - mid[live][:, None]  # (the pads' middle: centred between them)
    lx_l = lx[live]
    centre = contacts[live] - z * (k_at * step)[:, None] + y * mid[live][:, None]
    keep = np.ones(len(live), dtype=bool)
    if len(obs):
        o = np.einsum("knd,kdm->knm", obs[None, :, :] - centre[:, None, :], R)  # (L, M, 3)
        ox, oy, oz = o[..., 0], o[..., 1], o[..., 2]
        keep &= ~(
            (oz < -palm + c) & (oz > -palm - HAND_DEPTH_M) & (np.abs(oy) < gripper.palm_half_length_m)
            & (np.abs(ox) < gripper.palm_half_width_m)
        ).any(axis=1)  # fmt: skip
    fmax = gripper.finger_max_m
    openings = np.stack([np.full(len(live), fmax), np.minimum(width[live] / 2.0 + p.open_margin_m, fmax)], axis=1)
    along = (lz > -palm - p.approach_m) & (lz < hh + c)
    fing_across = np.abs(lx_l) < hw + c
    ay = np.abs(ly_c)
    if len(obs):
        o_along = (oz > -palm - p.approach_m) & (oz < hh + c)
        o_across = np.abs(ox) < hw + c
        o_ay = np.abs(oy)
    opening = np.full(len(live), np.nan)
    for i in range(2):
        o_m = openings[:, i][:, None]
        inner, outer = o_m - c, o_m + gripper.finger_thickness_m + c
        hits = (along & fing_across & (ay > inner) & (ay < outer)).any(axis=1)
        if len(obs):
            hits |= (o_along & o_across & (o_ay < outer)).any(axis=1)
        reach = openings[:, i] + gripper.finger_thickness_m
        low = centre[:, 2] - hw * np.abs(R[:, 2, 0]) - reach * np.abs(R[:, 2, 1]) + hh * R[:, 2, 2]
        fits = np.isnan(opening) & ~hits & (low >= surface_z + 0.002)
        opening[fits] = openings[fits, i]
    keep &= ~np.isnan(opening)
    normals: dict[int, np.ndarray] = {}
    cone = np.cos(np.radians(p.friction_cone_deg))
    for j in np.flatnonzero(keep):
        g = int(live[j])
        lyj = ly_c[j]
        band, slab = bands[g], slabs[g]
        extent = (float(lyj.min()), float(lyj.max()))
        ends = (float(lo_b[g] - mid[g]), float(hi_b[g] - mid[g]))
        seen = []
        for end, far in zip(ends, extent, strict=True):
            near_end = np.flatnonzero(slab & (np.abs(lyj - end) < 2.0 * p.voxel_m))
            if len(near_end) == 0:
                continue
            e = int(near_end[np.argmax(np.abs(lyj[near_end] - 0.5 * (ends[0] + ends[1])))])
            if e not in normals:
                normals[e] = normal_at(pts, e, p.normal_neighbours, centroid)
            a = abs(float(normals[e] @ ys[g]))
            if not (a < UNSEEN_FACE_ALIGNMENT and abs(float(lyj[e]) - far) < p.voxel_m):
                seen.append(a)
        if not seen or min(seen) < cone:
            continue
        w = float(width[g])
        square = 1.0 - min(seen)
        lever = float(np.linalg.norm(_cross(centroid - centre[j], ys[g])))
        tilt = float(np.arccos(np.clip(zs[g] @ DOWN, -1.0, 1.0)))
        cost = p.tilt_weight * tilt + p.square_weight * square + p.lever_weight * lever + p.width_weight * w / widest
        o_j = float(opening[j])
        out[g] = AntipodalGrasp(centre[j].copy(), Rs[g].copy(), w, cost, None if o_j >= fmax else o_j)
    return out


def _fingers_hit(
    local: np.ndarray, gripper: Gripper, p: AntipodalParams, opening_m: float, *, obstacle: bool = False
) -> bool:
    """Whether points (in the grasp's frame, centred between the pads) lie where the fingers, open
    ``opening_m`` each, sweep in along the approach, from ``approach_m`` back to their tips (the
    object's own points between the pads are what is grasped; an obstacle's are hits there too)."""
    c = p.clearance_m
    inner, outer = opening_m - c, opening_m + gripper.finger_thickness_m + c
    along = (local[:, 2] > -gripper.palm_above_tcp_m - p.approach_m) & (local[:, 2] < gripper.pad_half_height_m + c)
    across = np.abs(local[:, 0]) < gripper.pad_half_width_m + c
    ay = np.abs(local[:, 1])
    in_finger = (ay > inner) & (ay < outer)
    if obstacle:
        in_finger = ay < outer  # between the open fingers too: it would be grasped with the object
    return bool(np.any(along & across & in_finger))


def _palm_hits(local: np.ndarray, gripper: Gripper, clearance_m: float) -> bool:
    """Whether points lie behind the palm, within the hand's body seen along the approach."""
    z = local[:, 2]
    return bool(
        np.any(
            (z < -gripper.palm_above_tcp_m + clearance_m)
            & (z > -gripper.palm_above_tcp_m - HAND_DEPTH_M)
            & (np.abs(local[:, 1]) < gripper.palm_half_length_m)
            & (np.abs(local[:, 0]) < gripper.palm_half_width_m)
        )
    )


def by_tilt_in_turns(ranked: list[tuple[AntipodalGrasp, Out]]) -> list[tuple[AntipodalGrasp, Out]]:
    """Grasps ranked best first, reordered to take the best of each tilt in turn (tilts to the nearest
    15 deg; the tilts in the order of their best): the cost prefers the least tilt, and among a shelf's
    boards the Panda reaches some tilts only at some heights (level at 10-20 cm over the table, 15 deg
    down only from 30 cm up, measured), so the best two dozen were all of one tilt it could not reach."""
    bins: dict[int, list[tuple[AntipodalGrasp, Out]]] = {}
    for item in ranked:
        bins.setdefault(round(np.degrees(item[0].tilt_rad) / 15.0), []).append(item)
    out: list[tuple[AntipodalGrasp, Out]] = []
    for k in range(max((len(b) for b in bins.values()), default=0)):
        out += [b[k] for b in bins.values() if k < len(b)]
    return out


@dataclass
class AnySideGrasps:
    """A :class:`~pickdemo.grasping.selection.GraspSelector` of grasps from any side for an object nobody
    described (:func:`sample_antipodal` on the request's cloud, the cloud's neighbours and the request's
    obstacles kept out of): sampled once per plan (the request's ``plan_id``) in the frame of the target's
    pose as tracked then, and carried with the tracked pose after. Its own draw: ``rng``."""

    rng: np.random.Generator
    params: GraspParams = GraspParams()
    antipodal: AntipodalParams = AntipodalParams()
    best: int = 8  # the candidates offered, best first (the skill takes the first the arm reaches) ...
    #: ... among fixtures (a shelf), where the arm's links rule out more of them (the skill checks them)
    best_among_fixtures: int = 24
    _planned: tuple[int, list[tuple[AntipodalGrasp, tuple[float, float]]]] | None = field(default=None, repr=False)

    def _local(self, request) -> list[tuple[AntipodalGrasp, tuple[float, float]]]:  # noqa: ANN001
        """The grasps in the tracked pose's frame, best first, each with its way out (:func:`way_out`)."""
        at = request.pose
        if self._planned is None or self._planned[0] != request.plan_id:
            cloud = request.cloud
            if cloud is None:
                raise GraspPlanningError("no view of the object to plan a grasp from")
            obstacles = [o for o in (cloud.obstacles, request.obstacles) if o is not None and len(o)]
            found = sample_antipodal(
                cloud.points, request.surface_z, request.gripper, self.rng,
                obstacles=np.vstack(obstacles) if obstacles else None, grasp=self.params, params=self.antipodal,
                fixtures=request.fixtures,
            )  # fmt: skip
            held = (cloud.points.min(axis=0), cloud.points.max(axis=0))
            ways = [(g, way_out(g, held, request.gripper, self.params, request.fixtures)) for g in found]
            kept = [(g, out) for g, out in ways if out is not None]
            if not kept:
                raise GraspPlanningError(
                    "no grasp from any side fits what was seen: wherever the fingers could close, the object is "
                    "wider than the open hand or the hand would meet something"
                    + (" (or could not take it out)" if found else "")
                )
            inv = at.rotation.T
            if request.fixtures:  # (the best of each tilt by turns: the arm reaches into a shelf at some only)
                kept = by_tilt_in_turns(kept)
            local = [
                (dataclasses.replace(g, position=inv @ (g.position - at.position), rotation=inv @ g.rotation), out)
                for g, out in kept[: self.best_among_fixtures if request.fixtures else self.best]
            ]
            self._planned = (request.plan_id, local)
        return self._planned[1]

    def _world(self, request) -> list[tuple[AntipodalGrasp, np.ndarray, tuple[float, float]]]:  # noqa: ANN001
        """The grasps carried with the tracked pose now, each with the object's centre (the tracked
        position: what the place puts over the place and the camera checks there) and its way out."""
        local = self._local(request)
        at = request.pose
        where = at.position
        return [
            (
                dataclasses.replace(
                    g, position=at.position + at.rotation @ g.position, rotation=at.rotation @ g.rotation
                ),
                where,
                out,
            )
            for g, out in local
        ]

    def hand_yaws(self, request) -> list[float]:  # noqa: ANN001 - a GraspRequest
        """The candidates' hand angles, best first (each a grasp of its own: a grasp from the side is not
        the same turned about the vertical)."""
        return [
            tilted_pick(g, c, request.surface_z, request.place_xy, self.params, out).hand_yaw_rad
            for g, c, out in self._world(request)
        ]

    def candidates(self, request) -> Iterator[GraspPlan]:  # noqa: ANN001 - a GraspRequest
        """For each hand angle asked, the best candidate at the nearest angle (None: the best)."""
        plans = [
            tilted_pick(g, c, request.surface_z, request.place_xy, self.params, out)
            for g, c, out in self._world(request)
        ]
        offered: set[int] = set()
        for near in request.hand_yaws:  # (two asks at one angle: its best, then its next best)
            left = [k for k in range(len(plans)) if k not in offered] or list(range(len(plans)))
            if near is None:
                k = left[0]
            else:
                k = min(left, key=lambda i: abs(float(np.angle(np.exp(1j * (plans[i].hand_yaw_rad - near))))))
            offered.add(k)
            yield plans[k]
