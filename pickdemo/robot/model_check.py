"""What a robot file's URDF must be for Pinocchio, checked when the file is read; and a ``home``
proposed for a file that gives none.

The checks of :mod:`pickdemo.robot.robot_file` read the URDF as XML (the names are there); these
build the model the kinematics solve on, so that what would fail there (a tree Pinocchio cannot
read, arm joints out of order or not one chain, a joint that slides, a joint moving that the file
does not name, a TCP the arm does not move) is one line naming the file and the key instead.

A proposed home (:func:`propose_home`): the hand pointing straight down, over the table in front of
the robot (+x), its fingers' closing axis along world y, within both the URDF's and the file's joint
limits, every joint above the table. IK from a few seeded starts (the same every run), for targets
tried in a fixed order (scaled by the arm's reach); of the starts that reach the first target reached,
the configuration farthest from its joint limits; rounded to 4 decimals (what a user pastes).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from pickdemo.core.geometry import Pose
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.kinematics import IKParams, Kinematics, link_frame_id
from pickdemo.robot.urdf_files import model_urdf

#: Pinocchio's joints that turn about one axis (those the solver steps as q + v).
REVOLUTE = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned")
#: (x, z) of the proposed home's TCP as shares of the arm's reach, tried in this order: above the
#: near middle of its workspace first, as the shipped robots' homes are; lower for an arm whose hand
#: points down only low (the SO-101's).
HOME_TARGETS = tuple((x, z) for z in (0.45, 0.35, 0.55, 0.25, 0.15) for x in (0.35, 0.45, 0.25, 0.55))
#: The hand's turns about the vertical tried at each target (rad): fingers closing along y first.
HOME_YAWS = (0.0, np.pi / 2, -np.pi / 2, np.pi)
#: Seeded starts for each target (the middle of the limits, then random ones from seed 0).
HOME_STARTS = 8
#: Random configurations that measure the arm's reach (the TCP's farthest from the base's axis).
REACH_SAMPLES = 2000
#: Every joint's origin stays this far above the table in a proposed home (m).
ABOVE_TABLE_M = 0.02

Fail = Callable[[str, str], Exception]


def check_model(robot: RobotDescription, fail: Fail, label: str) -> None:
    """The model Pinocchio builds of the robot's URDF is one the kinematics can solve on (raises
    ``fail(key, message)``; ``label`` names the user's URDF)."""
    urdf, renamed = model_urdf(robot.files())
    try:
        model = pin.buildModelFromUrdf(str(urdf))
    except (RuntimeError, ValueError) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise fail("arm.urdf", f"Pinocchio cannot build a model of {label}: {first}") from None
    original = {v: k for k, v in renamed.items()}
    names = [original.get(n, n) for n in model.names]
    ids = [model.getJointId(renamed.get(n, n)) for n in robot.arm_joints]
    if ids != sorted(ids):
        order = ", ".join(f'"{names[i]}"' for i in sorted(ids))
        raise fail("arm.joints", f"not in {label}'s order from the base: write [{order}]")
    for i, (name, jid) in enumerate(zip(robot.arm_joints, ids, strict=True)):
        kind = model.joints[jid].shortname()
        if kind not in REVOLUTE:
            what = "slides (prismatic)" if "P" in kind.removeprefix("JointModel")[:2] else f"is a {kind}"
            raise fail(f"arm.joints[{i}]", f"{name!r} {what}: an arm's joints here turn (revolute or continuous)")
    for prev, nxt in zip(ids, ids[1:], strict=False):
        if not _below(model, nxt, prev):
            raise fail("arm.joints", f"{names[nxt]!r} is not below {names[prev]!r} in {label}'s tree: "
                                     "the arm's joints are one chain from the base to the hand")  # fmt: skip
    named = set(robot.arm_joints) | set(robot.gripper.finger_joints)
    extra = [n for n in names[1:] if n not in named]
    if extra:
        raise fail("arm.joints", f"{label} moves {', '.join(extra)} too: name each in arm.joints (the arm's, "
                                 "base to hand) or gripper.finger_joints (the hand's)")  # fmt: skip
    tcp = model.frames[link_frame_id(model, robot.tcp_frame)].parentJoint
    if not _below(model, tcp, ids[-1]):
        last = robot.arm_joints[-1]
        raise fail("arm.tcp_frame", f"{robot.tcp_frame!r} is not moved by the arm's last joint {last!r}: "
                                    "the TCP is on the hand, between its fingers")  # fmt: skip


def _below(model: pin.Model, joint: int, ancestor: int) -> bool:
    """Whether ``joint`` is ``ancestor`` or moves with it (its subtree)."""
    while joint > ancestor:
        joint = model.parents[joint]
    return joint == ancestor


def with_proposed_home(robot: RobotDescription, fail: Fail) -> RobotDescription:
    """The robot with :func:`propose_home`'s home (its file gave none), or ``fail`` saying none was found."""
    q = propose_home(robot)
    if q is None:
        raise fail("arm.home", "missing, and none found with the hand pointing down over the table in front of "
                               "the robot within its limits: give one (rad, a value a joint)")  # fmt: skip
    return dataclasses.replace(robot, home_q=q, home_proposed=True)


def propose_home(robot: RobotDescription) -> np.ndarray | None:
    """A home for the robot (module docstring), or None if no target is reached."""
    kin = Kinematics(robot)
    kin.lower = np.maximum(kin.lower, robot.limits.min_position_rad)
    kin.upper = np.minimum(kin.upper, robot.limits.max_position_rad)
    rng = np.random.default_rng(0)
    starts = [(kin.lower + kin.upper) / 2.0] + [rng.uniform(kin.lower, kin.upper) for _ in range(HOME_STARTS - 1)]
    samples = rng.uniform(kin.lower, kin.upper, size=(REACH_SAMPLES, robot.dof))
    reach = max(float(np.linalg.norm(kin.forward(q).position[:2])) for q in samples)
    params = IKParams(restarts=0)
    for fx, fz in HOME_TARGETS:
        for yaw in HOME_YAWS:
            target = Pose.from_se3(pin.SE3(pin.rpy.rpyToMatrix(np.pi, 0.0, yaw), np.array([fx, 0.0, fz]) * reach))
            found = []
            for start in starts:
                r = kin.solve(target, start, rng, params)
                q = np.clip(np.round(r.q, 4), kin.lower, kin.upper)
                if r.success and _above_table(kin, q) and _near(kin, q, target):
                    found.append(q)
            if found:
                span = kin.upper - kin.lower
                return max(found, key=lambda q: float(np.min(np.minimum(q - kin.lower, kin.upper - q) / span)))
    return None


def _above_table(kin: Kinematics, q: np.ndarray) -> bool:
    pin.forwardKinematics(kin.model, kin.data, q)
    return all(m.translation[2] >= ABOVE_TABLE_M for m in list(kin.data.oMi)[2:])


def _near(kin: Kinematics, q: np.ndarray, target: Pose) -> bool:
    """The rounded configuration still puts the TCP within 2 mm and 0.5 deg of the target."""
    err = pin.log6(kin.forward_se3(q).actInv(target.to_se3())).vector
    return bool(np.linalg.norm(err[:3]) < 0.002 and np.linalg.norm(err[3:]) < np.radians(0.5))
