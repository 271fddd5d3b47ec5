"""The pick skill's states that go to the target: LOOK, APPROACH and DESCEND (CLOSE, the hold, is
:mod:`~pickdemo.skills.pick.close`'s); each state's entry action (run once, when it is entered) and
exit test (run every tick), as functions of the machine (:mod:`~pickdemo.skills.pick.states` holds
the table the machine dispatches from)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.core.interfaces import Observation
from pickdemo.core.result import Stage
from pickdemo.grasping.side_plans import LEAST_LIFT_M
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.motion.ik_goals import line_trackable
from pickdemo.motion.lines import line_in_joints
from pickdemo.motion.online import hand_frame
from pickdemo.skills.pick.params import Event, State, Transition
from pickdemo.skills.pick.plans import half_turn, moved_place, turned_plan
from pickdemo.skills.pick.views import unsure

if TYPE_CHECKING:  # (the machine imports this table: a type only, for the reader and the checker)
    from pickdemo.skills.pick.machine import PickMachine

#: Whether the arm at ``q`` may go to a goal of the pose of index ``i`` (:meth:`.arm.ArmDriver.goal`).
Accept = Callable[[np.ndarray, int], bool]


def wrist_load(m: PickMachine, obs: Observation) -> float:
    """The wrist's load along world z (N)."""
    rotation = m.kin.forward(obs.arm_q).rotation
    return m.scale.vertical(obs, rotation if m.sensor_in_tcp is None else rotation @ m.sensor_in_tcp)


def _tilt(plan: GraspPlan) -> str:
    """How a grasp from the side is said: its approach's tilt from straight down ("" for a top-down one)."""
    down = -float(plan.grasp.rotation[2, 2])
    tilt = float(np.degrees(np.arccos(np.clip(down, -1.0, 1.0))))
    return f", from the side: tilted {tilt:.0f} deg" if tilt > 0.1 else ""


def _wrap(yaw_rad: float, period_rad: float) -> float:
    """The yaw in [-period/2, period/2): how a symmetric shape's yaw is said (a cube's modulo 90 deg)."""
    return float((yaw_rad + period_rad / 2.0) % period_rad - period_rad / 2.0)


# ---- LOOK: from the home pose, full frames until the tracker holds the target.
def enter_look(m: PickMachine, obs: Observation) -> None:
    if not m.events:
        m.events.append(Event(State.LOOK, obs.time_s, "looking for the target", note=True))
    m.grip.open()
    m.attempt_start_s = obs.time_s
    if m.last_at is None and m.belief.initialised:  # looking again: about where it was tracked last
        m.last_at = m.belief.predict(obs.time_s).position.copy()
    m.belief.restart()
    m.scale.start()
    m.weighed_force_n = 0.0
    m.look_frames = 0
    m.looked_from, m.no_aside = [], False
    m.searched, m.search_camera = [], None
    m.moved_from, m.shadow_moves = None, 0
    m.keep_hold = False
    m.fresh_estimate = False
    if m.look_here:  # the first look, from where the arm is (at rest)
        m.look_here = False
        return
    go_home(m)


def go_home(m: PickMachine) -> None:
    """Home, in joint space around what is in the way where the straight way meets it (else as
    :meth:`~pickdemo.skills.pick.arm.ArmDriver.home` goes)."""
    clear = None
    if m.p.plan_around and m.p.joint_transfers:
        scene = m.router.scene(m.world)
        route = m.router.joint(scene, m.arm.q, m.arm.home_q, m.grip.finger_max_m)
        m.note(route.note)
        if route.failure is not None:
            m.fail(Stage.MOTION_PLANNING, f"home: {route.failure}")
            return
        if route.waypoints is not None:
            m.arm.follow(route.waypoints, m.p.transfer_scale)
            return
        clear = m.router.clearance(scene, m.grip.finger_max_m)
    m.note(m.arm.home(clear))


