"""The pick skill's states that carry the target and put it down: LIFT, TRANSPORT, LOWER, RELEASE,
RETREAT, HOME, VERIFY and DONE, and BACK_OFF, which any of them may take to try again; each state's
entry action and exit test, as functions of the machine (:mod:`~pickdemo.skills.pick.states` holds the
table the machine dispatches from)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.core.interfaces import Observation
from pickdemo.core.result import Failure, Stage
from pickdemo.motion.ik_goals import along_line, goal_candidates, line_trackable
from pickdemo.motion.online import hand_frame
from pickdemo.skills.actions import GRAVITY_M_S2
from pickdemo.skills.pick.params import State, Transition
from pickdemo.skills.pick.plans import turned_plan
from pickdemo.skills.pick.routes import held_box, rise_over
from pickdemo.skills.pick.take import followed, go_home, side_line, wrist_load

if TYPE_CHECKING:  # (the machine imports this table: a type only, for the reader and the checker)
    from pickdemo.grasping.top_down import GraspPlan
    from pickdemo.perception import PoseEstimate
    from pickdemo.skills.pick.machine import PickMachine


def _weigh(m: PickMachine, obs: Observation) -> bool:
    """Lifted, at rest: weigh what hangs in the fingers (a few ticks, :meth:`~pickdemo.skills.actions.Scale.weigh`),
    and grip as hard as it needs; True once weighed."""
    if m.scale.payload_kg is not None:
        return True
    weighed = m.scale.weigh(wrist_load(m, obs), m.close_force_n, m.grip.max_force_n)
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
    return m.retry(stage, outcome, m.grip.reading(obs))


# ---- LIFT, TRANSPORT, LOWER: carry it, watching the hold.
def enter_lift(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.grip.watch_hold()
    m.arm.cartesian()  # (a side grasp's descent in joint space: the lift is a Cartesian line)
    # (its box where it stood, as the hand holds it now)
    tcp = m.kin.forward(obs.arm_q)
    m.held = held_box(m.world, tcp, m.router.solids)
    m.held_at = (obs.arm_q.copy(), 0.5 * (m.grasp_width_m if m.grasp_width_m is not None else obs.opening_m))
    if m.held is not None and m.plan.withdraw is None:  # (a shelf's way out is its own)
        # high enough that what it holds clears the walls of the bin it was taken from before it is carried off
        rise = rise_over(OrientedBox(tcp @ m.held.pose, m.held.lo, m.held.hi), m.router.named, RISE_REACH_M)
        low = m.plan.lift.position[2] - m.plan.grasp.position[2]
        if rise > low:
            m.note(f"lifting {rise * 1e3:.0f} mm, not {low * 1e3:.0f}: what it holds clears the walls beside it")
            m.plan = dataclasses.replace(
                m.plan, lift=Pose(m.plan.lift.position + [0.0, 0.0, rise - low], m.plan.lift.rotation)
            )
    lower = m.arm.lift_in_reach(m.plan)
    if lower is not m.plan:
        high = (lower.lift.position[2] - m.plan.grasp.position[2]) * 1e3
        m.note(f"lifting only {high:.0f} mm: higher, the arm could not keep the hand pointing down")
        m.plan = lower
    if m.p.plan_around and m.plan.withdraw is None:  # (a shelf's way out is its own)
        fingers = 0.5 * (m.grasp_width_m if m.grasp_width_m is not None else obs.opening_m)
        scene = m.router.scene(m.world, held=m.held, held_at=m.held_at)
        share = m.router.free_share(scene, m.arm.motion.q, m.plan.lift, fingers, m.arm.motion.posture)
        if share < 1.0:  # lifted only as high as it keeps clear (the carry then goes around)
            z = m.plan.grasp.position[2] + share * (m.plan.lift.position[2] - m.plan.grasp.position[2])
            z = max(z, m.plan.grasp.position[2] + m.p.payload.lift_off_m)
            m.note(f"lifting only {(z - m.plan.grasp.position[2]) * 1e3:.0f} mm: higher, it would meet something")
            m.plan = dataclasses.replace(
                m.plan, lift=Pose(np.array([*m.plan.lift.position[:2], z]), m.plan.lift.rotation)
            )
    motion = m.arm.motion
    lift = m.arm.move.x4(m.plan.lift)
    v = motion.velocity[:2]
    m.lifted_off = np.any(v != 0.0)  # (a target held on the move is weighed at the top)
    m.scale.start()
    m.withdrawing = False
    if m.lifted_off:  # held on the move: carry on along its way a little while rising
        lift[:2] = motion.setpoint[:2] + v * m.p.lift_lead_s
    else:  # first just off the table, to weigh it before it hangs long at the first grip force
        lift[2] = m.plan.grasp.position[2] + m.p.payload.lift_off_m
        off = Pose(np.array([*m.plan.lift.position[:2], lift[2]]), m.plan.lift.rotation)
        if m.plan.withdraw is not None and side_line(m, off, m.p.side_line_scale, checked=True):
            return
    motion.set_target(lift, limits=m.intercept.near_limits(m.now_s).scaled(m.lift_scale))


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
        # (under a board, as a joint path; elsewhere the Cartesian line, which keeps to it within a
        # millimetre: a joint path's 3 mm scraped a held cube along the carton flush beside it)
        if m.plan.withdraw is not None and side_line(m, m.plan.lift, m.p.side_line_scale, checked=True):
            return None
        m.arm.cartesian()
        lift = m.arm.move.x4(m.plan.lift)
        m.arm.motion.set_target(lift, limits=m.intercept.near_limits(m.now_s).scaled(m.lift_scale))
        return None
    if m.plan.withdraw is not None and not m.withdrawing:  # under a shelf's board: back out the way it came in
        m.withdrawing = True
        dz = float(m.kin.forward(m.arm.q).position[2] - m.plan.lift.position[2])
        if dz < -0.001:  # (lifted only as high as the arm followed: out level from there)
            w = m.plan.withdraw
            m.plan = dataclasses.replace(m.plan, withdraw=Pose(w.position + np.array([0.0, 0.0, dz]), w.rotation))
        if side_line(m, m.plan.withdraw, m.p.side_line_scale, partial=True, checked=True):
            return None
        m.arm.cartesian()
        m.arm.move.to(m.plan.withdraw, limits=m.intercept.near_limits(m.now_s).scaled(m.lift_scale))
        return None
    m.arm.cartesian()  # (a side grasp's lift in joint space: the carry starts at rest where it left the arm)
    return State.TRANSPORT, f"lifted, {m.grip.reading(obs)}"


def enter_transport(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    p = m.p
    straight = not (p.joint_transfers and p.carry_in_joint_space)
    fingers = 0.5 * (m.grasp_width_m if m.grasp_width_m is not None else obs.opening_m)
    scene = m.router.scene(m.world, held=m.held, held_at=m.held_at) if p.plan_around else None
    if scene is not None and p.joint_transfers and hand_frame(m.plan.place.rotation) is not None:
        if _carried_upright(m, scene, fingers):
            return
    if straight and (not p.joint_transfers or m.arm.straight_carry_ok(m.plan, m.lift_scale)):
        ends = [m.plan.place_above, m.plan.place]  # (then down onto the place)
        posture = m.arm.motion.posture
        hit = None if scene is None else m.router.line_blocked(scene, m.arm.motion.q, ends, fingers, posture)
        limits = p.free.scaled(m.lift_scale * m.scale.carry_share())
        if hit is None or not p.joint_transfers:
            m.arm.move.to(m.plan.place_above, limits=limits)
            return
        if _carried_higher(m, scene, fingers, limits, hit):
            return
        m.note(f"carried in joint space: on the straight line, {hit[0]} would meet {hit[1]}")
    elif straight:
        m.note("carried in joint space: the straight line would pass too near a singular posture")
    # in joint space, to a goal from which the lowering can be tracked
    other = turned_plan(m.plan, pick=False, place=True)
    ends = [m.plan.place, other.place]
    accept = None if scene is None else m.router.accepting(scene, ends, fingers)
    near = None if scene is None else m.router.accepting_near(scene, ends, fingers)
    fixed = None if scene is None else m.router.accepting_fixed(ends, fingers, followed(m, ends))
    q, turned = m.arm.goal(
        m.plan.place_above, m.plan.place, half_turned=(other.place_above, other.place), accept=accept, near=near,
        fixed=fixed,
    )  # fmt: skip
    if q is None:
        m.fail(Stage.IK, "place pose out of reach: no IK solution for either hand angle")
        return
    if turned:  # put down with the hand turned half a turn: the same for the place, not the grasp
        m.plan = other
    scale = p.carry_scale * m.lift_scale * m.scale.carry_share()
    limits = p.free.scaled(m.lift_scale * m.scale.carry_share())
    if scene is not None:
        route = m.router.joint(scene, m.arm.q, q, fingers)
        m.note(route.note)
        if route.failure is not None:
            m.fail(Stage.MOTION_PLANNING, f"to above the place: {route.failure}")
            return
        if route.waypoints is not None:
            m.arm.follow(route.waypoints, scale)
            return
    clear = None if scene is None else m.router.clearance(scene, fingers)
    note = m.arm.over_the_top(q, scale, limits, rise=True, above=m.plan.place_above, clear=clear)
    m.note(note)
    if note is None:
        m.arm.transfer_to(q, scale)


def _carried_upright(m: PickMachine, scene, fingers: float) -> bool:  # noqa: ANN001
    """An item held from the side carried about the base at the attitude it was lifted at, where the
    way keeps clear (within the margins the arm keeps now: the normal, or the tight, beside a shelf's
    bin it came out of) and the lowering from its end is followed and clear (:mod:`~pickdemo.skills.pick.upright`);
    False: none does, the carry as before."""
    assert m.plan is not None
    q = m.arm.q
    tight = scene.tighter() if scene.tighter is not None else None
    within = next((s for s in (scene, tight) if s is not None and s.free(q, fingers)), None)
    if within is None:
        return False

    def goal(plan: GraspPlan, q_end: np.ndarray) -> np.ndarray | None:  # (the lowering followed and clear)
        accept = m.router.accepting(within, [plan.place], fingers)
        if line_trackable(m.kin, q_end, plan.place_above, plan.place, m.p.goals) and accept(q_end, 0):
            return q_end
        found = goal_candidates(m.kin, [plan.place_above], q_end, m.rng, m.p.goals, lines_to=[plan.place])
        ok = [g.q for g in found if g.line_ok and accept(g.q, 0)]
        return min(ok, key=lambda g: float(np.max(np.abs(g - q_end)))) if ok else None

    carry = m.router.upright(within, q, m.plan, fingers, goal)
    if carry is None:
        m.note("no upright carry found: carried as before")  # (its wall time is the plans', not a phase's)
        return False
    m.plan = carry.plan
    scale = m.p.carry_scale * m.lift_scale * m.scale.carry_share()
    m.arm.joint_line(carry.waypoints, scale)
    rise = carry.rise_m
    way = "in joint space" if rise is None else f"about the base, {rise * 1e2:.0f} cm higher at the middle"
    m.note(f"carried upright {way}, in {len(carry.waypoints)} leg(s), put down turned "
           f"{np.degrees(carry.turn_rad):+.0f} deg")  # fmt: skip
    return True


#: A carry whose straight line meets something goes this much higher first, if that keeps clear (m).
CARRY_HIGHER_M = (0.05, 0.1, 0.15)
#: The fixtures this near the held object across (m) are what its lift must clear before the carry
#: (it sets off sideways from the top of the lift)
RISE_REACH_M = 0.05


def _carried_higher(m: PickMachine, scene, fingers: float, limits, hit: tuple[str, str]) -> bool:  # noqa: ANN001
    """The carry as straight lines over what the straight one would meet: up, across, down to above the
    place (the held object lifted over a tall box, a wall), where they keep clear and the per-tick IK
    follows them; False: none does."""
    assert m.plan is not None
    here = m.kin.forward(m.arm.motion.q)
    for dz in CARRY_HIGHER_M:
        up, over = m.arm.raised(here, dz), m.arm.raised(m.plan.place_above, dz)
        ends = [up, over, m.plan.place_above, m.plan.place]
        if m.router.line_blocked(scene, m.arm.motion.q, ends, fingers, m.arm.motion.posture, untracked=True):
            continue
        if not _followed(m, ends[:3], limits.velocity):  # (near a singular posture on the way)
            continue
        m.arm.legs.clear()
        m.arm.legs.extend([lambda over=over: m.arm.move.to(over), lambda: m.arm.move.to(m.plan.place_above)])
        m.arm.move.to(up, limits=limits)
        m.note(f"carried {dz * 1e2:.0f} cm higher: on the straight line, {hit[0]} would meet {hit[1]}")
        return True
    return False


def _followed(m: PickMachine, ends: list, speed_m_s: float) -> bool:
    """Whether the per-tick IK follows these straight lines one after another, from where the arm is,
    at this speed, with its joints within their speed limits (:func:`~pickdemo.motion.ik_goals.line_trackable`)."""
    g = dataclasses.replace(m.p.goals, line_speed_m_s=speed_m_s)
    q, start = m.arm.motion.q, m.kin.forward(m.arm.motion.q)
    for end in ends:
        if not line_trackable(m.kin, q, start, end, g):
            return False
        *_, q = along_line(m.kin, q, start, end, g.line_steps)
        start = end
    return True


def tick_transport(m: PickMachine, obs: Observation) -> Transition:
    dropped = _dropped(m, obs, Stage.TRANSPORT, "dropped in transit")
    if dropped is not None or m.finished:
        return dropped
    return (State.LOWER, "above the place position") if m.arm.finished else None


def enter_lower(m: PickMachine, obs: Observation) -> None:
    assert m.plan is not None
    m.arm.cartesian()
    m.arm.move.to(m.plan.place, limits=m.arm.line_limits(m.plan.place))


def _touched_down(m: PickMachine, obs: Observation) -> float | None:
    """How far (m) above the planned height the hand is when what it holds meets something (the
    wrist's vertical load falls ``touch_down_n`` below the weight of the hand and its load), or None."""
    assert m.plan is not None
    if m.scale.hand_kg is None:
        return None
    rest_n = (m.scale.hand_kg + (m.scale.payload_kg or 0.0)) * GRAVITY_M_S2
    if wrist_load(m, obs) > rest_n - m.p.touch_down_n:
        return None
    return float(m.kin.forward(obs.arm_q).position[2] - m.plan.place.position[2])


def tick_lower(m: PickMachine, obs: Observation) -> Transition:
    dropped = _dropped(m, obs, Stage.TRANSPORT, "dropped in transit")
    if dropped is not None or m.finished:
        return dropped
    # A described target rests where planned, to a millimetre or two: met early, it stands on something
    # (pressed on, it would be crushed or slip out). One nobody described may hang lower in the fingers
    # than its cloud said (it turned in them): lowered on to the planned height, it is set on its base
    # (let go where two meshes met the table, 14-15 mm early, one fell over).
    above = _touched_down(m, obs) if m.plan.width_known else None
    if above is not None and above >= m.p.touch_early_m:
        m.arm.motion.set_target(m.arm.motion.setpoint.copy())
        m.failing = Failure(Stage.PLACE, f"the target met something {above * 1e3:.0f} mm above where it should "
                                         "rest at the place: not put down on it")  # fmt: skip
        m.after_back_off, m.keep_hold = State.FAILED, True
        return State.BACK_OFF, f"met something {above * 1e3:.0f} mm above the place: stopping, rising with it"
    if above is not None:  # on the table, about where it was planned: let go here
        m.arm.motion.set_target(m.arm.motion.setpoint.copy())
        return State.RELEASE, f"touched down {above * 1e3:.1f} mm above the planned height"
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
        m.grip.open(m.grip.max_force_n)
        m.grip.watch()
        force = m.grip.max_force_n
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
    if side_line(m, m.plan.retreat, m.p.side_line_scale, partial=True):  # (then home, planned, from there)
        return
    m.arm.move.to(m.plan.retreat, limits=m.arm.line_limits(m.plan.retreat))


def tick_retreat(m: PickMachine, obs: Observation) -> Transition:
    return (State.HOME, "clear of the object") if m.arm.finished else None


def enter_home(m: PickMachine, obs: Observation) -> None:
    go_home(m)


def tick_home(m: PickMachine, obs: Observation) -> Transition:
    if not m.arm.finished:
        return None
    return (State.VERIFY, "arm home") if m.p.verify_place else (State.DONE, "arm home")


def enter_verify(m: PickMachine, obs: Observation) -> None:
    m.verify_asked, m.verify_frames, m.verify_settled = False, 0, True
    m.verify_estimate = None


def tick_verify(m: PickMachine, obs: Observation) -> Transition:
    if not m.verify_asked:
        return None
    if m.verify_estimate is None:
        return State.DONE, "the camera does not find the target at the end"
    if not m.verify_settled:
        m.note(f"the target still moves after {m.verify_frames} frames: judged where it was last seen")
    seen = m.verify_estimate.pose.position
    if m.rest_height_m is not None:  # on the table at the place, not on something there, not fallen over
        high = float(seen[2]) - (m.place_z_m + m.rest_height_m)
        sd = float(np.sqrt(max(m.verify_estimate.position_cov[2, 2], 0.0)))
        if abs(high) > max(m.p.verify_height_tolerance_m, m.p.verify_height_sigmas * sd):
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
    m.last_at = seen.copy()  # (picked up again from where it was seen lying)
    return State.LOOK, f"{said}: picking it up again; attempt {m.attempt} of {m.max_attempts} follows"


def verify_frame(m: PickMachine, seen: PoseEstimate | None) -> None:
    """A frame of the last look: over once two in a row agree (it lies still, or is nowhere twice)."""
    last, m.verify_estimate = m.verify_estimate, seen
    m.verify_frames += 1
    if m.verify_frames < 2:
        return
    same = last is None and seen is None
    if last is not None and seen is not None:
        same = float(np.linalg.norm(seen.pose.position - last.pose.position)) <= m.p.verify_settled_m
    if same or m.verify_frames >= m.p.verify_max_frames:
        m.verify_asked, m.verify_settled = True, same


def enter_done(m: PickMachine, obs: Observation) -> None:
    pass


def tick_done(m: PickMachine, obs: Observation) -> Transition:
    return None


# ---- BACK_OFF: open, straight up to a safe height, then look or approach again.
def enter_back_off(m: PickMachine, obs: Observation) -> None:
    if m.after_back_off is State.LOOK or (m.after_back_off is State.FAILED and not m.keep_hold):
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
