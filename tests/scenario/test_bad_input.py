"""Bad input gets a clear answer, every time: exit 2 and one line naming the file and the key (or the
argument), before any simulation starts; never a traceback, a hang or an accepted nonsense."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from pickdemo.apps.cli import main
from pickdemo.core.meshes import pybullet_data_dir

GOOD = """name = "t"
description = "a good scenario"
[camera]
position = [1.1, 0.0, 0.75]
look_at = [0.5, 0.0, 0.0]
width = 640
[[objects]]
name = "cube"
shape = "box"
size = [0.05, 0.05, 0.05]
color = [0.85, 0.1, 0.1]
mass = 0.1
position_range = [[0.45, 0.55], [-0.05, 0.05]]
target = true
[place]
position = [0.45, 0.3]
[success]
lift_height = 0.05
[sim]
max_sim_time_s = 60.0
time_step_s = 0.004166666666666667
[motion]
velocity_scale = 1.0
[control]
max_attempts = 3
"""

#: The fixtures the motion scenarios ship (a wall, a cubby).
FIXTURES = Path(__file__).resolve().parents[2] / "assets" / "fixtures"

SECOND = '\n[[objects]]\nname = "other"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.1, 0.1, 0.9]\n'


TRAY = '[place]\ntray = "pybullet_data:tray/traybox.urdf"\ntray_scale = 0.5\nposition = [0.4, 0.4]\n'
CLEAR = (
    'name = "c"\ntask = "clear"\n[clear]\nlayout = "packed"\nregion = [[0.4, 0.65], [-0.2, 0.12]]\ncount = 5\n'
    'objects_from = "pybullet_data:random_urdfs/??0/*.urdf"\nscale_range = [0.5, 0.5]\n' + TRAY
)

#: An object listed in a clear round (it joins the round), in the region, clear of the tray.
BRICK = (
    '\n[[objects]]\nname = "brick"\nshape = "box"\nsize = {size}\ncolor = [0.8, 0.5, 0.2]\nmass = {mass}\n'
    "position = [0.55, -0.05]\n"
)


def _clear(old: str, new: str) -> str:
    assert old in CLEAR, old
    return CLEAR.replace(old, new, 1)


def _bin(fields: str, name: str = "bin") -> str:
    """A ``[[fixtures]]`` bin with ``fields`` (its position at least; inner size 0.2 x 0.2 m unless given)."""
    size = "" if "inner_size" in fields else "\ninner_size = [0.2, 0.2]"
    return f'\n[[fixtures]]\nkind = "bin"\nname = "{name}"\n{fields}{size}\n'


def _model(fields: str, name: str = "shelf") -> str:
    """A ``[[fixtures]]`` model with ``fields`` (the shelf at ``position`` unless a file is given)."""
    file = "" if "file" in fields else '\nfile = "pybullet_data:kiva_shelf/model.sdf"'
    return f'\n[[fixtures]]\nkind = "model"\nname = "{name}"\n{fields}{file}\n'


def _edit(old: str, new: str) -> str:
    assert old in GOOD, old
    return GOOD.replace(old, new, 1)


# (id, file text, what the one line must say)
FILE_CASES: list[tuple[str, str, str]] = [
    # ---- the schema: no NaN or inf, no coercion, bounds, names
    (
        "nan in a range",
        _edit("[[0.45, 0.55]", "[[nan, 0.55]"),
        "objects.cube.position_range[0][0]: Input should be a finite number",
    ),
    (
        "inf budget",
        _edit("max_sim_time_s = 60.0", "max_sim_time_s = inf"),
        "sim.max_sim_time_s: Input should be a finite",
    ),
    ("inf far plane", _edit("width = 640", "width = 640\nfar_m = inf"), "camera.far_m: Input should be a finite"),
    ("nan size", _edit("size = [0.05, 0.05, 0.05]", "size = [0.05, nan, 0.05]"), "size[1]: Input should be a finite"),
    ("string mass", _edit("mass = 0.1", 'mass = "0.1"'), "mass: Input should be a valid number, got str '0.1'"),
    ("boolean mass", _edit("mass = 0.1", "mass = true"), "mass: Input should be a valid number, got bool True"),
    ("integer target", _edit("target = true", "target = 1"), "target: Input should be a valid boolean, got int 1"),
    ("string width", _edit("width = 640", 'width = "640"'), "camera.width: Input should be a valid integer, got str"),
    (
        "float width",
        _edit("width = 640", "width = 640.5"),
        "camera.width: Input should be a valid integer, got float 640.5 (a whole number: write 640, not 640.5)",
    ),
    (
        "tiny time step",
        _edit("time_step_s = 0.004166666666666667", "time_step_s = 1e-7"),
        "sim.time_step_s: Input should be greater than or equal to 0.001",
    ),
    (
        "huge time step",
        _edit("time_step_s = 0.004166666666666667", "time_step_s = 0.1"),
        "sim.time_step_s: Input should be less than or equal",
    ),
    (
        "tiny velocity scale",
        _edit("velocity_scale = 1.0", "velocity_scale = 1e-6"),
        "motion.velocity_scale: Input should be greater than or equal to 0.05",
    ),
    (
        "long budget",
        _edit("max_sim_time_s = 60.0", "max_sim_time_s = 1e9"),
        "sim.max_sim_time_s: Input should be less than or equal to 600",
    ),
    (
        "negative size",
        _edit("size = [0.05, 0.05, 0.05]", "size = [0.05, -0.05, 0.05]"),
        "size[1]: Input should be greater than or equal to 0.001",
    ),
    (
        "huge size",
        _edit("size = [0.05, 0.05, 0.05]", "size = [0.05, 0.05, 3.0]"),
        "size[2]: Input should be less than or equal to 0.5",
    ),
    ("two sizes for a box", _edit("size = [0.05, 0.05, 0.05]", "size = [0.05, 0.05]"), "a box needs 3 values"),
    ("huge mass", _edit("mass = 0.1", "mass = 100.0"), "mass: Input should be less than or equal to 20"),
    (
        "zero attempts",
        _edit("max_attempts = 3", "max_attempts = 0"),
        "control.max_attempts: Input should be greater than or equal to 1",
    ),
    ("far before near", _edit("width = 640", "width = 640\nnear_m = 0.5\nfar_m = 0.3"), "far_m must exceed near_m"),
    ("reversed range", _edit("[[0.45, 0.55]", "[[0.55, 0.45]"), "position_range bounds must be [min, max]"),
    ("reserved name", _edit('name = "cube"', 'name = "robot"'), "'robot' is reserved"),
    (
        "control characters in a name",
        _edit('name = "cube"', 'name = "cu\\u001b[31mbe"'),
        "name: String should match pattern",
    ),
    ("empty name", _edit('name = "cube"', 'name = ""'), "name: String should match pattern"),
    (
        "control characters in the description",
        _edit('description = "a good scenario"', 'description = "bad\\u0007"'),
        "description: control characters are not allowed",
    ),
    (
        "misspelt colour",
        _edit("color = [0.85, 0.1, 0.1]", "colour = [0.85, 0.1, 0.1]"),
        "objects.cube.colour: unknown key (did you mean 'color'?)",
    ),
    ("misspelt table", "[cammera]\nwidth = 640\n" + GOOD, "cammera: unknown key (did you mean 'camera'?)"),
    (
        "unknown key, nothing close",
        _edit("mass = 0.1", "mass = 0.1\nflavour = 3"),
        "objects.cube.flavour: unknown key (valid keys:",
    ),
    (
        "two targets",
        GOOD + SECOND + "position = [0.5, -0.2]\ntarget = true\n",
        "a pick needs exactly one object with target = true; 2 have it (cube, other)",
    ),
    ("no target", _edit("target = true", "target = false"), "one object must have target = true"),
    ("static target", _edit("target = true", "target = true\nstatic = true"), "the target of a pick cannot be static"),
    ("tilted, not static", _edit("target = true", "target = true\npitch_deg = 10.0"), "needs static = true"),
    (
        "a camera low behind the base",
        _edit("position = [1.1, 0.0, 0.75]", "position = [-0.5, 0.0, 0.3]"),
        "camera: objects.cube may stand at (0.45, -0.05) m, where the robot's base hides it",
    ),
    (
        "a mesh told by its size beside an object as large",
        _edit(
            'shape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.85, 0.1, 0.1]',
            'shape = "mesh"\nurdf = "pybullet_data:objects/mug.urdf"\nscale = 0.8\nrough_size_m = [0.08, 0.095, 0.065]',
        )
        + SECOND.replace('shape = "box"\nsize = [0.05, 0.05, 0.05]', 'shape = "cylinder"\nsize = [0.066, 0.085]')
        + "position = [0.5, -0.2]\n",
        "objects.other: about as large as the target objects.cube",
    ),
    (
        "a mesh told nothing beside another object",
        _edit(
            'shape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.85, 0.1, 0.1]',
            'shape = "mesh"\nurdf = "pybullet_data:objects/mug.urdf"\nscale = 0.8',
        )
        + SECOND
        + "position = [0.5, -0.2]\n",
        "objects.cube: the robot is told nothing of this target (not its shape, size or colour), so it cannot tell "
        "it from objects.other; state its rough size",
    ),
    (
        "a rough size the target never has",
        _edit(
            'shape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.85, 0.1, 0.1]',
            'shape = "mesh"\nurdf = "pybullet_data:objects/mug.urdf"\nscale = 0.8\nrough_size_m = [0.05, 0.095, 0.065]',
        ),
        "objects.cube.rough_size_m: the target stands 80 mm tall, not within 10 mm of the 50 mm stated",
    ),
    (
        "a rough size for a box",
        _edit("target = true", "target = true\nrough_size_m = [0.05, 0.05, 0.05]"),
        "objects.cube: rough_size_m is for a target nobody described (a mesh, a cylinder lying): a box's shape",
    ),
    (
        "a rough size with the shorter side first",
        _edit(
            'shape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.85, 0.1, 0.1]',
            'shape = "mesh"\nurdf = "pybullet_data:objects/mug.urdf"\nscale = 0.8\nrough_size_m = [0.08, 0.065, 0.095]',
        ),
        "rough_size_m is [height, longer side, shorter side]: the longer side first",
    ),
    (
        "duplicate names",
        GOOD + SECOND.replace('"other"', '"cube"') + "position = [0.5, -0.2]\n",
        "object names must be unique",
    ),
    (
        "an array for a table",
        "success = [1, 2]\n" + _edit("[success]\nlift_height = 0.05\n", ""),
        "success: Input should be a valid dictionary",
    ),
    # ---- geometry: what cannot succeed is refused before it runs
    (
        "off the table",
        _edit("position_range = [[0.45, 0.55], [-0.05, 0.05]]", "position = [1.3, 0.0]"),
        "objects.cube: at (1.300, 0.000) m its footprint (35 mm radius) is off the table",
    ),
    (
        "inside the robot",
        _edit("position_range = [[0.45, 0.55], [-0.05, 0.05]]", "position = [0.05, 0.0]"),
        "objects.cube: at (0.050, 0.000) m it stands inside the robot's base",
    ),
    (
        "sunk into the table",
        _edit("position_range = [[0.45, 0.55], [-0.05, 0.05]]", "position = [0.5, 0.0, 0.0]"),
        "sinks it into the table",
    ),
    (
        "overlapping at fixed positions",
        _edit("position_range = [[0.45, 0.55], [-0.05, 0.05]]", "position = [0.5, 0.0]")
        + SECOND
        + "position = [0.52, 0.01]\n",
        "objects.other: overlaps objects.cube",
    ),
    (
        "lift higher than carried",
        _edit("lift_height = 0.05", "lift_height = 0.2"),
        "success.lift_height: 0.200 m; the arm lifts the target 0.120 m",
    ),
    (
        "place out of reach",
        _edit("position = [0.45, 0.3]\n[success]", "position = [1.0, 0.55]\n[success]")
        + "[table]\nsize = [2.4, 1.2]\n",
        "place.position: out of the arm's reach",
    ),
    (
        "place off the table",
        _edit("position = [0.45, 0.3]\n[success]", "position = [0.45, 0.9]\n[success]"),
        "place.position: (0.450, 0.900) m is off the table",
    ),
    (
        "pick region out of reach",
        _edit("[[0.45, 0.55], [-0.05, 0.05]]", "[[0.95, 1.05], [-0.05, 0.05]]") + "[table]\nsize = [2.4, 1.2]\n",
        "out of the arm's reach",
    ),
    (
        "camera under the table",
        _edit("position = [1.1, 0.0, 0.75]", "position = [1.1, 0.0, -0.2]"),
        "camera.position: z = -0.200 m; the camera must be above the table",
    ),
    (
        "target out of view",
        _edit("look_at = [0.5, 0.0, 0.0]", "look_at = [0.5, 0.6, 0.0]"),
        "camera: objects.cube can stand out of the camera's view",
    ),
    (
        "too wide for the gripper",
        _edit("size = [0.05, 0.05, 0.05]", "size = [0.077, 0.09, 0.05]"),
        "its narrower side is 77 mm; the gripper opens to 80 mm and needs 5 mm of clearance, so at most 75 mm",
    ),
    ("too heavy", _edit("mass = 0.1", "mass = 5.0"), "objects.cube.mass: 5.0 kg is more than the Panda carries"),
    (
        "impossible layout",
        _edit("[[0.45, 0.55], [-0.05, 0.05]]", "[[0.49, 0.51], [-0.01, 0.01]]")
        + SECOND
        + "position_range = [[0.49, 0.51], [-0.01, 0.01]]\n",
        "layout (seed 0): objects.other: no free spot found",
    ),
    ("empty file", "", "name: Field required; place: Field required"),
    ("no objects", _edit(GOOD[GOOD.index("[[objects]]") : GOOD.index("[place]")], ""), "at least one object is needed"),
    (
        "misspelt colour and a bad mass: both said",
        _edit("color = [0.85, 0.1, 0.1]", "colour = [0.85, 0.1, 0.1]").replace("mass = 0.1", 'mass = "0.1"'),
        "objects.cube.colour: unknown key (did you mean 'color'?); objects.cube.mass: Input should be a valid number",
    ),
    (
        "many problems: the first said, the rest named",
        _edit("mass = 0.1", "mass = 0.1\nflavour = 1\nsmell = 2\ntaste = 3\nsound = 4\nmood = 5"),
        "objects.cube.smell: unknown key; objects.cube.taste: unknown key; 2 more at objects.cube.sound, "
        "objects.cube.mood",
    ),
    (
        "an unnamed object is named by its index",
        _edit('name = "cube"', 'name = "a cube"'),
        "objects[0].name: String should match pattern",
    ),
    (
        "a list without names: indices",
        GOOD + "[[disturbances]]\nat_time_s = -1.0\noffset_m = [0.05, 0.0]\n",
        "disturbances[0].at_time_s: Input should be greater than or equal to 0",
    ),
    (
        "a push of an object the scene does not have",
        GOOD + '[[disturbances]]\nat_time_s = 0.5\noffset_m = [0.05, 0.0]\nobject = "post"\n',
        "disturbances[0].object: 'post' is not one of the objects",
    ),
    ("invalid TOML", GOOD + "\n[[objects]\n", "invalid TOML"),
    # ---- a clear round
    (
        "clear: a listed object too wide for the gripper",
        CLEAR + BRICK.format(size="[0.077, 0.09, 0.05]", mass=0.1),
        "objects.brick.size: its narrower side is 77 mm; the gripper opens to 80 mm and needs 5 mm of clearance, "
        "so at most 75 mm",
    ),
    (
        "clear: a listed object too heavy",
        CLEAR + BRICK.format(size="[0.05, 0.05, 0.05]", mass=5.0),
        "objects.brick.mass: 5.0 kg is more than the Panda carries",
    ),
    ("clear: count 0", _clear("count = 5", "count = 0"), "clear.count: Input should be greater than or equal to 1"),
    ("clear: count 21", _clear("count = 5", "count = 21"), "clear.count: Input should be less than or equal to 20"),
    (
        "clear: more than the table holds",
        _clear("count = 5", "count = 20").replace("scale_range = [0.5, 0.5]", "scale_range = [40.0, 40.0]"),
        "clear.count: 20 objects of at least",
    ),
    (
        "clear: packed beyond its region",
        _clear("count = 5", "count = 20"),
        "layout (seed 0): clear.region: no room for 20 objects packed 10 mm apart",
    ),
    (
        "clear: a pile that cannot be laid out",
        _clear("count = 5", "count = 20")
        .replace('layout = "packed"', 'layout = "pile"')
        .replace("[[0.4, 0.65], [-0.2, 0.12]]", "[[0.5, 0.51], [0.0, 0.01]]"),
        "clear.region: a pile of 20 objects",
    ),
    ("clear: an unknown layout", _clear('"packed"', '"heap"'), "clear.layout: Input should be 'pile' or 'packed'"),
    ("clear: no [clear]", _clear("[clear]", "[other]").split("[other]")[0] + TRAY, "clear: a clear round"),
    ("clear: no tray", _clear(TRAY, "[place]\nposition = [0.4, 0.4]\n"), "place.tray: a clear round"),
    (
        "clear: a tray off the table",
        _clear("[0.4, 0.4]", "[0.4, 0.55]"),
        "place.position: the tray (300 x 300 mm) reaches off",
    ),
    (
        "clear: a tray out of reach",
        _clear("[0.4, 0.4]", "[1.05, 0.45]").replace("tray_scale = 0.5", "tray_scale = 0.2"),
        "the tray's drop spot (1.05, 0.45): out of the arm's reach",
    ),
    (
        "clear: a tray on the region",
        _clear("[0.4, 0.4]", "[0.5, 0.0]"),
        "place.position: the tray overlaps clear.region",
    ),
    ("robot: an unknown name", 'robot = "kuka_iiwa"\n' + GOOD, "robot: no robot named 'kuka_iiwa'; known: panda"),
    ("robot: a robot file that is not there", 'robot = "nowhere/arm.toml"\n' + GOOD, "arm.toml: no such robot file"),
    ("robot: not a name", "robot = 7\n" + GOOD, "robot: Input should be a valid string, got int 7"),
    (
        "wrist camera: a mount that is not a link of the hand",
        GOOD + '[wrist_camera]\nmount = "panda_leftfinger"\n',
        "wrist_camera.mount: 'panda_leftfinger' is not a link of the Panda's hand",
    ),
    ("wrist camera: no field of view", GOOD + "[wrist_camera]\nfov_deg = [0.0, 58.0]\n", "wrist_camera.fov_deg[0]"),
    ("wrist camera: a half sphere", GOOD + "[wrist_camera]\nfov_deg = [87.0, 180.0]\n", "wrist_camera.fov_deg[1]"),
    ("wrist camera: NaN", GOOD + "[wrist_camera]\nposition = [nan, 0.0, 0.04]\n", "wrist_camera.position[0]"),
    ("wrist camera: an unknown sensor", GOOD + '[wrist_camera]\nsensor = "zed2"\n', "wrist_camera.sensor"),
    (
        "wrist camera: looking at itself",
        GOOD + "[wrist_camera]\nposition = [0.0, 0.0, 0.1]\nlook_at = [0.0, 0.0, 0.1]\n",
        "wrist_camera: look_at must differ from position",
    ),
    (
        "wrist camera: an unknown key",
        GOOD + "[wrist_camera]\nhand_eye_errr = [1.0, 0.1]\n",
        "wrist_camera.hand_eye_errr: unknown key (did you mean 'hand_eye_error'?)",
    ),
    (
        "a place taken by another object",
        GOOD + '[[objects]]\nname = "box"\nshape = "box"\nsize = [0.06, 0.04, 0.08]\ncolor = [0.1, 0.1, 0.9]\n'
        "position = [0.47, 0.31]\n",
        "place.position: (0.450, 0.300) m is taken: objects.box stands there",
    ),
    (
        "a twin of the target",
        GOOD + '[[objects]]\nname = "twin"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [0.87, 0.1, 0.1]\n'
        "position = [0.6, -0.2]\n",
        "objects.twin: looks the same as the target objects.cube",
    ),
    (
        "beside an object not named before it",
        GOOD + '[[objects]]\nname = "carton"\nshape = "box"\nsize = [0.06, 0.1, 0.07]\ncolor = [0.2, 0.3, 0.8]\n'
        'beside = { object = "crate" }\n',
        "objects.carton.beside.object: 'crate' is not an object named before it",
    ),
    (
        "beside and a position both",
        GOOD + '[[objects]]\nname = "carton"\nshape = "box"\nsize = [0.06, 0.1, 0.07]\ncolor = [0.2, 0.3, 0.8]\n'
        'position = [0.6, 0.1]\nbeside = { object = "cube" }\n',
        "give exactly one of position, position_range, beside",
    ),
    (
        "clear: a region off the table",
        _clear("[-0.2, 0.12]", "[-0.2, 0.72]"),
        "clear.region: its corner (0.400, 0.720) m is off the table",
    ),
    (
        "clear: no files",
        _clear("??0/*.urdf", "zz*/*.urdf"),
        "clear.objects_from: 'pybullet_data:random_urdfs/zz*/*.urdf' matches no file",
    ),
    (
        "clear: a target",
        _clear(
            "[place]",
            '[[objects]]\nname = "c"\nshape = "box"\nsize = [0.05, 0.05, 0.05]\ncolor = [1.0, 0.0, 0.0]\n'
            "position = [0.6, 0.25]\ntarget = true\n[place]",
        ),
        "objects: target = true is for a pick",
    ),
    (
        "bin: off the table",
        GOOD + _bin("position = [1.05, 0.0]"),
        "fixtures.bin.position: the bin at (1.050, 0.000) reaches past the table's edge",
    ),
    (
        "bin: on the robot's base",
        GOOD + _bin("position = [0.1, 0.0]"),
        "fixtures.bin.position: the bin at (0.100, 0.000) stands on the robot's base",
    ),
    (
        "bin: overlapping another",
        GOOD + _bin("position = [0.5, -0.3]") + _bin("position = [0.6, -0.3]", name="bin2"),
        "fixtures.bin2.position: the bin at (0.600, -0.300) overlaps fixtures.bin",
    ),
    (
        "bin: overlapping the tray",
        _clear("[place]", _bin("position = [0.4, 0.3]") + "[place]"),
        "overlaps the tray (place.tray)",
    ),
    (
        "bin: out of reach",
        GOOD + _bin("position = [1.0, -0.45]\ninner_size = [0.15, 0.15]"),
        "fixtures.bin: its floor at",
    ),
    (
        "bin: the place on its wall",
        GOOD + _bin("position = [0.45, 0.4]\ninner_size = [0.15, 0.15]"),
        "place.position: (0.450, 0.300) m is on or against the walls of fixtures.bin",
    ),
    ("bin: too small", GOOD + _bin("position = [0.5, -0.3]\ninner_size = [0.01, 0.2]"), "fixtures.bin.inner_size[0]"),
    (
        "bin: an unknown kind",
        GOOD + _bin("position = [0.5, -0.3]").replace('"bin"', '"crate"', 1),
        "fixtures.bin.kind: 'crate' is not one of",
    ),
    (
        "bin: named as an object",
        GOOD + _bin("position = [0.5, -0.3]", name="cube"),
        "fixtures.cube: an object has that name",
    ),
    (
        "bin: named as a body of the scene",
        GOOD + _bin("position = [0.5, -0.3]", name="table"),
        "'table' is the name of a body of the scene",
    ),
    (
        "model: named as a body of the scene",
        GOOD + _model("position = [0.0, 1.05, -0.75]", name="robot"),
        "'robot' is the name of a body of the scene",
    ),
    (
        "bin: a wall of no height",
        GOOD + _bin("position = [0.5, -0.3]\nwall_height_m = 0.0"),
        "fixtures.bin.wall_height_m",
    ),
    (
        "model: no such file",
        GOOD + _model('position = [0.0, 1.05, -0.75]\nfile = "no_such_shelf.sdf"'),
        "fixtures.shelf.file: ",  # (then the path and "no such file")
    ),
    (
        "model: not XML",
        GOOD + _model('position = [0.0, 1.05, -0.75]\nfile = "pybullet_data:plane.obj"'),
        "not a URDF or SDF file (not XML",
    ),
    (
        "model: a collision mesh",
        GOOD + _model('position = [0.0, 1.05, -0.75]\nfile = "pybullet_data:duck_vhacd.urdf"'),
        "a <mesh> collision geometry; a model fixture is read as boxes",
    ),
    (
        "model: more than one link",
        GOOD + _model('position = [0.0, 1.05, -0.75]\nfile = "pybullet_data:r2d2.urdf"'),
        "links; a model fixture is one rigid body",
    ),
    ("model: into the table", GOOD + _model("position = [0.0, 0.9, -0.4]"), "reaches into the table"),
    ("model: on the robot's base", GOOD + _model("position = [0.0, 0.3, -0.75]"), "stands on the robot's base"),
    (
        "model: over the place",
        GOOD + _model("position = [0.03, 0.72, 0.0]"),  # a post on the place
        "place.position: (0.450, 0.300) m is inside or against fixtures.shelf",
    ),
    (
        "model: what stands on it out of reach",
        _edit(
            "position_range = [[0.45, 0.55], [-0.05, 0.05]]\ntarget = true",
            "position_range = [[-0.02, 0.02], [1.15, 1.19]]\ntarget = true\nlevel_m = 0.1",
        )
        + _model("position = [0.0, 1.5, -0.75]"),
        "objects.cube at (-0.02, 1.15): out of the arm's reach",
    ),  # fmt: skip
    (
        "model: meets the robot at home",
        GOOD + _model(f'position = [0.31, 0.0, 0.38]\nyaw_deg = 90.0\nfile = "{FIXTURES / "wall.urdf"}"', name="wall"),
        "fixtures.wall.position: the model at (0.310, 0.000) meets the robot's panda_",
    ),
    (
        "model: the target enclosed on every side",
        _edit("position_range = [[0.45, 0.55], [-0.05, 0.05]]", "position_range = [[0.53, 0.58], [-0.04, 0.04]]")
        + _model(f'position = [0.56, 0.0, 0.0]\nfile = "{FIXTURES / "cubby.urdf"}"', name="cubby")
        + _model(f'position = [0.437, 0.0, 0.0]\nyaw_deg = 90.0\nfile = "{FIXTURES / "wall.urdf"}"', name="door"),
        "objects.cube: at (0.555, 0.000) m the fixtures enclose it on every side a hand can come from",
    ),
    (
        "suction: a target under a board, a cup only from above",
        _edit('description = "a good scenario"', 'description = "a good scenario"\nrobot = "ur5_suction"')
        + _model(f'position = [0.5, 0.0, 0.0]\nfile = "{FIXTURES / "cubby.urdf"}"', name="cubby"),
        "takes a part only from above (a suction cup: no grasp from the side)",
    ),
    (
        "suction: a box narrower than the cup",
        _edit("size = [0.05, 0.05, 0.05]", "size = [0.012, 0.05, 0.05]").replace(
            'description = "a good scenario"', 'description = "a good scenario"\nrobot = "ur5_suction"'
        ),
        "objects.cube.size: its narrower side is 12 mm; the UR5 with a suction cup's 16 mm cup seals only on a face",
    ),
    (
        "object: on no fixture's top",
        _edit("target = true", "target = true\nlevel_m = 0.1"),
        "objects.cube.level_m: at (0.450, -0.050) m its footprint (35 mm radius) is not wholly on one top",
    ),
]


@pytest.mark.parametrize(("text", "expected"), [c[1:] for c in FILE_CASES], ids=[c[0] for c in FILE_CASES])
def test_bad_scenario_file(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, expected: str) -> None:
    f = tmp_path / "s.toml"
    f.write_text(text)
    assert main(["run", str(f), "--quiet"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"pickdemo: error: {f}: ") and expected in err, err
    assert err.isascii() and "\x1b" not in err  # nothing raw reaches the terminal


def test_the_good_scenario_validates(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "s.toml"
    f.write_text(GOOD)
    assert main(["validate", str(f), "pick_cube"]) == 0
    assert capsys.readouterr().out.splitlines() == ["ok t", "ok pick_cube"]
    f.write_text(CLEAR)
    assert main(["validate", str(f)]) == 0
    assert capsys.readouterr().out.splitlines() == ["ok c"]


def _bytes_case(tmp_path: Path, name: str, data: bytes) -> Path:
    f = tmp_path / name
    f.write_bytes(data)
    return f


@pytest.mark.parametrize(
    ("make", "expected"),
    [
        (lambda d: _bytes_case(d, "u16.toml", GOOD.encode("utf-16")), "UTF-16 text; TOML files are UTF-8"),
        (lambda d: _bytes_case(d, "bin.toml", bytes(range(256)) * 4), "a binary file, not TOML text"),
        (lambda d: _bytes_case(d, "deep.toml", b"x = " + b"[" * 5000 + b"]" * 5000 + b"\n"), "nested"),
        (lambda d: _bytes_case(d, "big.toml", b"# " + b"x" * (2 << 20) + b"\n"), "a scenario file is at most"),
        (lambda d: d / "missing.toml", "no such scenario file"),
        (lambda d: d, "is a directory, not a scenario file"),
        (lambda d: _bytes_case(d, "notes.txt", GOOD.encode()), "not a .toml file"),
        (lambda d: Path("../../../../etc/passwd"), "not a .toml file"),
        (lambda d: "pick_cub", "unknown scenario (did you mean 'pick_cube'?"),
        (lambda d: "no\x1bscenario", "not a scenario name or path"),
    ],
    ids=[
        "utf-16",
        "binary",
        "deep nesting",
        "too large",
        "missing",
        "directory",
        "not .toml",
        "escaping path",
        "misspelt name",
        "control characters",
    ],  # fmt: skip
)
def test_bad_file_or_name(tmp_path: Path, capsys: pytest.CaptureFixture[str], make, expected: str) -> None:
    target = make(tmp_path)
    for command in (["run", str(target)], ["bench", str(target), "--seeds", "0"], ["validate", str(target)]):
        code = main(command)
        out, err = capsys.readouterr()
        assert code == 2, (command, out, err)
        line = err if command[0] != "validate" else out
        assert expected in line and line.count("\n") == 1 and "Traceback" not in line + err, (command, line)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["run", "pick_cube", "--seed", "-1"], "--seed must be in 0.."),
        (["run", "pick_cube", "--seed", "99999999999999999999999"], "--seed must be in 0.."),
        (["run", "pick_cube", "--seed", "x"], "invalid int value"),
        (["run", "perceive_boxes"], "a perception-only scenario"),
        (["bench", "pick_cube", "--seeds", "0-999999999999"], "1000000000000 seeds; at most 100000"),
        (["bench", "pick_cube", "--seeds", "3-1"], "bad seeds '3-1'"),
        (["bench", "pick_cube", "--seeds", "0-"], "--seeds: bad seeds '0-'"),
        (["bench", "pick_cube", "--seeds", "-3"], "--seeds: bad seeds '-3'"),
        (["bench", "pick_cube", "--seeds", "0--1"], "--seeds: bad seeds '0--1'"),
        (["bench", "pick_cube", "--seeds", ","], "--seeds: bad seeds ',': an empty item"),
        (["bench", "pick_cube", "--seeds", "0,,1"], "--seeds: bad seeds '0,,1': an empty item"),
        (["bench", "pick_cube", "--seeds", " "], "--seeds: no seeds given"),
        (["perceive", "pick_cube", "--seeds", "0-"], "--seeds: bad seeds '0-'"),
        (["bench", "pick_cube", "--seeds", "a-b"], "bad seeds"),
        (["bench", "pick_cube", "--seeds", ""], "no seeds given"),
        (["bench", "pick_cube", "--episode-timeout", "nan"], "--episode-timeout must be a number of seconds"),
        (["bench", "pick_cube", "--episode-timeout", "inf"], "--episode-timeout must be a number of seconds"),
        (["bench", "pick_cube", "--episode-timeout", "-1"], "--episode-timeout must be a number of seconds"),
        (["bench", "pick_cube", "--workers", "0"], "--workers must be in 1..256"),
        (["bench", "pick_cube", "--min-success", "nan"], "--min-success must be in [0, 1]"),
        (["bench", "pick_cube", "--min-success", "1.5"], "--min-success must be in [0, 1]"),
        (["bench", "pick_cube", "--resume"], "--resume needs --out DIR"),
        (["perceive", "pick_cube", "--repeat", "0"], "--repeat must be in 1..100"),
        (["perceive", "pick_cube", "--methods", "magic"], "--methods: unknown magic"),
        (["frobnicate"], "invalid choice: 'frobnicate'"),
    ],
)
def test_bad_arguments(capsys: pytest.CaptureFixture[str], args: list[str], expected: str) -> None:
    assert main(args) == 2
    out, err = capsys.readouterr()
    assert expected in err and err.count("\n") == 1 and "Traceback" not in err, err


def test_out_must_be_a_writable_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    a_file = tmp_path / "f"
    a_file.write_text("")
    assert main(["run", "pick_cube", "--out", str(a_file)]) == 2
    assert "exists and is not a directory" in capsys.readouterr().err
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    if not __import__("os").access(locked, __import__("os").W_OK):  # root writes anywhere
        assert main(["run", "pick_cube", "--out", str(locked / "o")]) == 2
        assert "not writable" in capsys.readouterr().err
    assert main(["run", "pick_cube", "--out", "/proc/pickdemo"]) == 2
    assert "--out /proc/pickdemo: not writable" in capsys.readouterr().err


def test_junit_is_valid_xml_whatever_the_names_and_messages_hold() -> None:
    from pickdemo.apps.bench import junit_xml

    nasty = "fingers \x00\x01\x1b[31m <closed> & \"'\ud800 \ufffe"
    results = [
        {"scenario": "s\x07", "seed": 0, "success": False, "wall_time_s": 1.0,
         "failure": {"stage": "grasp\x0b", "reason": nasty}},
        {"scenario": "s\x07", "seed": 1, "success": True, "wall_time_s": 1.0, "failure": None},
    ]  # fmt: skip
    text = junit_xml(results)
    root = ET.fromstring(text.encode("utf-8"))
    failure = root.find("testsuite/testcase/failure")
    assert failure is not None and "\\x1b[31m <closed> &" in failure.get("message")


MESH = '\n[[objects]]\nname = "duck"\nshape = "mesh"\nurdf = "pybullet_data:duck_vhacd.urdf"\nposition = [0.6, -0.2]\n'
NOT_XML = "this is not XML\n"
SDF = '<?xml version="1.0"?>\n<sdf version="1.6"><model name="m"/></sdf>\n'
STL_URDF = (
    '<robot name="r"><link name="l"><collision><geometry><mesh filename="part.stl"/></geometry></collision>'
    "</link></robot>\n"
)
NO_MESH_URDF = (
    '<robot name="r"><link name="l"><collision><geometry><mesh filename="gone.obj"/></geometry></collision>'
    "</link></robot>\n"
)

# (id, scenario text, {file name: text} written beside it, what the one line must say)
MESH_CASES: list[tuple[str, str, dict[str, str], str]] = [
    ("a mesh beside the target validates", GOOD + MESH, {}, ""),
    ("missing URDF", GOOD + MESH.replace("pybullet_data:duck_vhacd.urdf", "nothing_here.urdf"), {},
     "objects.duck.urdf: {dir}/nothing_here.urdf: no such file"),
    ("not XML", GOOD + MESH.replace("pybullet_data:duck_vhacd.urdf", "notes.urdf"), {"notes.urdf": NOT_XML},
     "notes.urdf: not a URDF (not XML"),
    ("XML but not a URDF", GOOD + MESH.replace("pybullet_data:duck_vhacd.urdf", "model.sdf"), {"model.sdf": SDF},
     "model.sdf: not a URDF (its root element is <sdf>, not <robot>)"),
    ("an STL collision mesh", GOOD + MESH.replace("pybullet_data:duck_vhacd.urdf", "r.urdf"), {"r.urdf": STL_URDF},
     "collision mesh 'part.stl' is not a Wavefront .obj file"),
    ("a collision mesh that is not there", GOOD + MESH.replace("pybullet_data:duck_vhacd.urdf", "r.urdf"),
     {"r.urdf": NO_MESH_URDF}, "gone.obj: cannot read the mesh"),
    ("a glob matching nothing",
     GOOD + MESH.replace('urdf = "pybullet_data:duck_vhacd.urdf"',
                         'urdf_choice = "pybullet_data:random_urdfs/x*/*.urdf"'),
     {}, "objects.duck.urdf_choice: 'pybullet_data:random_urdfs/x*/*.urdf' matches no file"),
    ("a glob whose every match is broken",
     GOOD + MESH.replace('urdf = "pybullet_data:duck_vhacd.urdf"',
                         'urdf_choice = "pybullet_data:random_urdfs/168/*.urdf"'),
     {}, "none of its 1 matches can be read; {dir_data}/random_urdfs/168/168.obj: a vertex that is not finite"),
    ("scale 0", GOOD + MESH + "scale = 0.0\n", {}, "objects.duck.scale: Input should be greater than 0"),
    ("negative scale", GOOD + MESH + "scale = -1.0\n", {}, "objects.duck.scale: Input should be greater than 0"),
    ("NaN scale", GOOD + MESH + "scale = nan\n", {}, "objects.duck.scale: Input should be a finite number"),
    ("scale range reversed", GOOD + MESH + "scale_range = [0.7, 0.5]\n", {}, "scale_range must be [min, max]"),
    ("a mesh with a size", GOOD + MESH + "size = [0.05, 0.05, 0.05]\n", {}, "a mesh's size is its file's"),
    ("urdf and urdf_choice", GOOD + MESH + 'urdf_choice = "pybullet_data:lego/*.urdf"\n', {},
     "a mesh needs exactly one of urdf, urdf_choice"),
    ("a box with a urdf", _edit("mass = 0.1", 'mass = 0.1\nurdf = "pybullet_data:duck_vhacd.urdf"'), {},
     'objects.cube: urdf is for a mesh (shape = "mesh"), not a box'),
    ("a box without a colour", _edit("color = [0.85, 0.1, 0.1]\n", ""), {}, "objects.cube: a box needs a color"),
    ("a mesh target validates", GOOD.replace("target = true\n", "") + MESH + "target = true\n"
     "rough_size_m = [0.06, 0.095, 0.075]\n", {}, ""),
    ("a mesh target no grasp can hold", GOOD.replace("target = true\n", "") + MESH + "target = true\nscale = 1.6\n",
     {}, "objects.duck.urdf: no top-down grasp can hold it: at scale 1.6 it is "),
    ("a glob of meshes none of which a grasp can hold",
     GOOD.replace("target = true\n", "") + MESH.replace('urdf = "pybullet_data:duck_vhacd.urdf"',
                                                      'urdf_choice = "pybullet_data:random_urdfs/00[0-2]/*.urdf"')
     + "target = true\n", {}, "objects.duck.urdf_choice: no top-down grasp can hold it: at scale 1 each of its 3"),
    ("upright not a bool", _edit("lift_height = 0.05", 'lift_height = 0.05\nupright = "yes"'), {},
     "success.upright: Input should be a valid boolean"),
]  # fmt: skip


@pytest.mark.parametrize(("text", "files", "expected"), [c[1:] for c in MESH_CASES], ids=[c[0] for c in MESH_CASES])
def test_bad_mesh_object(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, files: dict[str, str], expected: str
) -> None:
    f = tmp_path / "s.toml"
    f.write_text(text)
    for name, content in files.items():
        (tmp_path / name).write_text(content)
    if not expected:
        assert main(["validate", str(f)]) == 0, capsys.readouterr().err
        return
    assert main(["run", str(f), "--quiet"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    data = pybullet_data_dir()
    assert err.startswith(f"pickdemo: error: {f}: ") and expected.format(dir=tmp_path, dir_data=data) in err, err
