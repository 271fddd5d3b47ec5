"""A robot file's URDF on this machine: found (``example-robot-data:`` or a path), joined with a
hand from another URDF and the file's own frames into one URDF (written once per process), and made
lean for rendering. What the robot file reads (:mod:`pickdemo.robot.robot_file`) and what the
simulator, the kinematics and the self-filter load. Imports neither pybullet nor pinocchio: the URDF
is read as XML.
"""

from __future__ import annotations

import atexit
import difflib
import functools
import os
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
    """A URDF's XML with its meshes' paths made absolute (a joined URDF mixes two packages, and is
    written elsewhere); a mesh that is not on this machine is a one-line error."""
    try:
        root = ET.fromstring(files.urdf.read_bytes())
    except (OSError, ET.ParseError) as exc:
        raise fail(key, f"{files.urdf} is not a readable URDF ({exc})") from None
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        mesh.set("filename", str(found_mesh(name, files, key, fail)))
    return root


def mesh_path(filename: str, files: RobotFiles) -> Path | None:
    """Where a URDF's mesh is on this machine (None: nowhere). ``package://PKG/REL`` is looked for as
    Pinocchio's ``package_dirs`` and example-robot-data's ``getModelPath`` look: beside the URDF
    (``package_root / REL``), in the package the URDF sits in (an ancestor directory named PKG, or an
    ancestor holding PKG), then in the installed packages (``<share>/PKG/REL``: example-robot-data's
    share directory, ``AMENT_PREFIX_PATH``'s, ``ROS_PACKAGE_PATH``'s, this Python's). ``file://`` and
    absolute paths are themselves; a relative path is relative to the URDF."""
    if filename.startswith("package://"):
        pkg, _, rel = filename[len("package://") :].partition("/")
        above = files.urdf.parent.parents
        candidates = [files.package_root / rel]
        candidates += [a / rel for a in (files.urdf.parent, *above) if a.name == pkg]
        candidates += [a / pkg / rel for a in (files.urdf.parent, *above)]
        candidates += [share / pkg / rel for share in installed_package_dirs()]
    elif filename.startswith("file://"):
        candidates = [Path(filename[len("file://") :])]
    else:
        candidates = [files.urdf.parent / filename]
    return next((c for c in candidates if c.is_file()), None)


def found_mesh(filename: str, files: RobotFiles, key: str, fail) -> Path:  # noqa: ANN001 - (key, message) -> error
    """:func:`mesh_path`, or a one-line error under ``key`` saying where it was looked for."""
    path = mesh_path(filename, files)
    if path is None:
        where = "beside the URDF" if not filename.startswith("package://") else (
            f"beside {files.urdf.name}, in the package it sits in, and in the installed packages "
            f"({', '.join(str(d) for d in installed_package_dirs()) or 'none found'})")  # fmt: skip
        raise fail(key, f"{files.urdf.name}'s mesh {filename!r} is not on this machine (looked {where})")
    return path


