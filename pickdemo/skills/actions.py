"""The pick skill's actions, as Drake's ``IiwaMove`` and ``WsgAction``: a move of the hand and a
grip of the fingers, each started by the skill and then asked whether it has finished or failed.

Pure: no simulator. :class:`Move` drives the online Ruckig motion of the TCP (x, y, z, yaw) and,
for a target that moves, meets it where it will be; which way round the hand turns to a new angle is
the one whose end the IK reaches with the joints clear of their limits
(:func:`pickdemo.motion.ik_goals.way_round`). :class:`Grip` commands the Franka Hand's opening and
force and reads its fingers: stopped, holding, dropped; :class:`Suck` is the same for a suction cup
(its valve, its vacuum sensor), and :func:`grip_for` gives a robot its own. :class:`Scale` weighs
what the hand holds with the wrist's force sensor.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from pickdemo.core.geometry import Pose, wrap_angle
from pickdemo.core.interfaces import Observation
from pickdemo.motion import ik_goals
from pickdemo.motion.online import CartesianLimits, MotionError, MotionSample, OnlineMotion, hand_frame, pose_to_x4
from pickdemo.robot.description import Gripper

GRAVITY_M_S2 = 9.81
#: A target within this of the last one whose way round the IK chose keeps that way round (rad, m).
TURN_KEPT_RAD = 0.2
TURN_KEPT_M = 0.05


class Status(str, enum.Enum):
    RUNNING = "running"
    FINISHED = "finished"
    FAILED = "failed"


class Move:
    """The hand's motion: one online Ruckig trajectory, re-targeted as the skill asks."""

    def __init__(self, motion: OnlineMotion, *, chase_fraction: float, meet_horizon_s: float) -> None:
        """``chase_fraction``: a target faster than this share of the hand's speed limit (an axis)
        runs away from it; ``meet_horizon_s``: a moving target not met within this is out of reach."""
        self.motion = motion
        self.chase_fraction = chase_fraction
        self.meet_horizon_s = meet_horizon_s
        self.failure: str | None = None
        self.last_sample: MotionSample | None = None
        self._turn: tuple[int, np.ndarray] | None = None  # (the motion's seat, the last x4 decided)

    # -------------------------------------------------------------------------------- started
    def x4(self, target: Pose | np.ndarray) -> np.ndarray:
        """(x, y, z, yaw) of a pose (or of an x4), its yaw unwrapped to the way round the arm can turn
        (:func:`pickdemo.motion.ik_goals.way_round`). A target near the last one decided (a moving target's
        next estimate, a lift above a grasp) keeps its way round without asking the IK again: the
        choice holds while the target moves, and does not flip halfway through a turn."""
        m = self.motion
        if isinstance(target, Pose):
            self._reframe(target)
            x4 = pose_to_x4(target, m.frame)
        else:
            x4 = np.array(target, dtype=float)
        if self._turn is not None and self._turn[0] == m.seated:
            last = self._turn[1]
            dyaw = float(wrap_angle(x4[3] - last[3]))
            if abs(dyaw) <= TURN_KEPT_RAD and float(np.hypot(*(x4[:2] - last[:2]))) <= TURN_KEPT_M:
                x4[3] = last[3] + dyaw
                return x4
        x4 = ik_goals.way_round(m.kin, m.q, m.setpoint, x4, frame=m.frame)
        self._turn = (m.seated, x4.copy())
        return x4

    def _reframe(self, target: Pose) -> None:
        """A target tilted otherwise than the motion's frame (a tilted grasp's pregrasp, reached by a joint
        transfer, or back to pointing down): the motion, at rest, is re-seated in the target's frame.
        Under way, it keeps its frame (a re-plan moves the target, it does not tilt it)."""
        m = self.motion
        frame = hand_frame(target.rotation)
        same = (frame is None) == (m.frame is None) and (frame is None or np.allclose(frame, m.frame, atol=1e-6))
        if not same and m.finished:
            m.reset_at(m.q, frame)

    def to(self, target: Pose | np.ndarray, *, limits: CartesianLimits | None = None) -> None:
        """Go to a fixed pose (limits change only at rest: ``None`` keeps the current ones)."""
        self.motion.set_target(self.x4(target), limits=limits)

    def meet_in(self, x4: np.ndarray, v: np.ndarray, limits: CartesianLimits | None) -> float | None:
        """Seconds from now until the hand can be at ``x4`` carried along at ``v`` (a plan's pose for
        the target where it is now), moving with it; None: not within the horizon, or faster than the hand."""
        vel4 = np.array([v[0], v[1], 0.0, 0.0])
        reach = np.array((limits or self.motion.limits).arrays()[0][:2])
        if np.any(np.abs(v) > self.chase_fraction * reach):  # it would run away from the hand
            return None
        return self.motion.intercept(lambda t: x4 + vel4 * t, vel4, limits=limits, latest_s=self.meet_horizon_s)

    def meet(self, target: Pose | np.ndarray, v: np.ndarray, limits: CartesianLimits | None = None) -> bool:
        """Go to where a target moving at ``v`` (m/s, horizontal) will be met, arriving then with its
        velocity (Ruckig's target velocity and minimum duration), and follow it; False: it cannot be met."""
        x4 = self.x4(target)
        t = self.meet_in(x4, v, limits or self.motion.limits)
        if t is None:
            return False
        vel4 = np.array([v[0], v[1], 0.0, 0.0])
        self.motion.set_target(x4 + vel4 * t, velocity=vel4, limits=limits, arrive_in_s=t)
        return True

    # ------------------------------------------------------------------------ finished, failed
    def step(self) -> MotionSample | None:
        """Advance one control tick; None when the motion failed (``failure`` says why)."""
        try:
            sample = self.motion.step()
        except MotionError as exc:
            self.failure = str(exc)
            return None
        self.last_sample = sample
        return sample

    @property
    def status(self) -> Status:
        if self.failure is not None:
            return Status.FAILED
        return Status.FINISHED if self.motion.finished else Status.RUNNING

    @property
    def finished(self) -> bool:
        return self.motion.finished


