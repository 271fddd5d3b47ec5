"""Which perception runs in the loop: the paper's method, a baseline, or a user's own estimator.

An estimator is any callable ``(frame: RGBDFrame, model: TargetModel) -> PoseEstimate`` that raises
:class:`~pickdemo.perception.PerceptionError` (with the reason) when it cannot measure the target.
The frame is what a real robot has (RGB, metric depth with holes as 0 or NaN, intrinsics, the pose it
is told, its sensor's noise model, and ``robot_boxes``: its own links where its joint states put them
when the frame was taken, for a self-filter); the model is the task's description of the target (shape, size,
colour). ``PoseEstimate.position_cov`` must be honest: the tracker weighs estimates by it.

Names: ``paper`` (the default), ``icp``, ``centroid``, ``pixel``, or ``module:function`` for your
own, importable from the current environment. That is how another project tests its perception
against pickdemo's control: ``python -m pickdemo bench pick_cube --perception mypkg.vision:estimate``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from pickdemo.core.camera import RGBDFrame
from pickdemo.perception import PoseEstimate, TargetModel, estimate_pose
from pickdemo.perception.baselines import METHODS as BASELINES

Estimator = Callable[[RGBDFrame, TargetModel], PoseEstimate]
BUILTIN: dict[str, Estimator] = {"paper": estimate_pose, **BASELINES}


class EstimatorError(ValueError):
    """A perception method that cannot be found or used (a one-line message)."""


def resolve_estimator(name: str) -> Estimator:
    """The estimator a name stands for; raises :class:`EstimatorError` with the reason."""
    if name in BUILTIN:
        return BUILTIN[name]
    module_name, sep, attr = name.partition(":")
    if not sep or not module_name or not attr:
        raise EstimatorError(f"unknown perception method {name!r} (built in: {', '.join(BUILTIN)}; or module:function)")
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # noqa: BLE001 - a user's module may fail in any way when imported
        raise EstimatorError(f"cannot import {module_name!r}: {type(exc).__name__}: {exc}") from None
    fn = getattr(module, attr, None)
    if not callable(fn):
        raise EstimatorError(f"{module_name!r} has no callable {attr!r}")
    return fn
