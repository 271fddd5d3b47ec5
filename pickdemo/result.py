"""What an episode returns: success, or the stage where it failed and why, and its measurements."""

from __future__ import annotations

import enum
import json
import math
from dataclasses import dataclass, field
from typing import Any


class Stage(str, enum.Enum):
    """Where an episode can end in failure (ordered as the pipeline runs)."""

    PERCEPTION = "perception"
    GRASP_PLANNING = "grasp_planning"
    IK = "ik"
    TRAJECTORY = "trajectory"
    GRASP = "grasp"
    LIFT = "lift"
    TRANSPORT = "transport"
    PLACE = "place"
    TIMEOUT = "timeout"
    ERROR = "error"


PHASES = ("perceive", "plan", "approach", "grasp", "lift", "place", "verify")


@dataclass(frozen=True)
class Failure:
    stage: Stage
    reason: str

    def to_dict(self) -> dict[str, str]:
        return {"stage": self.stage.value, "reason": self.reason}


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
    phases: tuple[dict[str, Any], ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return _clean(
            {
                "scenario": self.scenario,
                "seed": self.seed,
                "success": self.success,
                "failure": None if self.failure is None else self.failure.to_dict(),
                "perception": None if self.perception is None else self.perception.to_dict(),
                "place_error_mm": self.place_error_mm,
                "lift_height_mm": self.lift_height_mm,
                "grasp_width_mm": self.grasp_width_mm,
                "sim_time_s": self.sim_time_s,
                "wall_time_s": self.wall_time_s,
                "stage_wall_times_s": dict(self.stage_wall_times_s),
                "phases": list(self.phases),
            }
        )

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False)


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