def tick_look(m: PickMachine, obs: Observation) -> Transition:
    if m.arm.finished:  # at rest with the hand empty: what the wrist reads is the hand
        m.scale.tare(wrist_load(m, obs))
    needed = 1 if m.open_loop else m.p.look_min_estimates
    if m.belief.accepted >= needed:
        plan = m.replan(first=True)
        if plan is None:
            return None
        found = m.place_finder.spot(m.place_view, obs.time_s, plan)
        tried = [plan.hand_yaw_rad]
        while isinstance(found, str):  # the hand let go across other faces, if the target has them?
            other = m.replan(first=True, avoid=tuple(tried))
            if other is None:
                return None
            if any(abs(_wrap(other.hand_yaw_rad - yaw, np.pi)) < np.pi / 4 for yaw in tried):
                break  # (no other faces)
            tried.append(other.hand_yaw_rad)
            plan, found = other, m.place_finder.spot(m.place_view, obs.time_s, other)
        if isinstance(found, str):  # (put down there, it would stand on it, or be pressed into it)
            m.fail(Stage.PLACE, f"{found}: the target was not picked")
            return None
        spot, m.release_m = found
        if m.release_m is not None:
            m.note(f"something stands near the place: letting go with the fingers {m.release_m * 1e3:.0f} mm open each")
        if spot != m.place_xy:
            task = m.place_finder.place_xy
            off = float(np.hypot(spot[0] - task[0], spot[1] - task[1]))
            m.note(f"something stands at the place: putting the target down at ({spot[0]:.3f}, {spot[1]:.3f}), "
                   f"{off * 1e3:.0f} mm from it")  # fmt: skip
            plan = moved_place(plan, (spot[0] - m.place_xy[0], spot[1] - m.place_xy[1]))
            m.put_down_at(spot)
        m.plan = plan
        m.last_at = None  # (found: its track goes on from here)
        if m.chooser.descent_drop_m:
            m.note(f"the descent starts {m.chooser.descent_drop_m * 1e3:.0f} mm lower: from higher, no angle of "
                   "the hand has a descent the arm can follow")  # fmt: skip
        # (more frames cannot mend that)
        unsafe = unsure(m.belief, plan, obs.time_s, m.p, plan.open_m or m.grip.finger_max_m, calibration_only=True)
        if unsafe and (not m.hand_cameras or m.open_loop):
            m.fail(Stage.PERCEPTION, f"{unsafe}, and no camera can see it closer: not tried")
            return None
        tp = m.belief.predict(obs.time_s)
        yaw = ""
        if m.symmetry > 0:
            said = np.degrees(_wrap(tp.yaw_rad, m.symmetry))
            yaw = f", yaw {said:+.2f} deg (modulo {np.degrees(m.symmetry):.0f})"
        return State.APPROACH, (
            f"target at ({tp.position[0]:.4f}, {tp.position[1]:.4f}, {tp.position[2]:.4f}) m{yaw} "
            f"from {m.belief.accepted} estimate(s); grasp yaw {np.degrees(plan.hand_yaw_rad):+.1f} deg{_tilt(plan)}"
            + (f" (attempt {m.attempt})" if m.attempt > 1 else "")
        )
    if (
        m.look_frames >= m.p.look_aside_frames and len(m.looked_from) < m.p.look_asides and not m.no_aside
        and m.belief.accepted == 0 and m.arm.finished
    ):  # fmt: skip
        m.looked_from.append(m.arm.q.copy())  # (looked from here, and found nothing)
        aside = m.sight.aside(m.looked_from, m.rng)
        m.no_aside = aside is None or not _routed(m, aside[0])
        if not m.no_aside:  # (the frames start again once it is there)
            _, hid, still = aside
            m.note(
                f"no estimate in {m.look_frames} frames, and the arm hides {hid:.0%} of the table from the camera: "
                f"moving aside to look again (it still hides {still:.0%} of that)"
            )
            m.look_frames = 0
            return None
    if (
        m.look_frames >= m.p.look_aside_frames and len(m.searched) < m.p.look_searches and m.belief.accepted == 0
        and m.arm.finished and (m.no_aside or len(m.looked_from) >= m.p.look_asides)
    ):  # fmt: skip
        found = m.searcher.spot(m.world, m.searched, m.arm.q, m.rng)
        if found is not None:  # (no camera on the hand, or nothing left never seen: it fails below)
            at, q, area = found
            m.searched.append(at)
            if _routed(m, q):
                m.note(
                    f"no estimate in {m.look_frames} frames: looking with the hand's camera from above "
                    f"({at[0]:.2f}, {at[1]:.2f}), where no view has seen {area * 1e4:.0f} cm^2 of the table"
                )
                m.look_frames = 0
                m.search_camera = m.searcher.camera.name
                return None
    if m.look_frames >= m.p.look_max_frames:
        m.fail(
            Stage.PERCEPTION,
            f"no estimate of the target in {m.look_frames} frames: {m.counters.last_error or 'rejected'}",
        )
    return None


