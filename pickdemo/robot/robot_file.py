"""A robot described by a file (TOML): its URDF, joints, frames, home, datasheet limits and gripper,
read into one :class:`~pickdemo.robot.description.RobotDescription`.

The shipped robots are files in ``pickdemo/robot/robots/`` (the Panda first); a user's robot is a
file anywhere. A bad file is one line naming the file and the key (:class:`RobotFileError`): a
missing URDF, a joint or frame the URDF does not have, a limit that is not positive, a gripper whose
stroke cannot hold anything. ``urdf`` is ``example-robot-data:<path under its robots/>`` (the
installed package, never copied) or a file, relative to the robot file (found, joined and made lean
by :mod:`pickdemo.robot.urdf_files`). Imports neither pybullet nor pinocchio: the URDF is read as XML.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import tomllib
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pickdemo.robot.description import (
    Gripper,
    JointLimits,
    LeRobotChannel,
    LeRobotProfile,
    RobotDescription,
    RobotFiles,
)
from pickdemo.robot.stl import MESH_SUFFIXES
from pickdemo.robot.suction import GRAVITY_M_S2, Cup
from pickdemo.robot.urdf_files import ERD_PREFIX, found_mesh, joined, lean_urdf_path, locate, not_one_of

#: Where the shipped robot files are.
ROBOTS_DIR = Path(__file__).resolve().parent / "robots"
#: A parallel gripper must open at least this wide in all to hold anything (m).
MIN_STROKE_M = 0.01

Positive = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
Finite = Annotated[float, Field(allow_inf_nan=False)]


class RobotFileError(ValueError):
    """A robot file that cannot describe a robot: ``file: key: what is wrong``, one line."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class _Frame(_Model):
    """A frame the URDF does not have, fixed to one of its links (a TCP where the planners want it)."""

    name: str
    parent: str
    xyz: list[Finite] = Field([0.0, 0.0, 0.0], min_length=3, max_length=3)  # m, in the parent's frame
    rpy: list[Finite] = Field([0.0, 0.0, 0.0], min_length=3, max_length=3)  # rad


class _Arm(_Model):
    urdf: str
    joints: list[str] = Field(min_length=1)
    tcp_frame: str
    hand_frame: str
    wrist_joint: str
    home: list[Finite] | None = None  # rad; None: proposed (pickdemo.robot.home)
    payload_kg: Positive
    base_radius_m: Positive  # its base on the table: nothing may stand within this of the origin (m)
    camera_mounts: list[str] = []
    frames: list[_Frame] = []
    #: a collision mesh the simulator takes instead of one of the URDF's (by its file name): a convex
    #: decomposition of a concave part, whose single convex hull a simulator would otherwise collide with
    collision_meshes: dict[str, str] = {}
    #: a visual mesh rendered instead of one of the URDF's (by its file name): fewer triangles, where the
    #: renderer pays for every one of them in every camera frame
    render_meshes: dict[str, str] = {}


class _Limits(_Model):
    position_min: list[Finite]
    position_max: list[Finite]
    velocity: list[Positive]
    acceleration: list[Positive]
    jerk: list[Positive]
    effort: list[Positive]


class _Gripper(_Model):
    kind: Literal["parallel", "jaw"]
    finger_joints: list[str] = Field(min_length=1)
    finger_links: list[str] = Field(min_length=1)
    finger_max_m: Positive
    palm_above_tcp_m: Positive
    open_force_n: Positive
    max_force_n: Positive
    speed_m_s: Positive
    pad_half_height_m: Positive
    pad_half_width_m: Positive
    finger_thickness_m: Positive
    palm_half_length_m: Positive
    palm_half_width_m: Positive
    jaw_table: list[list[Finite]] = []  # a jaw's [[rad, opening m], ...], both rising
    jaw_lever_m: Positive | None = None
    jaw_clearance_m: Annotated[float, Field(ge=0.0, le=0.02)] = 0.0
    grip_force_n: Positive | None = None  # a grasp's force where this hand asks for its own (N)
    pad_friction: Annotated[float, Field(gt=0.0, le=2.0)] = 1.0  # the pads' friction coefficient (the simulator's)


