"""A worse perception, to see a gate catch it (docs/gate-a-pull-request.md): the paper's estimate with
its position moved by a few millimetres, while the covariance it reports stays the paper's (an
estimator that believes itself better than it is: the tracker takes its estimates, and the hand
goes where they say).

    cd docs/examples
    python -m pickdemo bench pick_cube pick_box --seeds 0-49 --out base
    python -m pickdemo bench pick_cube pick_box --seeds 0-49 --out new --perception noisy_estimator:estimate
    python -m pickdemo compare base new

The offset is drawn from the frame itself (its time and depth), so a seed's episode stays the same
episode on one machine.
"""

from __future__ import annotations

import dataclasses
import zlib

import numpy as np

from pickdemo.core.camera import RGBDFrame
from pickdemo.core.geometry import Pose
from pickdemo.perception import PoseEstimate, TargetModel
from pickdemo.perception.estimators import resolve_estimator

#: The offset's standard deviation across the table (m).
SIGMA_M = 0.006


def estimate(frame: RGBDFrame, model: TargetModel) -> PoseEstimate:
    est = resolve_estimator("paper")(frame, model)
    seed = zlib.crc32(np.asarray(frame.depth_m, dtype=np.float32).tobytes()) ^ int(frame.time_s * 1000)
    offset = np.random.default_rng(seed).normal(0.0, SIGMA_M, 3) * np.array([1.0, 1.0, 0.0])
    return dataclasses.replace(est, pose=Pose(est.pose.position + offset, est.pose.rotation))
