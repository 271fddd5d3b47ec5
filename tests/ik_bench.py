"""The per-tick IK's cost, measured (a benchmark that prints figures, not a test): pickdemo's damped
least squares with its null-space posture task against pin-pink, a QP on Pinocchio (a frame task and a
posture task, the model's configuration and velocity limits, the DAQP solver), both tracking the same
straight 20 cm descent at 120 Hz, one solve a tick, in the same run.

    python tests/ik_bench.py          # pink too if installed: pip install pin-pink qpsolvers daqp scipy
"""

from __future__ import annotations

import time

import numpy as np
import pinocchio as pin

from pickdemo.grasping.top_down import top_down
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of

ROBOT = robot_named()

TICKS = 1200


def main() -> None:
    kin = kinematics_of(ROBOT)
    start = top_down(np.array([0.5, 0.1, 0.25]), 0.4)
    q0 = kin.solve(start, ROBOT.home_q, np.random.default_rng(0)).q
    targets = [top_down(start.position - np.array([0.0, 0.0, 0.2 * k / TICKS]), 0.4) for k in range(TICKS)]

    q, times, lag = q0.copy(), [], 0.0
    for tg in targets:
        t0 = time.perf_counter()
        q = kin.track(tg, q, posture=q0).q
        times.append(time.perf_counter() - t0)
        lag = max(lag, float(np.linalg.norm(kin.forward(q).position - tg.position)))
    print(f"damped least squares + null-space posture: {np.median(times) * 1e3:.3f} ms a tick (median), "
          f"p95 {np.percentile(times, 95) * 1e3:.3f}; largest lag {lag * 1e3:.3f} mm")  # fmt: skip

    try:
        import pink
        from pink.tasks import FrameTask, PostureTask
    except ImportError:
        print("pin-pink is not installed: pip install pin-pink qpsolvers daqp scipy, for the comparison")
        return
    cfg = pink.Configuration(kin.model, kin.model.createData(), q0.copy())
    frame, posture = FrameTask(ROBOT.tcp_frame, position_cost=1.0, orientation_cost=1.0), PostureTask(cost=1e-3)
    posture.set_target(q0)
    dt, times, lag = 1.0 / 120.0, [], 0.0
    for tg in targets:
        frame.set_target(pin.SE3(tg.rotation, tg.position))
        t0 = time.perf_counter()
        v = pink.solve_ik(cfg, [frame, posture], dt, solver="daqp")
        cfg.integrate_inplace(v, dt)
        times.append(time.perf_counter() - t0)
        lag = max(lag, float(np.linalg.norm(kin.forward(cfg.q).position - tg.position)))
    print(f"pin-pink (DAQP), one QP a tick: {np.median(times) * 1e3:.3f} ms a tick (median), "
          f"p95 {np.percentile(times, 95) * 1e3:.3f}; largest lag {lag * 1e3:.3f} mm")  # fmt: skip


if __name__ == "__main__":
    main()
