"""Robot files for arms nobody ships, as a user writes them from the docs: the Unitree Z1 with its own
jaw (its URDF unmodified: a fixed joint named as its child link, a jaw whose opening falls as its
angle rises) reads and builds its kinematics and self-filter; a local copy of an installed URDF finds
its meshes in the installed package; a file without a home gets one proposed. And bad robot files,
each through ``python -m pickdemo validate``: one line naming the user's robot file and the key (the
valid names when a name is wrong), exit 2, never a traceback, never the URDF pickdemo writes."""

from __future__ import annotations

import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from pickdemo.apps.cli import main
from pickdemo.robot.kinematics import Kinematics
from pickdemo.robot.robot_file import load_robot_file
from pickdemo.robot.self_geometry import RobotBody
from pickdemo.robot.urdf_files import _erd_share_dirs

FILES = Path(__file__).resolve().parent / "files"
Z1 = (FILES / "z1.toml").read_text()
XARM = (FILES / "xarm7_franka_hand.toml").read_text()
ROOT = Path(__file__).resolve().parents[2]
SCENARIO = """name = "t"
robot = "robot.toml"
[camera]
position = [1.1, 0.0, 0.75]
look_at = [0.5, 0.0, 0.0]
[[objects]]
name = "cube"
shape = "box"
size = [0.05, 0.05, 0.05]
color = [0.85, 0.1, 0.1]
position_range = [[0.3, 0.4], [-0.05, 0.05]]
target = true
[place]
position = [0.32, 0.22]
[success]
lift_height = 0.05
"""


def _z1_urdf() -> str:
    return next(d / "robots/z1_description/urdf/z1.urdf" for d in _erd_share_dirs() if d.is_dir())


def _beside(tmp_path: Path) -> None:
    """The files ``z1.toml`` names beside it (its gripper's convex decompositions) copied into ``tmp_path``."""
    shutil.copytree(FILES / "z1", tmp_path / "z1")


def _links_with_collision() -> int:
    return sum(1 for link in ET.parse(_z1_urdf()).getroot().findall("link") if link.find("collision") is not None)


def test_the_z1_reads_as_shipped_and_builds_its_kinematics_and_self_filter() -> None:
    r = load_robot_file(FILES / "z1.toml")
    kin, body = Kinematics(r), RobotBody(r)  # (a bare-name frame lookup raised "Several frames match")
    down = kin.forward(r.home_q).rotation[:, 2]
    assert r.home_proposed and down[2] < -0.999, down  # the proposed home: the hand pointing down
    assert np.all(r.home_q >= r.limits.min_position_rad) and np.all(r.home_q <= r.limits.max_position_rad)
    assert len(body.boxes(r.home_q, np.full(2, 0.02))) == _links_with_collision()  # (cylinders bounded too)
    assert kin.tcp_to_frame(r.wrist_joint).position.shape == (3,)  # (a fixed joint named as its child link)
    g = r.gripper  # its opening falls as its angle rises: both ways through the table
    for finger in (0.0, 0.01, 0.02, g.finger_max_m):
        (angle,) = g.joint_targets(finger)
        assert g.fingers_of([angle]) == pytest.approx([finger, finger], abs=1e-9)
    assert g.joint_targets(0.0)[0] == pytest.approx(0.0) and g.joint_targets(g.finger_max_m)[0] < -0.7
    assert load_robot_file(FILES / "z1.toml").home_q.tolist() == r.home_q.tolist()  # (the same every time)


def test_a_local_copy_of_an_installed_urdf_finds_its_package_meshes(tmp_path: Path) -> None:
    (tmp_path / "z1.urdf").write_text(Path(_z1_urdf()).read_text())  # package://example-robot-data/... inside
    _beside(tmp_path)
    f = tmp_path / "robot.toml"
    f.write_text(Z1.replace('"example-robot-data:z1_description/urdf/z1.urdf"', '"z1.urdf"'))
    r = load_robot_file(f)
    assert "package://" not in r.render_urdf().read_text()
    assert len(RobotBody(r).boxes(r.home_q, np.full(2, 0.02))) == _links_with_collision()


