"""What an episode returns: success, or the stage where it failed and why, and its measurements."""

from __future__ import annotations

import enum
import json
import math
from dataclasses import dataclass, field
from typing import Any, TypeAlias

import numpy as np


class Stage(str, enum.Enum):
    """Where an episode can end in failure (ordered as the pipeline runs)."""

    PERCEPTION = "perception"
    GRASP_PLANNING = "grasp_planning"
    IK = "ik"
    MOTION_PLANNING = "motion_planning"  # no path around what is in the way
    TRAJECTORY = "trajectory"
    REFLEX = "reflex"  # a command beyond the Franka's limits: the robot stopped
    GRASP = "grasp"
    LIFT = "lift"
    TRANSPORT = "transport"
    PLACE = "place"
    TIMEOUT = "timeout"
    ERROR = "error"


@dataclass(frozen=True)
class PhaseRecord:
    """A state of the pick entered at a simulated time, with what it said."""

    phase: str
    sim_time_s: float
    message: str

    def to_dict(self) -> dict[str, Any]:
        return {"phase": self.phase, "sim_time_s": self.sim_time_s, "message": self.message}


@dataclass(frozen=True)
class AttemptRecord:
    """One try at the grasp and how it ended (``outcome``: placed, missed, dropped ..., failed)."""

    number: int
    outcome: str
    reason: str
    start_s: float
    end_s: float
    grip_force_n: float
    hand_yaw_deg: float | None
    lift_speed_scale: float
    payload_kg: float | None = None  # what the wrist's force sensor weighed while lifting

    def to_dict(self) -> dict[str, Any]:
        return {
            "number": self.number,
            "outcome": self.outcome,
            "reason": self.reason,
            "start_s": self.start_s,
            "end_s": self.end_s,
            "grip_force_n": self.grip_force_n,
            "hand_yaw_deg": self.hand_yaw_deg,
            "lift_speed_scale": self.lift_speed_scale,
            "payload_kg": self.payload_kg,
        }


@dataclass(frozen=True)
class EpisodeTrace:
    """Per control tick, for plots and tests (not in ``result.json``): the commanded Cartesian motion
    with the limits it was given, the joint command, the true TCP and the tracked target."""

    time_s: np.ndarray  # (N,)
    state: tuple[str, ...]  # (N,)
    setpoint: np.ndarray  # (N, 4) x, y, z (m), yaw (rad)
    velocity: np.ndarray  # (N, 4)
    acceleration: np.ndarray  # (N, 4)
    jerk: np.ndarray  # (N, 4)
    max_velocity: np.ndarray  # (N, 4): the limits Ruckig had at that tick
    max_acceleration: np.ndarray  # (N, 4)
    max_jerk: np.ndarray  # (N, 4)
    retarget: np.ndarray  # (N,) bool: Ruckig recomputed (a re-target or new limits)
    q: np.ndarray  # (N, dof) joint command
    tcp_true: np.ndarray  # (N, 3) the TCP's true position (truth: for scoring)
    tracked: np.ndarray  # (N, 4) the tracker's x, y, z, yaw now (nan before it has one)


@dataclass(frozen=True)
class Failure:
    stage: Stage
    reason: str
    #: a bug's (an exception no stage expects, ending the episode in ``error``): where it was raised, so
    #: that a bug is never read as an episode that merely failed; None for every named failure
    traceback: str | None = None

    def to_dict(self) -> dict[str, str]:
        out = {"stage": self.stage.value, "reason": self.reason}
        if self.traceback is not None:  # (only a bug's record has the key)
            out["traceback"] = self.traceback
        return out

    @property
    def is_bug(self) -> bool:
        """An exception the code did not expect (its traceback kept), not a failure of the task."""
        return self.traceback is not None


class EpisodeFailure(Exception):
    """Raised inside an episode to end it in a named stage."""

    def __init__(self, stage: Stage, reason: str) -> None:
        super().__init__(f"{stage.value}: {reason}")
        self.failure = Failure(stage, reason)


@dataclass(frozen=True)
class PerceptionScore:
    """The estimate against the truth (truth from the simulator, for scoring only)."""

    estimated_pose: dict[str, Any]
    true_pose: dict[str, Any]
    position_error_mm: float
    yaw_error_deg: float | None  # None where the shape has no yaw (cylinder)
    position_nees: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "estimated_pose": self.estimated_pose,
            "true_pose": self.true_pose,
            "position_error_mm": self.position_error_mm,
            "yaw_error_deg": self.yaw_error_deg,
            "position_nees": self.position_nees,
        }


