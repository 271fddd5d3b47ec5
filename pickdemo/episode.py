"""One episode, wired end to end: scenario -> scene -> camera -> perception -> grasp -> IK ->
trajectory -> controller -> metrics.

The controller acts only on the camera frame (RGB, depth, intrinsics, camera pose) and the joint
states (encoders, finger openings, finger contacts). The simulator's true poses are read only for
scoring. Every random draw comes from one generator per stage, spawned from the seed in a fixed
order, so one seed makes one episode, bit for bit.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from pickdemo import robot_model as rm
from pickdemo.grasp import GraspParams, GraspPlan, GraspPlanningError, plan_grasp
from pickdemo.kinematics import IKParams, panda_kinematics
from pickdemo.layout import LayoutError, Placement, camera_position, sample_layout
from pickdemo.metrics import score_perception, score_place
from pickdemo.perception import PerceptionError, PerceptionParams, PoseEstimate, TargetModel, estimate_pose
from pickdemo.result import EpisodeFailure, EpisodeResult, Failure, PerceptionScore, Stage
from pickdemo.scenario import Scenario
from pickdemo.trajectory import (
    CartesianLimits,
    JointTrajectory,
    Limits,
    TrajectoryError,
    plan_cartesian_line,
    plan_joint_motion,
)

PhaseCallback = Callable[[str, str], None]

#: Order in which the seed's generators are spawned. Append only: reordering changes every episode.
RNG_STREAMS = ("layout", "camera", "ik", "camera_pose")

MAX_ATTEMPTS = 2  # a missed grasp is retried once, from a fresh look at the scene


@dataclass(frozen=True)
class EpisodeOptions:
    gui: bool = False
    perception: PerceptionParams = PerceptionParams()
    grasp: GraspParams = GraspParams()
    ik: IKParams = IKParams()
    approach: CartesianLimits = CartesianLimits(velocity=0.10, acceleration=0.5, jerk=5.0)
    transport: CartesianLimits = CartesianLimits(velocity=0.25, acceleration=1.0, jerk=10.0)


def spawn_rngs(seed: int) -> dict[str, np.random.Generator]:
    """One independent generator per stage, spawned from the seed."""
    children = np.random.SeedSequence(seed).spawn(len(RNG_STREAMS))
    return {name: np.random.default_rng(s) for name, s in zip(RNG_STREAMS, children, strict=True)}


class _Timer:
    def __init__(self) -> None:
        self.times: dict[str, float] = {}

    @contextmanager
    def __call__(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.times[name] = self.times.get(name, 0.0) + time.perf_counter() - t0


def target_model(scenario: Scenario, placement: Placement) -> TargetModel:
    """What the task tells the robot about an object: shape, size (as placed) and colour."""
    spec = next(o for o in scenario.objects if o.name == placement.name)
    return TargetModel(shape=spec.shape, size=tuple(placement.size), color=tuple(spec.color))


def run_episode(
    scenario: Scenario,
    seed: int,
    *,
    options: EpisodeOptions | None = None,
    on_phase: PhaseCallback | None = None,
) -> EpisodeResult:
    """Run one seeded episode of a scenario headless (or in the GUI) and score it.

    Never raises for an episode that goes wrong: the result names the stage and the reason. Only
    programming errors inside pickdemo itself propagate, and only with ``options`` that ask for it.
    """
    from pickdemo.sim.controller import Controller, StepBudgetExceeded  # simulator side, imported late
    from pickdemo.sim.render import Camera
    from pickdemo.sim.scene import Scene

    options = options or EpisodeOptions()
    say = on_phase or (lambda phase, msg: None)
    timer = _Timer()
    wall0 = time.perf_counter()
    rngs = spawn_rngs(seed)
    record: dict[str, Any] = {
        "perception": None,
        "place_error_mm": None,
        "lift_height_mm": None,
        "grasp_width_mm": None,
    }
    phases: list[dict[str, Any]] = []
    failure: Failure | None = None
    scene = None

    def phase(name: str, msg: str) -> None:
        phases.append({"phase": name, "sim_time_s": round(scene.sim_time_s if scene else 0.0, 6), "message": msg})
        say(name, msg)

    try:
        if len(scenario.targets) != 1:
            raise EpisodeFailure(
                Stage.ERROR, f"a pick needs exactly one target; the scenario has {len(scenario.targets)}"
            )
        try:
            layout = sample_layout(scenario, rngs["layout"])
        except LayoutError as exc:
            raise EpisodeFailure(Stage.ERROR, str(exc)) from None
        placement = next(p for p in layout if p.name == scenario.target.name)
        model = target_model(scenario, placement)
        with timer("scene"):
            scene = Scene(scenario, layout, gui=options.gui)
        camera = Camera(scenario.camera, rngs["camera"], position=camera_position(scenario.camera, rngs["camera_pose"]))
        max_steps = int(round(scenario.sim.max_sim_time_s / scene.time_step_s))
        ctl = Controller(scene, max_steps=max_steps)
        kin = panda_kinematics()
        limits = Limits.panda(
            scenario.motion.velocity_scale, scenario.motion.acceleration_scale, scenario.motion.jerk_scale
        )
        dt = scene.time_step_s
        target_name = scenario.target.name

        with timer("settle"):
            ctl.hold(120)  # let the objects come to rest on the table
        start_pose = scene.true_pose(target_name)  # truth: for scoring only

        def perceive() -> PoseEstimate:
            with timer("render"):
                frame = camera.capture(scene)
            with timer("perceive"):
                try:
                    return estimate_pose(frame, model, options.perception)
                except PerceptionError as exc:
                    raise EpisodeFailure(Stage.PERCEPTION, str(exc)) from None

        def solve(name: str, pose, q_seed: np.ndarray) -> np.ndarray:
            res = kin.solve(pose, q_seed, rngs["ik"], options.ik)
            if not res.success:
                raise EpisodeFailure(Stage.IK, f"{name}: {res.reason}")
            return res.q

        def motion(q0: np.ndarray, q1: np.ndarray, lim: Limits) -> JointTrajectory:
            try:
                return plan_joint_motion(q0, q1, lim, dt)
            except TrajectoryError as exc:
                raise EpisodeFailure(Stage.TRAJECTORY, str(exc)) from None

        def line(name: str, q0: np.ndarray, goal, cart: CartesianLimits) -> JointTrajectory:
            try:
                return plan_cartesian_line(kin, q0, goal, cart, limits, dt, rngs["ik"])
            except TrajectoryError as exc:
                raise EpisodeFailure(Stage.TRAJECTORY, f"{name}: {exc}") from None

        def holding(plan: GraspPlan) -> tuple[bool, float]:
            js = scene.joint_state()
            opening = float(np.sum(js.fingers_m))
            left, right = scene.finger_contacts()
            ok = left > 0 and right > 0 and opening > plan.object_width_m - 0.008
            return ok, opening

        plan: GraspPlan | None = None
        estimate: PoseEstimate | None = None
        for attempt in range(1, MAX_ATTEMPTS + 1):
            # ---------------------------------------------------------------- perceive
            estimate = perceive()
            est = estimate.pose
            if attempt == 1:
                record["perception"] = score_perception(estimate, start_pose)
            phase(
                "perceive",
                f"target at ({est.position[0]:.4f}, {est.position[1]:.4f}, {est.position[2]:.4f}) m, "
                f"yaw {np.degrees(est.rpy[2]):+.2f} deg, {estimate.n_features} features, "
                f"{estimate.n_face_pixels} face px" + (f" (attempt {attempt})" if attempt > 1 else ""),
            )
            # ---------------------------------------------------------------- plan
            with timer("plan"):
                try:
                    plan = plan_grasp(estimate, model, scenario.place.position, options.grasp)
                except GraspPlanningError as exc:
                    raise EpisodeFailure(Stage.GRASP_PLANNING, str(exc)) from None
                q_now = scene.joint_state().arm_q
                q_pre = solve("pre-grasp", plan.pregrasp, q_now)
                segments = {"to_pregrasp": motion(q_now, q_pre, limits)}
                # Near the table the TCP moves on straight lines; each starts where the last ends.
                chain = (
                    ("descend", plan.grasp, options.approach),
                    ("lift", plan.lift, options.approach),
                    ("transport", plan.place_above, options.transport),
                    ("lower", plan.place, options.approach),
                    ("retreat", plan.retreat, options.approach),
                )
                q_end = q_pre
                for name, goal, cart in chain:
                    segments[name] = line(name, q_end, goal, cart)
                    q_end = segments[name].positions[-1]
                segments["home"] = motion(q_end, rm.HOME_Q, limits)
            total = sum(s.duration_s for s in segments.values())
            phase(
                "plan",
                f"grasp yaw {np.degrees(plan.hand_yaw_rad):+.1f} deg; {len(segments)} Ruckig segments "
                f"({len(segments) - 2} straight lines), {total:.2f} s of motion",
            )
            # ---------------------------------------------------------------- approach
            with timer("approach"):
                ctl.gripper(rm.FINGER_MAX_M, max_steps=120)
                ctl.follow(segments["to_pregrasp"])
                ctl.follow(segments["descend"])
            phase("approach", f"at grasp pose, t = {scene.sim_time_s:.2f} s")
            # ---------------------------------------------------------------- grasp
            with timer("grasp"):
                opening = ctl.gripper(0.0, max_steps=240)
                ok, opening = holding(plan)
            record["grasp_width_mm"] = opening * 1e3
            if ok:
                phase("grasp", f"holding: fingers at {opening * 1e3:.1f} mm, contact on both")
                break
            reason = (
                f"fingers closed to {opening * 1e3:.1f} mm (expected {plan.object_width_m * 1e3:.0f} mm): nothing held"
            )
            if attempt == MAX_ATTEMPTS:
                raise EpisodeFailure(Stage.GRASP, reason)
            phase("grasp", f"missed ({reason}); backing off to look again")
            with timer("approach"):
                ctl.gripper(rm.FINGER_MAX_M, max_steps=120)
                back = line("back off", scene.joint_state().arm_q, plan.pregrasp, options.approach)
                ctl.follow(back)
                ctl.follow(motion(back.positions[-1], rm.HOME_Q, limits))
        assert plan is not None
        # -------------------------------------------------------------------- lift
        with timer("lift"):
            ctl.follow(segments["lift"])
            ok, opening = holding(plan)
        lifted_pose = scene.true_pose(target_name)  # truth: for scoring only
        record["lift_height_mm"] = (lifted_pose.position[2] - start_pose.position[2]) * 1e3
        if not ok:
            raise EpisodeFailure(Stage.LIFT, f"lost the target while lifting (fingers at {opening * 1e3:.1f} mm)")
        phase("lift", f"lifted, fingers at {opening * 1e3:.1f} mm")
        # -------------------------------------------------------------------- place
        with timer("place"):
            ctl.follow(segments["transport"])
            ok, opening = holding(plan)
            if not ok:
                raise EpisodeFailure(Stage.TRANSPORT, f"lost the target in transit (fingers at {opening * 1e3:.1f} mm)")
            ctl.follow(segments["lower"])
            ctl.gripper(rm.FINGER_MAX_M, max_steps=120)
            ctl.follow(segments["retreat"])
            ctl.follow(segments["home"])
            ctl.hold(120)
        phase("place", f"released at ({plan.place.position[0]:.3f}, {plan.place.position[1]:.3f}), arm home")
        # -------------------------------------------------------------------- verify
        with timer("verify"):
            seen = perceive()
            seen_err = float(np.hypot(*(seen.pose.position[:2] - np.asarray(scenario.place.position))))
            final = scene.true_pose(target_name)  # truth: for scoring only
            outcome = score_place(
                start=start_pose,
                max_z_m=lifted_pose.position[2],
                final=final,
                final_speed_m_s=scene.true_speed(target_name),
                place_xy=scenario.place.position,
                height_m=placement.height_m,
                lift_height_m=scenario.success.lift_height,
                place_tolerance_m=scenario.success.place_tolerance,
            )
        record["place_error_mm"] = outcome.place_error_m * 1e3
        phase("verify", f"camera sees the target {seen_err * 1e3:.1f} mm from the place position")
        if not outcome.success:
            stage = Stage.LIFT if outcome.lifted_m < scenario.success.lift_height else Stage.PLACE
            raise EpisodeFailure(stage, outcome.reason)
    except EpisodeFailure as exc:
        failure = exc.failure
    except StepBudgetExceeded as exc:
        failure = Failure(Stage.TIMEOUT, str(exc))
    except Exception as exc:  # noqa: BLE001 - one bad episode must not take a batch down
        failure = Failure(Stage.ERROR, f"{type(exc).__name__}: {exc}".splitlines()[0])
    finally:
        sim_time = scene.sim_time_s if scene is not None else 0.0
        if scene is not None:
            scene.close()
    perception: PerceptionScore | None = record["perception"]
    return EpisodeResult(
        scenario=scenario.name,
        seed=seed,
        success=failure is None,
        failure=failure,
        perception=perception,
        place_error_mm=record["place_error_mm"],
        lift_height_mm=record["lift_height_mm"],
        grasp_width_mm=record["grasp_width_mm"],
        sim_time_s=sim_time,
        wall_time_s=time.perf_counter() - wall0,
        stage_wall_times_s={k: round(v, 6) for k, v in timer.times.items()},
        phases=tuple(phases),
    )