def test_validate_prints_the_proposed_home(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "robot.toml").write_text(Z1)
    _beside(tmp_path)
    (tmp_path / "s.toml").write_text(SCENARIO)
    assert main(["validate", str(tmp_path / "s.toml")]) == 0
    out = capsys.readouterr().out
    assert "no home given; proposed" in out and "home = [" in out, out
    # pasted into the file as printed, it is the home the robot ran with (and no "-0.0000" in it)
    import tomllib

    from pickdemo.scenario.load import load_scenario

    printed = tomllib.loads(out[out.index("home = [") :].strip())["home"]
    ran = load_scenario(tmp_path / "s.toml").robot_description.home_q
    assert len(printed) == len(ran) and max(abs(a - b) for a, b in zip(printed, ran, strict=True)) < 1e-4
    assert "-0.0000" not in out


def test_pybullet_s_warnings_stay_off_stdout(tmp_path: Path) -> None:
    """The xArm7's ``link_eef`` has no inertia: PyBullet's C code prints a warning about it on stdout,
    which glued itself to pickdemo's next line ("link_eefSUCCESS: ...")."""
    (tmp_path / "robot.toml").write_text(XARM)
    (tmp_path / "s.toml").write_text(SCENARIO)
    code = ("import sys; from pickdemo import load_scenario; from pickdemo.sim.scene import Scene; "
            "sc = load_scenario(sys.argv[1]); Scene(sc, (), robot=sc.robot_description); print('built')")  # fmt: skip
    run = subprocess.run([sys.executable, "-c", code, str(tmp_path / "s.toml")], capture_output=True, text=True,
                         cwd=ROOT, timeout=120, check=False)  # fmt: skip
    assert run.returncode == 0 and run.stdout == "built\n", (run.stdout, run.stderr[-2000:])


def _edit(old: str, new: str, text: str = Z1) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def _urdf(joints: str, links: str = "") -> str:
    """A small URDF: a base and links a..c (box collisions), with these joints."""
    body = "".join(f'<link name="{n}"><collision><geometry><box size="0.05 0.05 0.05"/></geometry></collision>'
                   f'<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>'
                   f"</inertial></link>" for n in ("base", "a", "b", "c"))  # fmt: skip
    return f'<robot name="r">{body}{links}{joints}</robot>'


def _joint(name: str, kind: str, parent: str, child: str) -> str:
    limit = '<limit lower="-1" upper="1" effort="10" velocity="1"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>{limit}</joint>')  # fmt: skip


#: A small arm's robot file: joints j1, j2 (a and b), a parallel gripper's fingers f1, f2.
SMALL = """name = "small"
label = "small"
[arm]
urdf = "r.urdf"
joints = ["j1", "j2"]
tcp_frame = "c"
hand_frame = "c"
wrist_joint = "j2"
home = [0.0, 0.0]
payload_kg = 1.0
base_radius_m = 0.05
[limits]
position_min = [-1.0, -1.0]
position_max = [1.0, 1.0]
velocity = [1.0, 1.0]
acceleration = [1.0, 1.0]
jerk = [1.0, 1.0]
effort = [1.0, 1.0]
[gripper]
kind = "parallel"
finger_joints = ["f1", "f2"]
finger_links = ["c", "c"]
finger_max_m = 0.04
palm_above_tcp_m = 0.03
open_force_n = 10.0
max_force_n = 20.0
speed_m_s = 0.1
pad_half_height_m = 0.01
pad_half_width_m = 0.01
finger_thickness_m = 0.01
palm_half_length_m = 0.05
palm_half_width_m = 0.03
"""
FINGERS = '<link name="l"/><link name="r"/>'
FINGER_JOINTS = _joint("f1", "prismatic", "c", "l") + _joint("f2", "prismatic", "c", "r")
GOOD_SMALL = _urdf(_joint("j1", "revolute", "base", "a") + _joint("j2", "revolute", "a", "b")
                   + _joint("jc", "fixed", "b", "c") + FINGER_JOINTS, FINGERS)  # fmt: skip

