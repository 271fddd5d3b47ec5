"""The robot's world: every object it has seen, each with a persistent id, kept across frames and
cameras (:class:`WorldModel`), and which of them is its target.

Pure: :class:`~pickdemo.worldmodel.instances.SceneView` in, answers out; no simulator. Each view's
instances are matched to the tracked objects by where their footprints stand (nearest first, within
the larger of the two footprints' half sides and :data:`MATCH_M`); an instance nothing matches is a
new object with the next id. An object a view should have shown (in its image, nothing nearer in
front of it) and did not is missed; missed :data:`GONE_AFTER` views in a row, it is gone (picked,
pushed away). An object's points are its newest view's from each camera while it has not moved
(they add up: a hand camera sees the side the fixed one does not), and the newest alone once it has.
The target is the object whose footprint holds where the skill tracks its target
(:meth:`WorldModel.mark_target`); the rest is what the hand and the arm must keep out of
(:meth:`WorldModel.obstacles`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose, box_surface_points
from pickdemo.perception.model import ObjectCloud
from pickdemo.perception.unknown import SeenObject, Survey
from pickdemo.worldmodel.instances import Instance, SceneView
from pickdemo.worldmodel.occupancy import Occupancy

#: An instance matches an object whose footprint's centre is within this (m), or within half the
#: shorter side of the larger of the two footprints.
MATCH_M = 0.02
#: ... or within this many sigmas of the two centres' uncertainty
MATCH_SIGMAS = 3.0
#: An object moved when its footprint's centre moved this far (m): its older views are dropped.
MOVED_M = 0.008
#: An object with this share of its points in the cells (this wide, m) of the target's seen points is a
#: piece of the target (an object nobody described that a view cut where its colour steps)
PIECE_SHARE = 0.3
PIECE_CELL_M = 0.005
#: An instance narrower than this across (m) makes no object of its own: a sliver of an edge.
MIN_SIDE_M = 0.006
#: An instance hidden in part whose centre is this near a known object's footprint is a piece of it (m).
PIECE_MARGIN_M = 0.01
#: A view shows an object whole when its footprint seen covers this share of the object's.
WHOLE_SHARE = 0.5
#: What a view showed only in part (cut off at its edge) is taken to reach this high over the table (m):
#: the rest of it is unseen (a region's view of a post beside the target shows its foot only).
PIECE_TOP_M = 0.5
#: ... and the grasps see its box's faces as points this far apart (m)
PIECE_SPACING_M = 0.005
#: ... and it is gone once a view reads the table's top (this high, m) all over its footprint
TABLE_SEEN_M = 0.005
#: Views in a row that should have shown an object and did not, and it is gone.
GONE_AFTER = 2
#: An instance whose top is this far above the held object's, as it stood, is it in the hand (m).
HELD_ABOVE_M = 0.01
#: Points an object keeps at most.
MAX_OBJECT_POINTS = 3000
#: A survey's object has as obstacles to its grasps the other objects' points this near (m, across the table).
SURVEY_NEAR_M = 0.25


@dataclass(frozen=True)
class PlaceView:
    """What the world knows standing at a spot (where something is to be put down), once a view showed
    all of it: the points (M, 3) of its objects within ``radius_m`` of ``xy``, the surface each stands
    for (M,) m^2, and the time of that view."""

    xy: tuple[float, float]
    radius_m: float
    points: np.ndarray
    time_s: float
    areas_m2: np.ndarray


@dataclass
class TrackedObject:
    """One object of the world, as seen so far."""

    id: int
    centre: np.ndarray  # (3,) m: the middle of its footprint, at half its top
    extents: tuple[float, float]  # its footprint's longer and shorter side seen (m)
    yaw_rad: float
    top_m: float
    colour: tuple[float, float, float]
    cov: np.ndarray  # (3, 3) its centre's covariance (m^2)
    first_seen_s: float
    last_seen_s: float
    views: int = 1
    missed: int = 0
    is_target: bool = False
    #: each camera's newest view of its points (world, m)
    by_camera: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    #: the surface seen that each of its points stands for (m^2: the newest view's, its area over its points)
    point_area_m2: float = 0.0
    #: where it stands was inferred, not seen (let go there, carried with the track): the next view of it moves it
    inferred: bool = False

    @property
    def points(self) -> np.ndarray:
        pts = [p for p in self.by_camera.values() if len(p)]
        return np.vstack(pts) if pts else np.zeros((0, 3))

    @property
    def box(self) -> OrientedBox:
        """Its footprint's box, from the table to its top."""
        c, s = np.cos(self.yaw_rad), np.sin(self.yaw_rad)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        half = np.array([self.extents[0] / 2.0, self.extents[1] / 2.0, self.top_m / 2.0])
        return OrientedBox(Pose(np.array([self.centre[0], self.centre[1], self.top_m / 2.0]), R), -half, half)

    def summary(self) -> dict:
        """What ``result.json``'s ``world`` says of it."""
        return {
            "id": self.id,
            "target": self.is_target,
            "centre_m": [round(float(v), 4) for v in self.centre],
            "size_m": [round(self.top_m, 4), round(self.extents[0], 4), round(self.extents[1], 4)],
            "sigma_mm": [round(float(np.sqrt(max(self.cov[i, i], 0.0))) * 1e3, 2) for i in range(3)],
            "colour": [round(c, 3) for c in self.colour],
            "first_seen_s": round(self.first_seen_s, 4),
            "last_seen_s": round(self.last_seen_s, 4),
            "views": self.views,
        }


