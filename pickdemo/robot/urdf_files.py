"""A robot file's URDF on this machine: found (``example-robot-data:`` or a path), joined with a
hand from another URDF and the file's own frames into one URDF (written once per process), and made
lean for rendering. What the robot file reads (:mod:`pickdemo.robot.robot_file`) and what the
simulator, the kinematics and the self-filter load. Imports neither pybullet nor pinocchio: the URDF
is read as XML.
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
from typing import TYPE_CHECKING

from pickdemo.robot.description import RobotFiles
from pickdemo.robot.stl import has_normals, write_obj_with_normals

if TYPE_CHECKING:
    from pickdemo.robot.robot_file import _Hand, _RobotFile

#: The prefix of a URDF in the installed example-robot-data.
ERD_PREFIX = "example-robot-data:"


def locate(spec: str, base: Path, fail, key: str) -> RobotFiles:  # noqa: ANN001 - (key, message) -> error
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


def joined(arm: RobotFiles, hand: RobotFiles | None, spec: _RobotFile, fail) -> RobotFiles:  # noqa: ANN001
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
def lean_urdf_path(files: RobotFiles, name: str, collision: tuple = (), render: tuple = ()) -> Path:
    """A lean URDF for rendering (:func:`lean_urdf_text`), written once per process into a temporary
    directory; it refers to the installed meshes by absolute path (nothing copied or downloaded)."""
    out_dir = _scratch_dir()
    mesh_dir = out_dir / "meshes"
    mesh_dir.mkdir()
    out = out_dir / f"{name}_lean.urdf"
    out.write_text(lean_urdf_text(files, mesh_dir, collision, render))
    return out