# (id, robot file, {other file: text}, what the one line says after "<robot file>: ")
CASES: list[tuple[str, str, dict[str, str], str]] = [
    ("a TCP misspelt: the links listed", _edit('tcp_frame = "z1_tcp"', 'tcp_frame = "gripperStatr"'), {},
     "arm.tcp_frame: 'gripperStatr' is not a link of z1.urdf (did you mean 'gripperStator'?); its links: world,"),
    ("a fixed joint as an arm joint", _edit('"joint6"]', '"gripperStator"]'), {},
     "arm.joints[5]: 'gripperStator' is not a moving joint of z1.urdf (it is fixed); its moving joints: joint1,"),
    ("the arm's joints out of order", _edit('"joint1", "joint2"', '"joint2", "joint1"'), {},
     'arm.joints: not in z1.urdf\'s order from the base: write ["joint1", "joint2",'),
    ("a moving joint left out", _edit(', "joint6"]', "]").replace(", 30.0]", "]").replace(", 5000.0]", "]")
     .replace(", 10.0]", "]").replace(", 3.1415]", "]").replace(", 2.7925]", "]").replace(", -2.7925]", "]"), {},
     "arm.joints: z1.urdf moves joint6 too: name each in arm.joints"),
    ("a joint named twice", _edit('"joint5", "joint6"', '"joint5", "joint5"'), {}, "arm.joints: a joint named twice"),
    ("the jaw's joint in the arm too", _edit('finger_joints = ["jointGripper"]', 'finger_joints = ["joint6"]'), {},
     "gripper.finger_joints[0]: 'joint6' is an arm joint too"),
    ("a TCP the arm's last joint does not move", _edit('tcp_frame = "z1_tcp"', 'tcp_frame = "link03"'), {},
     "arm.tcp_frame: 'link03' is not moved by the arm's last joint 'joint6'"),
    ("a finger link misspelt", _edit('["gripperMover", "gripperStator"]', '["gripperMovr", "gripperStator"]'), {},
     "gripper.finger_links[0]: 'gripperMovr' is not a link of z1.urdf (did you mean 'gripperMover'?)"),
    ("a wrist joint misspelt", _edit('wrist_joint = "gripperStator"', 'wrist_joint = "gripperStatorJoint"'), {},
     "arm.wrist_joint: 'gripperStatorJoint' is not a joint of z1.urdf (did you mean 'gripperStator'?)"),
    ("a camera mount not there", _edit('camera_mounts = ["gripperStator"', 'camera_mounts = ["camera_link"'), {},
     "arm.camera_mounts[0]: 'camera_link' is not a link of z1.urdf; its links: world,"),
    ("a frame on a link not there", _edit('parent = "gripperStator"', 'parent = "gripper"'), {},
     "arm.frames[0].parent: 'gripper' is not a link of z1.urdf"),
    ("a frame named as a link", _edit('name = "z1_tcp", parent', 'name = "link06", parent'), {},
     "arm.frames[0].name: 'link06' is a link of z1.urdf already"),
    ("a jaw's table with an angle twice", _edit("[-0.3355, 0.020]", "[-0.4109, 0.020]"), {},
     "gripper.jaw_table: the opening must rise, or fall, with the angle at every row, and no angle twice"),
    ("a jaw's table that turns back", _edit("[-0.3355, 0.020]", "[-0.3355, 0.030]"), {},
     "gripper.jaw_table: the opening must rise, or fall, with the angle"),
    ("a hand's flange misspelt: the arm's links listed",
     _edit('flange_link = "link_eef"', 'flange_link = "link8"', XARM), {},
     "hand.flange_link: 'link8' is not a link of xarm7.urdf (did you mean 'link7'?); its links: world, link_base,"),
    ("a hand's root misspelt", _edit('root_link = "panda_hand"', 'root_link = "panda_hnd"', XARM), {},
     "hand.root_link: 'panda_hnd' is not a link of panda.urdf (did you mean 'panda_hand'?)"),
    ("a link of the hand misspelt names the user's URDFs",
     _edit('tcp_frame = "panda_hand_tcp"', 'tcp_frame = "panda_tcp"', XARM), {},
     "arm.tcp_frame: 'panda_tcp' is not a link of xarm7.urdf with panda.urdf's hand"),
    ("a local URDF whose package is nowhere",
     _edit('"example-robot-data:z1_description/urdf/z1.urdf"', '"z1.urdf"'),
     {"z1.urdf": "Z1:example-robot-data/robots/z1_description=nowhere_description"},
     "arm.urdf: z1.urdf's mesh 'package://nowhere_description/meshes/visual/z1_Link00.dae' is not on this machine"),
    ("a local URDF's relative mesh missing", SMALL, {"r.urdf": GOOD_SMALL.replace(
        '<box size="0.05 0.05 0.05"/>', '<mesh filename="meshes/a.stl"/>', 1)},
     "arm.urdf: r.urdf's mesh 'meshes/a.stl' is not on this machine (looked beside the URDF)"),
    ("a collision mesh the self-filter cannot read", SMALL, {"a.ply": "ply", "r.urdf": GOOD_SMALL.replace(
        '<box size="0.05 0.05 0.05"/>', '<mesh filename="a.ply"/>', 1)},
     "arm.urdf: link 'base''s collision mesh 'a.ply' is not one of .stl, .obj, .dae"),
    ("a URDF that is not XML", SMALL, {"r.urdf": "<robot"}, "arm.urdf: "),
    ("a URDF Pinocchio cannot build", SMALL,
     {"r.urdf": GOOD_SMALL.replace('<parent link="a"/>', '<parent link="zz"/>')},
     "arm.urdf: Pinocchio cannot build a model of r.urdf"),
    ("an arm joint that slides", SMALL, {"r.urdf": GOOD_SMALL.replace('name="j2" type="revolute"',
                                                                       'name="j2" type="prismatic"')},
     "arm.joints[1]: 'j2' slides (prismatic): an arm's joints here turn"),
    ("a parallel gripper's finger that turns", SMALL, {"r.urdf": GOOD_SMALL.replace('name="f2" type="prismatic"',
                                                                                     'name="f2" type="revolute"')},
     "gripper.finger_joints[1]: 'f2' is revolute: a parallel gripper's fingers slide"),
    ("arm joints on two branches", SMALL, {"r.urdf": GOOD_SMALL.replace('<parent link="a"/><child link="b"/>',
                                                                         '<parent link="base"/><child link="b"/>')},
     "arm.joints: 'j2' is not below 'j1' in r.urdf's tree"),
    ("no home, and none the hand can take pointing down",
     SMALL.replace("home = [0.0, 0.0]\n", ""), {"r.urdf": GOOD_SMALL},
     "arm.home: missing, and none found with the hand pointing down"),
]  # fmt: skip


