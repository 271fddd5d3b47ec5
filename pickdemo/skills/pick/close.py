"""The pick skill's CLOSE state: the fingers close with the attempt's force (or a cup's valve opens),
and the object is held or missed; its entry action and exit test, as functions of the machine
(:mod:`~pickdemo.skills.pick.states` holds the table the machine dispatches from)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from pickdemo.core.geometry import Pose
from pickdemo.core.interfaces import Observation
from pickdemo.core.result import Stage
from pickdemo.motion.online import CartesianLimits
from pickdemo.skills.pick.params import State, Transition
from pickdemo.skills.pick.take import moved_under_hand

if TYPE_CHECKING:  # (the machine imports this table: a type only, for the reader and the checker)
    from pickdemo.skills.pick.machine import PickMachine


#: A cup at its grasp whose sensor reads no vacuum at all once its valve is open (nothing under its lip:
#: a leak reads some) goes on along its approach, slowly, up to this much further (m), and stops where
#: the lip touches: the face was seen that much nearer than it is (measured in ``suction_clear_bin``: 3
#: of 5 such misses had the lip 2.5 to 4 mm short of the face). A real cell searches so on its vacuum.
SEARCH_M = 0.006
SEARCH_LIMITS = CartesianLimits(velocity=0.02, acceleration=0.2, jerk=2.0)


# ---- CLOSE: fingers close with this attempt's force; held or missed.
def enter_close(m: PickMachine, obs: Observation) -> None:
    tp = m.belief.predict(obs.time_s)  # how high its centre rests above what it stands on: so at the place
    m.rest_height_m = float(tp.position[2]) - m.belief.surface_z(*(float(v) for v in tp.position))
    m.grip.close(m.close_force_n)
    m.grip.watch()
    m.watch.start_hold()
    m.searched_on = False


def _searching_on(m: PickMachine, obs: Observation) -> bool:
    """A cup going on along its approach for the face it does not touch (:data:`SEARCH_M`): True while
    it does (the close waits for it)."""
    if not m.grip.vacuum or m.plan is None or obs.time_s - m.since_s < 1.5 * m.grip.dt_s:
        return False  # (the first reading is from before the valve opened)
    touching = obs.vacuum_kpa > 0.0
    if not m.searched_on:
        if touching:
            return False
        m.searched_on = True
        g = m.plan.grasp
        m.arm.cartesian()
        m.arm.move.to(Pose(g.position + g.rotation[:, 2] * SEARCH_M, g.rotation), limits=SEARCH_LIMITS)
        m.note(f"no vacuum at the grasp: on along the approach, up to {SEARCH_M * 1e3:.0f} mm further")
    elif m.arm.finished:
        return False
    elif touching:  # the lip meets the face: stopped there, the seal given its time
        m.arm.motion.set_target(m.arm.motion.setpoint.copy())
        m.grip.watch()
        return False
    m.grip.watch()
    return True


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


def _pushed_harder(m: PickMachine, obs: Observation) -> bool:
    """A jaw that stalled on the object before the object reached the fixed jaw (one finger touching):
    closes harder, doubling its force up to the hand's most. The moving jaw's arc presses the object
    into the table as it pushes it, and the table's friction can hold it; a real servo gripper pushes
    on at a higher current. (Two fingers closing about the middle do not push the object across.)"""
    left, right = obs.finger_contacts
    if m.kin.robot.gripper.coupled or (left > 0) == (right > 0) or m.grip.force_n >= m.grip.max_force_n:
        return False
    force = min(2.0 * m.grip.force_n, m.grip.max_force_n)
    m.note(f"the jaw stopped at {obs.opening_m * 1e3:.1f} mm on the object alone: closing at {force:.0f} N")
    m.grip.close(force)
    m.grip.watch()
    return True


def tick_close(m: PickMachine, obs: Observation) -> Transition:
    assert m.plan is not None
    if _searching_on(m, obs):
        return None
    stalled = m.grip.stopped(obs)
    if stalled and not m.grip.holding(obs, m.plan.object_width_m) and _pushed_harder(m, obs):
        return None
    if stalled:
        _held_across_another_side(m, obs)
    width = m.plan.object_width_m
    if not stalled and not m.grip.holding(obs, width):
        moved = moved_under_hand(m)
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
        if m.grip.force_n > m.close_force_n:  # (pushed harder to the fixed jaw: held with the grip's force)
            m.grip.close(m.close_force_n)
        return State.LIFT, f"holding: {m.grip.hold_text(obs)}"
    reason = (
        f"fingers closed to {obs.opening_m * 1e3:.1f} mm (expected {width * 1e3:.0f} mm): nothing held"
        if not m.grip.vacuum
        else f"no seal ({m.grip.reading(obs)}): nothing held"
    )
    return m.retry(Stage.GRASP, "missed", reason)
