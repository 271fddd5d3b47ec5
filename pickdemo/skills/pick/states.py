"""The pick skill's states: each state's entry action (run once, when it is entered: plan, send a
target) and exit test (run every tick: the next state and what it says, or stay), as functions of
the machine, and the table :data:`STATES` the machine dispatches from.

States, in the order of a pick::

    LOOK -> APPROACH -> DESCEND -> CLOSE -> LIFT -> TRANSPORT -> LOWER -> RELEASE -> RETREAT -> HOME
         -> VERIFY -> DONE
    DESCEND --(the target moved)--> BACK_OFF -> APPROACH
    CLOSE --(nothing held)--> BACK_OFF -> LOOK          (a retry, up to ``max_attempts``)
    LIFT / TRANSPORT --(dropped)--> BACK_OFF -> LOOK    (a retry with more grip force, a slower lift)
    VERIFY --(seen put down off the place)--> LOOK      (picked up again, within ``max_attempts``)

While it approaches, descends and closes it keeps looking (closed loop): the tracker fuses every
estimate, and the motion is re-targeted to where the tracker says the target is. With
``open_loop`` it looks only in ``LOOK`` and plays the plan from that one look, for comparison. A
target the tracker sees moving (a belt) is met where it will be
(:class:`~pickdemo.skills.pick.intercept.Interceptor`); one that will have left the arm's reach by
the time it is held, or that runs faster than the hand, fails the episode in ``ik`` by name.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pickdemo.core.interfaces import Observation
from pickdemo.core.result import Stage
from pickdemo.skills.pick.params import HAND_OVER_TARGET, Event, State, Transition
from pickdemo.skills.pick.plans import moved_place, turned_plan
from pickdemo.skills.pick.views import unsure

if TYPE_CHECKING:  # (the machine imports this table: a type only, for the reader and the checker)
    from pickdemo.skills.pick.machine import PickMachine


def _wrap(yaw_rad: float, period_rad: float) -> float:
    """The yaw in [-period/2, period/2): how a symmetric shape's yaw is said (a cube's modulo 90 deg)."""
    return float((yaw_rad + period_rad / 2.0) % period_rad - period_rad / 2.0)


def _wrist_load(m: PickMachine, obs: Observation) -> float:
    """The wrist's load along world z (N)."""
    return m.scale.vertical(obs, m.kin.forward(obs.arm_q).rotation)


def _weigh(m: PickMachine, obs: Observation) -> bool:
    """Lifted, at rest: weigh what hangs in the fingers (a few ticks, :meth:`~pickdemo.skills.actions.Scale.weigh`),
    and grip as hard as it needs; True once weighed."""
    if m.scale.payload_kg is not None:
        return True
    weighed = m.scale.weigh(_wrist_load(m, obs), m.grip_force_n, m.p.max_grip_force_n)
    if weighed is None:
        return False
    payload, force = weighed
    m.weighed_force_n = force
    note = f"weighed {payload:.2f} kg at the wrist"
    if force > m.grip.force_n:
        m.grip.close(force)
        note += f": gripping with {force:.0f} N"
    m.note(note)
    return True


def _dropped(m: PickMachine, obs: Observation, stage: Stage, outcome: str) -> Transition:
    """The fingers lost their hold (a retry), or None."""
    assert m.plan is not None
    if not m.grip.dropped(obs, m.plan.object_width_m):
        return None
    return m.retry(stage, outcome, f"fingers at {obs.opening_m * 1e3:.1f} mm")


# ---- LOOK: from the home pose, full frames until the tracker holds the target.
def enter_look(m: PickMachine, obs: Observation) -> None:
    if not m.events:
        m.events.append(Event(State.LOOK, obs.time_s, "looking for the target", note=True))
    m.grip.open()
    m.attempt_start_s = obs.time_s
    m.belief.restart()
    m.scale.start()
    m.weighed_force_n = 0.0
    m.look_frames = 0
    m.looked_from, m.no_aside = [], False
    m.fresh_estimate = False
    if m.look_here:  # the first look, from where the arm is (at rest)
        m.look_here = False
        return
    m.note(m.arm.home())