def _routed(m: PickMachine, q: np.ndarray) -> bool:
    """A transfer to look from ``q`` (aside, or with the hand's camera), around what is in the way where
    its straight way meets it; False (and no motion): ``q`` itself meets something, or no way was found."""
    if not (m.p.plan_around and m.p.joint_transfers):
        m.arm.transfer_to(q, m.p.transfer_scale)
        return True
    scene, fingers = m.router.scene(m.world), m.grip.finger_max_m
    if scene.contact(q, fingers) is not None:  # (within the margins: as the routes do, the tight ones)
        tight = scene.tighter() if scene.tighter is not None else scene
        if tight.contact(q, fingers) is not None:
            return False
    route = m.router.joint(scene, m.arm.q, q, fingers)
    if route.failure is not None:
        return False
    m.note(route.note)
    if route.waypoints is not None:
        m.arm.follow(route.waypoints, m.p.transfer_scale)
    else:
        m.arm.transfer_to(q, m.p.transfer_scale)
    return True


#: A re-plan of a grasp from the side whose approach turns more than this is another grasp (rad).
SIDE_TURN_RAD = float(np.radians(5.0))


def _same_side(m: PickMachine, plan: GraspPlan | None) -> GraspPlan | None:
    """A re-plan, or None where the plan in hand is a grasp from the side and the re-plan turned its
    approach: the grasps from any side are drawn anew from each cloud of a target that stands still (a
    side grasp is for one that does), and the arm, on its way in around a shelf's boards, would be sent
    to another grasp it did not plan its way to."""
    if plan is None or m.plan is None or hand_frame(m.plan.grasp.rotation) is None:
        return plan
    cos = float(np.dot(plan.grasp.rotation[:, 2], m.plan.grasp.rotation[:, 2]))
    if cos < np.cos(SIDE_TURN_RAD):
        return None
    # the parallel gripper's equivalent nearest the hand in hand (a re-drawn grasp may come turned half a
    # turn about its approach: near a joint's limit the arm cannot turn so, and jumped to another branch)
    if float(np.dot(plan.grasp.rotation[:, 1], m.plan.grasp.rotation[:, 1])) < 0.0:
        return turned_plan(plan, pick=True, place=True)
    return plan


