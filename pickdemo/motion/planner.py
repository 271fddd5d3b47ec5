"""Joint paths around what is in the way: OMPL's RRT-Connect, then its path simplifier (issue 59).

Pure: OMPL and a validity check (no simulator). A path is asked from one joint configuration to
another, each state checked by the caller's ``free`` (a :class:`~pickdemo.robot.collision.CollisionScene`
at the fingers' opening), the motion between two states every ``resolution_rad``
(OMPL's discrete motion validator). The answer is the same for the same question and seed on one
machine: OMPL's generator is seeded before each plan from the caller's ``seed``, the search stops after
``max_checks`` states checked or as many steps (not after a time, which a busy machine would change), and the path
is simplified by fixed rules (``simplifyMax``: vertices removed and shortcuts taken until nothing
shortens it). OMPL's own log is kept out of the output.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

#: States checked before a search gives up (the Panda's transfers around a shelf need a few thousand).
MAX_CHECKS = 20000
#: The motion between two states is checked every this far in joint space (rad; OMPL's resolution is
#: a share of the space's extent, which differs by robot: a UR5's 12 rad joints make a share of it
#: ten times coarser than a Panda's).
RESOLUTION_RAD = 0.02


@dataclass(frozen=True)
class JointPath:
    """A planned path: its waypoints (K, dof), the first the start and the last the goal, and the
    states checked to find it."""

    waypoints: np.ndarray
    checks: int


def plan_joint_path(
    q_start: np.ndarray,
    q_goal: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    free: Callable[[np.ndarray], bool],
    seed: int,
    *,
    max_checks: int = MAX_CHECKS,
    resolution_rad: float = RESOLUTION_RAD,
) -> JointPath | None:
    """A collision-free joint path from ``q_start`` to ``q_goal`` within the joint limits, or None
    when none was found within ``max_checks`` checked states (see the module docstring)."""
    if not (free(np.asarray(q_start, dtype=float)) and free(np.asarray(q_goal, dtype=float))):
        return None  # (OMPL would wait for a valid end it is never given)
    from ompl import base as ob
    from ompl import geometric as og
    from ompl import util as ou

    ou.setLogLevel(ou.LogLevel.LOG_NONE)
    ou.RNG.setSeed(int(seed) % (2**31 - 1) + 1)
    n = len(q_start)
    space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    for i in range(n):
        bounds.setLow(i, float(lower[i]))
        bounds.setHigh(i, float(upper[i]))
    space.setBounds(bounds)
    setup = og.SimpleSetup(space)
    checks = [0]

    def valid(state) -> bool:  # noqa: ANN001 - an OMPL state
        checks[0] += 1
        return bool(free(np.array([state[i] for i in range(n)])))

    setup.setStateValidityChecker(valid)
    info = setup.getSpaceInformation()
    info.setStateValidityCheckingResolution(min(1.0, resolution_rad / space.getMaximumExtent()))
    start, goal = space.allocState(), space.allocState()
    for i in range(n):
        start[i], goal[i] = float(q_start[i]), float(q_goal[i])
    setup.setStartAndGoalStates(start, goal)
    setup.setPlanner(og.RRTConnect(info))
    asked = [0]

    def spent() -> bool:  # (the planner asks between its steps: bounded by its asking too)
        asked[0] += 1
        return checks[0] >= max_checks or asked[0] >= max_checks

    stop = ob.PlannerTerminationCondition(spent)
    solved = setup.solve(stop)
    if not setup.haveExactSolutionPath() or not bool(solved):
        return None
    path = setup.getSolutionPath()
    og.PathSimplifier(info).simplifyMax(path)
    waypoints = np.array([[path.getState(k)[i] for i in range(n)] for k in range(path.getStateCount())])
    return JointPath(waypoints, checks[0])
