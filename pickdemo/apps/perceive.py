"""Perception only, measured: ``python -m pickdemo perceive SCENARIO --seeds 0-99 [--methods ...]``.

Each seed's scene is built and rendered once (no arm motion); every method sees that same frame and
estimates every target's pose; each estimate is scored against the truth (position error, 3-D and
per axis; yaw, pitch, roll errors modulo the object's symmetry; the position NEES, which averages 3
when the reported covariance is honest; the method's own time, rendering excluded).
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeAlias

import numpy as np

from pickdemo.apps.files import write_atomic, write_figure
from pickdemo.core.shapes import Unknown
from pickdemo.core.stats import describe
from pickdemo.perception import PerceptionError, PoseEstimate, TargetModel
from pickdemo.perception.estimators import BUILTIN, resolve_estimator
from pickdemo.robot.self_geometry import robot_body
from pickdemo.runtime.evaluation import pose_errors
from pickdemo.runtime.metrics import position_nees, seen_truth
from pickdemo.runtime.world import World
from pickdemo.scenario.load import Scenario
from pickdemo.scenario.task import target_model

MethodFn = Callable[..., PoseEstimate]
METHODS: dict[str, MethodFn] = dict(BUILTIN)
ORIENTED = {"paper", "centroid", "icp"}  # pixel gives a position only; a user's own: when its yaw has a variance
#: The baselines need the target described (its shape and colour): not for an object nobody described.
NEEDS_DESCRIPTION = {"pixel", "centroid", "icp"}


def _oriented(name: str, est: PoseEstimate) -> bool:
    """Whether an estimate's orientation is scored: a built-in's by name, a user's when it gives its yaw a
    finite variance."""
    return name in ORIENTED if name in METHODS else bool(np.isfinite(est.rpy_cov[2, 2]))


#: One method on one target of one seed's frame, as perception.json holds it: ``method``, ``seed``,
#: ``target``, ``time_ms``, ``camera_distance_m``, ``failure`` (None or perception's reason), the
#: errors of :data:`ERROR_KEYS` (None when it failed), ``feature_point_error_mm``, ``nees``,
#: ``estimated_pose``, ``true_pose``, and ``reference`` (the paper's row) where the target has one.
PerceptionSample: TypeAlias = dict[str, Any]
#: Per method: ``n``, ``failures``, the statistics of each error and ``nees``, the time per frame.
MethodSummary: TypeAlias = dict[str, Any]

ERROR_KEYS = (
    "position_error_mm",
    "x_error_mm",
    "y_error_mm",
    "z_error_mm",
    "feature_point_error_mm",
    "yaw_error_deg",
    "pitch_error_deg",
    "roll_error_deg",
)


def perceive_seed(scenario: Scenario, seed: int, methods: list[str], *, repeat: int = 1) -> list[PerceptionSample]:
    """One sample per method and target for one seed. With ``repeat`` > 1 each method runs that many
    times on the frame and its time is the median (a steadier benchmark; the estimate is the same)."""
    with World.build(scenario, seed) as world:  # the episode's world for this seed
        if any(not o.static for o in scenario.objects):
            world.scene.step(120)  # let what is not held come to rest
        camera = world.camera
        frame = camera.capture(world.scene)
        # the robot stands at home: the self-filter is told so (what its joint states would say)
        robot = world.robot
        fingers = [robot.gripper.finger_max_m] * 2
        frame = dataclasses.replace(frame, robot_boxes=robot_body(robot).boxes(robot.home_q, fingers))
        truths = {  # truth: scoring only
            t.name: seen_truth(world.true_pose(t.name), world.placement(t.name).geometry) for t in scenario.targets
        }
    distance = float(np.linalg.norm(camera.T_world_cam.position - np.asarray(scenario.camera.look_at)))
    samples = []
    fns = {name: resolve_estimator(name) for name in methods}  # a built-in, or module:function
    for spec in scenario.targets:
        model = target_model(scenario, world.placement(spec.name))
        truth = truths[spec.name]
        for name in methods:
            times = []
            for _ in range(max(repeat, 1)):
                t0 = time.perf_counter()
                try:
                    est = fns[name](frame, model)
                    error = None
                except PerceptionError as exc:
                    est, error = None, str(exc)
                times.append((time.perf_counter() - t0) * 1e3)
            elapsed_ms = float(np.median(times))
            sample: PerceptionSample = {"method": name, "seed": seed, "target": spec.name, "time_ms": elapsed_ms,
                                      "camera_distance_m": distance, "failure": error}  # fmt: skip
            if est is None:
                sample.update({k: None for k in ERROR_KEYS}, nees=None)
            else:
                unknown = isinstance(model.geometry, Unknown)  # its principal axes are no axis of its body
                sample.update(_score(est, truth, model, oriented=_oriented(name, est) and not unknown))
            if spec.reference is not None:
                sample["reference"] = spec.reference.model_dump()
            samples.append(sample)
    return samples


def _score(est: PoseEstimate, truth, model: TargetModel, *, oriented: bool) -> dict[str, Any]:
    errs = pose_errors(est.pose, truth, est.yaw_symmetry_rad, has_orientation=oriented)
    nees = position_nees(est, truth) if np.all(np.isfinite(est.position_cov)) else None
    # The paper's "main feature point": the centre of the top face.
    half = 0.0 if isinstance(model.geometry, Unknown) else model.height_m / 2.0
    top_est = est.pose.position + (est.pose.rotation[:, 2] * half if oriented else np.array([0.0, 0.0, half]))
    top_true = truth.position + truth.rotation[:, 2] * half
    return {
        **errs,
        "feature_point_error_mm": float(np.linalg.norm(top_est - top_true) * 1e3),
        "nees": nees,
        "estimated_pose": est.pose.to_dict(),
        "true_pose": truth.to_dict(),
    }


def iter_samples(
    scenario: Scenario, seeds: list[int], methods: list[str], *, repeat: int = 1
) -> Iterator[list[PerceptionSample]]:
    for seed in seeds:
        yield perceive_seed(scenario, seed, methods, repeat=repeat)


def summarise(samples: list[PerceptionSample]) -> dict[str, MethodSummary]:
    out: dict[str, MethodSummary] = {}
    for method in dict.fromkeys(s["method"] for s in samples):
        ms = [s for s in samples if s["method"] == method]
        nees = [s["nees"] for s in ms if s["nees"] is not None]
        out[method] = {
            "samples": len(ms),
            "failures": sum(1 for s in ms if s["failure"]),
            **{k: describe([s[k] for s in ms]) for k in ERROR_KEYS},
            "nees_mean": float(np.mean(nees)) if nees else None,
            "nees_in_band": (1.5 <= float(np.mean(nees)) <= 6.0) if nees else None,
            "time_ms": describe([s["time_ms"] for s in ms]),
        }
    return out


def _fmt(st: dict[str, float] | None, digits: int = 2) -> str:
    if st is None:
        return "-"
    return f"{st['median']:.{digits}f} / {st['p95']:.{digits}f} / {st['max']:.{digits}f}"


def format_summary(summary: dict[str, MethodSummary]) -> str:
    w = max([9, *(len(m) for m in summary)])  # a user's module:function may be longer than the built-ins
    head = (f"{'method':<{w}} {'3-D mm (med/p95/max)':<22} {'x / y / z mm (median)':<22} {'yaw deg':<20} "
            f"{'pitch deg':<20} {'roll deg':<20} {'NEES':>6} {'ms':>6} fail")  # fmt: skip
    lines = [head, "-" * len(head)]
    for method, s in summary.items():
        axes = " / ".join(
            "-" if s[k] is None else f"{s[k]['median']:.2f}" for k in ("x_error_mm", "y_error_mm", "z_error_mm")
        )
        nees = "-" if s["nees_mean"] is None else f"{s['nees_mean']:.2f}"
        lines.append(
            f"{method:<{w}} {_fmt(s['position_error_mm']):<22} {axes:<22} {_fmt(s['yaw_error_deg']):<20} "
            f"{_fmt(s['pitch_error_deg']):<20} {_fmt(s['roll_error_deg']):<20} {nees:>6} "
            f"{s['time_ms']['median']:>6.2f} {s['failures']}"
        )
    lines.append(
        "yaw: modulo each target's symmetry (90 deg for a square box, 180 deg for another box); a cylinder has no yaw."
    )
    lines.append("NEES: mean normalised squared position error; 3 when the reported covariance matches the errors.")
    return "\n".join(lines)


def format_reference_rows(samples: list[PerceptionSample], method: str = "paper") -> str | None:
    """Row by row, the reference's errors (the paper's) beside ours, for targets that carry one."""
    rows = [s for s in samples if s["method"] == method and s.get("reference")]
    if not rows:
        return None
    by_target: dict[str, list[PerceptionSample]] = {}
    for s in rows:
        by_target.setdefault(s["target"], []).append(s)
    lines = [f"{'target':<10} {'reference':<24} {'3-D mm: ref / ours (median over seeds)':<40} "
             f"{'yaw deg: ref / ours':<22} {'pitch deg':<18} {'roll deg':<18}"]  # fmt: skip
    for target, ss in by_target.items():
        ref = ss[0]["reference"]

        def med(key: str, ss: list[PerceptionSample] = ss) -> float:
            return float(np.median([s[key] for s in ss if s[key] is not None]))

        lines.append(
            f"{target:<10} {ref.get('label', ''):<24} "
            f"{ref['position_error_mm']:>6.2f} / {med('feature_point_error_mm'):<31.3f} "
            f"{ref['yaw_error_deg']:>5.2f} / {med('yaw_error_deg'):<14.3f} "
            f"{ref['pitch_error_deg']:>4.2f} / {med('pitch_error_deg'):<9.3f} "
            f"{ref['roll_error_deg']:>4.2f} / {med('roll_error_deg'):<9.3f}"
        )
    return "\n".join(lines)


def write_plot(samples: list[PerceptionSample], path: Path, title: str) -> bool:
    """Error per method (like the paper's Fig. 2): 3-D position error and yaw error. False without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    methods = list(dict.fromkeys(s["method"] for s in samples))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for ax, key, label in ((axes[0], "position_error_mm", "3-D position error (mm)"),
                           (axes[1], "yaw_error_deg", "yaw error (deg)")):  # fmt: skip
        data, names = [], []
        for m in methods:
            vals = [s[key] for s in samples if s["method"] == m and s[key] is not None]
            if vals:
                data.append(vals)
                names.append(m)
        if data:
            ax.boxplot(data, showfliers=True)
            ax.set_xticks(range(1, len(names) + 1), names)
            ax.set_yscale("log")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    ax = axes[2]  # error against the camera's distance
    for m in methods:
        pts = [(s["camera_distance_m"], s["position_error_mm"]) for s in samples
               if s["method"] == m and s["position_error_mm"] is not None]  # fmt: skip
        if pts:
            d, e = np.array(pts).T
            ax.scatter(d, e, s=8, alpha=0.6, label=m)
    ax.set_yscale("log")
    ax.set_xlabel("camera distance to the workspace (m)")
    ax.set_ylabel("3-D position error (mm)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    write_figure(fig, path, dpi=120)
    plt.close(fig)
    return True


def write_outputs(
    out_dir: Path, samples: list[PerceptionSample], summary: dict[str, MethodSummary], title: str
) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    written = [out_dir / "perception.json"]
    write_atomic(written[0], json.dumps({"samples": samples, "summary": summary}, indent=1, allow_nan=False) + "\n")
    plot = out_dir / "perception.png"
    if write_plot(samples, plot, title):
        written.append(plot)
    return written
