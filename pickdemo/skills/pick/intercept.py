"""Meeting a moving target: its velocity as the belief decides it, where the hand meets it and
holds it, whether the arm reaches there in time, and whether the hand is moving with it. A part of
the pick skill: it answers and sends the hand where the machine says, never writes the machine's state."""

from __future__ import annotations

import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.grasping.top_down import GraspPlan
from pickdemo.motion.online import CartesianLimits
from pickdemo.robot.kinematics import IKParams, Kinematics
from pickdemo.skills.pick.arm import ArmDriver
from pickdemo.skills.pick.params import MachineParams
from pickdemo.tracking.belief import TargetBelief

LEAVES_REACH = "the target leaves the arm's reach"


def leaves_reach(where: str) -> str:
    """Why a moving target cannot be picked: where the arm would meet or hold it is out of reach."""
    return f"{LEAVES_REACH} before the arm can meet it: {where} is out of reach"


class Interceptor:
    """A target the tracker sees moving (a belt) is met where it will be: each re-target solves for the
    soonest time the hand can be at the plan's pose carried along at the target's velocity, and sends
    Ruckig there with that velocity as its target velocity and that time as its minimum duration."""

    def __init__(
        self,
        kin: Kinematics,
        rng: np.random.Generator,
        params: MachineParams,
        belief: TargetBelief,
        arm: ArmDriver,
        *,
        open_loop: bool,
    ) -> None:
        self.kin, self.rng, self.p, self.belief, self.arm, self.open_loop = kin, rng, params, belief, arm, open_loop

    def velocity(self, now_s: float) -> np.ndarray | None:
        """The target's horizontal velocity (m/s) while the tracker sees it move; None when it is at
        rest (or not surely moving), and always in open loop (it plans to where the target was)."""
        if self.open_loop:
            return None
        return self.belief.moving_velocity(now_s, self.p.moving_speed_m_s)

    def too_fast(self, v: np.ndarray) -> str:
        return (
            f"the target moves at {np.linalg.norm(v):.2f} m/s: too fast for the hand "
            f"({self.p.free.velocity:.2f} m/s an axis) to meet it within {self.p.meet_horizon_s:.0f} s"
        )

    def go_to(self, pose: Pose | np.ndarray, now_s: float, limits: CartesianLimits | None = None) -> str:
        """Send the hand to a pose of the plan (or an x4). For a moving target: to where they meet,
        arriving then with its velocity, and following it. Why it cannot ("" if it can)."""
        v = self.velocity(now_s)
        if v is None:
            self.arm.move.to(pose, limits=limits)
        elif not self.arm.move.meet(pose, v, limits):
            return self.too_fast(v)
        return ""

    def near_limits(self, now_s: float) -> CartesianLimits:
        """Near the object: gentle, but keeping up across the table with a target that moves."""
        return self.p.near if self.velocity(now_s) is None else self.p.near.with_xy_of(self.p.free)

    def with_target(self, pose: Pose, now_s: float, planned_at_s: float) -> bool:
        """Whether the hand is at ``pose`` of the plan (for the target where it was at ``planned_at_s``)
        and moving with the target: a moving target's arrival, which re-targets on every estimate
        never let finish."""
        v = self.velocity(now_s)
        if v is None:
            return False
        motion = self.arm.motion
        vel4 = np.array([v[0], v[1], 0.0, 0.0])
        want = self.arm.move.x4(pose) + vel4 * (now_s - planned_at_s)
        off = np.abs(motion.setpoint - want)
        p = self.p
        return bool(
            np.linalg.norm(off[:3]) < p.arrive_tolerance_m
            and off[3] < p.arrive_tolerance_rad
            and np.linalg.norm(motion.velocity - vel4) < p.arrive_speed_tolerance_m_s
        )

    def reach_targets(self, plan: GraspPlan, now_s: float) -> list[tuple[str, Pose]] | str:
        """The poses of the pick that must be in reach: the grasp; for a moving target, where the hand
        will meet it and where it will hold it (``grasp_time_s`` later). A string: it cannot be met."""
        v = self.velocity(now_s)
        if v is None:
            return [("grasp", plan.grasp)]
        t = self.arm.move.meet_in(self.arm.move.x4(plan.pregrasp), v, self.p.free)
        if t is None:
            return self.too_fast(v)
        out = []
        for name, dt in (("the meeting point", t), ("where it would be held", t + self.p.grasp_time_s)):
            d = np.array([v[0], v[1], 0.0]) * dt
            p = plan.grasp.position + d
            out.append((f"{name} ({p[0]:.2f}, {p[1]:.2f}) m in {dt:.1f} s", Pose(p, plan.grasp.rotation)))
        return out

    def out_of_reach(self, plan: GraspPlan, now_s: float) -> str:
        """Why the moving target cannot be picked where it will be ("" if it can)."""
        reach = self.reach_targets(plan, now_s)
        if isinstance(reach, str):
            return reach
        for name, target in reach:
            if not self.kin.solve(target, self.arm.motion.q, self.rng, IKParams()).success:
                return leaves_reach(name)
        return ""
