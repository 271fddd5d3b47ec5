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

from pickdemo.robot.suction import Cup


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
    """The hand: its kind, its finger joints and links, how far it opens, and where its palm is.

    What the rest of pickdemo knows of the fingers is each finger's opening from the middle (m) and a
    force (N); the kind turns them into the finger joints' positions and forces and back: "parallel",
    two prismatic fingers closing symmetrically (the joints' positions are the openings); "jaw", one
    revolute jaw closing against a fixed one (the opening between them, by the angle, from
    ``jaw_table``; the force at the jaw's pad, ``jaw_lever_m`` from its axis). A jaw moves what it
    holds to the fixed jaw: the TCP is the fixed jaw's face, and a grasp puts it ``jaw_clearance_m``
    beside the object (:meth:`tcp_offset_m`). "suction": no fingers; a vacuum cup (:attr:`cup`) on a
    bellows, whose one prismatic joint is the tool's ``finger_joints`` (the spring holds it extended: it
    is never commanded) and whose cup is its ``finger_links``; its openings are zero."""

    kind: str  # "parallel" | "jaw" | "suction"
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
    #: a jaw's opening (m) at its joint's angles (rad), by rising angle: [(rad, m), ...] (the opening
    #: rises or falls with the angle)
    jaw_table: tuple[tuple[float, float], ...] = ()
    jaw_lever_m: float = 0.0  # a jaw's axis to where it presses (m)
    jaw_clearance_m: float = 0.0  # the fixed jaw's face lowered this far beside the object (m)
    #: the force a grasp squeezes with where this hand's own differs from the skill's (N; None: the skill's)
    grip_force_n: float | None = None
    #: the pads' friction coefficient as the simulator takes it (it multiplies the object's): 1.0 for the
    #: Franka's fingers (with 20 N, a 5 cm cube held with about 1 mm of slip)
    pad_friction: float = 1.0
    cup: Cup | None = None  # a suction tool's cup and vacuum

    @property
    def suction(self) -> bool:
        return self.kind == "suction"

    @property
    def max_opening_m(self) -> float:
        return 2.0 * self.finger_max_m

    @property
    def coupled(self) -> bool:
        """Two fingers that the mechanism moves together (the simulator couples them)."""
        return self.kind == "parallel"

    def joint_targets(self, finger_m: float) -> list[float]:
        """The finger joints' positions for each finger ``finger_m`` from the middle."""
        if self.suction:  # (the bellows, extended)
            return [0.0]
        if self.kind == "parallel":
            return [finger_m] * len(self.finger_joints)
        rad, gap = zip(*self.jaw_table, strict=True)
        if gap[0] > gap[-1]:  # a jaw whose opening falls as its angle rises (the Unitree Z1's)
            rad, gap = rad[::-1], gap[::-1]
        return [float(np.interp(2.0 * finger_m, gap, rad))]

    def joint_positions(self, fingers_m: np.ndarray) -> np.ndarray:
        """The finger joints' positions for these openings (each finger's, from the middle)."""
        if self.suction:
            return np.zeros(1)
        if self.kind == "parallel":
            return np.asarray(fingers_m, dtype=float)
        return np.array(self.joint_targets(float(np.sum(fingers_m)) / 2.0))

    def fingers_of(self, joint_q: list[float]) -> np.ndarray:
        """Each finger's opening from the middle (m) at these finger joints' positions."""
        if self.suction:
            return np.zeros(2)
        if self.kind == "parallel":
            return np.array(joint_q)
        rad, gap = zip(*self.jaw_table, strict=True)
        half = float(np.interp(joint_q[0], rad, gap)) / 2.0
        return np.array([half, half])

    def joint_force(self, force_n: float) -> float:
        """The finger joints' force (N) or torque (N m) that squeezes with ``force_n`` (a bellows: its spring)."""
        if self.cup is not None:
            return self.cup.bellows_force_n
        return force_n if self.kind == "parallel" else force_n * self.jaw_lever_m

    def joint_speed(self) -> float:
        """The finger joints' top speed (m/s, or rad/s for a jaw)."""
        if self.suction:
            return 1.0  # (a bellows springs back at once)
        return self.speed_m_s if self.kind == "parallel" else self.speed_m_s / self.jaw_lever_m

    def tcp_offset_m(self, width_m: float) -> float:
        """Where the TCP is from a ``width_m``-wide object's centre along the hand's y (its closing
        axis) as the hand comes down on it: 0 for fingers closing about the middle; for a jaw, the
        fixed jaw's face beside the object (the jaw then presses it there)."""
        return 0.0 if self.kind != "jaw" else -(width_m / 2.0 + self.jaw_clearance_m)

    def held_offset_m(self, width_m: float) -> float:
        """Where the TCP is from a ``width_m``-wide object's centre along the hand's y once the hand
        has closed on it: 0 for fingers closing about the middle; a jaw has pressed it to the fixed
        jaw's face (``so101_pick_cube``: put down 8.8 mm off, median, when this was taken as
        :meth:`tcp_offset_m`, with 10 mm of clearance)."""
        return 0.0 if self.kind != "jaw" else -width_m / 2.0


@dataclass(frozen=True)
class LeRobotChannel:
    """A LeRobot follower's channel (``<motor>.pos``): the joint it reads and drives, and its unit
    ("degrees" from the joint's zero, or "range_0_100" over the joint's range ``low``..``high``, rad)."""

    name: str
    joint: str
    unit: str
    low: float
    high: float


@dataclass(frozen=True)
class LeRobotProfile:
    """How LeRobot's own follower of the arm records it (a robot file's ``[lerobot]``): its recorder's
    ``robot_type``, its channels in order, its cameras' names (the scenario's camera -> the follower's),
    their images' size (width, height; px), and the video codec."""

    robot_type: str
    channels: tuple[LeRobotChannel, ...]
    cameras: tuple[tuple[str, str], ...]
    image_size: tuple[int, int]
    video_codec: str


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
    base_radius_m: float  # its base on the table: nothing may stand within this of the origin (m)
    locate: Callable[[], RobotFiles]  # its URDF on this machine
    render_urdf: Callable[[], Path]  # a URDF for rendering (may be lighter than ``locate``'s)
    #: the heights of a pick where the robot's own differ from the skill's (m, by the names of
    #: :class:`~pickdemo.grasping.top_down.GraspParams`: pregrasp, transport, retreat, the TCP's lowest)
    grasp_heights: tuple[tuple[str, float], ...] = ()
    #: a pick's speeds where the robot file sets its own (``[speeds]``: near_m_s, free_m_s, transfer_scale,
    #: carry_scale)
    speeds: tuple[tuple[str, float], ...] = ()
    lerobot: LeRobotProfile | None = None  # how LeRobot's own follower of the arm records it (None: not one)
    home_proposed: bool = False  # its file gave no home: ``home_q`` is :mod:`pickdemo.robot.model_check`'s proposal

    @property
    def dof(self) -> int:
        return len(self.arm_joints)

    @property
    def grasps_any_side(self) -> bool:
        """Whether its hand can take a grasp from any side: six arm joints or more (any orientation
        within reach) and two fingers closing about the middle (a jaw's grasps are planned top-down)."""
        return self.dof >= 6 and self.gripper.coupled

    def files(self) -> RobotFiles:
        return self.locate()