# ---- APPROACH: to above the target, re-targeted as estimates arrive.
def enter_approach(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.hover_since = None
    if m.plan.open_m is not None:  # (wide open, the fingers would meet a wall or a neighbour)
        m.grip.open(to_m=m.plan.open_m)
    if not m.p.joint_transfers or m.intercept.velocity(m.now_s) is not None:
        # Cartesian (a moving target is met so, moving with it)
        m.arm.cartesian()
        m.go_to(m.plan.pregrasp, limits=m.p.free)
        return
    fingers = m.plan.open_m or m.grip.finger_max_m
    scene = m.router.scene(m.world) if m.p.plan_around else None
    grasps = [m.plan.grasp, half_turn(m.plan.grasp)]
    accept = None if scene is None else m.router.accepting(scene, grasps, fingers)
    near = None if scene is None else m.router.accepting_near(scene, grasps, fingers)
    q, turned = None, 0
    if m.plan.withdraw is not None and accept is not None:  # (and the way out of a shelf's bin followed)
        out = _taking_out(m, accept, all_out=True), _taking_out(m, near, all_out=True)
        q, turned = m.arm.goal(m.plan.pregrasp, m.plan.grasp, accept=out[0], near=out[1])
        if q is not None and not any(f is not None and f(q, turned) for f in out):  # (none all the way out)
            q = None
        if q is None:
            accept, near = _taking_out(m, accept), _taking_out(m, near)
    if q is None:
        fixed = None if scene is None else m.router.accepting_fixed(grasps, fingers, followed(m, grasps))
        if m.plan.withdraw is not None:
            fixed = _taking_out(m, fixed)
        q, turned = m.arm.goal(m.plan.pregrasp, m.plan.grasp, accept=accept, near=near, fixed=fixed)
    if q is None:
        m.fail(Stage.IK, "pregrasp pose out of reach: no IK solution for either hand angle")
        return
    if turned:
        m.plan = turned_plan(m.plan, pick=True, place=True)

    def down() -> None:  # the last leg, to where the plan is by then
        if side_line(m, m.plan.pregrasp, m.p.transfer_scale):
            return
        m.arm.cartesian()
        m.go_to(m.plan.pregrasp, limits=m.p.free)

    if scene is not None:
        route = m.router.joint(scene, m.arm.q, q, fingers)
        m.note(route.note)
        if route.failure is not None:
            m.fail(Stage.MOTION_PLANNING, f"to above the target: {route.failure}")
            return
        if route.waypoints is not None:
            m.arm.follow(route.waypoints, m.p.transfer_scale, down)
            return
    clear = None if scene is None else m.router.clearance(scene, fingers)
    note = m.arm.over_the_top(
        q, m.p.transfer_scale, m.p.free, rise=False, above=m.plan.pregrasp, down=down, clear=clear
    )
    m.note(note)
    if note is None:
        m.arm.transfer_to(q, m.p.transfer_scale)


def followed(m: PickMachine, ends: list[Pose]) -> Callable[[np.ndarray, int], bool]:
    """``followed(q, i)``: whether the arm at ``q`` follows the line to ``ends[i]`` as it will make it: a
    tilted hand's as joint transfers (:func:`side_line`), a hand pointing down's by the per-tick IK."""

    def follows(q: np.ndarray, i: int) -> bool:
        if hand_frame(ends[i].rotation) is not None:  # (its own seeds: a check does not move the pick's)
            return line_in_joints(m.kin, q, ends[i], np.random.default_rng(0), m.p.goals.ik) is not None
        return line_trackable(m.kin, q, m.kin.forward(q), ends[i], m.p.goals)

    return follows


def _taking_out(m: PickMachine, accept: Accept | None, *, all_out: bool = False) -> Accept | None:
    """``accept`` (a goal of the pregrasp, of the plan or the plan turned half a turn), where the arm
    can also follow the descent and lift over the lip from there, as the chooser checked the plan;
    ``all_out``: and back out of the bin all the way, clear within the tight margins (a way out cut
    short leaves the hand in the bin, from where no carry was found: `pick_shelf`, 7 of 100)."""
    if accept is None:
        return None
    assert m.plan is not None
    plans = (m.plan, turned_plan(m.plan, pick=True, place=True))
    scene = m.router.scene(m.world) if all_out else None
    tight = scene.tighter() if scene is not None and scene.tighter is not None else scene
    fingers = m.plan.open_m or m.grip.finger_max_m

    def taking_out(q: np.ndarray, i: int) -> bool:
        p = plans[i]
        if not accept(q, i):
            return False
        descent = line_in_joints(m.kin, q, p.grasp, m.rng, m.p.goals.ik)
        if descent is None:
            return False
        lift = line_in_joints(m.kin, descent[-1], p.lift, m.rng, m.p.goals.ik, partial=True)
        if lift is None:
            return False
        top = m.kin.forward(lift[-1]).position[2]
        if top - m.kin.forward(descent[-1]).position[2] < LEAST_LIFT_M - 1e-3:
            return False
        if tight is None or p.withdraw is None:
            return True
        out = Pose(p.withdraw.position + np.array([0.0, 0.0, top - p.lift.position[2]]), p.withdraw.rotation)
        way = line_in_joints(m.kin, lift[-1], out, m.rng, m.p.goals.ik, clear=lambda q_k: tight.free(q_k, fingers))
        return way is not None and float(np.linalg.norm(m.kin.forward(way[-1]).position - out.position)) < 0.005

    return taking_out


def tick_approach(m: PickMachine, obs: Observation) -> Transition:
    hidden = m.belief.initialised and m.sight.hidden(obs.arm_q, m.belief.predict(obs.time_s).position[None, :])[0]
    # (on a path planned around something, the cameras may not see a target that stood still: a hand's
    # camera looks where the path turns it)
    hidden = hidden or (bool(m.arm.legs) and m.intercept.velocity(m.now_s) is None)
    if not m.open_loop and m.belief.lost(obs.time_s) and not hidden:  # (hidden by the arm: on, on its belief)
        # Nothing it sees agrees with its belief any more: look again from home, a few times.
        m.relooks += 1
        if m.relooks > m.p.max_relooks:
            m.fail(Stage.PERCEPTION, f"target lost: no estimate accepted for {m.p.tracker.lost_after_s} s")
            return None
        m.after_back_off = State.LOOK
        return State.BACK_OFF, "target lost while approaching: looking again"
    plan = _same_side(m, m.track_plan())
    if m.moving_off is not None and not m.finished:
        m.after_back_off = State.LOOK
        return State.BACK_OFF, f"{m.moving_off[0]}, but it stood still: looking again once it stops"
    if plan is not None:
        before, m.plan = m.plan, plan
        if m.arm.legs:  # going over the top: its last leg goes down to where the plan is by then
            pass
        elif m.arm.joint:  # the transfer goes on to the new plan's goal, on the same branch
            q, turned = m.arm.goal(plan.pregrasp, plan.grasp, seeded=m.arm.joints.target)
            if q is None and before is not None and abs(_wrap(plan.hand_yaw_rad - before.hand_yaw_rad, np.pi)) > 1e-6:
                # the re-plan turned the hand (its angle was running out of room), to an angle whose
                # descent cannot be followed from the pregrasp: the angle the pick was planned with
                plan = m.plan = before
                q, turned = m.arm.goal(plan.pregrasp, plan.grasp, seeded=m.arm.joints.target)
            if q is None:
                m.fail(Stage.IK, "pregrasp pose out of reach: no IK solution for either hand angle")
                return None
            if turned:
                m.plan = turned_plan(plan, pick=True, place=True)
            if _retarget_clear(m, q):
                m.arm.joints.retarget(q)
            elif before is not None:
                m.plan = before  # (the plan of the goal the arm goes on to)
        else:
            m.go_to(plan.pregrasp)
    arrived = m.arm.finished or m.intercept.with_target(m.plan.pregrasp, m.now_s, m.planned_at_s)
    if arrived and not m.finished:
        # (open loop: the plan of one look)
        when = obs.time_s
        last = m.belief.tracker.last_accept_s
        if hidden and not m.hand_cameras and last is not None and m.intercept.velocity(m.now_s) is None:
            when = last  # the arm hides it from the camera: as sure as when it was last seen (it stood still)
        unsafe = "" if m.open_loop else unsure(m.belief, m.plan, when, m.p, m.plan.open_m or m.grip.finger_max_m)
        if unsafe:  # wait above it for more frames, or the hand's camera, to make it surer (a bounded wait)
            m.hover_since = obs.time_s if m.hover_since is None else m.hover_since
            if obs.time_s - m.hover_since >= m.p.hover_max_s:
                m.fail(Stage.PERCEPTION, f"{unsafe} after {obs.time_s - m.hover_since:.1f} s above it")
            return None
        moving = m.intercept.velocity(m.now_s) is not None
        return State.DESCEND, "above the target" + (", moving with it" if moving else "")
    return None


def _retarget_clear(m: PickMachine, q: np.ndarray) -> bool:
    """Whether a transfer under way may turn to the re-plan's goal ``q``: its straight path from where the
    arm is now, and the descent from it, keep clear (a re-plan's goal may be on another branch, whose
    path was never checked: the arm goes on to the goal it has, and the descent corrects)."""
    if not m.p.plan_around:
        return True
    assert m.plan is not None
    fingers = m.plan.open_m or m.grip.finger_max_m
    scene = m.router.scene(m.world)
    accept = m.router.accepting(scene, [m.plan.grasp], fingers)
    return m.router.straight_free(scene, m.arm.q, q, fingers) and accept(q, 0)


# ---- DESCEND: straight down onto the grasp; backs off if the target moves away.
def moved_under_hand(m: PickMachine) -> Transition:
    """Back off (and approach again) when views refused by the tracker say the target moved under the hand."""
    moved = m.watch.moved()
    if moved is None:
        return None
    off, camera, t = moved
    m.grip.open()
    m.after_back_off = State.APPROACH
    by = "the hand's camera" if camera in m.hand_cameras else "the camera"
    return State.BACK_OFF, (
        f"{by} sees the target {off * 1e3:.0f} mm from where it was tracked (frame of t = {t:.2f} s) "
        f"during the {m.state.value}: backing off to approach again"
    )


def _touched_early(m: PickMachine, obs: Observation) -> Transition:
    """Back off and look again when a finger touches something on the way down (:meth:`~pickdemo.skills.pick.watch.MoveWatch.touched`)."""  # noqa: E501
    assert m.plan is not None
    touched = m.watch.touched(obs, m.plan)
    if touched is None:
        return None
    m.avoid_yaws.append(m.plan.hand_yaw_rad)  # (the next look grasps it by other faces first)
    m.grip.open()
    m.after_back_off = State.LOOK
    return State.BACK_OFF, f"{touched}: backing off to look again"


def enter_descend(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.watch.forget_move()
    m.descent_plan = m.plan
    if m.moved_from is not None:  # backed off for a move: found back where it was, it did not move
        back = np.linalg.norm(m.plan.grasp.position[:2] - m.moved_from) <= m.p.moved_tolerance_m
        m.shadow_moves += bool(back)
        m.moved_from = None
    v = m.intercept.velocity(m.now_s)
    m.descent_ref = (m.plan.grasp.position[:2].copy(), np.zeros(2) if v is None else v, m.planned_at_s)
    if side_line(m, m.plan.grasp, m.p.side_line_scale):
        return
    m.arm.cartesian()
    m.go_to(m.plan.grasp, limits=m.intercept.near_limits(m.now_s))


def side_line(m: PickMachine, pose: Pose, scale: float, *, partial: bool = False, checked: bool = False) -> bool:
    """A grasp from the side's straight line (the last of the way in, the descent, the lift, the way
    out, the retreat from the place) as joint transfers, where they keep to the line (the per-tick IK
    loses tilted lines near the arm's joint limits, as in a shelf's bin); False: the caller's
    Cartesian line. ``partial``: as far along it as the arm can follow it (the way out of a shelf's bin:
    backing out level brings the wrist near the arm's base; the carry's plan goes on from there).
    ``checked``: the arm's links checked against what is in the way, the line ending before what it
    would meet (a lift under a shelf's board: the hand and the object clear it, the wrist behind them
    may not)."""
    if not m.p.plan_around or hand_frame(pose.rotation) is None:
        return False
    clear = _arm_clear(m) if checked else None
    waypoints = line_in_joints(m.kin, m.arm.q, pose, m.rng, m.p.goals.ik, partial=partial, clear=clear)
    if waypoints is None:
        return False
    short = float(np.linalg.norm(m.kin.forward(waypoints[-1]).position - pose.position))
    if short > 0.005:
        further = "further, the arm could not follow the line, or would meet something"
        m.note(f"going only part of the way: {short * 1e3:.0f} mm short ({further})")
    m.arm.joint_line(waypoints, scale)
    return True


def _arm_clear(m: PickMachine) -> Callable[[np.ndarray], bool] | None:
    """Whether the arm's links (the held object aside: its way out is the grasp plan's own check) keep
    clear at ``q``, within the margins the arm keeps clear of them now (the normal, or the tight; None:
    within neither, as at a grasp beside a board)."""
    fingers = 0.5 * m.grasp_width_m if m.grasp_width_m is not None else m.grip.finger_max_m  # (each finger's)
    scene = m.router.scene(m.world)
    for s in (scene, scene.tighter() if scene.tighter is not None else None):
        if s is not None and s.free(m.arm.q, fingers):
            return lambda q, s=s: s.free(q, fingers)
    return None


def tick_descend(m: PickMachine, obs: Observation) -> Transition:
    moved = moved_under_hand(m)
    if moved is None:
        moved = _touched_early(m, obs)
    if moved is not None:
        return moved
    plan = _same_side(m, m.track_plan())
    if m.shadow_moves >= m.p.shadow_back_offs:
        plan = None  # (the views on the way down shift with the hand over the target: its plan holds)
    if plan is not None:
        assert m.descent_plan is not None and m.descent_ref is not None
        xy, v, t = m.descent_ref  # where the descent expected the target now
        off = float(np.linalg.norm(plan.grasp.position[:2] - (xy + v * (obs.time_s - t))))
        turned = abs(plan.hand_yaw_rad - m.descent_plan.hand_yaw_rad)
        m.plan = plan
        if off > m.p.moved_tolerance_m or turned > m.p.moved_tolerance_rad:
            m.after_back_off = State.APPROACH
            m.moved_from = xy.copy()
            return State.BACK_OFF, (
                f"the target moved {off * 1e3:.0f} mm, {np.degrees(turned):.0f} deg during the descent: "
                "backing off to approach again"
            )
        if not m.arm.joint:  # (a side grasp's descent in joint space goes to where it was planned)
            m.go_to(plan.grasp)
    arrived = m.arm.finished or m.intercept.with_target(m.plan.grasp, m.now_s, m.planned_at_s)
    if arrived and not m.finished:
        return State.CLOSE, "at the grasp pose"
    return None