#: Keys of ``result.json`` measured on the wall clock: the only ones that differ between two runs of a seed.
WALL_CLOCK_KEYS = ("wall_time_s", "stage_wall_times_s", "control_tick_wall_ms")

#: An episode's record: the ``result.json`` object, one line of ``episodes.jsonl``, what a bench worker
#: returns and what the bench, its summary, the report and the CLI read. It is always made by
#: :meth:`EpisodeResult.to_dict` (so its keys are :class:`EpisodeResult`'s fields but ``trace``, in that
#: order, with JSON values: ``failure`` a ``{"stage", "reason"}`` object (and ``"traceback"`` for a
#: bug) or null, ``perception`` a :meth:`PerceptionScore.to_dict` or null, ``phases`` and ``attempts``
#: lists of their ``to_dict``); the key list is written there once, not again here.
EpisodeRecord: TypeAlias = dict[str, Any]


def result_key(record: EpisodeRecord) -> tuple[str, int, bool, str]:
    """Which job a record belongs to: scenario, seed, open or closed loop, perception method."""
    return (
        record["scenario"],
        record["seed"],
        bool(record.get("open_loop", False)),
        record.get("perception_method", "paper"),
    )


def summary_name(record: EpisodeRecord) -> str:
    """The scenario's name, marked when the episode ran open loop or with another perception."""
    method = record.get("perception_method", "paper")
    return (
        record["scenario"]
        + (" [open loop]" if record.get("open_loop") else "")
        + (f" [{method}]" if method != "paper" else "")
    )


