"""The grasp oracle on mesh objects (a benchmark that prints figures, not a test): how often the contact
physics lets a top-down grasp hold an object when perception is perfect.

For each object (by default the 100 test-split ``random_urdfs`` of the pybullet wheel, the folders
ending in 0, at 0.6 of their scale) and seed: the object is dropped at a seeded spot and yaw and
settles; the oracle then reads its true pose and shape and grasps it top-down across the narrowest
horizontal width of its footprint, centred on its vertices' centroid, as deep as the palm allows
(the grasp planner's rule), with 20 N; the hand lifts it 10 cm and holds it 1 s. It is the same arm,
motion and controller as an episode (Cartesian Ruckig, the per-tick IK, the rate limiter and the
reflex), but no camera. Outcomes: ``held`` (it rose at least 8 cm and turned less than 30 deg in the
grip), ``rotated in the grip`` (it rose but turned 30 deg or more about the finger axis),
``slipped`` (it did not rise), ``too wide`` (no horizontal width fits the open hand), ``unreachable``.

    python tests/oracle_grasp.py                      # the test split, 1 seed each
    python tests/oracle_grasp.py --seeds 3 --scale 0.6 --glob "pybullet_data:random_urdfs/??0/*.urdf"
"""

from __future__ import annotations

import argparse
import collections
import math
import time

import numpy as np

from pickdemo.apps.bench import wilson_interval
from pickdemo.core.interfaces import Command
from pickdemo.core.meshes import expand
from pickdemo.core.shapes import caliper_widths
from pickdemo.core.streams import spawn_rngs
from pickdemo.grasping.top_down import GraspParams, top_down
from pickdemo.motion.online import CartesianLimits, OnlineMotion
from pickdemo.robot import robot_named
from pickdemo.robot.kinematics import kinematics_of
from pickdemo.robot.rate_limit import RateLimiter
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.parse import parse_scenario

ROBOT = robot_named()

GRIP_N = 20.0
LIFT_M = 0.10
HOLD_S = 1.0
TURN_LIMIT_DEG = 30.0


def _scenario(urdf: str, scale: float) -> object:
    marker = {"name": "marker", "shape": "box", "size": [0.02] * 3, "color": [0.5, 0.5, 0.5],
              "position": [0.2, 0.55], "static": True, "target": True}  # fmt: skip
    obj = {"name": "obj", "shape": "mesh", "urdf": urdf, "scale": scale,
           "position_range": [[0.45, 0.6], [-0.15, 0.15]], "yaw_range_deg": [-180.0, 180.0]}  # fmt: skip
    return parse_scenario({"name": "oracle", "task": "perceive", "objects": [marker, obj],
                           "place": {"position": [0.45, 0.3]}})  # fmt: skip


def one(urdf: str, scale: float, seed: int) -> str:
    from pickdemo.sim.controller import RobotInterface
    from pickdemo.sim.scene import Scene

    sc = _scenario(urdf, scale)
    rngs = spawn_rngs(seed)
    layout = sample_layout(sc, rngs["layout"], rngs["objects"])
    shape = next(p for p in layout if p.name == "obj").geometry
    dt = 1.0 / 120.0
    with Scene(sc, layout) as scene:
        scene.settle(2000)
        truth = scene.true_pose("obj")
        v = truth.transform_points(shape.vertices)  # the oracle: its true surface
        narrow, angle, _ = caliper_widths(v[:, :2])
        params = GraspParams()
        if narrow > 2.0 * ROBOT.gripper.finger_max_m - params.width_margin_m:
            return "too wide"
        centre = v.mean(axis=0)
        top_z = float(v[:, 2].max())
        depth = min((top_z - float(v[:, 2].min())) / 2.0, ROBOT.gripper.palm_above_tcp_m - params.palm_clearance_m)
        grasp_z = max(top_z - depth, params.min_tcp_height_m)
        yaw = math.atan2(math.sin(angle + np.pi / 2), math.cos(angle + np.pi / 2))  # fingers close along angle
        yaw = (yaw + np.pi / 2) % np.pi - np.pi / 2  # either way round: the one nearer the home hand
        kin = kinematics_of(ROBOT)
        pre = top_down(np.array([centre[0], centre[1], grasp_z + params.pregrasp_height_m]), yaw)
        res = kin.solve(pre, ROBOT.home_q, np.random.default_rng(seed))
        if not res.success:
            return "unreachable"
        robot = scene.bodies["robot"]
        for j, qj in zip(scene.arm_joints, res.q, strict=True):
            scene.client.resetJointState(robot, j, float(qj))  # the oracle starts above it
        iface = RobotInterface(scene, dt)
        motion = OnlineMotion(kin, res.q, dt, CartesianLimits())
        limiter = RateLimiter(res.q, dt, ROBOT.limits)
        opening, force = ROBOT.gripper.finger_max_m, GRIP_N

        def tick() -> None:
            s = motion.step()
            q, _ = limiter(s.q)
            iface.apply(Command(q, s.dq, opening, force))
            scene.step(2)

        def until_done(max_ticks: int) -> None:
            for _ in range(max_ticks):
                tick()
                if motion.finished:
                    return

        motion.set_target(np.array([centre[0], centre[1], grasp_z, yaw]))
        until_done(1200)
        opening = 0.0
        still = 0
        last = iface.observe().opening_m
        for _ in range(240):
            tick()
            now = iface.observe().opening_m
            still = still + 1 if abs(now - last) < 2e-6 * 2 else 0
            last = now
            if still >= 8:
                break
        hold = scene.true_pose("obj")
        hand_at_grasp = kin.forward(motion.q)
        rel0 = hand_at_grasp.inverse() @ hold
        motion.set_target(np.array([centre[0], centre[1], grasp_z + LIFT_M, yaw]))
        until_done(1200)
        for _ in range(int(HOLD_S / dt)):
            tick()
        end = scene.true_pose("obj")
        rel1 = kin.forward(motion.q).inverse() @ end
        turn = float(np.degrees(np.arccos(np.clip((np.trace(rel0.rotation.T @ rel1.rotation) - 1.0) / 2.0, -1, 1))))
        if end.position[2] - hold.position[2] < 0.8 * LIFT_M:
            return "slipped"
        return "held" if turn < TURN_LIMIT_DEG else "rotated in the grip"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--glob", default="pybullet_data:random_urdfs/??0/*.urdf")
    ap.add_argument("--scale", type=float, default=0.6)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--limit", type=int, default=0, help="only the first N files")
    a = ap.parse_args()
    files = expand(a.glob, None)[: a.limit or None]
    outcomes: collections.Counter[str] = collections.Counter()
    by_file: dict[str, list[str]] = {}
    t0 = time.perf_counter()
    for f in files:
        for seed in range(a.seeds):
            r = one(f, a.scale, seed)
            outcomes[r] += 1
            by_file.setdefault(f, []).append(r)
    n = sum(outcomes.values())
    lo, hi = wilson_interval(outcomes["held"], n)
    print(f"oracle: {outcomes['held']}/{n} held ({100 * outcomes['held'] / max(n, 1):.1f} %, Wilson 95 % "
          f"[{100 * lo:.1f}, {100 * hi:.1f}]) over {len(files)} files x {a.seeds} seed(s), scale {a.scale}, "
          f"{time.perf_counter() - t0:.0f} s")  # fmt: skip
    for k, v in outcomes.most_common():
        print(f"  {k}: {v}")
    for f, rs in by_file.items():
        bad = [r for r in rs if r != "held"]
        if bad:
            print(f"  {f}: {', '.join(bad)}")


if __name__ == "__main__":
    main()