@pytest.mark.parametrize(("robot", "files", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_a_bad_robot_file_is_one_line_from_validate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], robot: str, files: dict[str, str], expected: str
) -> None:
    f = tmp_path / "robot.toml"
    f.write_text(robot)
    _beside(tmp_path)
    for name, text in files.items():
        if text.startswith("Z1:"):  # the installed Z1's URDF copied beside the file, a package renamed
            old, new = text[3:].split("=")
            text = Path(_z1_urdf()).read_text().replace(old, new)
        (tmp_path / name).write_text(text)
    (tmp_path / "s.toml").write_text(SCENARIO)
    assert main(["validate", str(tmp_path / "s.toml")]) == 2
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and "Traceback" not in out and "_joined" not in out and "_model" not in out, out
    assert f"robot: bad robot file: {f}: {expected}" in out, out


def test_a_link_is_looked_up_by_name_and_type() -> None:
    """The Z1's URDF names a fixed joint as its child link: by bare name Pinocchio finds two frames."""
    import pinocchio as pin

    from pickdemo.robot.kinematics import frame_id, link_frame_id

    model = pin.buildModelFromUrdf(str(_z1_urdf()))
    with pytest.raises(ValueError, match="Several frames match"):
        model.getFrameId("gripperStator")
    assert model.frames[link_frame_id(model, "gripperStator")].type == pin.FrameType.BODY
    assert model.frames[frame_id(model, "gripperStator")].type == pin.FrameType.BODY
    with pytest.raises(KeyError):
        link_frame_id(model, "jointGripper")  # (a joint, not a link)
