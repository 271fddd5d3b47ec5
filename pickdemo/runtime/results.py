"""What an episode's result says: the loop's counts as it runs, and the :class:`EpisodeResult` made of
them, the referee's scores against the truth and the controller's records."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pickdemo.core.result import (
    EpisodeResult,
    Failure,
    PhaseRecord,
    RateLimits,
    limit_exceedances,
    peak_limit_ratios,
)
from pickdemo.robot import robot_named
from pickdemo.runtime.observers import TraceRecorder
from pickdemo.runtime.referee import diagnose
from pickdemo.runtime.world import World
from pickdemo.scenario.load import Scenario


@dataclass
class LoopCounts:
    """What the loop counts as it runs (the truth's view is the referee's)."""

    phases: list[PhaseRecord] = field(default_factory=list)
    frames: int = 0
    tracking_frames: int = 0  # frames taken while tracking (approach, descend, close, back off)
    tracking_ticks: int = 0
    tick_ms: list[float] = field(default_factory=list)
    commanded: list[tuple[float, np.ndarray]] = field(default_factory=list)  # (t, joint command) per tick


def episode_result(
    *,
    scenario: Scenario,
    seed: int,
    options: Any,  # EpisodeOptions
    failure: Failure | None,
    counts: LoopCounts,
    referee: Any,
    controller: Any,
    world: World | None,
    sim_time_s: float,
    wall_s: float,
    stage_wall_times_s: dict[str, float],
    dt_ctl: float,
    pushes: list,
    round_score: dict | None,
    trace: TraceRecorder | None,
) -> EpisodeResult:
    """The scored episode: the referee's figures (truth), the controller's records, the loop's counts."""
    ref, m = referee, controller
    router = getattr(m, "router", None)  # (a pick's motions planned around what is in the way)
    ticks = np.array(counts.tick_ms) if counts.tick_ms else np.zeros(1)
    lifted = ref.lifted_mm() if ref is not None and m is not None and m.attempts else None
    tracking_error_mm = ref.tracking_error_mm if ref is not None else None
    rates = (world.robot if world is not None else robot_named()).limits.rates()
    return EpisodeResult(
        scenario=scenario.name,
        seed=seed,
        robot=scenario.robot_description.name,
        success=failure is None,
        failure=failure,
        perception=ref.perception if ref is not None else None,
        place_error_mm=ref.place_error_mm if ref is not None else None,
        lift_height_mm=lifted,
        grasp_width_mm=None if m is None or m.grasp_width_m is None else m.grasp_width_m * 1e3,
        sim_time_s=sim_time_s,
        wall_time_s=wall_s,
        stage_wall_times_s={k: round(v, 6) for k, v in stage_wall_times_s.items()},
        phases=tuple(counts.phases),
        open_loop=options.open_loop,
        attempts=tuple(m.attempts) if m is not None else (),
        perception_frames=counts.frames,
        perception_rate_hz=(
            counts.tracking_frames / (counts.tracking_ticks * dt_ctl) if counts.tracking_ticks else None
        ),
        estimates_rejected=m.counters.rejected if m is not None else 0,
        perception_failures=m.counters.perception_errors if m is not None else 0,
        target_moves_detected=m.counters.jumps if m is not None else 0,
        retargets=m.counters.retargets if m is not None else 0,
        tracking_error_mm=tracking_error_mm,
        tracking_yaw_error_deg=ref.tracking_yaw_deg if ref is not None else None,
        diagnosis=diagnose(failure, tracking_error_mm, ref.grasp_existed if ref is not None else None),
        estimates_off=ref.wrong_estimates if ref is not None else 0,
        estimates_off_accepted=ref.wrong_estimates_accepted if ref is not None else 0,
        estimates_off_fit_rejected=ref.wrong_estimates_self_rejected if ref is not None else 0,
        target_off_table=ref.off_table if ref is not None else None,
        perception_method=options.perception_method,
        disturbances=tuple({**p.push.to_dict(), "object": p.body} for p in pushes),
        control_tick_wall_ms={
            "median": float(np.median(ticks)),
            "p95": float(np.percentile(ticks, 95)),
            "ticks": len(counts.tick_ms),
            "plans": [round(s * 1e3, 3) for s in router.seconds] if router is not None else [],
        },
        motion_plans=None if router is None else {"count": router.plans, "checks": list(router.checks)},
        limit_exceedances=tuple(e.to_dict() for e in _exceedances(counts.commanded, rates)),
        peak_joint_limit_ratio=_peak_ratios(counts.commanded, rates),
        place_position_m=None if world is None else world.place_xy,
        others_moved_mm=getattr(ref, "others_moved_mm", None),
        collisions=ref.collision_summary() if ref is not None else None,
        clear=round_score,
        world=ref.world_summary(m) if ref is not None else None,
        trace=trace.freeze() if trace is not None else None,
    )


def _commanded_arrays(commanded: list[tuple[float, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    t, q = zip(*commanded, strict=True)
    return np.array(t, dtype=float), np.array(q, dtype=float).reshape(len(t), -1)


def _peak_ratios(commanded: list[tuple[float, np.ndarray]], limits: RateLimits) -> dict[str, float] | None:
    """The commanded joint motion's largest ratios to the datasheet limits (``peak_joint_limit_ratio``)."""
    return None if len(commanded) < 4 else peak_limit_ratios(*_commanded_arrays(commanded), limits)


def _exceedances(commanded: list[tuple[float, np.ndarray]], limits: RateLimits):  # noqa: ANN202
    """The joint command's excursions beyond the datasheet limits (as the motion plot marks them)."""
    return [] if len(commanded) < 4 else limit_exceedances(*_commanded_arrays(commanded), limits)