@dataclass(frozen=True)
class GripParams:
    """How the skill reads and drives a parallel hand's fingers; SI units."""

    open_force_n: float = 20.0
    #: fingers moving slower than this are still (2 um a 240 Hz physics step)
    still_speed_m_s: float = 2e-6 * 240.0
    stall_ticks: int = 8  # ticks in a row of fingers not moving: they have closed or opened
    drop_ticks: int = 3  # ticks in a row without a hold before a drop is called
    hold_margin_m: float = 0.008  # fingers closed this far past the object's width: nothing held
    #: fingers stopped this far wider than a known object's width: held askew, or not it alone ...
    wide_margin_m: float = 0.008
    #: ... or this share of its width, if less: a small cube held corner to corner is 41 % wider
    wide_share: float = 0.25
    open_margin_m: float = 0.004  # fingers within this of wide open: opened


class Grip:
    """The fingers: a target opening and force, and what the finger sensors say of them."""

    vacuum = False  # (fingers have no valve)

    def __init__(self, params: GripParams, dt_s: float, gripper: Gripper) -> None:
        self.p = params
        self.dt_s = dt_s
        self.finger_max_m = gripper.finger_max_m
        self.max_force_n = gripper.max_force_n  # (a retry's harder grip goes up to it)
        self.target_m = self.finger_max_m
        self.force_n = params.open_force_n
        self._stall = 0
        self._no_hold = 0
        self._prev_opening: float | None = None

    def open(self, force_n: float | None = None, to_m: float | None = None) -> None:
        """Open wide, or each finger ``to_m`` from the middle (with ``force_n``, default the usual
        opening force)."""
        self.target_m = self.finger_max_m if to_m is None else min(to_m, self.finger_max_m)
        self.force_n = self.p.open_force_n if force_n is None else force_n

    def close(self, force_n: float) -> None:
        self.target_m, self.force_n = 0.0, force_n

    def watch(self) -> None:
        """Started: watch the fingers from now on until they stop."""
        self._stall = 0
        self._prev_opening = None

    def stopped(self, obs: Observation) -> bool:
        """Finished: the fingers have not moved for ``stall_ticks`` ticks (closed on something, or open)."""
        opening = obs.opening_m
        moved = self._prev_opening is None or abs(opening - self._prev_opening) > self.p.still_speed_m_s * self.dt_s
        self._prev_opening = opening
        self._stall = 0 if moved else self._stall + 1
        return self._stall >= self.p.stall_ticks

    def opened(self, obs: Observation) -> bool:
        """As open as they were told to be (wide, or as far as :meth:`open` said)."""
        return obs.opening_m > 2.0 * self.target_m - self.p.open_margin_m

    def holding(self, obs: Observation, width_m: float) -> bool:
        """Both fingers touch and the opening matches an object ``width_m`` wide."""
        left, right = obs.finger_contacts
        return left > 0 and right > 0 and obs.opening_m > width_m - self.p.hold_margin_m

    def too_wide(self, obs: Observation, width_m: float) -> bool:
        """The fingers stopped wider than an object ``width_m`` wide by ``wide_margin_m`` (or
        ``wide_share`` of its width, if less): held askew (turned between the pads) or with something else."""
        return obs.opening_m > width_m + min(self.p.wide_margin_m, self.p.wide_share * width_m)

    def watch_hold(self) -> None:
        self._no_hold = 0

    def reading(self, obs: Observation) -> str:
        """What the sensors say of the grip, as a note puts it."""
        return f"fingers at {obs.opening_m * 1e3:.1f} mm"

    def hold_text(self, obs: Observation) -> str:
        """A hold as a note puts it."""
        return f"fingers at {obs.opening_m * 1e3:.1f} mm, contact on both, {self.force_n:.0f} N"

    def dropped(self, obs: Observation, width_m: float) -> bool:
        """Failed: no hold for ``drop_ticks`` ticks in a row."""
        self._no_hold = 0 if self.holding(obs, width_m) else self._no_hold + 1
        return self._no_hold >= self.p.drop_ticks


