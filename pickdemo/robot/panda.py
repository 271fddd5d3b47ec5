"""The Franka Panda as shipped by ``example-robot-data``: where its files are, its names and limits.

Owns the facts about the robot, as one :class:`~pickdemo.robot.description.RobotDescription`
(:data:`PANDA`): the URDF found in the installed package (never copied into this repository), a
lean variant of it for fast rendering (visual meshes swapped for the collision STLs, derived at load
time), joint and frame names, home, and the datasheet motion limits (Franka Emika's "Robot and
interface specifications" for the Panda's joints; the Franka Hand's stroke). Imports neither
pybullet nor pinocchio. Nothing outside :mod:`pickdemo.robot` reads these constants: everything
else takes the description as a value.
"""

from __future__ import annotations

import atexit
import functools
import re
import shutil
import sys
import tempfile
from importlib import metadata
from pathlib import Path

import numpy as np

from pickdemo.robot.description import Gripper, JointLimits, RobotDescription, RobotFiles

ARM_JOINTS: tuple[str, ...] = tuple(f"panda_joint{i}" for i in range(1, 8))
FINGER_JOINTS: tuple[str, str] = ("panda_finger_joint1", "panda_finger_joint2")
TCP_FRAME = "panda_hand_tcp"
WRIST_JOINT = "panda_hand_joint"  # flange to hand: where a wrist force sensor sits
HAND_FRAME = "panda_hand"
FINGER_LINKS: tuple[str, str] = ("panda_leftfinger", "panda_rightfinger")

#: Home configuration (rad): the usual "ready" pose; q7 = pi/4 aligns the fingers with world y.
HOME_Q = np.array([0.0, -0.785398, 0.0, -2.356194, 0.0, 1.570796, 0.785398])
#: Each finger travels 0 .. 0.04 m; the gripper opens to 0.08 m in all.
FINGER_MAX_M = 0.04
PALM_ABOVE_TCP_M = 0.034  # the hand's palm (between the fingers) is this far above the TCP
#: The fingers' rubber tips: 18.5 mm tall, centred on the TCP, 22 mm wide (m, halves).
PAD_HALF_HEIGHT_M = 0.00925
PAD_HALF_WIDTH_M = 0.011
#: A finger's thickness outside its pad (m): the open finger's outer face.
FINGER_THICKNESS_M = 0.022
#: The hand's body above the palm, seen from above: half its length along the closing axis, half its width (m).
PALM_HALF_LENGTH_M = 0.105
PALM_HALF_WIDTH_M = 0.035

#: Datasheet limits of the seven arm joints (Franka Emika Panda).
MIN_POSITION_RAD = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])
MAX_POSITION_RAD = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
MAX_VELOCITY_RAD_S = np.array([2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61])
MAX_ACCELERATION_RAD_S2 = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0])
MAX_JERK_RAD_S3 = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0])


#: The hand's links a camera may be mounted on: they move rigidly with it (the fingers do not).
CAMERA_MOUNTS = ("panda_hand", "panda_link8", "panda_hand_tcp")
PAYLOAD_KG = 3.0  # the datasheet's payload
EFFORT_NM = np.array([87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0])  # the datasheet's joint torque limits
FINGER_SPEED_M_S = 0.1  # each finger's top speed in simulation
OPEN_FORCE_N = 20.0  # the fingers' force when opening
MAX_FORCE_N = 70.0  # the Franka Hand's continuous grip force


class RobotModelError(RuntimeError):
    """The robot description could not be found in the installed packages."""


PandaFiles = RobotFiles  # (paths of the Panda description inside the installed ``example-robot-data``)


def _candidate_share_dirs() -> list[Path]:
    dirs: list[Path] = []
    try:
        dist = metadata.distribution("example-robot-data")
        for f in dist.files or ():
            s = str(f)
            if s.endswith("panda_description/urdf/panda.urdf"):
                urdf = Path(str(dist.locate_file(f))).resolve()
                dirs.append(urdf.parents[3])
    except metadata.PackageNotFoundError:
        pass
    for base in {sys.prefix, sys.exec_prefix, *sys.path}:
        for rel in ("cmeel.prefix/share/example-robot-data", "share/example-robot-data"):
            dirs.append(Path(base) / rel)
    return dirs


