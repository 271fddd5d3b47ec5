"""The robot: its description (files, joints, frames, home, datasheet limits, gripper, camera
mounts), read from a robot file (:mod:`pickdemo.robot.robot_file`; the shipped ones in
``pickdemo/robot/robots/``), its kinematics (Pinocchio), the rate limiter every joint command
passes, and the geometry of its own links (the self-filter). Imports only `pickdemo.core`."""

import functools
from pathlib import Path

from pickdemo.robot.description import RobotDescription
from pickdemo.robot.robot_file import ROBOTS_DIR, RobotFileError, load_robot_file

#: The robot of a scenario that names none.
DEFAULT_ROBOT = "panda"


def shipped_robots() -> list[str]:
    """The names of the robots that ship (their files in ``pickdemo/robot/robots/``)."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.toml"))


def robot_named(name: str = DEFAULT_ROBOT) -> RobotDescription:
    """The shipped robot of this name, or the robot a file describes (a path ending in ``.toml``);
    one description per name and process. A ``KeyError`` naming the known ones if none;
    :class:`~pickdemo.robot.robot_file.RobotFileError` for a bad file."""
    return _robot(name)


@functools.cache
def _robot(name: str) -> RobotDescription:
    if name.endswith(".toml"):
        return load_robot_file(Path(name))
    if name not in shipped_robots():
        raise KeyError(f"no robot named {name!r}; known: {', '.join(shipped_robots())}, or a robot file (.toml)")
    return load_robot_file(ROBOTS_DIR / f"{name}.toml")


__all__ = ["DEFAULT_ROBOT", "RobotDescription", "RobotFileError", "robot_named", "shipped_robots"]
