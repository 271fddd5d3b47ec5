"""A robot described by a file (TOML): its URDF, joints, frames, home, datasheet limits and gripper,
read into one :class:`~pickdemo.robot.description.RobotDescription`.

The shipped robots are files in ``pickdemo/robot/robots/`` (the Panda first); a user's robot is a
file anywhere. A bad file is one line naming the file and the key (:class:`RobotFileError`): a
missing URDF, a joint or frame the URDF does not have, a limit that is not positive, a gripper whose
stroke cannot hold anything. ``urdf`` is ``example-robot-data:<path under its robots/>`` (the
installed package, never copied) or a file, relative to the robot file. Imports neither pybullet nor
pinocchio: the URDF is read as XML.
"""

from __future__ import annotations

import atexit
import functools
import re
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from importlib import metadata
from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import tomllib
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from pickdemo.robot.description import Gripper, JointLimits, RobotDescription, RobotFiles
from pickdemo.robot.stl import has_normals, write_obj_with_normals

#: Where the shipped robot files are.
ROBOTS_DIR = Path(__file__).resolve().parent / "robots"
#: A parallel gripper must open at least this wide in all to hold anything (m).
MIN_STROKE_M = 0.01
#: The prefix of a URDF in the installed example-robot-data.
ERD_PREFIX = "example-robot-data:"

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
    home: list[Finite]
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


class _RobotFile(_Model):
    name: str = Field(pattern=r"^[A-Za-z0-9_.+-]+$")
    label: str
    arm: _Arm
    hand: _Hand | None = None
    limits: _Limits
    gripper: _Gripper
    grasp: _Grasp = _Grasp()


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
        key = ".".join(str(p) for p in err["loc"]) or "(top level)"
        msg = {"extra_forbidden": "unknown key", "missing": "missing"}.get(err["type"], err["msg"])
        raise RobotFileError(f"{path}: {key}: {msg}") from None

    def fail(key: str, msg: str) -> RobotFileError:
        return RobotFileError(f"{path}: {key}: {msg}")

    files = _locate(spec.arm.urdf, path.parent, fail, "arm.urdf")
    if spec.hand is not None or spec.arm.frames:
        hand = None if spec.hand is None else _locate(spec.hand.urdf, path.parent, fail, "hand.urdf")
        files = _joined(files, hand, spec, fail)
    _check(spec, files.urdf, fail)

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
    return RobotDescription(
        name=spec.name,
        label=spec.label,
        arm_joints=tuple(a.joints),
        tcp_frame=a.tcp_frame,
        hand_frame=a.hand_frame,
        wrist_joint=a.wrist_joint,
        gripper=Gripper(
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
            jaw_table=tuple((float(a), float(b)) for a, b in g.jaw_table),
            jaw_lever_m=g.jaw_lever_m or 0.0,
            jaw_clearance_m=g.jaw_clearance_m,
            grip_force_n=g.grip_force_n,
            pad_friction=g.pad_friction,
        ),  # fmt: skip
        home_q=np.array(a.home),
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
        render_urdf=functools.partial(_lean_urdf_path, files, spec.name, meshes, renders),
        grasp_heights=tuple((k, v) for k, v in spec.grasp.model_dump().items() if v is not None),
    )


