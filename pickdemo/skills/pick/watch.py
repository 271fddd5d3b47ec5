"""What moved: views refused far from where the target is tracked (the target moved under the hand),
a finger touching something on the way down, and the hand's camera's view of a hold off centre. A
part of the pick skill: it keeps its own runs of views and says what it saw (a reason, a move),
never writes the machine's state."""

from __future__ import annotations

import numpy as np

from pickdemo.core.interfaces import Observation
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.perception import TargetModel
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.pick.params import MachineParams
from pickdemo.tracking.belief import Offered, TargetBelief, Verdict


class MoveWatch:
    """Watches the target under the hand through every camera's views and the fingers' contacts."""

    def __init__(
        self,
        kin: Kinematics,
        params: MachineParams,
        model: TargetModel,
        belief: TargetBelief,
        hand_cameras: frozenset[str],
        *,
        open_loop: bool,
    ) -> None:
        self.kin, self.p, self.model, self.belief = kin, params, model, belief
        self.hand_cameras = hand_cameras
        self.open_loop = open_loop
        #: per camera: views refused far from the track, in a row (how far, where seen, partial or not)
        self._far_views: dict[str, list[tuple[float, np.ndarray | None, bool]]] = {}
        #: the target moved under the hand: how far, seen by which camera, in the frame of when
        self._moved_seen: tuple[float, str, float] | None = None
        self._move_unconfirmed = False  # it backed off on a move the tracker has not confirmed (yet)
        self._touch_back_offs = 0  # backed off this often on a finger touching something in the descent
        self._touched_at: np.ndarray | None = None  # where the grasp was when a finger last touched (x, y)
        self._held_at: float | None = None  # closing: when the fingers were found holding it
        self._hold_views: list[tuple[float, np.ndarray]] = []  # closing: the hand camera's whole views (t, centre)

    # ======================================================================= under the hand
    def offered(
        self, offered: Offered, camera: str, frame_time_s: float, seen: np.ndarray | None, *, hand_over_target: bool
    ) -> None:
        """With the hand over the target, views of it that are refused, ``moved_views`` of them in a row
        from one camera, each farther than ``moved_tolerance_m`` from where it is tracked (and than a view
        of it there could be off), one at least a whole view (after a far view, a frame in which the model
        fits nothing counts too): the target moved under the hand (the tracker confirms where to only
        once it is at rest again; until it does, no views send the hand back again). Meanwhile each
        camera also looks where it last saw it (:meth:`far_seen`)."""
        if offered.jumped:
            self._move_unconfirmed = False
        if self.belief.unknown:  # told from its neighbours only by where it is: a view far off may be one
            return
        if not self.hand_cameras:  # the fixed camera alone sees the hand over it: its views there mislead
            return
        if self._move_unconfirmed:
            return  # views said it moved before, and the tracker never found it moved: not again until it does
        # How far off a view may be and still be of the target where it is tracked: a partial view's
        # centre up to half its top face; a whole one's, from the fixed camera, up to the share of the
        # face a view may miss and still pass as whole (the fingers hide an edge of a large face; the
        # hand's camera sees past them).
        extents = self.belief.top_extents_m
        half = max(extents) / 2.0 if extents is not None else self.model.geometry.footprint_radius_m
        whole = 0.0 if camera in self.hand_cameras else self.p.gate.face_size_tolerance * half  # (its fingers)
        far = self.p.moved_tolerance_m + (half if offered.partial else whole)
        if offered.verdict is Verdict.ACCEPTED:  # where it is tracked, as a camera sees it: no run goes on
            self._far_views.clear()
            return
        run = self._far_views.get(camera)
        if offered.verdict is Verdict.NO_ESTIMATE and run and hand_over_target:
            run.append(run[-1])  # after a far view, the model fits nothing where it was tracked: on the run goes
            self._judge_run(run, camera, frame_time_s)
            return
        if offered.off_m is None or offered.off_m <= far:
            if offered.off_m is not None and not offered.partial:
                self._far_views.pop(camera, None)  # a near whole view ends its camera's run (no view does not)
            return
        if not hand_over_target:
            return
        run = self._far_views.setdefault(camera, [])
        run.append((offered.off_m, seen, offered.partial))
        self._judge_run(run, camera, frame_time_s)

    def _judge_run(self, run: list, camera: str, frame_time_s: float) -> None:
        """``moved_views`` in a row, one of them at least a whole view (partial views alone can mislead
        consistently: the fixed camera's, of the face the hand leaves): it moved (evidence:
        docs/decisions.md#the-loop-and-the-tracker)."""
        if len(run) >= self.p.moved_views and any(not partial for *_, partial in run):
            self._moved_seen = (max(off for off, *_ in run), camera, frame_time_s)

    def far_seen(self, camera: str) -> np.ndarray | None:
        """Where a camera last saw the target far from where it is tracked (a run under way), or None."""
        run = self._far_views.get(camera)
        return None if not run else run[-1][1]

    def forget_move(self) -> None:
        """A descent begins: no move seen under the hand yet."""
        self._moved_seen = None

    def moved(self) -> tuple[float, str, float] | None:
        """The target moved under the hand: (how far, seen by which camera, in the frame of when), once;
        the views' runs start afresh, and no views say so again until the tracker finds where it went."""
        if self._moved_seen is None:
            return None
        seen, self._moved_seen = self._moved_seen, None
        self._far_views.clear()
        self._move_unconfirmed = True
        return seen

    # ============================================================================ the fingers
    def touched(self, obs: Observation, plan: GraspPlan) -> str | None:
        """Which finger touched something on the way down, and how far above the grasp (None: no news).
        The fingers go down beside the target, in free space, so a touch means the target (or
        something else) is not where it was seen; closing there would close on nothing or on it
        askew. The fixed camera, with the hand over the target, cannot say so; the fingers can. At
        most ``touch_back_offs`` times (then the descent goes on as before), and not again where it
        touched before if the look since found the target there (a neighbour brushed, not a move).
        Not for an object nobody described: its grasps, from its cloud, go down close to its surface,
        so a finger brushing it is no news (evidence: docs/decisions.md#the-loop-and-the-tracker)."""
        left, right = obs.finger_contacts
        if not (left or right) or self._touch_back_offs >= self.p.touch_back_offs:
            return None
        if self.belief.unknown or self.open_loop:  # (open loop: one look and the plan played, no feedback)
            return None
        grasp_xy = plan.grasp.position[:2]
        if self._touched_at is not None and np.linalg.norm(grasp_xy - self._touched_at) < self.p.moved_tolerance_m:
            return None  # touched here before, and the look since found the target where it was: a neighbour
        self._touched_at = grasp_xy.copy()
        self._touch_back_offs += 1
        above = (float(self.kin.forward(obs.arm_q).position[2]) - float(plan.grasp.position[2])) * 1e3
        which = "both fingers" if left and right else ("the left finger" if left else "the right finger")
        return f"{which} touched something {above:.0f} mm above the grasp during the descent"

    # =============================================================================== the hold
    def start_hold(self) -> None:
        """The fingers begin to close: the hand camera's views of the hold start afresh."""
        self._held_at = None
        self._hold_views.clear()

    def hold_view(self, frame_time_s: float, seen: np.ndarray) -> None:
        """A plausible whole view of the target from a camera on the hand, while closing."""
        self._hold_views.append((frame_time_s, seen.copy()))

    def held_off_centre(self, obs: Observation, plan: GraspPlan) -> str | bool | None:
        """Held, the width right: whether the hand's camera sees it held off centre (a reason), cannot
        say yet (False: a view of the hold is on its way) or sees nothing wrong (None). The fingers
        centre it between them, not along them: pushed as they closed, it may be held near an end of
        a face and carried that far from where it should go. A whole view from a frame taken once the
        fingers held it, within ``hold_look_s``; no view (or no camera on the hand): as before, lifted.
        Not for an object nobody described (a grasp from its cloud holds it anywhere)."""
        if not self.hand_cameras or self.open_loop or self.belief.unknown:
            return None
        if self._held_at is None:
            self._held_at = obs.time_s
        views = [c for t, c in self._hold_views if t >= self._held_at]
        if not views:
            return False if obs.time_s - self._held_at < self.p.hold_look_s else None
        tcp = self.kin.forward(obs.arm_q).position[:2]
        off = float(np.linalg.norm(tcp - views[-1][:2] - np.asarray(plan.place_offset_xy)))
        if off <= self.p.off_centre_tolerance_m:
            return None
        return f"the hand's camera sees it held {off * 1e3:.0f} mm off centre"