class _Suction(_Model):
    """A vacuum cup on a bellows at the tool's end (``kind = "suction"``)."""

    kind: Literal["suction"]
    datasheet: str  # the cup its figures are from (maker and type)
    bellows_joint: str  # the URDF's prismatic joint the bellows compresses along (0: extended)
    cup_link: str  # the URDF's link of the cup (its lip is the TCP)
    cup_diameter_m: Annotated[float, Field(gt=0.0, le=0.2)]
    bellows_stroke_m: Annotated[float, Field(gt=0.0, le=0.05)]
    bellows_force_n: Positive  # the bellows' spring, fully compressed (N)
    vacuum_kpa: Annotated[float, Field(gt=0.0, lt=101.3)]  # below the ambient, at a sealed cup
    lip_friction: Annotated[float, Field(gt=0.0, le=2.0)] = 0.5


#: A suction cup's holding force must be this many times the payload's weight (Schmalz's design rule:
#: "a safety factor of at least 2").
SUCTION_SAFETY = 2.0


class _Hand(_Model):
    """A tool from another URDF joined to the arm's flange by a fixed joint (an arm and a hand, as
    real cells are built)."""

    urdf: str
    root_link: str  # the hand's first link: it and everything below it are taken
    flange_link: str  # the arm's link the hand is bolted to
    joint: str  # the fixed joint made between them (a name the arm's URDF does not use)
    xyz: list[Finite] = Field([0.0, 0.0, 0.0], min_length=3, max_length=3)  # m: the hand's root in the flange's frame
    rpy: list[Finite] = Field([0.0, 0.0, 0.0], min_length=3, max_length=3)  # rad


class _Grasp(_Model):
    """A pick's heights where the robot's reach asks for others than the skill's (m)."""

    pregrasp_height_m: Annotated[float, Field(gt=0.0, le=0.5)] | None = None
    transport_height_m: Annotated[float, Field(gt=0.0, le=0.5)] | None = None
    retreat_height_m: Annotated[float, Field(gt=0.0, le=0.5)] | None = None
    min_tcp_height_m: Annotated[float, Field(gt=0.0, le=0.1)] | None = None  # the TCP's lowest: the tips off the table


class _Speeds(_Model):
    """A pick's speeds where the robot and its tool allow others than the skill's: the Cartesian
    velocities (their accelerations and jerks scaled alike) and the joint transfers' shares of
    ``[limits]``."""

    near_m_s: Annotated[float, Field(gt=0.0, le=1.0)] | None = None  # the descent onto a part, the lift
    free_m_s: Annotated[float, Field(gt=0.0, le=2.0)] | None = None  # straight lines away from the parts
    transfer_scale: Annotated[float, Field(gt=0.0, le=1.0)] | None = None  # joint transfers, the hand empty
    carry_scale: Annotated[float, Field(gt=0.0, le=1.0)] | None = None  # ... holding a part


class _LeRobotChannel(_Model):
    """One of a LeRobot follower's channels: ``<motor>.pos``, the URDF joint it reads and drives, and the
    unit LeRobot normalises that motor's position to (its ``MotorNormMode``)."""

    motor: str = Field(pattern=r"^[A-Za-z0-9_]+$")
    joint: str  # an arm joint, or the jaw's finger joint
    #: "degrees": from the joint's zero (the URDF's zero at the calibrated range's middle); "range_0_100":
    #: 0 at the joint's lower limit (the URDF's), 100 at its upper
    unit: Literal["degrees", "range_0_100"]


class _LeRobot(_Model):
    """How LeRobot's own follower of this arm records it: a dataset recorded with it in LeRobot's format
    has a real recording's features (their names, units, cameras and video codec)."""

    robot_type: str = Field(min_length=1)  # what its recorder writes as the dataset's robot_type
    channels: list[_LeRobotChannel] = Field(min_length=1)  # in the order of its state and action
    cameras: dict[str, str] = {}  # the scenario's camera ("camera", "wrist_camera") -> the follower's name
    image_size: list[Annotated[int, Field(ge=16, le=4096)]] = Field([640, 480], min_length=2, max_length=2)  # px: w, h
    video_codec: Literal["av1", "h264"] = "av1"