class WorldModel:
    """Every object seen, kept across views (see the module docstring)."""

    def __init__(self) -> None:
        self.objects: dict[int, TrackedObject] = {}
        self.next_id = 1
        self.views = 0
        self.gone: list[int] = []  # the ids of objects gone, in order
        #: where the skill tracks its target (x, y) and how far from that its footprint may reach
        self._target_at: tuple[np.ndarray, float] | None = None
        self._held: int | None = None  # the id of the object in the hand
        self.occupancy = Occupancy()  # the space seen free, apart from the never seen
        #: what views showed in part and no object took (cut off at the edge of a region's view: an
        #: object that moved there, in part), kept until a view shows the table there or an object takes
        #: it: an obstacle to the arm, not an object (its boxes, from its points: :meth:`seen_in_part`)
        self.pieces: list[OrientedBox] = []

    # ---------------------------------------------------------------------------------- update
    def update(self, view: SceneView) -> None:
        """A view's instances matched to the objects (new ones added, missed ones counted)."""
        self.views += 1
        self.occupancy.add(view)
        matched: set[int] = set()
        pairs = []
        if self._held is not None:
            matched.add(self._held)  # (in the hand: no view moves it or misses it)
        for k, inst in enumerate(view.instances):
            for obj in self.objects.values():
                if obj.id == self._held:
                    continue
                d = float(np.hypot(*(inst.centre[:2] - obj.centre[:2])))
                # (within its footprint, or as far as the two centres' uncertainty reaches: a camera
                # known only to its calibration sees an object some centimetres from where another does)
                sigma = float(np.sqrt(0.5 * (inst.cov[0, 0] + inst.cov[1, 1] + obj.cov[0, 0] + obj.cov[1, 1])))
                gate = max(MATCH_M, 0.5 * max(min(inst.extents), min(obj.extents)), MATCH_SIGMAS * sigma)
                if d <= gate or _holds(obj, inst.centre):
                    pairs.append((d, k, obj.id))
        pairs.sort()
        taken: set[int] = set()
        for _, k, oid in pairs:
            if k in taken or oid in matched:
                continue
            taken.add(k)
            matched.add(oid)
            self._seen(self.objects[oid], view.instances[k], view)
        fresh: list[OrientedBox] = []
        for k, inst in enumerate(view.instances):
            if k in taken or self._in_hand(inst):
                continue
            if not self._piece(inst):  # (no object of its own)
                matched.add(self._add(inst, view))  # (new: this view showed it)
            elif inst.clipped and inst.extents[1] >= MIN_SIDE_M and not self._of_an_object(inst):
                lo, hi = inst.points.min(axis=0), inst.points.max(axis=0)
                lo[2], hi[2] = 0.0, max(hi[2], PIECE_TOP_M)  # (on the table; its unseen rest as high as that)
                fresh.append(OrientedBox(Pose.identity(), lo, hi))
        self._missed(view, matched)
        self.pieces = [b for b in self.pieces if self._piece_kept(b, fresh, view)] + fresh
        self._mark()

    def _add(self, inst: Instance, view: SceneView) -> int:
        obj = TrackedObject(self.next_id, inst.centre.copy(), inst.extents, inst.yaw_rad, inst.top_m,
                            inst.colour, inst.cov.copy(), view.time_s, view.time_s,
                            by_camera={view.camera: inst.points},
                            point_area_m2=inst.area_m2 / max(len(inst.points), 1))  # fmt: skip
        self.objects[obj.id] = obj
        self.next_id += 1
        return obj.id

    @staticmethod
    def _seen(obj: TrackedObject, inst: Instance, view: SceneView) -> None:
        obj.last_seen_s = view.time_s
        obj.missed = 0
        if inst.clipped:  # seen there, in part: what it is stays the whole views'
            return
        # (a view of it in part, something nearer hiding the rest, neither moves it nor shrinks it)
        # (and a piece of it is no evidence it moved: as large as it was, seen whole, elsewhere)
        whole = inst.area_m2 >= WHOLE_SHARE * obj.extents[0] * obj.extents[1]
        away = float(np.hypot(*(inst.centre[:2] - obj.centre[:2]))) > MOVED_M
        # (where it stands only inferred, a view of it in part is better evidence than none)
        moved = away and (obj.inferred or (not inst.hidden and whole))
        obj.inferred = False
        if moved:
            obj.by_camera = {}
        if moved or not inst.hidden or view.camera not in obj.by_camera:
            obj.by_camera[view.camera] = inst.points
            obj.point_area_m2 = inst.area_m2 / max(len(inst.points), 1)
        if len(obj.points) > MAX_OBJECT_POINTS:
            obj.by_camera = {view.camera: inst.points}
        # its footprint: the view's that shows more of it (a partial view of it keeps the whole one's)
        if moved or (not inst.hidden and inst.area_m2 >= 0.8 * obj.extents[0] * obj.extents[1]):
            obj.centre, obj.extents, obj.yaw_rad = inst.centre.copy(), inst.extents, inst.yaw_rad
            obj.top_m = inst.top_m if moved else max(obj.top_m, inst.top_m)
            obj.colour, obj.cov = inst.colour, inst.cov.copy()
        obj.centre[2] = 0.5 * obj.top_m
        obj.views += 1

    def _piece(self, inst: Instance) -> bool:
        """Whether an instance nothing matched is a piece of something: cut off at the image's edge, a
        sliver narrower than :data:`MIN_SIDE_M`, or with its centre in a known object's footprint (1 cm
        grown): two objects do not stand in one place (a view that cut one in two, or saw a part of it
        beside the hand, saw a piece of it)."""
        if inst.clipped or inst.extents[1] < MIN_SIDE_M:  # (a sliver beside the hand is an edge, not a thing)
            return True
        return self._of_an_object(inst)

    def _of_an_object(self, inst: Instance) -> bool:
        """Whether the instance's centre lies in a known object's footprint (a piece of it)."""
        return any(_holds(obj, inst.centre) for obj in self.objects.values())

    def seen_in_part(self) -> list[OrientedBox]:
        """The boxes of what views showed in part only (:attr:`pieces`)."""
        return list(self.pieces)

    def _piece_kept(self, box: OrientedBox, fresh: list[OrientedBox], view: SceneView) -> bool:
        """Whether a piece stays: no piece of this view stands on its footprint (the newer is kept), no
        object holds its middle, and this view does not show the table all over its footprint."""
        lo, hi = box.lo[:2], box.hi[:2]
        if any(np.all(f.lo[:2] <= hi) and np.all(lo <= f.hi[:2]) for f in fresh):
            return False
        mid = 0.5 * (lo + hi)
        if any(_holds(obj, mid) for obj in self.objects.values()):
            return False
        inner = lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo)
        xs, ys = (inner[0][0], mid[0], inner[1][0]), (inner[0][1], mid[1], inner[1][1])
        spots = np.array([[x, y, TABLE_SEEN_M] for x in xs for y in ys])
        return not bool(np.all(view.sees(spots)))

    def _in_hand(self, inst: Instance) -> bool:
        """Whether the instance is the held object seen in the hand (off the table, above where it was)."""
        if self._held is None or self._held not in self.objects:
            return False
        return inst.top_m - 2.0 * float(np.sqrt(inst.cov[2, 2])) > self.objects[self._held].top_m + HELD_ABOVE_M

    def _missed(self, view: SceneView, matched: set[int]) -> None:
        for oid in [o for o in self.objects if o not in matched]:
            obj = self.objects[oid]
            # it should have been seen: its top's middle in view, nothing nearer in front of it
            if bool(view.sees(np.array([[obj.centre[0], obj.centre[1], obj.top_m]]))[0]):
                obj.missed += 1
                if obj.missed >= GONE_AFTER:
                    del self.objects[oid]
                    self.gone.append(oid)

    # ---------------------------------------------------------------------------------- target
    def hold(self) -> None:
        """The hand holds the target: its object goes with the hand (no view misses it, none moves it;
        what is seen of it in the hand is the hand's), until :meth:`release`."""
        target = self.target
        self._held = None if target is None else target.id

    def release(self, position: np.ndarray | None) -> None:
        """The hand let the target go with its centre at ``position``: its object stands there now
        (None: where it stood, never lifted)."""
        if position is not None and self._held is not None and self._held in self.objects:
            obj = self.objects[self._held]
            shift = np.asarray(position, dtype=float)[:2] - obj.centre[:2]
            obj.centre[:2] += shift
            obj.by_camera = {k: v + np.array([shift[0], shift[1], 0.0]) for k, v in obj.by_camera.items()}
            obj.inferred = True
        self._held = None

    def mark_target(self, position: np.ndarray, reach_m: float, *, follow: bool = False) -> None:
        """The skill tracks its target at ``position``; its footprint reaches ``reach_m`` from there.
        ``follow`` (the track has just taken an estimate in: it is as fresh as any view): the target's
        object, when its footprint does not hold where the track is, goes there (a belt carries it, a
        push moves it out of the regions looked at; no view showed it there yet)."""
        xy = np.asarray(position, dtype=float)[:2].copy()
        target = self.target  # (the one it was: it goes where the track went, then is looked for there)
        if follow and target is not None and self._held is None and not _holds(target, xy):
            shift = xy - target.centre[:2]
            target.centre[:2] += shift
            target.by_camera = {k: v + np.array([shift[0], shift[1], 0.0]) for k, v in target.by_camera.items()}
            target.inferred = True
        self._target_at = (xy, float(reach_m))
        self._mark()

    def _mark(self) -> None:
        was, target = self.target, self._find_target()
        if was is not None and target is not None and target.id != was.id and was.last_seen_s <= target.first_seen_s:
            # the target's object, no view of it since another appeared where the track now is: it
            # moved there (a belt, a push), and is that one (its id kept, what it was left behind)
            was.centre, was.extents, was.yaw_rad, was.top_m = (
                target.centre,
                target.extents,
                target.yaw_rad,
                target.top_m,
            )
            was.colour, was.cov, was.by_camera = target.colour, target.cov, target.by_camera
            was.point_area_m2 = target.point_area_m2
            was.last_seen_s, was.views = target.last_seen_s, was.views + target.views
            del self.objects[target.id]
            target = was
        for obj in self.objects.values():
            obj.is_target = target is not None and obj.id == target.id

    def _find_target(self) -> TrackedObject | None:
        if self._target_at is None:
            return None
        xy, reach = self._target_at
        at = np.array([[xy[0], xy[1], 0.0]])
        best, best_key = None, (True, np.inf)
        for obj in self.objects.values():
            d = float(np.hypot(*(obj.centre[:2] - xy)))
            if d > reach + 0.5 * obj.extents[1]:
                continue
            key = (not _holds(obj, at[0]), d)  # (its footprint holding where the target is first, then the nearest)
            if key < best_key:
                best, best_key = obj, key
        return best

    @property
    def target(self) -> TrackedObject | None:
        return next((o for o in self.objects.values() if o.is_target), None)

    # --------------------------------------------------------------------------------- queries
    def obstacles(
        self, at: np.ndarray, within_m: float, own: tuple[float, float] | None = None, seen: np.ndarray | None = None
    ) -> np.ndarray:
        """The points (M, 3) of every object but the target within ``within_m`` (across the table) of
        ``at``, the target's position. ``own``: the target's known size, (the radius of its footprint's
        circle with its margin, its top's height with it): then an object standing within that circle
        no taller than the target is a piece of it (a view cut it in two where its colour steps), and the target's own
        object, when its footprint is wider than the target (something flush against it that no view
        told apart from it), keeps its points outside the circle, whatever the target's yaw; None
        (nothing known of its size): the target's object is the target, and ``seen`` (its points as
        perception saw it, an object nobody described) says which other objects are pieces of it (a
        share :data:`PIECE_SHARE` of their points in its cells)."""
        cells = (
            None if seen is None or len(seen) == 0 else set(map(tuple, np.floor(seen / PIECE_CELL_M).astype(np.int64)))
        )
        out = []
        for obj in self.objects.values():
            p = obj.points
            if len(p) == 0:
                continue
            if cells is not None and not obj.is_target:
                mine = np.floor(p[:: max(1, len(p) // 200)] / PIECE_CELL_M).astype(np.int64)
                if np.mean([tuple(c) in cells for c in mine]) >= PIECE_SHARE:
                    continue  # a piece of the target, as perception saw it
            d_obj = float(np.hypot(*(obj.centre[:2] - at[:2])))
            if own is not None and not obj.is_target and d_obj <= own[0] and obj.top_m <= own[1]:
                continue  # a piece of the target: no taller than it, standing within it
            if obj.is_target and (own is None or obj.extents[0] <= 2.0 * own[0]):
                continue
            d = np.hypot(p[:, 0] - at[0], p[:, 1] - at[1])
            keep = d <= within_m
            if obj.is_target:
                keep &= (d > own[0]) | (p[:, 2] > own[1])
            if keep.any():
                out.append(p[keep])
        pieces = tuple(self.seen_in_part())
        if pieces:  # (what a view showed in part: its box's faces, as a fixture's are seen)
            p = box_surface_points(pieces, PIECE_SPACING_M)
            out.append(p[np.hypot(p[:, 0] - at[0], p[:, 1] - at[1]) <= within_m])
        return np.vstack(out) if out else np.zeros((0, 3))

    def survey(self, view: SceneView) -> Survey:
        """What stands on the table as ``view`` showed it (a clear round's look, its next object chosen
        among them): each of the view's instances (slivers left out), largest first, with its points
        and, as obstacles to its grasps, every other instance's points within :data:`SURVEY_NEAR_M`,
        and those of the objects the world keeps that this view did not show (hidden behind another)."""
        kept = [o.points for o in self.objects.values() if o.id != self._held and o.last_seen_s < view.time_s]
        unseen = np.vstack([p for p in kept if len(p)]) if any(len(p) for p in kept) else np.zeros((0, 3))
        insts = [i for i in view.instances if i.extents[1] >= MIN_SIDE_M]
        out = []
        for k, inst in enumerate(insts):
            near = np.vstack([unseen, *(o.points for j, o in enumerate(insts) if j != k)])
            near = near[np.hypot(near[:, 0] - inst.centre[0], near[:, 1] - inst.centre[1]) < SURVEY_NEAR_M]
            cloud = ObjectCloud(points=inst.points, obstacles=near, time_s=view.time_s, depth_m=view.depth_m,
                                intrinsics=view.intrinsics, T_world_cam=view.T_world_cam)  # fmt: skip
            centre = np.array([inst.centre[0], inst.centre[1], 0.5 * inst.top_m])
            out.append(SeenObject(centre, (inst.top_m, *inst.extents), len(inst.points), cloud))
        return Survey(tuple(out), view.time_s)

    def standing_near(self, xy: tuple[float, float], radius_m: float) -> tuple[np.ndarray, np.ndarray]:
        """The points (M, 3) of every object on the table within ``radius_m`` of ``xy``, across the table,
        and the surface each stands for (M,): what stands at a spot. The target's object (held, or
        standing near the spot after a place that missed) is the target, not something in its way."""
        kept = [o for o in self.objects.values() if o.id != self._held and not o.is_target and len(o.by_camera)]
        if not kept:
            return np.zeros((0, 3)), np.zeros(0)
        p = np.vstack([o.points for o in kept])
        a = np.concatenate([np.full(len(o.points), o.point_area_m2) for o in kept])
        near = np.hypot(p[:, 0] - xy[0], p[:, 1] - xy[1]) <= radius_m
        return p[near], a[near]

    def classify(self, points: np.ndarray) -> np.ndarray:
        """(N,) int8 per point: occupied, free or never seen (:mod:`~pickdemo.worldmodel.occupancy`)."""
        return self.occupancy.classify(points, [o.box for o in self.objects.values()])

    def octree(self, *, but_target: bool = True):  # noqa: ANN201 - a coal.OcTree or None
        """The objects' boxes as coal's octree (the target's left out: the hand goes to it)."""
        return self.occupancy.octree([o.box for o in self.objects.values() if not (but_target and o.is_target)])

    def summary(self) -> list[dict]:
        """Every object, for ``result.json``."""
        return [o.summary() for o in sorted(self.objects.values(), key=lambda o: o.id)]


def _holds(obj: TrackedObject, at: np.ndarray) -> bool:
    """Whether the object's footprint, :data:`PIECE_MARGIN_M` grown, holds the point ``at`` (x, y)."""
    dx, dy = float(at[0]) - float(obj.centre[0]), float(at[1]) - float(obj.centre[1])
    c, s = np.cos(obj.yaw_rad), np.sin(obj.yaw_rad)
    return (
        abs(c * dx + s * dy) <= 0.5 * obj.extents[0] + PIECE_MARGIN_M
        and abs(-s * dx + c * dy) <= 0.5 * obj.extents[1] + PIECE_MARGIN_M
    )