def _check(spec: _RobotFile, urdf: Path, fail) -> None:  # noqa: ANN001 - (key, message) -> error
    """What the URDF must have, the limits' lengths and order, home within them, the stroke."""
    try:
        root = ET.fromstring(urdf.read_bytes())
    except (OSError, ET.ParseError) as exc:
        raise fail("arm.urdf", f"{urdf} is not a readable URDF ({exc})") from None
    joints = {j.get("name"): j.get("type") for j in root.findall("joint")}
    links = {lk.get("name") for lk in root.findall("link")}
    a, g, lim = spec.arm, spec.gripper, spec.limits
    for i, name in enumerate(a.joints):
        if joints.get(name) not in ("revolute", "continuous", "prismatic"):
            what = "is not a moving joint" if name in joints else "is not a joint"
            raise fail(f"arm.joints[{i}]", f"{name!r} {what} of {urdf.name}")
    for key, name in (("arm.wrist_joint", a.wrist_joint),):
        if name not in joints:
            raise fail(key, f"{name!r} is not a joint of {urdf.name}")
    for key, name in (("arm.tcp_frame", a.tcp_frame), ("arm.hand_frame", a.hand_frame)):
        if name not in links:
            raise fail(key, f"{name!r} is not a link of {urdf.name}")
    for i, name in enumerate(a.camera_mounts):
        if name not in links:
            raise fail(f"arm.camera_mounts[{i}]", f"{name!r} is not a link of {urdf.name}")
    for i, name in enumerate(g.finger_joints):
        if name not in joints:
            raise fail(f"gripper.finger_joints[{i}]", f"{name!r} is not a joint of {urdf.name}")
    for i, name in enumerate(g.finger_links):
        if name not in links:
            raise fail(f"gripper.finger_links[{i}]", f"{name!r} is not a link of {urdf.name}")
    n = len(a.joints)
    for key in ("home",):
        if len(getattr(a, key)) != n:
            raise fail(f"arm.{key}", f"{len(getattr(a, key))} values for {n} joints")
    for key in ("position_min", "position_max", "velocity", "acceleration", "jerk", "effort"):
        if len(getattr(lim, key)) != n:
            raise fail(f"limits.{key}", f"{len(getattr(lim, key))} values for {n} joints")
    for i, (lo, hi) in enumerate(zip(lim.position_min, lim.position_max, strict=True)):
        if not lo < hi:
            raise fail(f"limits.position_min[{i}]", f"{lo} is not below position_max's {hi}")
        if not lo <= a.home[i] <= hi:
            raise fail(f"arm.home[{i}]", f"{a.home[i]} is outside the joint's limits [{lo}, {hi}]")
    if 2.0 * g.finger_max_m < MIN_STROKE_M:
        raise fail("gripper.finger_max_m", f"the hand opens {2e3 * g.finger_max_m:.1f} mm in all: it cannot hold "
                                           f"anything (at least {MIN_STROKE_M * 1e3:.0f} mm)")  # fmt: skip
    if g.grip_force_n is not None and g.grip_force_n > g.max_force_n:
        raise fail("gripper.grip_force_n", f"{g.grip_force_n} N is more than max_force_n's {g.max_force_n} N")
    if g.open_force_n > g.max_force_n:
        raise fail("gripper.open_force_n", f"{g.open_force_n} N is more than max_force_n's {g.max_force_n} N")
    if g.kind == "parallel" and len(g.finger_joints) != 2:
        raise fail("gripper.finger_joints", f"a parallel gripper has two finger joints, not {len(g.finger_joints)}")
    if g.kind == "jaw":
        _check_jaw(g, joints, fail)


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
    rad, gap = np.array(table).T
    if not (np.all(np.diff(rad) > 0) and np.all(np.diff(gap) > 0)):
        raise fail("gripper.jaw_table", "its angles and openings must both rise, row by row")
    if gap[-1] < 2.0 * g.finger_max_m - 1e-9:
        raise fail(
            "gripper.jaw_table", f"it reaches {gap[-1] * 1e3:.1f} mm; the gripper opens {2e3 * g.finger_max_m:.1f}"
        )


def _locate(spec: str, base: Path, fail, key: str) -> RobotFiles:  # noqa: ANN001 - (key, message) -> error
    """The URDF and the directory its ``package://`` paths point to."""
    if spec.startswith(ERD_PREFIX):
        rel = spec[len(ERD_PREFIX) :]
        for share in _erd_share_dirs():
            urdf = share / "robots" / rel
            if urdf.is_file():
                return RobotFiles(urdf=urdf, package_root=share)
        raise fail(key, f"{rel} is not in the installed example-robot-data (`pip install example-robot-data`)")
    urdf = (base / spec).resolve()
    if not urdf.is_file():
        raise fail(key, f"no such file: {urdf}")
    return RobotFiles(urdf=urdf, package_root=urdf.parent)


def _read_urdf(files: RobotFiles, key: str, fail) -> ET.Element:  # noqa: ANN001 - (key, message) -> error
    """A URDF's XML with its meshes' ``package://`` paths made absolute (a joined URDF mixes two packages)."""
    try:
        root = ET.fromstring(files.urdf.read_bytes())
    except (OSError, ET.ParseError) as exc:
        raise fail(key, f"{files.urdf} is not a readable URDF ({exc})") from None
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name.startswith("package://"):
            mesh.set("filename", str(files.package_root / re.sub(r"^package://[^/]+/", "", name)))
    return root