@functools.cache
def panda_files() -> PandaFiles:
    """Locate the Panda URDF of the installed ``example-robot-data`` (version 6 layout)."""
    for share in _candidate_share_dirs():
        urdf = share / "robots" / "panda_description" / "urdf" / "panda.urdf"
        if urdf.is_file():
            return PandaFiles(urdf=urdf, package_root=share)
    raise RobotModelError(
        "example-robot-data's Panda URDF was not found; install it with `pip install example-robot-data`"
    )


_MESH_RE = re.compile(r'filename="package://example-robot-data/([^"]+)"')
_VISUAL_RE = re.compile(r"<visual>(.*?)</visual>", re.DOTALL)

# Colours for the lean visuals (RGBA): the real arm is white with a dark hand.
_LINK_RGBA = "0.92 0.92 0.92 1"
_HAND_RGBA = "0.25 0.25 0.28 1"


def _lean_urdf_text(files: PandaFiles) -> str:
    text = files.urdf.read_text()

    def visual(match: re.Match[str]) -> str:
        body = match.group(1).replace("/meshes/visual/", "/meshes/collision/").replace(".dae", ".stl")
        rgba = _HAND_RGBA if ("hand" in body or "finger" in body) else _LINK_RGBA
        return f'<visual>{body}<material name="pd_{rgba.split()[0]}"><color rgba="{rgba}"/></material></visual>'

    text = _VISUAL_RE.sub(visual, text)
    return _MESH_RE.sub(lambda m: f'filename="{files.package_root / m.group(1)}"', text)


@functools.cache
def lean_urdf_path() -> Path:
    """A lean Panda URDF for rendering: collision STLs as visuals (~2k triangles instead of ~128k).

    Written once per process into a temporary directory; it refers to the meshes of the installed
    package by absolute path, so nothing is copied or downloaded.
    """
    out_dir = Path(tempfile.mkdtemp(prefix="pickdemo_urdf_"))
    atexit.register(shutil.rmtree, out_dir, ignore_errors=True)
    out = out_dir / "panda_lean.urdf"
    out.write_text(_lean_urdf_text(panda_files()))
    return out


#: The Franka Panda with the Franka Hand.
PANDA = RobotDescription(
    name="panda",
    label="Panda",
    arm_joints=ARM_JOINTS,
    tcp_frame=TCP_FRAME,
    hand_frame=HAND_FRAME,
    wrist_joint=WRIST_JOINT,
    gripper=Gripper(
        kind="parallel",
        finger_joints=FINGER_JOINTS,
        finger_links=FINGER_LINKS,
        finger_max_m=FINGER_MAX_M,
        palm_above_tcp_m=PALM_ABOVE_TCP_M,
        open_force_n=OPEN_FORCE_N,
        max_force_n=MAX_FORCE_N,
        speed_m_s=FINGER_SPEED_M_S,
        pad_half_height_m=PAD_HALF_HEIGHT_M,
        pad_half_width_m=PAD_HALF_WIDTH_M,
        finger_thickness_m=FINGER_THICKNESS_M,
        palm_half_length_m=PALM_HALF_LENGTH_M,
        palm_half_width_m=PALM_HALF_WIDTH_M,
    ),
    home_q=HOME_Q,
    limits=JointLimits(
        MIN_POSITION_RAD, MAX_POSITION_RAD, MAX_VELOCITY_RAD_S, MAX_ACCELERATION_RAD_S2, MAX_JERK_RAD_S3
    ),
    payload_kg=PAYLOAD_KG,
    effort_nm=EFFORT_NM,
    camera_mounts=CAMERA_MOUNTS,
    locate=panda_files,
    render_urdf=lean_urdf_path,
)