@dataclass(frozen=True)
class EpisodeResult:
    """One scored episode. ``to_dict`` gives the ``result.json`` object."""

    scenario: str
    seed: int
    success: bool
    failure: Failure | None
    perception: PerceptionScore | None
    place_error_mm: float | None
    lift_height_mm: float | None
    grasp_width_mm: float | None
    sim_time_s: float
    wall_time_s: float
    stage_wall_times_s: dict[str, float] = field(default_factory=dict)
    phases: tuple[PhaseRecord, ...] = ()
    open_loop: bool = False
    attempts: tuple[AttemptRecord, ...] = ()
    perception_frames: int = 0
    perception_rate_hz: float | None = None  # frames per simulated second while it tracked the target
    estimates_rejected: int = 0  # estimates the tracker's gate turned away
    perception_failures: int = 0  # frames in which perception found no estimate
    target_moves_detected: int = 0  # times the tracker restarted on a target that had moved
    retargets: int = 0  # re-targets written into Ruckig while a motion was under way
    tracking_error_mm: float | None = None  # tracker vs truth when the gripper last closed
    tracking_yaw_error_deg: float | None = None
    disturbances: tuple[dict[str, Any], ...] = ()  # the pushes applied (drawn per seed)
    control_tick_wall_ms: dict[str, float] = field(default_factory=dict)  # wall time of a decision: median, p95
    diagnosis: str | None = None  # failed: perception_off | perception_ok | not_committed (from the truth)
    perception_method: str = "paper"
    robot: str | None = None  # the robot that ran it (its file's ``name``); None: not known (the episode never started)
    estimates_off: int = 0  # estimates > 5 mm off the truth that reached the controller (scored on the truth)
    estimates_off_accepted: int = 0  # of those, the ones it fused into its belief instead of rejecting
    estimates_off_fit_rejected: int = 0  # of those, the ones perception's own fit check rejected
    target_off_table: bool | None = None  # at the end the target had fallen off the table (scored on the truth)
    limit_exceedances: tuple[dict[str, Any], ...] = ()  # commanded joint motion beyond the datasheet (see below)
    #: the largest ratio of a commanded joint velocity, acceleration, jerk to its datasheet limit, over all
    #: joints and ticks (at most 1.0: within); None when nothing was commanded
    peak_joint_limit_ratio: dict[str, float] | None = None
    place_position_m: tuple[float, float] | None = None  # where it was to be put down (drawn per seed from a range)
    #: the other objects the episode moved 10 mm or more from where they stood, {name: mm} (truth); None
    #: for a clear round (it moves them all) or a belt (it carries them)
    others_moved_mm: dict[str, float] | None = None
    #: the robot's and the held object's contacts with anything they may not touch (truth:
    #: :mod:`pickdemo.runtime.collisions`), ``{"count": n, "first": [...]}``; None: never started
    collisions: dict[str, Any] | None = None
    #: the motions planned around what was in the way: how many, and the states each checked
    #: (its wall time is ``control_tick_wall_ms.plans``); None: a controller that plans none
    motion_plans: dict[str, Any] | None = None
    #: a clear round's figures: each object's fate, its picks, cleared, percent_cleared, grasp_success_rate,
    #: picks_per_hour (simulated time); None for a pick
    clear: dict[str, Any] | None = None
    #: the robot's world model at the end, each object scored against the truth, and its scores over the
    #: episode (found, missed, phantoms, id switches: :mod:`pickdemo.runtime.world_score`); None: none kept
    world: dict[str, Any] | None = None
    trace: EpisodeTrace | None = field(default=None, repr=False, compare=False)

    @classmethod
    def failed(
        cls,
        scenario: str,
        seed: int,
        stage: Stage,
        reason: str,
        *,
        wall_time_s: float = 0.0,
        open_loop: bool = False,
        perception_method: str = "paper",
        diagnosis: str | None = "not_committed",
        traceback: str | None = None,
    ) -> EpisodeResult:
        """The result of an episode that produced none of its own (its job raised, crashed or hung, or
        it could not start): failed in ``stage``, nothing measured, no simulated time; ``traceback``:
        where it raised (a bug)."""
        return cls(
            scenario=scenario,
            seed=seed,
            success=False,
            failure=Failure(stage, reason, traceback),
            perception=None,
            place_error_mm=None,
            lift_height_mm=None,
            grasp_width_mm=None,
            sim_time_s=0.0,
            wall_time_s=wall_time_s,
            open_loop=open_loop,
            diagnosis=diagnosis,
            perception_method=perception_method,
        )

    def to_dict(self) -> EpisodeRecord:
        return _clean(
            {
                "scenario": self.scenario,
                "seed": self.seed,
                "robot": self.robot,
                "success": self.success,
                "failure": None if self.failure is None else self.failure.to_dict(),
                "perception": None if self.perception is None else self.perception.to_dict(),
                "place_error_mm": self.place_error_mm,
                "lift_height_mm": self.lift_height_mm,
                "grasp_width_mm": self.grasp_width_mm,
                "sim_time_s": self.sim_time_s,
                "wall_time_s": self.wall_time_s,
                "stage_wall_times_s": dict(self.stage_wall_times_s),
                "phases": [p.to_dict() for p in self.phases],
                "open_loop": self.open_loop,
                "attempts": [a.to_dict() for a in self.attempts],
                "perception_frames": self.perception_frames,
                "perception_rate_hz": self.perception_rate_hz,
                "estimates_rejected": self.estimates_rejected,
                "perception_failures": self.perception_failures,
                "target_moves_detected": self.target_moves_detected,
                "retargets": self.retargets,
                "tracking_error_mm": self.tracking_error_mm,
                "tracking_yaw_error_deg": self.tracking_yaw_error_deg,
                "disturbances": list(self.disturbances),
                "control_tick_wall_ms": dict(self.control_tick_wall_ms),
                "diagnosis": self.diagnosis,
                "perception_method": self.perception_method,
                "estimates_off": self.estimates_off,
                "estimates_off_accepted": self.estimates_off_accepted,
                "estimates_off_fit_rejected": self.estimates_off_fit_rejected,
                "target_off_table": self.target_off_table,
                "limit_exceedances": [dict(e) for e in self.limit_exceedances],
                "place_position_m": None if self.place_position_m is None else list(self.place_position_m),
                "peak_joint_limit_ratio": None
                if self.peak_joint_limit_ratio is None
                else dict(self.peak_joint_limit_ratio),
                "others_moved_mm": None if self.others_moved_mm is None else dict(self.others_moved_mm),
                "collisions": self.collisions,
                "motion_plans": self.motion_plans,
                **({} if self.clear is None else {"clear": self.clear}),
                **({} if self.world is None else {"world": self.world}),
            }
        )

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)


#: Datasheet limits the commanded joint motion is checked against: {quantity: (per joint, unit)}
#: (a robot's: :meth:`pickdemo.robot.description.JointLimits.rates`)
RateLimits = dict[str, tuple[np.ndarray, str]]