def _joined(arm: RobotFiles, hand: RobotFiles | None, spec: _RobotFile, fail) -> RobotFiles:  # noqa: ANN001
    """One URDF: the arm's; the hand's links from ``root_link`` down joined to the arm's
    ``flange_link`` by a fixed joint (a ``[hand]``); and the file's own frames. Written once per
    process into a temporary directory (meshes referred to where they are installed; nothing copied)."""
    arm_root = _read_urdf(arm, "arm.urdf", fail)
    arm_links = {lk.get("name") for lk in arm_root.findall("link")}
    arm_joints = {j.get("name") for j in arm_root.findall("joint")}
    if hand is not None and spec.hand is not None:
        _take_hand(arm_root, arm, hand, spec.hand, arm_links, arm_joints, fail)
    for i, frame in enumerate(spec.arm.frames):
        links = {lk.get("name") for lk in arm_root.findall("link")}
        if frame.parent not in links:
            raise fail(f"arm.frames[{i}].parent", f"{frame.parent!r} is not a link of {arm.urdf.name}")
        if frame.name in links:
            raise fail(f"arm.frames[{i}].name", f"{frame.name!r} is a link of {arm.urdf.name} already")
        link = ET.SubElement(arm_root, "link", name=frame.name)
        inertial = ET.SubElement(link, "inertial")  # (none: a simulator would give the frame a mass of 1 kg)
        ET.SubElement(inertial, "mass", value="1e-9")
        ET.SubElement(inertial, "inertia", ixx="1e-9", ixy="0", ixz="0", iyy="1e-9", iyz="0", izz="1e-9")
        _fixed_joint(arm_root, f"{frame.name}_joint", frame.parent, frame.name, frame.xyz, frame.rpy)
    joined = _write_joined(ET.tostring(arm_root, encoding="unicode"), spec.name)
    return RobotFiles(urdf=joined, package_root=arm.package_root)


def _fixed_joint(root: ET.Element, name: str, parent: str, child: str, xyz: list, rpy: list) -> None:
    join = ET.SubElement(root, "joint", name=name, type="fixed")
    ET.SubElement(join, "parent", link=parent)
    ET.SubElement(join, "child", link=child)
    ET.SubElement(join, "origin", xyz=" ".join(map(str, xyz)), rpy=" ".join(map(str, rpy)))


def _take_hand(arm_root: ET.Element, arm: RobotFiles, hand: RobotFiles, spec: _Hand, arm_links: set,
               arm_joints: set, fail) -> None:  # noqa: ANN001  # fmt: skip
    """The hand's links from its root down, and their joints, into the arm's URDF at its flange."""
    hand_root = _read_urdf(hand, "hand.urdf", fail)
    if spec.flange_link not in arm_links:
        raise fail("hand.flange_link", f"{spec.flange_link!r} is not a link of {arm.urdf.name}")
    hand_links = {lk.get("name"): lk for lk in hand_root.findall("link")}
    if spec.root_link not in hand_links:
        raise fail("hand.root_link", f"{spec.root_link!r} is not a link of {hand.urdf.name}")
    if spec.joint in arm_joints:
        raise fail("hand.joint", f"{spec.joint!r} is a joint of {arm.urdf.name} already: name the new joint anew")
    taken, joints, grew = {spec.root_link}, [], True
    while grew:  # the hand's subtree: every joint whose parent is taken, and its child
        grew = False
        for j in hand_root.findall("joint"):
            parent, child = j.find("parent").get("link"), j.find("child").get("link")  # type: ignore[union-attr]
            if parent in taken and child not in taken:
                taken.add(child)
                joints.append(j)
                grew = True
    clash = sorted((taken & arm_links) | ({j.get("name") for j in joints} & arm_joints))
    if clash:
        raise fail("hand.urdf", f"{', '.join(clash)}: named in both URDFs")
    for name, link in hand_links.items():  # in the hand's file's order: the same file in every process
        if name in taken:
            arm_root.append(link)
    arm_root.extend(joints)
    _fixed_joint(arm_root, spec.joint, spec.flange_link, spec.root_link, spec.xyz, spec.rpy)


def _scratch_dir() -> Path:
    """A temporary directory of this process's own, removed when it exits."""
    out_dir = Path(tempfile.mkdtemp(prefix="pickdemo_urdf_"))
    atexit.register(shutil.rmtree, out_dir, ignore_errors=True)
    return out_dir


@functools.cache
def _write_joined(text: str, name: str) -> Path:
    out = _scratch_dir() / f"{name}_joined.urdf"
    out.write_text(text)
    return out


@functools.cache
def _erd_share_dirs() -> tuple[Path, ...]:
    """Where the installed example-robot-data may keep its ``robots/`` (its version 6 layout)."""
    dirs: list[Path] = []
    try:
        dist = metadata.distribution("example-robot-data")
        for f in dist.files or ():
            parts = Path(str(f)).parts
            if str(f).endswith(".urdf") and "robots" in parts:
                urdf = Path(str(dist.locate_file(f))).resolve()
                dirs.append(urdf.parents[len(parts) - parts.index("robots") - 1])
                break
    except metadata.PackageNotFoundError:
        pass
    for base in {sys.prefix, sys.exec_prefix, *sys.path}:
        for rel in ("cmeel.prefix/share/example-robot-data", "share/example-robot-data"):
            dirs.append(Path(base) / rel)
    return tuple(dict.fromkeys(dirs))


_MESH_RE = re.compile(r'filename="package://[^/"]+/([^"]+)"')
_VISUAL_RE = re.compile(r"<visual>(.*?)</visual>", re.DOTALL)
#: Colours for the lean visuals (RGBA): the arm white, its hand dark.
_LINK_RGBA = "0.92 0.92 0.92 1"
_HAND_RGBA = "0.25 0.25 0.28 1"


def lean_urdf_text(files: RobotFiles, mesh_dir: Path | None = None, collision: tuple = (), render: tuple = ()) -> str:
    """The URDF with its collision meshes as visuals (example-robot-data keeps them beside the visual
    ones: ~2k triangles instead of ~128k for the Panda; a visual whose collision twin is not there is
    kept) and package paths made absolute. ``mesh_dir``: where an STL without normals is written as an
    OBJ with them (None: used as it is). ``collision``: (file name, path) pairs, a collision mesh to
    take instead of the URDF's of that name (the robot file's ``collision_meshes``); ``render``: the same for
    the visuals (its ``render_meshes``)."""
    text = _MESH_RE.sub(lambda m: f'filename="{files.package_root / m.group(1)}"', files.urdf.read_text())
    swap, seen = dict(collision), dict(render)

    def swapped(body: str, table: dict[str, str]) -> str:
        """``body`` with each mesh file named in ``table`` (by its file name) replaced by its entry."""
        return re.sub(r'filename="([^"]+)"', lambda f: f'filename="{table.get(Path(f.group(1)).name, f.group(1))}"',
                      body)  # fmt: skip

    if swap:
        text = re.sub(r"<collision>.*?</collision>", lambda m: swapped(m.group(0), swap), text, flags=re.DOTALL)

    def shaded(match: re.Match[str]) -> str:
        path = Path(match.group(1))
        if mesh_dir is None or path.suffix.lower() != ".stl" or has_normals(path):
            return match.group(0)
        out = mesh_dir / f"{len(list(mesh_dir.iterdir()))}_{path.stem}.obj"
        return f'filename="{write_obj_with_normals(path, out)}"'

    def visual(match: re.Match[str]) -> str:
        body = match.group(1)
        lean = body.replace("/visual/", "/collision/").replace(".dae", ".stl")
        if all(Path(f).is_file() for f in re.findall(r'filename="([^"]+)"', lean)):
            body = re.sub(r'filename="([^"]+)"', shaded, lean)
        if seen:
            body = swapped(body, seen)
        rgba = _HAND_RGBA if ("hand" in body or "finger" in body) else _LINK_RGBA
        return f'<visual>{body}<material name="pd_{rgba.split()[0]}"><color rgba="{rgba}"/></material></visual>'

    return _VISUAL_RE.sub(visual, text)


@functools.cache
def _lean_urdf_path(files: RobotFiles, name: str, collision: tuple = (), render: tuple = ()) -> Path:
    """A lean URDF for rendering (:func:`lean_urdf_text`), written once per process into a temporary
    directory; it refers to the installed meshes by absolute path (nothing copied or downloaded)."""
    out_dir = _scratch_dir()
    mesh_dir = out_dir / "meshes"
    mesh_dir.mkdir()
    out = out_dir / f"{name}_lean.urdf"
    out.write_text(lean_urdf_text(files, mesh_dir, collision, render))
    return out