@functools.cache
def installed_package_dirs() -> tuple[Path, ...]:
    """The directories that hold installed packages by name (ROS's ``share``): example-robot-data's
    parent, each ``AMENT_PREFIX_PATH`` prefix's ``share``, each ``ROS_PACKAGE_PATH`` entry, and this
    Python's ``share`` and ``cmeel.prefix/share`` (where pip's robot packages install them)."""
    dirs = [d.parent for d in _erd_share_dirs()]
    dirs += [Path(p) / "share" for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    dirs += [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p]
    for base in (sys.prefix, sys.exec_prefix, *sys.path):
        dirs += [Path(base) / "share", Path(base) / "cmeel.prefix" / "share"]
    return tuple(d for d in dict.fromkeys(dirs) if d.is_dir())


def joined(arm: RobotFiles, hand: RobotFiles | None, spec: _RobotFile, fail) -> RobotFiles:  # noqa: ANN001
    """One URDF: the arm's; the hand's links from ``root_link`` down joined to the arm's
    ``flange_link`` by a fixed joint (a ``[hand]``); and the file's own frames. Written once per
    process into a temporary directory (meshes referred to where they are installed; nothing copied)."""
    arm_root = _read_urdf(arm, "arm.urdf", fail)
    arm_links = [lk.get("name", "") for lk in arm_root.findall("link")]
    arm_joints = {j.get("name") for j in arm_root.findall("joint")}
    if hand is not None and spec.hand is not None:
        _take_hand(arm_root, arm, hand, spec.hand, arm_links, arm_joints, fail)
    for i, frame in enumerate(spec.arm.frames):
        links = [lk.get("name", "") for lk in arm_root.findall("link")]
        if frame.parent not in links:
            raise fail(f"arm.frames[{i}].parent", not_one_of(frame.parent, "link", links, arm.urdf.name))
        if frame.name in links:
            raise fail(f"arm.frames[{i}].name", f"{frame.name!r} is a link of {arm.urdf.name} already")
        link = ET.SubElement(arm_root, "link", name=frame.name)
        inertial = ET.SubElement(link, "inertial")  # (none: a simulator would give the frame a mass of 1 kg)
        ET.SubElement(inertial, "mass", value="1e-9")
        ET.SubElement(inertial, "inertia", ixx="1e-9", ixy="0", ixz="0", iyy="1e-9", iyz="0", izz="1e-9")
        _fixed_joint(arm_root, f"{frame.name}_joint", frame.parent, frame.name, frame.xyz, frame.rpy)
    _bound_continuous(arm_root, spec)
    joined = _write_joined(ET.tostring(arm_root, encoding="unicode"), spec.name)
    return RobotFiles(urdf=joined, package_root=arm.package_root)


def _bound_continuous(root: ET.Element, spec: _RobotFile) -> None:
    """The arm's continuous joints made revolute within the file's limits (a Kinova's first, fourth and
    sixth): Pinocchio gives a continuous joint two coordinates (its cosine and sine), where the
    solver, the motion and the datasheet's limits take one angle."""
    lim = spec.limits
    for i, name in enumerate(spec.arm.joints):
        for joint in root.findall("joint"):
            if joint.get("name") != name or joint.get("type") != "continuous":
                continue
            joint.set("type", "revolute")
            limit = joint.find("limit")
            if limit is None:
                limit = ET.SubElement(joint, "limit")
            given = i < min(len(lim.position_min), len(lim.position_max), len(lim.effort), len(lim.velocity))
            if given:  # (a list of the wrong length is said by the checks, naming its key)
                limit.set("lower", repr(lim.position_min[i]))
                limit.set("upper", repr(lim.position_max[i]))
                limit.set("effort", limit.get("effort") or repr(lim.effort[i]))
                limit.set("velocity", limit.get("velocity") or repr(lim.velocity[i]))


def not_one_of(name: str, kind: str, names: list[str], label: str) -> str:
    """``'x' is not a link of z1.urdf (did you mean 'y'?); its links: a, b, ...``: what to write instead."""
    close = difflib.get_close_matches(name, names, n=1, cutoff=0.6)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"{name!r} is not a {kind} of {label}{hint}; its {kind}s: {', '.join(names) or '(none)'}"


@functools.cache
def model_urdf(files: RobotFiles) -> tuple[Path, dict[str, str]]:
    """The URDF Pinocchio builds its models from, and the joints renamed in it ({URDF's name: the
    model's}). A joint named as a link (the Unitree Z1's fixed joint ``gripperStator``, its child) is
    renamed ``<name>_joint`` in a copy: Pinocchio's ``buildReducedModel`` looks frames up by bare name
    and raises on two. Most URDFs have no such joint: the URDF itself, nothing renamed."""
    try:
        root = ET.fromstring(files.urdf.read_bytes())
    except (OSError, ET.ParseError):
        return files.urdf, {}  # (said by the robot file's checks)
    names = {lk.get("name") for lk in root.findall("link")} | {j.get("name") for j in root.findall("joint")}
    renamed: dict[str, str] = {}
    for joint in root.findall("joint"):
        name = joint.get("name", "")
        if name in {lk.get("name") for lk in root.findall("link")}:
            new = f"{name}_joint"
            while new in names:
                new += "_"
            names.add(new)
            joint.set("name", new)
            renamed[name] = new
    if not renamed:
        return files.urdf, {}
    for mimic in root.iter("mimic"):
        mimic.set("joint", renamed.get(mimic.get("joint", ""), mimic.get("joint", "")))
    out = _scratch_dir() / f"{files.urdf.stem}_model.urdf"
    out.write_text(ET.tostring(root, encoding="unicode"))
    return out, renamed


def _fixed_joint(root: ET.Element, name: str, parent: str, child: str, xyz: list, rpy: list) -> None:
    join = ET.SubElement(root, "joint", name=name, type="fixed")
    ET.SubElement(join, "parent", link=parent)
    ET.SubElement(join, "child", link=child)
    ET.SubElement(join, "origin", xyz=" ".join(map(str, xyz)), rpy=" ".join(map(str, rpy)))


def _take_hand(arm_root: ET.Element, arm: RobotFiles, hand: RobotFiles, spec: _Hand, arm_links: list,
               arm_joints: set, fail) -> None:  # noqa: ANN001  # fmt: skip
    """The hand's links from its root down, and their joints, into the arm's URDF at its flange."""
    hand_root = _read_urdf(hand, "hand.urdf", fail)
    if spec.flange_link not in arm_links:
        raise fail("hand.flange_link", not_one_of(spec.flange_link, "link", arm_links, arm.urdf.name))
    hand_links = {lk.get("name"): lk for lk in hand_root.findall("link")}
    if spec.root_link not in hand_links:
        raise fail("hand.root_link", not_one_of(spec.root_link, "link", list(hand_links), hand.urdf.name))
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
    clash = sorted((taken & set(arm_links)) | ({j.get("name") for j in joints} & arm_joints))
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


_MESH_RE = re.compile(r'(<mesh\b[^>]*?\bfilename=")([^"]+)"')
_VISUAL_RE = re.compile(r"<visual>(.*?)</visual>", re.DOTALL)
#: Colours for the lean visuals (RGBA): the arm white, its hand dark.
_LINK_RGBA = "0.92 0.92 0.92 1"
_HAND_RGBA = "0.25 0.25 0.28 1"


def lean_urdf_text(files: RobotFiles, mesh_dir: Path | None = None, collision: tuple = (), render: tuple = ()) -> str:
    """The URDF with its collision meshes as visuals (example-robot-data keeps them beside the visual
    ones: ~2k triangles instead of ~128k for the Panda; a visual whose collision twin is not there is
    kept) and its meshes' paths made absolute (:func:`mesh_path`). ``mesh_dir``: where an STL without
    normals is written as an OBJ with them (None: used as it is). ``collision``: (file name, path)
    pairs, a collision mesh to take instead of the URDF's of that name (the robot file's
    ``collision_meshes``); ``render``: the same for the visuals (its ``render_meshes``)."""
    text = _MESH_RE.sub(lambda m: f'{m.group(1)}{mesh_path(m.group(2), files) or m.group(2)}"', files.urdf.read_text())
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