def joint_derivatives(time_s: np.ndarray, q: np.ndarray) -> dict[str, np.ndarray]:
    """The commanded joints' position, velocity, acceleration and jerk per tick: finite differences
    (``np.gradient``, second order inside, one-sided at the ends) of the joint command ``q`` (N, dof)."""
    t = np.asarray(time_s, dtype=float)
    q = np.asarray(q, dtype=float)
    if len(t) < 4:
        raise ValueError("the trace is too short to differentiate")
    vel = np.gradient(q, t, axis=0)
    acc = np.gradient(vel, t, axis=0)
    jerk = np.gradient(acc, t, axis=0)
    return {"time_s": t, "position": q, "velocity": vel, "acceleration": acc, "jerk": jerk}


@dataclass(frozen=True)
class LimitExceedance:
    """One joint's commanded velocity, acceleration or jerk beyond its datasheet limit: the peak
    (absolute), the limit, how many ticks were over it and when. ``times_s``/``values`` are the samples
    over the limit (signed), for a plot; ``to_dict`` (``result.json``) leaves them out."""

    joint: int  # 1 .. 7
    quantity: str  # velocity | acceleration | jerk
    unit: str
    peak: float  # the largest |value| (its sign is in ``values``)
    limit: float
    samples: int  # ticks over the limit
    first_time_s: float
    peak_time_s: float
    times_s: np.ndarray = field(repr=False, compare=False, default_factory=lambda: np.zeros(0))
    values: np.ndarray = field(repr=False, compare=False, default_factory=lambda: np.zeros(0))

    def to_dict(self) -> dict[str, Any]:
        return {
            "joint": self.joint,
            "quantity": self.quantity,
            "unit": self.unit,
            "peak": self.peak,
            "limit": self.limit,
            "samples": self.samples,
            "first_time_s": self.first_time_s,
            "peak_time_s": self.peak_time_s,
        }

    def note(self) -> str:
        """One line, e.g. ``joint 2: 7.59 rad/s^2 > 7.5 at 1.45 s (3 ticks)``."""
        ticks = f"{self.samples} tick{'s' if self.samples != 1 else ''}"
        value = f"{self.peak:.3g} {self.unit} > {self.limit:.3g}"
        return f"joint {self.joint}: {value} at {self.peak_time_s:.2f} s ({ticks})"


def peak_limit_ratios(time_s: np.ndarray, q: np.ndarray, limits: RateLimits) -> dict[str, float] | None:
    """Per quantity (velocity, acceleration, jerk), the largest ratio of the commanded joint motion
    (the finite differences of :func:`joint_derivatives`) to its datasheet limit, over all joints and
    ticks: at most 1.0 means within the limits. None when the command is too short to differentiate."""
    if len(time_s) < 4:
        return None
    motion = joint_derivatives(time_s, q)
    return {
        key: float(np.max(np.abs(motion[key]) / np.asarray(lim, dtype=float)[None, :]))
        for key, (lim, _unit) in limits.items()
    }


def limit_exceedances(time_s: np.ndarray, q: np.ndarray, limits: RateLimits) -> list[LimitExceedance]:
    """Every joint and quantity whose commanded motion went beyond its datasheet limit (strictly),
    from the joint command per tick (the finite differences of :func:`joint_derivatives`); ordered by
    quantity, then joint. Empty when nothing exceeded, or the command is too short to differentiate.
    Pure (numpy only): the same for the plot and for ``result.json``."""
    if len(time_s) < 4:
        return []
    motion = joint_derivatives(time_s, q)
    t = motion["time_s"]
    out: list[LimitExceedance] = []
    for key, (lim, unit) in limits.items():
        values = motion[key]
        over = np.abs(values) > np.asarray(lim, dtype=float)[None, :]
        for j in np.flatnonzero(over.any(axis=0)):
            idx = np.flatnonzero(over[:, j])
            k = idx[int(np.argmax(np.abs(values[idx, j])))]
            out.append(
                LimitExceedance(
                    joint=int(j) + 1,
                    quantity=key,
                    unit=unit,
                    peak=float(abs(values[k, j])),
                    limit=float(lim[j]),
                    samples=len(idx),
                    first_time_s=float(t[idx[0]]),
                    peak_time_s=float(t[k]),
                    times_s=t[idx].copy(),
                    values=values[idx, j].copy(),
                )
            )
    return out


def _clean(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, non-finite floats to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if hasattr(obj, "item") and not isinstance(obj, (str, bytes)):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj
