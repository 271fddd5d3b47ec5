"""The robot's belief about one target: the tracker, and the gate every estimate passes on its way in.

Pure: no simulator. :meth:`TargetBelief.offer` takes what perception made of a frame (an estimate,
or its word that it found none) and says what became of it (:class:`Verdict`): an estimate that
cannot be the target resting where the cell's layout says it rests, one less sure than any grasp
tolerates, or (while the hand is over the target) one that saw only part of its top face, is
rejected before the tracker sees it; the rest go to the tracker, whose gate may reject them too.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pickdemo.core.shapes import Unknown
from pickdemo.perception import ObjectCloud, PerceptionError, PoseEstimate, TargetModel
from pickdemo.tracking.tracker import TargetTracker, TrackedPose, TrackerParams

#: Moving or not is decided on the track's accepted positions over this long (s, up to the newest) ...
MOVING_WINDOW_S = 1.5
#: ... once there are this many, spanning this long (before: the tracker's speed against 3 sigma)
MOVING_WINDOW_MIN = 5
MOVING_WINDOW_MIN_SPAN_S = 0.5
#: A straight-line fit's speed beyond this many standard errors (and the least speed) is moving; a
#: moving target has stopped once its fit's speed is under half of both (hysteresis)
MOVING_SIGMAS = 5.0
#: The least standard error of a position in the fit (m): the estimates' noise is never nil
MOVING_POSITION_FLOOR_M = 0.0005


class Verdict(str, enum.Enum):
    """What became of an estimate offered to the controller."""

    ACCEPTED = "accepted"  # fused into the belief
    REJECTED = "rejected"  # implausible, a partial view under the hand, or beyond the tracker's gate
    NO_ESTIMATE = "no estimate"  # perception found none (or its own fit check refused it)
    UNUSED = "unused"  # the controller was not looking


@dataclass
class Counters:
    """What the controller counted of perception and motion (reported in ``EpisodeResult``)."""

    estimates: int = 0
    rejected: int = 0
    perception_errors: int = 0
    jumps: int = 0
    retargets: int = 0
    last_error: str = ""


@dataclass(frozen=True)
class GateParams:
    """When an estimate is no use, whatever the tracker would say; SI units."""

    max_sigma_m: float = 0.005  # an estimate noisier than this (its camera's calibration aside) is no use to a grasp
    table_gap_m: float = 0.008  # a resting target has its centre at half its height, give or take
    face_size_tolerance: float = 0.2  # a top face measured this far off the model's size: a partial view


@dataclass(frozen=True)
class Offered:
    """An estimate's fate: the verdict, and whether the track restarted on it (the target moved)."""

    verdict: Verdict
    jumped: bool = False
    #: a view refused (by the tracker's gate, or as a partial one under the hand): how far (m, across
    #: the table) from where the track has the target; whether it saw only part of the target
    off_m: float | None = None
    partial: bool = False


class TargetBelief:
    """One tracked target: its :class:`~pickdemo.tracking.tracker.TargetTracker` and the gate in front of it."""

    def __init__(
        self,
        model: TargetModel,
        symmetry_rad: float,
        tracker_params: TrackerParams,
        gate: GateParams,
        *,
        surface_z: Callable[..., float],
        counters: Counters,
    ) -> None:
        """``surface_z(x, y, z)``: the height of what a target at (x, y), its centre at ``z``, rests on (a
        belt's top, the table, a shelf's board)."""
        self.model = model
        self.symmetry = symmetry_rad
        self.tracker_params = tracker_params
        self.gate = gate
        self.surface_z = surface_z
        self.counters = counters
        self.tracker = TargetTracker(symmetry_rad, tracker_params)
        self._velocity_cache: tuple[tuple, np.ndarray | None] | None = None
        #: the track's accepted positions over the last ``MOVING_WINDOW_S`` (time, x, y, variance), and
        #: whether it is moving as last decided (on which track, after how many accepted estimates)
        self._seen: list[tuple[float, float, float, float]] = []
        self._moving = False
        self._decided: tuple[int, int] | None = None
        self.unknown = isinstance(model.geometry, Unknown)
        #: an object nobody described: the newest cloud seen of it whole with the hand away, or the
        #: first seen at all until then (grasps are planned from it); its extents as first seen on this track
        self.cloud: ObjectCloud | None = None
        self._extents: tuple[float, float] | None = None
        #: the points of everything near it, from the newest accepted estimate that saw all around it
        #: with the hand away (:attr:`~pickdemo.perception.model.PoseEstimate.neighbours`; None: not seen)
        self.neighbours: np.ndarray | None = None

    @property
    def top_extents_m(self) -> tuple[float, float] | None:
        """Its top face's extents: the model's, or for an object nobody described as first seen on this
        track (None: not seen yet)."""
        return self._extents if self.unknown else self.model.geometry.top_extents_m

    def restart(self) -> None:
        """Forget the target: the next estimate starts a new track."""
        self.tracker = TargetTracker(self.symmetry, self.tracker_params)
        self._extents = None
        self.neighbours = None
        self._seen, self._moving, self._decided = [], False, None

    @property
    def initialised(self) -> bool:
        return self.tracker.initialised

    @property
    def accepted(self) -> int:
        return self.tracker.accepted

    def predict(self, t_s: float) -> TrackedPose:
        return self.tracker.predict(t_s)

    def lost(self, t_s: float) -> bool:
        return self.tracker.lost(t_s)

    # ============================================================================== the gate
    def offer(
        self,
        result: PoseEstimate | PerceptionError,
        frame_time_s: float,
        *,
        hand_over_target: bool,
        camera: str = "camera",
    ) -> Offered:
        """Gate and fuse what perception made of a frame taken at ``frame_time_s``. While the hand is
        over the target a view of part of its top face is not acted on (it can mislead the fit
        consistently); the tracker predicts through. ``camera``: which camera took the frame."""
        verdict = Verdict.NO_ESTIMATE
        off: tuple[float | None, bool] = (None, False)
        if isinstance(result, PoseEstimate):
            implausible = self.implausible(result)
            if not implausible and hand_over_target and not self.complete_view(result):
                implausible = "a partial view: its top face measures off the model's size"
                off = (self._off_track(result, frame_time_s), True)
            if implausible:
                result = PerceptionError(implausible)
                verdict = Verdict.REJECTED
        if isinstance(result, PerceptionError):
            self.counters.perception_errors += 1
            self.counters.last_error = str(result)
            return Offered(verdict, off_m=off[0], partial=off[1])
        self.counters.estimates += 1
        up = self.tracker.update(result, frame_time_s, partial=not self.complete_view(result), source=camera)
        if not up.accepted:
            self.counters.rejected += 1
        if not up.accepted:
            off = (self._off_track(result, frame_time_s), not self.complete_view(result))
        if up.jumped:
            self.counters.jumps += 1
            self._seen, self._moving = [], False  # a new track: moving or not is decided afresh
        if up.accepted:
            p = result.pose.position
            var = float(np.mean(np.diag(result.position_cov)[:2]))  # its stated variance across the table
            self._seen.append((frame_time_s, float(p[0]), float(p[1]), var))
            self._seen = [s for s in self._seen if s[0] >= frame_time_s - MOVING_WINDOW_S]  # (the window only)
        if up.accepted and result.neighbours is not None and not hand_over_target:
            self.neighbours = result.neighbours
        if up.accepted and self.unknown and result.cloud is not None and not hand_over_target:
            if self._extents is None or up.jumped:
                self._extents = result.top_face_size_m
            if self.complete_view(result) or self.cloud is None:  # a partial view until a whole one comes
                self.cloud = result.cloud
        verdict = Verdict.ACCEPTED if up.accepted else Verdict.REJECTED
        return Offered(verdict, jumped=up.jumped, off_m=off[0], partial=off[1])

    def _off_track(self, est: PoseEstimate, frame_time_s: float) -> float | None:
        """How far (m, across the table) an estimate lies from where the track has the target then."""
        if not self.tracker.initialised:
            return None
        return float(np.linalg.norm(est.pose.position[:2] - self.tracker.predict(frame_time_s).position[:2]))

    def implausible(self, est: PoseEstimate) -> str:
        """Why an estimate cannot be the target resting on the table or the belt ("" if it can): not
        finite, an uncertainty beyond anything the grasp tolerates, or floating above / sunk into what
        it rests on."""
        p = est.pose.position
        if not (np.all(np.isfinite(p)) and np.all(np.isfinite(est.position_cov))):
            return "estimate not finite"
        # (its camera's calibration aside: a bias the same in every frame, weighed against the grasp's
        # clearance before the hand goes down, where another camera may have corrected it)
        cov = est.frame_cov if est.calibration_cov is None else est.frame_cov - est.calibration_cov
        sigma = float(np.sqrt(max(np.max(np.linalg.eigvalsh(cov)), 0.0)))
        if sigma > self.gate.max_sigma_m:
            return f"estimate too uncertain ({sigma * 1e3:.1f} mm)"
        surface = self.surface_z(float(p[0]), float(p[1]), float(p[2]))
        if self.unknown:  # its features lie on it: between what it rests on and its size bound above
            if float(p[2]) < surface - self.gate.table_gap_m - self._calibration_slack(est):
                return f"estimate sinks {(surface - float(p[2])) * 1e3:.0f} mm into what it rests on"
            if float(p[2]) > surface + self.model.height_m + self._calibration_slack(est):
                return f"estimate floats {(float(p[2]) - surface) * 1e3:.0f} mm above what it rests on"
            return ""
        gap = float(p[2]) - surface - self.model.height_m / 2.0
        if abs(gap) > self.gate.table_gap_m + self._calibration_slack(est):
            where = "above" if gap > 0 else "into"
            what = "the table" if surface == 0.0 else "the belt"
            return f"estimate {'floats' if gap > 0 else 'sinks'} {abs(gap) * 1e3:.0f} mm {where} {what}"
        return ""

    @staticmethod
    def _calibration_slack(est: PoseEstimate) -> float:
        """How far (m, 3 sigma) its camera's calibration may put an estimate above or below where it is."""
        return 0.0 if est.calibration_cov is None else 3.0 * float(np.sqrt(est.calibration_cov[2, 2]))

    def complete_view(self, estimate: PoseEstimate) -> bool:
        """Whether the estimate saw the whole top face: its measured extents within
        ``face_size_tolerance`` of the model's. A partly hidden face (the hand over it while it
        descends) can mislead the fit consistently, so only a complete view may restart the track."""
        if self.unknown:  # seen whole, and its extents as first seen on this track
            if estimate.occluded:
                return False
            expected = self._extents if self._extents is not None else estimate.top_face_size_m
        else:
            expected = self.model.geometry.top_extents_m
        measured = sorted(estimate.top_face_size_m, reverse=True)
        tol = self.gate.face_size_tolerance
        return all(abs(m - e) <= tol * e for m, e in zip(measured, expected, strict=True))

    # ========================================================================= a moving target
    def moving_velocity(self, now_s: float, min_speed_m_s: float) -> np.ndarray | None:
        """The target's horizontal velocity (m/s) while it is moving; None when it is at rest.

        Moving or not is a decision, taken again on each accepted estimate and held between them (the
        hand hiding the target changes nothing): a straight line fitted to the track's positions over
        the last ``MOVING_WINDOW_S`` moves faster than ``min_speed_m_s`` and ``MOVING_SIGMAS`` standard
        errors of its slope; a moving target has stopped once the fit's speed falls under half of
        both. (A slow belt is told from the noise by the line, where the tracker's speed
        alone, sure only to a centimetre a second, is not.) Until the track has such a window: the
        tracker's speed against ``min_speed_m_s`` and 3 sigma."""
        if not self.tracker.initialised:
            return None
        at = (id(self.tracker), self.tracker.accepted)
        if self._decided != at:
            self._decided = at
            self._moving = self._decide(min_speed_m_s)
        if not self._moving:
            return None
        key = (now_s, id(self.tracker), self.tracker.accepted)  # the belief changes only on an accept
        if self._velocity_cache is not None and self._velocity_cache[0] == key:
            return self._velocity_cache[1].copy()  # type: ignore[union-attr]
        v = self.tracker.predict(now_s).velocity[:2].copy()
        self._velocity_cache = (key, v)
        return v.copy()

    def _decide(self, min_speed_m_s: float) -> bool:
        fit = self._line_fit()
        if fit is not None:
            speed, se = fit
            if self._moving:
                return speed >= max(0.5 * min_speed_m_s, 0.5 * MOVING_SIGMAS * se)
            return speed > max(min_speed_m_s, MOVING_SIGMAS * se)
        tp = self.tracker.predict(self._seen[-1][0] if self._seen else 0.0)
        speed = float(np.linalg.norm(tp.velocity[:2]))
        if self._moving:
            return speed >= 0.5 * min_speed_m_s
        sigma = float(np.sqrt(max(np.max(np.linalg.eigvalsh(tp.covariance[4:6, 4:6])), 0.0)))
        return speed > max(min_speed_m_s, 3.0 * sigma)

    def _line_fit(self) -> tuple[float, float] | None:
        """The speed (m/s) of a straight line through the track's positions over the last window, and
        its standard error; None when the window holds too few, or too short a span."""
        if not self._seen:
            return None
        newest = self._seen[-1][0]
        pts = np.array([s for s in self._seen if s[0] >= newest - MOVING_WINDOW_S])
        if len(pts) < MOVING_WINDOW_MIN or pts[-1, 0] - pts[0, 0] < MOVING_WINDOW_MIN_SPAN_S:
            return None
        t = pts[:, 0] - pts[:, 0].mean()
        stt = float(t @ t)
        xy = pts[:, 1:3] - pts[:, 1:3].mean(axis=0)
        v = (t @ xy) / stt  # (2,) the slope of each axis
        resid = xy - np.outer(t, v)
        # a position's variance: what the residuals say, or what the estimates said of themselves if more
        s2 = max(
            float(np.sum(resid**2)) / (2.0 * (len(pts) - 2)), float(np.mean(pts[:, 3])), MOVING_POSITION_FLOOR_M**2
        )
        return float(np.linalg.norm(v)), float(np.sqrt(s2 / stt))