def tick_look(m: PickMachine, obs: Observation) -> Transition:
    if m.arm.finished:  # at rest with the hand empty: what the wrist reads is the hand
        m.scale.tare(_wrist_load(m, obs))
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
        # (more frames cannot mend that)
        unsafe = unsure(m.belief, plan, obs.time_s, m.p, m.grip.finger_max_m, calibration_only=True)
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
            f"from {m.belief.accepted} estimate(s); grasp yaw {np.degrees(plan.hand_yaw_rad):+.1f} deg"
            + (f" (attempt {m.attempt})" if m.attempt > 1 else "")
        )
    if (
        m.look_frames >= m.p.look_aside_frames and len(m.looked_from) < m.p.look_asides and not m.no_aside
        and m.belief.accepted == 0 and m.arm.finished
    ):  # fmt: skip
        m.looked_from.append(m.arm.q.copy())  # (looked from here, and found nothing)
        aside = m.sight.aside(m.looked_from, m.rng)
        m.no_aside = aside is None
        if aside is not None:  # (the frames start again once it is there)
            q, hid, still = aside
            m.note(
                f"no estimate in {m.look_frames} frames, and the arm hides {hid:.0%} of the table from the camera: "
                f"moving aside to look again (it still hides {still:.0%} of that)"
            )
            m.look_frames = 0
            m.arm.transfer_to(q, m.p.transfer_scale)
            return None
    if m.look_frames >= m.p.look_max_frames:
        m.fail(
            Stage.PERCEPTION,
            f"no estimate of the target in {m.look_frames} frames: {m.counters.last_error or 'rejected'}",
        )
    return None


