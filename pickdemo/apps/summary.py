"""The one line ``run`` prints for an episode: its outcome, its errors against the truth, its figures."""

from __future__ import annotations

import math

from pickdemo.core.result import EpisodeResult
from pickdemo.scenario.load import ObjectSpec


def yaw_modulus_deg(target: ObjectSpec) -> float | None:
    """The turn (deg) after which the target looks the same, modulo which its yaw is estimated and
    scored (90 for a square box, 180 for another box); None for a cylinder, which has no yaw."""
    if target.shape == "mesh":
        return 180.0  # seen as an unknown object: its principal axes, a half turn
    symmetry = target.largest_shape.yaw_symmetry_rad
    if symmetry == 0.0:
        return None
    if target.size is None:  # drawn per seed: square only if both sides are one fixed value
        (a0, a1), (b0, b1) = target.size_range[:2]  # type: ignore[index]
        if not a0 == a1 == b0 == b1:
            return 180.0  # a box's half turn
    return math.degrees(symmetry)


def summary_line(result: EpisodeResult, yaw_modulus: float | None = None) -> str:
    head = "SUCCESS" if result.success else f"FAILED in {result.failure.stage.value}"  # type: ignore[union-attr]
    parts = [f"{head}: {result.scenario} seed {result.seed}"]
    if result.perception_method != "paper":
        parts[0] += f" [{result.perception_method}]"
    if result.perception is not None:
        yaw = result.perception.yaw_error_deg
        modulo = f" modulo {yaw_modulus:g} deg" if yaw_modulus else ""
        parts.append(
            f"pose error {result.perception.position_error_mm:.2f} mm"
            + (f", yaw error {yaw:.2f} deg{modulo}" if yaw is not None else "")
        )
    if result.place_error_mm is not None:
        parts.append(f"place error {result.place_error_mm:.1f} mm")
    c = result.clear
    if c is not None:
        rate = c["grasp_success_rate"]
        parts.append(
            f"cleared {c['cleared']}/{c['total']} ({c['percent_cleared']:.0f} %), "
            f"grasps {c['successful_grasps']}/{c['grasp_attempts']}"
            + (f" ({100 * rate:.0f} %)" if rate is not None else "")
            + f", {c['picks_per_hour']:.0f} picks/h"
        )
    if result.attempts:
        parts.append(f"{len(result.attempts)} attempt(s)")
    parts.append(f"{result.perception_frames} frames")
    video = result.stage_wall_times_s.get("video")
    parts.append(
        f"{result.sim_time_s:.1f} s simulated in {result.wall_time_s:.2f} s"
        + (f" ({video:.2f} s of it the video)" if video else "")
    )
    line = " | ".join(parts)
    if result.failure is not None:
        line += f"\n  reason: {result.failure.reason}"
        line += f"\n  diagnosis (from the truth): {result.diagnosis}"
    return line
