"""Robot files: the shipped Panda's reads as the robot it was, and a bad file is one line naming the
file and the key (missing URDF, unknown joint or frame, a limit that is not positive, a gripper whose
stroke cannot hold anything, ...)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pickdemo.robot import robot_named, shipped_robots
from pickdemo.robot.robot_file import ROBOTS_DIR, RobotFileError, load_robot_file

PANDA_FILE = (ROBOTS_DIR / "panda.toml").read_text()
UR5_FILE = (ROBOTS_DIR / "ur5_franka_hand.toml").read_text()
SO101_FILE = (ROBOTS_DIR / "so101.toml").read_text()
#: (its tool's URDF by its absolute path: the bad files are written elsewhere)
SUCTION_FILE = (
    (ROBOTS_DIR / "ur5_suction.toml").read_text().replace('urdf = "ur5_suction/', f'urdf = "{ROBOTS_DIR}/ur5_suction/')
)


def test_the_panda_ships_as_a_file_and_is_the_default() -> None:
    assert "panda" in shipped_robots()
    r = robot_named()
    assert r is robot_named("panda")  # (one description per name: kinematics are cached by identity)
    assert r.dof == 7 and r.arm_joints[0] == "panda_joint1" and r.tcp_frame == "panda_hand_tcp"
    assert r.gripper.max_opening_m == pytest.approx(0.08) and r.gripper.max_force_n == 70.0
    assert np.allclose(r.limits.max_velocity_rad_s, [2.175] * 4 + [2.61] * 3)
    assert r.files().urdf.is_file() and r.render_urdf().is_file()
    assert "package://" not in r.render_urdf().read_text()  # (the meshes by absolute path)


def test_a_robot_file_anywhere_is_a_robot_by_its_path(tmp_path: Path) -> None:
    f = tmp_path / "my_panda.toml"
    f.write_text(PANDA_FILE.replace('name = "panda"', 'name = "my_panda"'))
    r = robot_named(str(f))
    assert r.name == "my_panda" and r.dof == 7
    with pytest.raises(KeyError, match="no robot named 'ur3'; known: panda"):
        robot_named("ur3")


def test_the_ur5_is_an_arm_and_a_hand_joined_at_its_flange() -> None:
    r = robot_named("ur5_franka_hand")
    assert r.dof == 6 and r.label == "UR5" and r.tcp_frame == "panda_hand_tcp"
    text = r.files().urdf.read_text()
    for name in ("shoulder_pan_joint", "wrist_3_joint", "flange_to_hand", "panda_finger_joint2", "panda_hand_tcp"):
        assert f'name="{name}"' in text, name
    assert "panda_joint1" not in text  # (only the hand is taken from the Panda's URDF)
    assert "package://" not in text and "package://" not in r.render_urdf().read_text()


def test_the_ur5_with_a_suction_cup_is_a_tool_on_its_flange() -> None:
    r = robot_named("ur5_suction")
    g = r.gripper
    assert r.dof == 6 and g.suction and g.cup is not None and not g.coupled and not r.grasps_any_side
    assert g.cup.holding_force_n == pytest.approx(12.06, abs=0.01)  # 60 kPa on a 16 mm cup
    assert g.finger_joints == ("suction_bellows",) and g.finger_links == ("suction_cup",)
    assert list(g.fingers_of([0.004])) == [0.0, 0.0]  # (no fingers: a bellows pressed is no opening)


def test_the_so101_has_a_jaw_and_a_tcp_of_its_own() -> None:
    r = robot_named("so101")
    g = r.gripper
    assert r.dof == 5 and g.kind == "jaw" and not g.coupled and g.finger_joints == ("gripper",)
    assert 'name="so101_tcp"' in r.files().urdf.read_text()
    render = r.render_urdf().read_text()
    assert "moving_jaw_vhacd.obj" in render and "wrist_roll_follower_vhacd.obj" in render  # (the sim's jaws)
    # the jaw's angle and its opening, both ways; its force at the lever
    for finger in (0.0, 0.005, 0.0125, 0.02, g.finger_max_m):
        (angle,) = g.joint_targets(finger)
        assert g.fingers_of([angle]) == pytest.approx([finger, finger], abs=1e-9)
    assert g.joint_force(10.0) == pytest.approx(10.0 * g.jaw_lever_m)
    # the TCP (the fixed jaw's face) beside the object, towards its own side
    assert g.tcp_offset_m(0.025) == pytest.approx(-(0.0125 + g.jaw_clearance_m))
    assert robot_named("panda").gripper.tcp_offset_m(0.025) == 0.0


def test_the_so101_records_as_lerobots_own_follower_does() -> None:
    """Its file's ``[lerobot]``: LeRobot 0.4.4's SO follower (robots/so_follower): six ``<motor>.pos``, the
    arm's in degrees, the gripper 0 to 100; its recorder's robot_type; front and wrist cameras, 640 x 480, AV1."""
    lr = robot_named("so101").lerobot
    assert lr is not None and lr.robot_type == "so_follower"
    motors = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]
    assert [c.name for c in lr.channels] == [f"{m}.pos" for m in motors]
    assert [c.unit for c in lr.channels] == ["degrees"] * 5 + ["range_0_100"]
    assert (lr.channels[-1].low, lr.channels[-1].high) == (-0.174533, 1.74533)  # the URDF's range of the jaw
    assert dict(lr.cameras) == {"camera": "front", "wrist_camera": "wrist"} and lr.image_size == (640, 480)
    assert lr.video_codec == "av1" and robot_named("panda").lerobot is None


def _edit(old: str, new: str, text: str = PANDA_FILE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


BAD = [
    (
        "missing URDF",
        _edit('urdf = "example-robot-data:panda_description/urdf/panda.urdf"', 'urdf = "nowhere.urdf"'),
        "arm.urdf: no such file",
    ),
    (
        "URDF not in the package",
        _edit("panda_description/urdf/panda.urdf", "panda_description/urdf/pandaX.urdf"),
        "arm.urdf: panda_description/urdf/pandaX.urdf is not in the installed example-robot-data",
    ),
    ("unknown arm joint", _edit('"panda_joint7"]', '"panda_joint9"]'), "arm.joints[6]: 'panda_joint9' is not a joint"),
    (
        "a fixed joint in the arm",
        _edit('"panda_joint7"]', '"panda_hand_joint"]'),
        "arm.joints[6]: 'panda_hand_joint' is not a moving joint",
    ),
    (
        "unknown TCP frame",
        _edit('tcp_frame = "panda_hand_tcp"', 'tcp_frame = "tool0"'),
        "arm.tcp_frame: 'tool0' is not a link",
    ),
    (
        "unknown finger link",
        _edit('"panda_rightfinger"]', '"right_pad"]'),
        "gripper.finger_links[1]: 'right_pad' is not a link",
    ),
    (
        "unknown finger joint",
        _edit('"panda_finger_joint2"]', '"finger2"]'),
        "gripper.finger_joints[1]: 'finger2' is not a joint",
    ),
    (
        "velocity not positive",
        _edit("velocity = [2.175,", "velocity = [0.0,"),
        "limits.velocity.0: Input should be greater than 0",
    ),
    ("jerk negative", _edit("jerk = [7500.0,", "jerk = [-7500.0,"), "limits.jerk.0: Input should be greater than 0"),
    (
        "a limit short of a joint",
        _edit("effort = [87.0, 87.0,", "effort = [87.0,"),
        "limits.effort: 6 values for 7 joints",
    ),
    (
        "min above max",
        _edit("position_min = [-2.8973,", "position_min = [2.9,"),
        "limits.position_min[0]: 2.9 is not below position_max's 2.8973",
    ),
    (
        "home outside the limits",
        _edit("home = [0.0,", "home = [3.0,"),
        "arm.home[0]: 3.0 is outside the joint's limits",
    ),
    (
        "a stroke that holds nothing",
        _edit("finger_max_m = 0.04", "finger_max_m = 0.004"),
        "gripper.finger_max_m: the hand opens 8.0 mm in all: it cannot hold anything",
    ),
    (
        "a gripper kind not known",
        _edit('kind = "parallel"', 'kind = "vacuum"'),
        "gripper.kind: 'vacuum' is not one of parallel, jaw, suction",
    ),
    (
        "a suction gripper with fingers' keys",
        _edit('kind = "parallel"', 'kind = "suction"'),
        "gripper.finger_joints: unknown key",
    ),
    ("a misspelt key", _edit("payload_kg = 3.0", "payload = 3.0"), "arm.payload: unknown key"),
    (
        "a number as text",
        _edit("speed_m_s = 0.1", 'speed_m_s = "0.1"'),
        "gripper.speed_m_s: Input should be a valid number",
    ),
    (
        "opening harder than it may squeeze",
        _edit("open_force_n = 20.0", "open_force_n = 90.0"),
        "gripper.open_force_n: 90.0 N is more than max_force_n's 70.0 N",
    ),
    ("not TOML", "name = panda\n", "invalid TOML"),
    (
        "a hand bolted to a link the arm does not have",
        _edit('flange_link = "tool0"', 'flange_link = "tool9"', UR5_FILE),
        "hand.flange_link: 'tool9' is not a link of ur5_robot.urdf",
    ),
    (
        "a hand whose first link is not in its URDF",
        _edit('root_link = "panda_hand"', 'root_link = "robotiq_base"', UR5_FILE),
        "hand.root_link: 'robotiq_base' is not a link of panda.urdf",
    ),
    (
        "a hand joined by a joint the arm has already",
        _edit('\njoint = "flange_to_hand"', '\njoint = "wrist_3_joint"', UR5_FILE),
        "hand.joint: 'wrist_3_joint' is a joint of ur5_robot.urdf already",
    ),
    (
        "a hand's URDF that is missing",
        _edit('urdf = "example-robot-data:panda_description/urdf/panda.urdf"', 'urdf = "hand.urdf"', UR5_FILE),
        "hand.urdf: no such file",
    ),
    ("a flange offset of two numbers", _edit("xyz = [0.0, 0.0, 0.0]", "xyz = [0.0, 0.0]", UR5_FILE), "hand.xyz"),
    (
        "a jaw of two joints",
        _edit('finger_joints = ["gripper"]', 'finger_joints = ["gripper", "gripper"]', SO101_FILE),
        "gripper.finger_joints: a jaw gripper has one revolute finger joint",
    ),
    (
        "a jaw's table that does not rise",
        _edit("[0.0907, 0.020]", "[0.0907, 0.012]", SO101_FILE),
        "gripper.jaw_table: the opening must rise, or fall, with the angle at every row",
    ),
    (
        "a jaw that opens less than the gripper says",
        _edit("finger_max_m = 0.0225", "finger_max_m = 0.03", SO101_FILE),
        "gripper.jaw_table: it reaches 55.0 mm; the gripper opens 60.0",
    ),
    (
        "a jaw without its lever",
        _edit("jaw_lever_m = 0.065\n", "", SO101_FILE),
        "gripper.jaw_lever_m: missing",
    ),
    (
        "a frame on a link the URDF does not have",
        _edit('parent = "gripper_frame_link"', 'parent = "jaw_link"', SO101_FILE),
        "arm.frames[0].parent: 'jaw_link' is not a link of so101.urdf",
    ),
    (
        "a collision mesh that is not there",
        _edit('"so101/collision/base_motor_holder_so101_v1.stl"', '"so101/missing.stl"', SO101_FILE),
        "arm.collision_meshes.base_motor_holder_so101_v1.stl: no such file",
    ),
    (
        "a grasp harder than the gripper can squeeze",
        _edit("grip_force_n = 5.0", "grip_force_n = 50.0", SO101_FILE),
        "gripper.grip_force_n: 50.0 N is more than max_force_n's 40.0 N",
    ),
    (
        "a cup wider than its tool",
        _edit("cup_diameter_m = 0.016", "cup_diameter_m = 0.03", SUCTION_FILE),
        "gripper.cup_diameter_m: a 30.0 mm cup is wider than its tool: the link 'suction_cup' is 16.0 mm across",
    ),
    (
        "a vacuum that cannot hold the payload",
        _edit("payload_kg = 0.6", "payload_kg = 1.0", SUCTION_FILE),
        "gripper.vacuum_kpa: the cup holds 12.1 N at 60 kPa; arm.payload_kg 1 asks for 19.6 N",
    ),
    (
        "a bellows stroke past its joint's travel",
        _edit("bellows_stroke_m = 0.008", "bellows_stroke_m = 0.02", SUCTION_FILE),
        "gripper.bellows_stroke_m: 20.0 mm is more than the bellows joint 'suction_bellows' travels",
    ),
    (
        "a bellows that is not a prismatic joint",
        _edit('bellows_joint = "suction_bellows"', 'bellows_joint = "wrist_3_joint"', SUCTION_FILE),
        "gripper.bellows_joint: 'wrist_3_joint' is revolute",
    ),
    (
        "a tool speed past the bound",
        _edit("free_m_s = 0.6", "free_m_s = 3.0", SUCTION_FILE),
        "speeds.free_m_s",
    ),
    (
        "a follower's channel on no joint of the arm",
        _edit('motor = "wrist_roll", joint = "wrist_roll"', 'motor = "wrist_roll", joint = "wrist_yaw"', SO101_FILE),
        "lerobot.channels[4].joint: 'wrist_yaw' is none of the arm's joints or a jaw's finger joint",
    ),
    (
        "a follower without one of the arm's joints",
        _edit('    { motor = "elbow_flex", joint = "elbow_flex", unit = "degrees" },\n', "", SO101_FILE),
        "lerobot.channels: each arm joint once (a follower's action drives them all); missing: elbow_flex",
    ),
    (
        "a follower's jaw in degrees",
        _edit('joint = "gripper", unit = "range_0_100"', 'joint = "gripper", unit = "degrees"', SO101_FILE),
        "lerobot.channels[5].unit: degrees for an arm joint, range_0_100 for the jaw",
    ),
    (
        "a follower's camera no scenario has",
        _edit('cameras = { camera = "front"', 'cameras = { top = "front"', SO101_FILE),
        "lerobot.cameras.top: not a scenario's camera (camera, wrist_camera)",
    ),
    (
        "a follower's codec nobody writes",
        _edit('video_codec = "av1"', 'video_codec = "vp9"', SO101_FILE),
        "lerobot.video_codec",
    ),
    (
        "pads without friction",
        _edit("pad_friction = 0.5", "pad_friction = 0.0", SO101_FILE),
        "gripper.pad_friction",
    ),
]


@pytest.mark.parametrize(("text", "expected"), [(t, e) for _, t, e in BAD], ids=[n for n, _, _ in BAD])
def test_a_bad_robot_file_is_one_line_naming_the_file_and_key(tmp_path: Path, text: str, expected: str) -> None:
    f = tmp_path / "robot.toml"
    f.write_text(text)
    with pytest.raises(RobotFileError) as err:
        load_robot_file(f)
    message = str(err.value)
    assert message.startswith(f"{f}: ") and "\n" not in message and expected in message, message


def test_a_missing_robot_file_is_one_line(tmp_path: Path) -> None:
    with pytest.raises(RobotFileError, match="no such robot file"):
        load_robot_file(tmp_path / "none.toml")