# ---- APPROACH: to above the target, re-targeted as estimates arrive.
def enter_approach(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.hover_since = None
    if not m.p.joint_transfers or m.intercept.velocity(m.now_s) is not None:
        # Cartesian (a moving target is met so, moving with it)
        m.arm.cartesian()
        m.go_to(m.plan.pregrasp, limits=m.p.free)
        return
    q, turned = m.arm.goal(m.plan.pregrasp, m.plan.grasp)
    if q is None:
        m.fail(Stage.IK, "pregrasp pose out of reach: no IK solution for either hand angle")
        return
    if turned:
        m.plan = turned_plan(m.plan, pick=True, place=True)
    down = lambda: (m.arm.cartesian(), m.go_to(m.plan.pregrasp, limits=m.p.free))  # noqa: E731
    note = m.arm.over_the_top(q, m.p.transfer_scale, m.p.free, rise=False, above=m.plan.pregrasp, down=down)
    m.note(note)
    if note is None:
        m.arm.transfer_to(q, m.p.transfer_scale)


def tick_approach(m: PickMachine, obs: Observation) -> Transition:
    hidden = m.belief.initialised and m.sight.hidden(obs.arm_q, m.belief.predict(obs.time_s).position[None, :])[0]
    if not m.open_loop and m.belief.lost(obs.time_s) and not hidden:  # (hidden by the arm: on, on its belief)
        # Nothing it sees agrees with its belief any more: look again from home, a few times.
        m.relooks += 1
        if m.relooks > m.p.max_relooks:
            m.fail(Stage.PERCEPTION, f"target lost: no estimate accepted for {m.p.tracker.lost_after_s} s")
            return None
        m.after_back_off = State.LOOK
        return State.BACK_OFF, "target lost while approaching: looking again"
    plan = m.track_plan()
    if plan is not None:
        m.plan = plan
        if m.arm.legs:  # going over the top: its last leg goes down to where the plan is by then
            pass
        elif m.arm.joint:  # the transfer goes on to the new plan's goal, on the same branch
            q, turned = m.arm.goal(plan.pregrasp, plan.grasp, seeded=m.arm.joints.target)
            if q is None:
                m.fail(Stage.IK, "pregrasp pose out of reach: no IK solution for either hand angle")
                return None
            if turned:
                m.plan = turned_plan(plan, pick=True, place=True)
            m.arm.joints.retarget(q)
        else:
            m.go_to(plan.pregrasp)
    arrived = m.arm.finished or m.intercept.with_target(m.plan.pregrasp, m.now_s, m.planned_at_s)
    if arrived and not m.finished:
        # (open loop: the plan of one look)
        when = obs.time_s
        last = m.belief.tracker.last_accept_s
        if hidden and not m.hand_cameras and last is not None and m.intercept.velocity(m.now_s) is None:
            when = last  # the arm hides it from the camera: as sure as when it was last seen (it stood still)
        unsafe = "" if m.open_loop else unsure(m.belief, m.plan, when, m.p, m.grip.finger_max_m)
        if unsafe:  # wait above it for more frames, or the hand's camera, to make it surer (a bounded wait)
            m.hover_since = obs.time_s if m.hover_since is None else m.hover_since
            if obs.time_s - m.hover_since >= m.p.hover_max_s:
                m.fail(Stage.PERCEPTION, f"{unsafe} after {obs.time_s - m.hover_since:.1f} s above it")
            return None
        moving = m.intercept.velocity(m.now_s) is not None
        return State.DESCEND, "above the target" + (", moving with it" if moving else "")
    return None


# ---- DESCEND: straight down onto the grasp; backs off if the target moves away.
def _moved_under_hand(m: PickMachine) -> Transition:
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
    v = m.intercept.velocity(m.now_s)
    m.descent_ref = (m.plan.grasp.position[:2].copy(), np.zeros(2) if v is None else v, m.planned_at_s)
    m.arm.cartesian()
    m.go_to(m.plan.grasp, limits=m.intercept.near_limits(m.now_s))


def tick_descend(m: PickMachine, obs: Observation) -> Transition:
    moved = _moved_under_hand(m)
    if moved is None:
        moved = _touched_early(m, obs)
    if moved is not None:
        return moved
    plan = m.track_plan()
    if plan is not None:
        assert m.descent_plan is not None and m.descent_ref is not None
        xy, v, t = m.descent_ref  # where the descent expected the target now
        off = float(np.linalg.norm(plan.grasp.position[:2] - (xy + v * (obs.time_s - t))))
        turned = abs(plan.hand_yaw_rad - m.descent_plan.hand_yaw_rad)
        m.plan = plan
        if off > m.p.moved_tolerance_m or turned > m.p.moved_tolerance_rad:
            m.after_back_off = State.APPROACH
            return State.BACK_OFF, (
                f"the target moved {off * 1e3:.0f} mm, {np.degrees(turned):.0f} deg during the descent: "
                "backing off to approach again"
            )
        m.go_to(plan.grasp)
    arrived = m.arm.finished or m.intercept.with_target(m.plan.grasp, m.now_s, m.planned_at_s)
    if arrived and not m.finished:
        return State.CLOSE, "at the grasp pose"
    return None


# ---- CLOSE: fingers close with this attempt's force; held or missed.
def enter_close(m: PickMachine, obs: Observation) -> None:
    tp = m.belief.predict(obs.time_s)  # how high its centre rests above what it stands on: so at the place
    m.rest_height_m = float(tp.position[2]) - m.belief.surface_z(float(tp.position[0]), float(tp.position[1]))
    m.grip.close(m.grip_force_n)
    m.grip.watch()
    m.watch.start_hold()


def _held_across_another_side(m: PickMachine, obs: Observation) -> None:
    """Closed on a described box across its other side (its yaw was seen a quarter turn off): held all
    the same. The plan takes the width held (the checks of the hold while carried go by it)."""
    assert m.plan is not None
    width = m.plan.object_width_m
    if not m.plan.width_known or m.grip.holding(obs, width):
        return
    for other in m.model.geometry.top_extents_m:
        if abs(other - width) > 1e-6 and m.grip.holding(obs, other) and not m.grip.too_wide(obs, other):
            m.note(f"fingers at {obs.opening_m * 1e3:.1f} mm: held across its {other * 1e3:.0f} mm side, "
                   f"not its {width * 1e3:.0f} mm one")  # fmt: skip
            m.plan = dataclasses.replace(m.plan, object_width_m=float(other))
            return


def tick_close(m: PickMachine, obs: Observation) -> Transition:
    assert m.plan is not None
    stalled = m.grip.stopped(obs)
    if stalled:
        _held_across_another_side(m, obs)
    width = m.plan.object_width_m
    if not stalled and not m.grip.holding(obs, width):
        moved = _moved_under_hand(m)
        if moved is not None:
            return moved
    if not stalled and obs.time_s - m.since_s < m.p.close_timeout_s:
        return None
    if m.grip.holding(obs, width):
        if m.plan.width_known and m.grip.too_wide(obs, width):
            reason = (
                f"fingers stopped at {obs.opening_m * 1e3:.1f} mm "
                f"(expected {width * 1e3:.0f} mm): held askew, or not it alone"
            )
            if m.attempt < m.max_attempts:
                return m.retry(Stage.GRASP, "missed", reason)
            m.note(f"{reason}: no attempt left to grasp it better, carried as it is held")
        off_centre = m.watch.held_off_centre(obs, m.plan)
        if off_centre is False:
            return None  # (waiting for the hand's camera to see the hold)
        if off_centre is not None:
            return m.retry(Stage.GRASP, "held off centre", off_centre)
        m.grasp_width_m = obs.opening_m
        return State.LIFT, f"holding: fingers at {obs.opening_m * 1e3:.1f} mm, contact on both, {m.grip_force_n:.0f} N"
    reason = f"fingers closed to {obs.opening_m * 1e3:.1f} mm (expected {width * 1e3:.0f} mm): nothing held"
    return m.retry(Stage.GRASP, "missed", reason)


# ---- LIFT, TRANSPORT, LOWER: carry it, watching the hold.
def enter_lift(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.grip.watch_hold()
    motion = m.arm.motion
    lift = m.arm.move.x4(m.plan.lift)
    v = motion.velocity[:2]
    m.lifted_off = np.any(v != 0.0)  # (a target held on the move is weighed at the top)
    if m.lifted_off:  # held on the move: carry on along its way a little while rising
        lift[:2] = motion.setpoint[:2] + v * m.p.lift_lead_s
    else:  # first just off the table, to weigh it before it hangs long at the first grip force
        lift[2] = m.plan.grasp.position[2] + m.p.payload.lift_off_m
    motion.set_target(lift, limits=m.intercept.near_limits(m.now_s).scaled(m.lift_scale))
    m.scale.start()


def tick_lift(m: PickMachine, obs: Observation) -> Transition:
    dropped = _dropped(m, obs, Stage.LIFT, "dropped while lifting")
    if dropped is not None or m.finished:
        return dropped
    if not (m.arm.finished and _weigh(m, obs)):
        return None
    if not m.lifted_off:  # weighed just off the table: on up to the carry height
        if m.plan.width_known and m.grasp_width_m is not None and m.grip.too_wide(obs, m.grasp_width_m):
            # It turned between the pads as it came off the table (held off its centre of mass, or a
            # light cube pivoting on the pads): carried so, it lands askew and off the place.
            reason = f"fingers at {obs.opening_m * 1e3:.1f} mm, {m.grasp_width_m * 1e3:.1f} mm when it was grasped"
            return m.retry(Stage.LIFT, "turned in the grip", reason)
        m.lifted_off = True
        lift = m.arm.move.x4(m.plan.lift)
        m.arm.motion.set_target(lift, limits=m.intercept.near_limits(m.now_s).scaled(m.lift_scale))
        return None
    return State.TRANSPORT, f"lifted, fingers at {obs.opening_m * 1e3:.1f} mm"


def enter_transport(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    p = m.p
    straight = not (p.joint_transfers and p.carry_in_joint_space)
    if straight and (not p.joint_transfers or m.arm.straight_carry_ok(m.plan, m.lift_scale)):
        m.arm.move.to(m.plan.place_above, limits=p.free.scaled(m.lift_scale * m.scale.carry_share()))
        return
    # in joint space, to a goal from which the lowering can be tracked
    if straight:
        m.note("carried in joint space: the straight line would pass too near a singular posture")
    other = turned_plan(m.plan, pick=False, place=True)
    q, turned = m.arm.goal(m.plan.place_above, m.plan.place, half_turned=(other.place_above, other.place))
    if q is None:
        m.fail(Stage.IK, "place pose out of reach: no IK solution for either hand angle")
        return
    if turned:  # put down with the hand turned half a turn: the same for the place, not the grasp
        m.plan = other
    scale = p.carry_scale * m.lift_scale * m.scale.carry_share()
    limits = p.free.scaled(m.lift_scale * m.scale.carry_share())
    note = m.arm.over_the_top(q, scale, limits, rise=True, above=m.plan.place_above)
    m.note(note)
    if note is None:
        m.arm.transfer_to(q, scale)


def tick_transport(m: PickMachine, obs: Observation) -> Transition:
    dropped = _dropped(m, obs, Stage.TRANSPORT, "dropped in transit")
    if dropped is not None or m.finished:
        return dropped
    return (State.LOWER, "above the place position") if m.arm.finished else None


def enter_lower(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.arm.cartesian()
    m.arm.move.to(m.plan.place, limits=m.arm.line_limits(m.plan.place))


def tick_lower(m: PickMachine, obs: Observation) -> Transition:
    dropped = _dropped(m, obs, Stage.TRANSPORT, "dropped in transit")
    if dropped is not None or m.finished:
        return dropped
    return (State.RELEASE, "lowered onto the table") if m.arm.finished else None


# ---- RELEASE, RETREAT, HOME, VERIFY.
def enter_release(m: PickMachine, obs: Observation) -> None:
    m.released_at_s = obs.time_s
    m.grip.open(to_m=m.release_m)
    m.grip.watch()
    m.forced_open = False


def tick_release(m: PickMachine, obs: Observation) -> Transition:
    assert m.plan is not None
    opened = m.grip.opened(obs)
    stopped = not opened and m.grip.stopped(obs)
    if stopped and not m.forced_open and m.grip.holding(obs, m.plan.object_width_m):
        # The fingers stopped on the object instead of opening (a simulated Panda's fingers jammed
        # so after a held cube had turned half a turn in the carry, measured: the retreat then
        # lifted it away). Open with the hand's full force before letting go of it for good.
        m.forced_open = True
        m.grip.open(m.p.max_grip_force_n)
        m.grip.watch()
        force = m.p.max_grip_force_n
        m.note(f"the fingers stopped at {obs.opening_m * 1e3:.1f} mm, still on the target: opening with {force:.0f} N")
        return None
    if opened or stopped or obs.time_s - m.since_s > m.p.close_timeout_s:
        m.end_attempt("placed", "")
        p = m.plan.place.position
        if m.p.drop_place:  # (let go from above: nothing to back away from)
            nxt = State.HOME if m.p.home_after_place else State.DONE
            return nxt, f"dropped at ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})"
        return State.RETREAT, f"released at ({p[0]:.3f}, {p[1]:.3f})"
    return None


def enter_retreat(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.arm.move.to(m.plan.retreat, limits=m.arm.line_limits(m.plan.retreat))


def tick_retreat(m: PickMachine, obs: Observation) -> Transition:
    return (State.HOME, "clear of the object") if m.arm.finished else None


def enter_home(m: PickMachine, obs: Observation) -> None:
    m.note(m.arm.home())


def tick_home(m: PickMachine, obs: Observation) -> Transition:
    if not m.arm.finished:
        return None
    return (State.VERIFY, "arm home") if m.p.verify_place else (State.DONE, "arm home")


def enter_verify(m: PickMachine, obs: Observation) -> None:
    m.verify_asked = False
    m.verify_estimate = None


def tick_verify(m: PickMachine, obs: Observation) -> Transition:
    if not m.verify_asked:
        return None
    if m.verify_estimate is None:
        return State.DONE, "the camera does not find the target at the end"
    seen = m.verify_estimate.pose.position
    if m.rest_height_m is not None:  # on the table at the place, not on something there, not fallen over
        high = float(seen[2]) - (m.place_z_m + m.rest_height_m)
        if abs(high) > m.p.verify_height_tolerance_m:
            how = "put down on something at the place" if high > 0 else "fallen over"
            where = "above" if high > 0 else "below"
            m.fail(Stage.PLACE, f"the camera sees the target's centre {abs(high) * 1e3:.0f} mm {where} where it "
                                f"should rest: {how}")  # fmt: skip
            return None
    err = float(np.hypot(seen[0] - m.place_xy[0], seen[1] - m.place_xy[1]))
    said = f"the camera sees the target {err * 1e3:.1f} mm from the place position"
    if m.place_tolerance_m is None or err <= m.place_tolerance_m:
        return State.DONE, said
    said += f" (tolerance {m.place_tolerance_m * 1e3:.0f} mm)"
    if m.attempt >= m.max_attempts:
        return State.DONE, f"{said}; no attempt left to place it again"
    # Placed off: this attempt's record says so, and the next picks it up from where it lies.
    m.attempts[-1] = dataclasses.replace(m.attempts[-1], outcome="placed off", reason=said)
    m.attempt += 1
    return State.LOOK, f"{said}: picking it up again; attempt {m.attempt} of {m.max_attempts} follows"


def enter_done(m: PickMachine, obs: Observation) -> None:
    pass


def tick_done(m: PickMachine, obs: Observation) -> Transition:
    return None


# ---- BACK_OFF: open, straight up to a safe height, then look or approach again.
def enter_back_off(m: PickMachine, obs: Observation) -> None:
    if m.after_back_off in (State.LOOK, State.FAILED):
        m.grip.open()
    arm = m.arm
    if arm.joint:  # in free space, mid-transfer: on to home from where it is
        arm.joints.retarget(arm.home_q)
        return
    grasp_z = m.plan.grasp.position[2] if m.plan is not None else m.p.back_off_grasp_z_m
    safe_z = m.p.grasp.pregrasp_height_m + grasp_z
    x4 = arm.motion.setpoint.copy()
    x4[2] = max(x4[2], safe_z)
    # Limits change only at rest: lowered mid-motion, Ruckig may overshoot while braking.
    limits = m.intercept.near_limits(m.now_s) if arm.motion.finished else None
    if m.after_back_off is State.APPROACH and m.intercept.velocity(m.now_s) is not None:
        m.go_to(x4, limits=limits)  # up, and along with it
        return
    arm.motion.set_target(x4, limits=limits)


def tick_back_off(m: PickMachine, obs: Observation) -> Transition:
    if m.after_back_off is State.APPROACH:
        plan = m.track_plan()  # keep following the target while rising
        if plan is not None:
            m.plan = plan
    if m.arm.finished:
        nxt = m.after_back_off
        if nxt is State.FAILED and m.failing is not None:
            m.arm.braked = True  # (at rest already)
            m.fail(m.failing.stage, m.failing.reason)
            return None
        return nxt, "clear above the table: " + ("look again" if nxt is State.LOOK else "approach again")
    return None


@dataclass(frozen=True)
class StateHandlers:
    """A state's entry action (run once, when it is entered) and exit test (run every tick)."""

    enter: Callable[[PickMachine, Observation], None]
    tick: Callable[[PickMachine, Observation], Transition]


#: The dispatch table: every state the machine runs (``FAILED`` is final and runs nothing).
STATES: dict[State, StateHandlers] = {
    State.LOOK: StateHandlers(enter_look, tick_look),
    State.APPROACH: StateHandlers(enter_approach, tick_approach),
    State.DESCEND: StateHandlers(enter_descend, tick_descend),
    State.CLOSE: StateHandlers(enter_close, tick_close),
    State.LIFT: StateHandlers(enter_lift, tick_lift),
    State.TRANSPORT: StateHandlers(enter_transport, tick_transport),
    State.LOWER: StateHandlers(enter_lower, tick_lower),
    State.RELEASE: StateHandlers(enter_release, tick_release),
    State.RETREAT: StateHandlers(enter_retreat, tick_retreat),
    State.HOME: StateHandlers(enter_home, tick_home),
    State.VERIFY: StateHandlers(enter_verify, tick_verify),
    State.BACK_OFF: StateHandlers(enter_back_off, tick_back_off),
    State.DONE: StateHandlers(enter_done, tick_done),
}

__all__ = ["HAND_OVER_TARGET", "STATES", "StateHandlers"]