class _RobotFile(_Model):
    name: str = Field(pattern=r"^[A-Za-z0-9_.+-]+$")
    label: str
    arm: _Arm
    hand: _Hand | None = None
    limits: _Limits
    gripper: Annotated[_Gripper | _Suction, Field(discriminator="kind")]
    grasp: _Grasp = _Grasp()
    speeds: _Speeds = _Speeds()
    lerobot: _LeRobot | None = None


#: The file's sections as docs/robot-file.md documents them, each with the model that reads it.
SECTIONS: dict[str, type[BaseModel]] = {
    "Top level": _RobotFile,
    "[arm]": _Arm,
    "[[arm.frames]]": _Frame,
    "[hand]": _Hand,
    "[limits]": _Limits,
    "[gripper]": _Gripper,
    '[gripper] kind = "suction"': _Suction,
    "[grasp]": _Grasp,
    "[speeds]": _Speeds,
    "[lerobot]": _LeRobot,
    "[[lerobot.channels]]": _LeRobotChannel,
}


def load_robot_file(path: str | Path) -> RobotDescription:
    """The robot a file describes (raises :class:`RobotFileError`, one line, for a bad one)."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RobotFileError(f"{path}: no such robot file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise RobotFileError(f"{path}: cannot be read ({exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise RobotFileError(f"{path}: invalid TOML: {exc}") from None
    try:
        spec = _RobotFile.model_validate(data)
    except ValidationError as exc:
        errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")  # (a misspelt key first)
        err = errors[0]
        loc = [p for i, p in enumerate(err["loc"]) if not (i == 1 and err["loc"][0] == "gripper" and p in _KINDS)]
        key = ".".join(str(p) for p in loc) or "(top level)"
        msg = {"extra_forbidden": "unknown key", "missing": "missing"}.get(err["type"], err["msg"])
        if err["type"] == "union_tag_invalid":  # (the gripper's kind)
            key, msg = f"{key}.kind", f"{err['ctx']['tag']!r} is not one of {', '.join(_KINDS)}"
        raise RobotFileError(f"{path}: {key}: {msg}") from None

    def fail(key: str, msg: str) -> RobotFileError:
        return RobotFileError(f"{path}: {key}: {msg}")

    files = locate(spec.arm.urdf, path.parent, fail, "arm.urdf")
    label = _source(spec)
    if spec.hand is not None or spec.arm.frames or _continuous(files, spec.arm.joints):
        hand = None if spec.hand is None else locate(spec.hand.urdf, path.parent, fail, "hand.urdf")
        files = joined(files, hand, spec, fail)
    _check(spec, files, fail, label)
    lerobot = None if spec.lerobot is None else _lerobot(spec, files, fail)

    def mesh_files(key: str, table: dict[str, str]) -> tuple[tuple[str, str], ...]:
        """(a URDF mesh's file name, the file beside the robot file taking its place), each there."""
        pairs = []
        for name, rel in sorted(table.items()):
            mesh = (path.parent / rel).resolve()
            if not mesh.is_file():
                raise fail(f"arm.{key}.{name}", f"no such file: {mesh}")
            pairs.append((name, str(mesh)))
        return tuple(pairs)

    meshes = mesh_files("collision_meshes", spec.arm.collision_meshes)
    renders = mesh_files("render_meshes", spec.arm.render_meshes)
    a, g, lim = spec.arm, spec.gripper, spec.limits
    lim_lo, lim_hi = np.array(lim.position_min), np.array(lim.position_max)
    robot = RobotDescription(
        name=spec.name,
        label=spec.label,
        arm_joints=tuple(a.joints),
        tcp_frame=a.tcp_frame,
        hand_frame=a.hand_frame,
        wrist_joint=a.wrist_joint,
        gripper=_suction(g)
        if isinstance(g, _Suction)
        else Gripper(
            kind=g.kind,
            finger_joints=tuple(g.finger_joints),
            finger_links=tuple(g.finger_links),
            finger_max_m=g.finger_max_m,
            palm_above_tcp_m=g.palm_above_tcp_m,
            open_force_n=g.open_force_n,
            max_force_n=g.max_force_n,
            speed_m_s=g.speed_m_s,
            pad_half_height_m=g.pad_half_height_m,
            pad_half_width_m=g.pad_half_width_m,
            finger_thickness_m=g.finger_thickness_m,
            palm_half_length_m=g.palm_half_length_m,
            palm_half_width_m=g.palm_half_width_m,
            jaw_table=tuple((float(a), float(b)) for a, b in sorted(g.jaw_table)),
            jaw_lever_m=g.jaw_lever_m or 0.0,
            jaw_clearance_m=g.jaw_clearance_m,
            grip_force_n=g.grip_force_n,
            pad_friction=g.pad_friction,
        ),  # fmt: skip
        home_q=np.array(a.home if a.home is not None else (lim_lo + lim_hi) / 2.0),
        home_proposed=a.home is None,
        limits=JointLimits(
            np.array(lim.position_min),
            np.array(lim.position_max),
            np.array(lim.velocity),
            np.array(lim.acceleration),
            np.array(lim.jerk),
        ),  # fmt: skip
        payload_kg=a.payload_kg,
        effort_nm=np.array(lim.effort),
        camera_mounts=tuple(a.camera_mounts),
        base_radius_m=a.base_radius_m,
        locate=lambda: files,
        render_urdf=functools.partial(lean_urdf_path, files, spec.name, meshes, renders),
        grasp_heights=tuple((k, v) for k, v in spec.grasp.model_dump().items() if v is not None),
        speeds=tuple((k, v) for k, v in spec.speeds.model_dump().items() if v is not None),
        lerobot=lerobot,
    )
    from pickdemo.robot.model_check import check_model, with_proposed_home  # (pinocchio: only once a file is read)

    check_model(robot, fail, label)
    return robot if a.home is not None else with_proposed_home(robot, fail)


#: The gripper kinds (a discriminated union's tag, left out of a message's key).
_KINDS = ("parallel", "jaw", "suction")


#: The cameras a scenario may have (its keys), which ``[lerobot] cameras`` names for the follower
SCENARIO_CAMERAS = ("camera", "wrist_camera")


def _lerobot(spec: _RobotFile, files: RobotFiles, fail) -> LeRobotProfile:  # noqa: ANN001 - (key, message) -> error
    """The follower's channels checked against the arm and its URDF: every arm joint once, in degrees;
    at most the jaw's one finger joint beside them, in 0 to 100 over its URDF range."""
    lr, g = spec.lerobot, spec.gripper
    assert lr is not None
    fingers = [] if isinstance(g, _Suction) or g.kind != "jaw" else g.finger_joints
    limits = {j.get("name"): j.find("limit") for j in ET.fromstring(files.urdf.read_bytes()).findall("joint")}
    channels = []
    for i, c in enumerate(lr.channels):
        key = f"lerobot.channels[{i}]"
        if c.joint not in (*spec.arm.joints, *fingers):
            raise fail(f"{key}.joint", f"{c.joint!r} is none of the arm's joints or a jaw's finger joint "
                                       f"({', '.join((*spec.arm.joints, *fingers))})")  # fmt: skip
        if (c.unit == "range_0_100") != (c.joint in fingers):
            raise fail(f"{key}.unit", "degrees for an arm joint, range_0_100 for the jaw (its opening)")
        lim = limits.get(c.joint)
        low, high = (0.0, 0.0) if lim is None else (float(lim.get("lower", 0.0)), float(lim.get("upper", 0.0)))
        if c.unit == "range_0_100" and not low < high:
            raise fail(f"{key}.joint", f"{c.joint!r} has no range in the URDF to scale 0 to 100 over")
        channels.append(LeRobotChannel(f"{c.motor}.pos", c.joint, c.unit, low, high))
    joints = [c.joint for c in lr.channels]
    missing = [j for j in spec.arm.joints if j not in joints]
    if missing or len(set(joints)) != len(joints):
        raise fail("lerobot.channels", "each arm joint once (a follower's action drives them all)"
                                       + (f"; missing: {', '.join(missing)}" if missing else ""))  # fmt: skip
    for cam in lr.cameras:
        if cam not in SCENARIO_CAMERAS:
            raise fail(f"lerobot.cameras.{cam}", f"not a scenario's camera ({', '.join(SCENARIO_CAMERAS)})")
    if len(set(lr.cameras.values())) != len(lr.cameras):
        raise fail("lerobot.cameras", "two cameras under one name")
    return LeRobotProfile(
        lr.robot_type, tuple(channels), tuple(lr.cameras.items()), (lr.image_size[0], lr.image_size[1]), lr.video_codec
    )


def _suction(g: _Suction) -> Gripper:
    """A suction tool as the rest of pickdemo knows a gripper: its bellows the one finger joint, its cup
    the finger link, no opening; the cup and its vacuum in :attr:`Gripper.cup`."""
    cup = Cup(g.cup_diameter_m, g.bellows_stroke_m, g.bellows_force_n, g.vacuum_kpa, friction=g.lip_friction)
    r = cup.radius_m
    return Gripper(
        kind="suction",
        finger_joints=(g.bellows_joint,),
        finger_links=(g.cup_link,),
        finger_max_m=r,
        palm_above_tcp_m=g.bellows_stroke_m,
        open_force_n=g.bellows_force_n,
        max_force_n=cup.holding_force_n,
        speed_m_s=1.0,
        pad_half_height_m=r,
        pad_half_width_m=r,
        finger_thickness_m=r,
        palm_half_length_m=r,
        palm_half_width_m=r,
        cup=cup,
    )


def _source(spec: _RobotFile) -> str:
    """The user's URDF (and the hand's) as a message names them, never the joined file pickdemo wrote."""
    arm = Path(spec.arm.urdf.removeprefix(ERD_PREFIX)).name
    return arm if spec.hand is None else f"{arm} with {Path(spec.hand.urdf.removeprefix(ERD_PREFIX)).name}'s hand"


def _continuous(files: RobotFiles, arm_joints: list[str]) -> bool:
    """Whether one of the arm's joints is continuous in its URDF (written as revolute within the file's
    limits: the solver steps angles, and the datasheet bounds them)."""
    try:
        root = ET.fromstring(files.urdf.read_bytes())
    except (OSError, ET.ParseError):
        return False  # (said by the checks, naming the key)
    return any(j.get("type") == "continuous" and j.get("name") in arm_joints for j in root.findall("joint"))


def _check(spec: _RobotFile, files: RobotFiles, fail, label: str) -> None:  # noqa: ANN001 - (key, message) -> error
    """What the URDF must have, its meshes on this machine, the limits' lengths and order, home within
    them, the stroke."""
    try:
        root = ET.fromstring(files.urdf.read_bytes())
    except (OSError, ET.ParseError) as exc:
        raise fail("arm.urdf", f"{files.urdf} is not a readable URDF ({exc})") from None
    joints = {j.get("name"): j.get("type") for j in root.findall("joint")}
    moving = [n for n, kind in joints.items() if kind in ("revolute", "continuous", "prismatic")]
    links = [lk.get("name") for lk in root.findall("link")]
    a, g, lim = spec.arm, spec.gripper, spec.limits
    for i, name in enumerate(a.joints):
        if name in joints and name not in moving:
            raise fail(f"arm.joints[{i}]", f"{name!r} is not a moving joint of {label} (it is {joints[name]}); "
                                           f"its moving joints: {', '.join(moving)}")  # fmt: skip
        if name not in joints:
            raise fail(f"arm.joints[{i}]", not_one_of(name, "joint", moving, label))
    if len(set(a.joints)) != len(a.joints):
        raise fail("arm.joints", "a joint named twice")
    if a.wrist_joint not in joints:
        raise fail("arm.wrist_joint", not_one_of(a.wrist_joint, "joint", list(joints), label))
    for key, name in (("arm.tcp_frame", a.tcp_frame), ("arm.hand_frame", a.hand_frame)):
        if name not in links:
            raise fail(key, not_one_of(name, "link", links, label))
    for i, name in enumerate(a.camera_mounts):
        if name not in links:
            raise fail(f"arm.camera_mounts[{i}]", not_one_of(name, "link", links, label))
    if isinstance(g, _Suction):
        _check_suction(g, spec, root, joints, links, fail, label)
    else:
        for i, name in enumerate(g.finger_joints):
            if name not in joints:
                raise fail(f"gripper.finger_joints[{i}]", not_one_of(name, "joint", moving, label))
            if name in a.joints:
                raise fail(
                    f"gripper.finger_joints[{i}]", f"{name!r} is an arm joint too: it is the arm's or the hand's"
                )
        for i, name in enumerate(g.finger_links):
            if name not in links:
                raise fail(f"gripper.finger_links[{i}]", not_one_of(name, "link", links, label))
    _check_meshes(root, files, fail)
    n = len(a.joints)
    if a.home is not None and len(a.home) != n:
        raise fail("arm.home", f"{len(a.home)} values for {n} joints")
    for key in ("position_min", "position_max", "velocity", "acceleration", "jerk", "effort"):
        if len(getattr(lim, key)) != n:
            raise fail(f"limits.{key}", f"{len(getattr(lim, key))} values for {n} joints")
    for i, (lo, hi) in enumerate(zip(lim.position_min, lim.position_max, strict=True)):
        if not lo < hi:
            raise fail(f"limits.position_min[{i}]", f"{lo} is not below position_max's {hi}")
        if a.home is not None and not lo <= a.home[i] <= hi:
            raise fail(f"arm.home[{i}]", f"{a.home[i]} is outside the joint's limits [{lo}, {hi}]")
    if isinstance(g, _Suction):
        return
    if 2.0 * g.finger_max_m < MIN_STROKE_M:
        raise fail("gripper.finger_max_m", f"the hand opens {2e3 * g.finger_max_m:.1f} mm in all: it cannot hold "
                                           f"anything (at least {MIN_STROKE_M * 1e3:.0f} mm)")  # fmt: skip
    if g.grip_force_n is not None and g.grip_force_n > g.max_force_n:
        raise fail("gripper.grip_force_n", f"{g.grip_force_n} N is more than max_force_n's {g.max_force_n} N")
    if g.open_force_n > g.max_force_n:
        raise fail("gripper.open_force_n", f"{g.open_force_n} N is more than max_force_n's {g.max_force_n} N")
    if g.kind == "parallel":
        if len(g.finger_joints) != 2:
            raise fail("gripper.finger_joints", f"a parallel gripper has two finger joints, not {len(g.finger_joints)}")
        for i, name in enumerate(g.finger_joints):
            if joints[name] != "prismatic":
                msg = f"{name!r} is {joints[name]}: a parallel gripper's fingers slide (prismatic joints)"
                raise fail(f"gripper.finger_joints[{i}]", msg + '; a turning jaw is kind = "jaw"')
    if g.kind == "jaw":
        _check_jaw(g, joints, fail)


def _check_suction(
    g: _Suction, spec: _RobotFile, root: ET.Element, joints: dict, links: list, fail, label: str
) -> None:  # noqa: ANN001, E501
    """The bellows' prismatic joint and its stroke, the cup's link and its width, the vacuum against the
    payload."""
    if g.bellows_joint not in joints:
        moving = [n for n, kind in joints.items() if kind == "prismatic"]
        raise fail("gripper.bellows_joint", not_one_of(g.bellows_joint, "joint", moving, label))
    if joints[g.bellows_joint] != "prismatic":
        raise fail("gripper.bellows_joint", f"{g.bellows_joint!r} is {joints[g.bellows_joint]}: a bellows compresses "
                                            "along a prismatic joint")  # fmt: skip
    if g.bellows_joint in spec.arm.joints:
        raise fail("gripper.bellows_joint", f"{g.bellows_joint!r} is an arm joint too")
    joint = next(j for j in root.findall("joint") if j.get("name") == g.bellows_joint)
    limit = joint.find("limit")
    travel = abs(float(limit.get("upper", 0)) - float(limit.get("lower", 0))) if limit is not None else 0.0
    if g.bellows_stroke_m > travel + 1e-9:
        msg = f"{g.bellows_stroke_m * 1e3:.1f} mm is more than the bellows joint {g.bellows_joint!r} travels"
        raise fail("gripper.bellows_stroke_m", f"{msg} in the URDF ({travel * 1e3:.1f} mm)")
    if g.cup_link not in links:
        raise fail("gripper.cup_link", not_one_of(g.cup_link, "link", links, label))
    width = _collision_width(root, g.cup_link)
    if width is None:
        raise fail("gripper.cup_link", f"{g.cup_link!r} has no cylinder or box collision geometry (the cup's lip)")
    if g.cup_diameter_m > width + 1e-4:
        msg = f"a {g.cup_diameter_m * 1e3:.1f} mm cup is wider than its tool: the link {g.cup_link!r} is"
        raise fail("gripper.cup_diameter_m", f"{msg} {width * 1e3:.1f} mm across in the URDF")
    cup = Cup(g.cup_diameter_m, g.bellows_stroke_m, g.bellows_force_n, g.vacuum_kpa)
    needs = SUCTION_SAFETY * spec.arm.payload_kg * GRAVITY_M_S2
    if cup.holding_force_n < needs:
        raise fail("gripper.vacuum_kpa", f"the cup holds {cup.holding_force_n:.1f} N at {g.vacuum_kpa:g} kPa; "
                                         f"arm.payload_kg {spec.arm.payload_kg:g} asks for {needs:.1f} N "
                                         f"(its weight times a safety factor of {SUCTION_SAFETY:g})")  # fmt: skip


def _collision_width(root: ET.Element, link_name: str) -> float | None:
    """How wide a link's collision geometry is across its z (a cylinder's diameter, a box's narrower
    side), the widest of its shapes; None: no cylinder or box."""
    link = next(lk for lk in root.findall("link") if lk.get("name") == link_name)
    widths = []
    for col in link.findall("collision"):
        for cyl in col.iter("cylinder"):
            widths.append(2.0 * float(cyl.get("radius", 0)))
        for box in col.iter("box"):
            x, y, _ = (float(v) for v in box.get("size", "0 0 0").split())
            widths.append(min(x, y))
    return max(widths) if widths else None


def _check_meshes(root: ET.Element, files: RobotFiles, fail) -> None:  # noqa: ANN001 - (key, message) -> error
    """Every mesh the URDF names is on this machine, and each collision mesh is one the self-filter reads."""
    for link in root.findall("link"):
        for mesh in link.iter("mesh"):
            name = mesh.get("filename", "")
            path = found_mesh(name, files, "arm.urdf", fail)
            in_collision = any(mesh in col.iter("mesh") for col in link.findall("collision"))
            if in_collision and path.suffix.lower() not in MESH_SUFFIXES:
                raise fail("arm.urdf", f"link {link.get('name')!r}'s collision mesh {name!r} is not one of "
                                       f"{', '.join(MESH_SUFFIXES)} (the self-filter reads it)")  # fmt: skip


def _check_jaw(g: _Gripper, joints: dict, fail) -> None:  # noqa: ANN001 - (key, message) -> error
    """One revolute jaw, its links (the moving jaw's, then the fixed one's), its table and lever."""
    if len(g.finger_joints) != 1 or joints.get(g.finger_joints[0]) != "revolute":
        raise fail("gripper.finger_joints", "a jaw gripper has one revolute finger joint (the moving jaw's)")
    if len(g.finger_links) != 2:
        raise fail("gripper.finger_links", "a jaw gripper names two links: the moving jaw's, then the fixed jaw's")
    if g.jaw_lever_m is None:
        raise fail("gripper.jaw_lever_m", "missing (a jaw gripper's axis to where it presses, m)")
    table = g.jaw_table
    if len(table) < 2 or any(len(row) != 2 for row in table):
        raise fail("gripper.jaw_table", "at least two [rad, opening m] rows")
    rad, gap = np.array(sorted(table)).T  # (by angle: a jaw whose opening falls as its angle rises is one too)
    if not (np.all(np.diff(rad) > 0) and (np.all(np.diff(gap) > 0) or np.all(np.diff(gap) < 0))):
        raise fail("gripper.jaw_table", "the opening must rise, or fall, with the angle at every row, and no angle "
                                        "twice (rows of [rad, opening m])")  # fmt: skip
    if gap.max() < 2.0 * g.finger_max_m - 1e-9:
        raise fail(
            "gripper.jaw_table", f"it reaches {gap.max() * 1e3:.1f} mm; the gripper opens {2e3 * g.finger_max_m:.1f}"
        )
