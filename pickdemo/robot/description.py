"""What the rest of pickdemo knows of a robot: one value, :class:`RobotDescription`.

Kinematics, motion, the rate limiter, the self-filter, the schema's checks and the simulator take
the robot as this value; none of them names one robot's constants. Its files are found when first
asked for (a description is cheap to import and to pass around). A robot file describes one
(:mod:`pickdemo.robot.robot_file`; the Panda's ships first), and :func:`pickdemo.robot.robot_named`
finds it by name or path.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class RobotFiles:
    """Where a robot's description is on this machine."""

    urdf: Path
    package_root: Path  # the directory that the URDF's ``package://`` paths point to


@dataclass(frozen=True, eq=False)
class JointLimits:
    """The arm joints' datasheet limits (rad, rad/s, rad/s^2, rad/s^3), one entry a joint."""

    min_position_rad: np.ndarray
    max_position_rad: np.ndarray
    max_velocity_rad_s: np.ndarray
    max_acceleration_rad_s2: np.ndarray
    max_jerk_rad_s3: np.ndarray

    def rates(self) -> dict[str, tuple[np.ndarray, str]]:
        """{quantity: (per joint, unit)} for velocity, acceleration and jerk: what a commanded joint
        motion is checked against (:func:`pickdemo.core.result.limit_exceedances`)."""
        return {
            "velocity": (self.max_velocity_rad_s, "rad/s"),
            "acceleration": (self.max_acceleration_rad_s2, "rad/s^2"),
            "jerk": (self.max_jerk_rad_s3, "rad/s^3"),
        }


@dataclass(frozen=True)
class Gripper:
    """The hand: its kind, its finger joints and links, how far it opens, and where its palm is."""

    kind: str  # "parallel": two fingers that close symmetrically
    finger_joints: tuple[str, ...]
    finger_links: tuple[str, ...]
    finger_max_m: float  # each finger's travel: the hand opens to twice this
    palm_above_tcp_m: float  # the palm (between the fingers) is this far above the TCP
    open_force_n: float  # the fingers' force when opening
    max_force_n: float  # the most the fingers may squeeze with (its datasheet's continuous force)
    speed_m_s: float  # each finger's top speed
    #: The pads and the hand's body as the grasp planners see them (m): each pad's half height (it is
    #: centred on the TCP) and half width (along the hand's x), a finger's thickness outside its pad,
    #: and the body above the palm seen from above (half its length along the closing axis, half its
    #: width).
    pad_half_height_m: float
    pad_half_width_m: float
    finger_thickness_m: float
    palm_half_length_m: float
    palm_half_width_m: float

    @property
    def max_opening_m(self) -> float:
        return 2.0 * self.finger_max_m


@dataclass(frozen=True, eq=False)
class RobotDescription:
    """A robot arm and its hand, as a value (compared, and cached, by identity)."""

    name: str
    label: str  # as a sentence names it ("the {label} carries ...")
    arm_joints: tuple[str, ...]
    tcp_frame: str  # the tool centre point: between the fingertips
    hand_frame: str
    wrist_joint: str  # flange to hand: where a wrist force sensor sits
    gripper: Gripper
    home_q: np.ndarray  # rad: where it starts, looks from and goes back to
    limits: JointLimits
    payload_kg: float  # the most it carries (its datasheet's)
    effort_nm: np.ndarray  # each arm joint's torque limit (N m): what its simulated motors may exert
    camera_mounts: tuple[str, ...]  # the links a camera on the hand may be mounted on (rigid with it)
    locate: Callable[[], RobotFiles]  # its URDF on this machine
    render_urdf: Callable[[], Path]  # a URDF for rendering (may be lighter than ``locate``'s)

    @property
    def dof(self) -> int:
        return len(self.arm_joints)

    def files(self) -> RobotFiles:
        return self.locate()