class Suck(Grip):
    """A suction cup as the skill's grip: closing opens the vacuum's valve, opening shuts it (and blows
    the part off); what it holds is what its vacuum sensor says (at least the cup's switch level: a
    sealed cup), never a finger's contact. A cup that has not sealed :attr:`SEAL_WAIT_S` after its valve
    opened has stopped on nothing: the close ends there (a leak, or no face under it)."""

    #: a valve open this long without a seal: the close has ended on nothing (s; a vacuum builds in 0.1 s)
    SEAL_WAIT_S = 0.25

    def __init__(self, params: GripParams, dt_s: float, gripper: Gripper) -> None:
        super().__init__(params, dt_s, gripper)
        assert gripper.cup is not None
        self.switch_kpa = gripper.cup.switch_kpa
        self.vacuum = False
        self._open_ticks = 0

    def open(self, force_n: float | None = None, to_m: float | None = None) -> None:
        super().open(force_n, to_m)
        self.vacuum = False

    def close(self, force_n: float) -> None:
        super().close(force_n)
        self.vacuum = True

    def watch(self) -> None:
        super().watch()
        self._open_ticks = 0

    def stopped(self, obs: Observation) -> bool:
        """Sealed, or the valve open ``SEAL_WAIT_S`` without a seal (the valve shut, letting go: the vacuum
        falls, it never stalls)."""
        if not self.vacuum:
            return False
        self._open_ticks += 1
        return self.holding(obs, 0.0) or self._open_ticks * self.dt_s >= self.SEAL_WAIT_S

    def opened(self, obs: Observation) -> bool:
        return not self.vacuum and obs.vacuum_kpa < self.switch_kpa

    def holding(self, obs: Observation, width_m: float) -> bool:
        return obs.vacuum_kpa >= self.switch_kpa

    def too_wide(self, obs: Observation, width_m: float) -> bool:
        return False  # (a seal is a seal: nothing is held askew between pads)

    def reading(self, obs: Observation) -> str:
        return f"vacuum at {obs.vacuum_kpa:.0f} kPa"

    def hold_text(self, obs: Observation) -> str:
        return f"sealed, {self.reading(obs)}"


def grip_for(params: GripParams, dt_s: float, gripper: Gripper) -> Grip:
    """The skill's grip for this robot's gripper: fingers, or a suction cup."""
    return Suck(params, dt_s, gripper) if gripper.suction else Grip(params, dt_s, gripper)


@dataclass(frozen=True)
class PayloadParams:
    """Weighing what the hand holds with the wrist's force sensor, and gripping to suit; SI units."""

    tare_ticks: int = 10  # at rest with nothing held (looking from home): the hand's own weight
    weigh_ticks: int = 5  # readings at rest, lifted, their median is the payload
    lift_off_m: float = 0.015  # a lift pauses this far up (the object hanging) to be weighed
    #: a payload heavier than this is carried at sqrt(this / payload) of the speed (accelerations at
    #: this / payload): a 0.8 kg cube at 0.61, 1.2 kg at 0.5
    gentle_above_kg: float = 0.3
    #: grip force per kg held, per finger: 50 N/kg holds a 0.8 kg cube without turning in the pads
    #: (evidence: docs/decisions.md#grasps-and-holds)
    grip_n_per_kg: float = 50.0


class Scale:
    """The wrist's force sensor as a scale: tared at rest with the hand empty, read at rest lifted.

    The vertical load is ``(m_hand + m) (g + a_z)``; a reading may give the hand's vertical
    acceleration (0 at rest).
    """

    def __init__(self, params: PayloadParams) -> None:
        self.p = params
        self._tare: list[float] = []
        self._readings: list[float] = []
        self.hand_kg: float | None = None
        self.payload_kg: float | None = None

    @staticmethod
    def vertical(obs: Observation, hand_rotation: np.ndarray) -> float:
        """The wrist's load along world z (N, up positive)."""
        return float((hand_rotation @ obs.wrist_force_n)[2])

    def tare(self, load_z_n: float) -> None:
        """A reading at rest with nothing in the hand."""
        self._tare = [*self._tare, load_z_n][-self.p.tare_ticks :]
        self.hand_kg = float(np.median(self._tare)) / GRAVITY_M_S2

    def start(self) -> None:
        """A lift begins: weigh afresh."""
        self._readings = []
        self.payload_kg = None

    def read(self, load_z_n: float, accel_z_m_s2: float) -> float | None:
        """A reading with the object hanging in the fingers; the payload (kg) once enough are in."""
        if self.hand_kg is None or self.payload_kg is not None:
            return self.payload_kg
        self._readings.append(load_z_n / (GRAVITY_M_S2 + accel_z_m_s2) - self.hand_kg)
        if len(self._readings) >= self.p.weigh_ticks:
            self.payload_kg = max(0.0, float(np.median(self._readings)))
        return self.payload_kg

    def grip_force_n(self, payload_kg: float) -> float:
        return self.p.grip_n_per_kg * payload_kg

    def weigh(self, load_z_n: float, grip_force_n: float, max_force_n: float) -> tuple[float, float] | None:
        """A reading lifted, at rest (readings on the move are no use: the simulated sensor, like the
        Franka's estimate, misses the motors' share then); once enough are in, the payload (kg) and
        the grip force it asks for (N, at least ``grip_force_n``, at most ``max_force_n``)."""
        payload = self.read(load_z_n, 0.0)
        if payload is None:
            return None
        return payload, min(max(grip_force_n, self.grip_force_n(payload)), max_force_n)

    def carry_share(self) -> float:
        """The carry's speed share for what was weighed: a heavier hold is carried more gently (its
        accelerations as the square of this), so that it does not swing in the pads."""
        m = self.payload_kg
        light = self.p.gentle_above_kg
        return 1.0 if m is None or m <= light else float(np.sqrt(light / m))
