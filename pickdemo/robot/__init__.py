"""The robot: its description (files, joints, frames, home, datasheet limits, gripper, camera
mounts), its kinematics (Pinocchio), the rate limiter every joint command passes, and the geometry
of its own links (the self-filter). Imports only `pickdemo.core`."""

from pickdemo.robot.description import RobotDescription
from pickdemo.robot.panda import PANDA

#: The robots pickdemo knows by name (a scenario's robot; the Panda by default).
ROBOTS: dict[str, RobotDescription] = {PANDA.name: PANDA}
DEFAULT_ROBOT = PANDA.name


def robot_named(name: str = DEFAULT_ROBOT) -> RobotDescription:
    """The robot of this name (:data:`ROBOTS`); a ``KeyError`` naming the known ones if none."""
    try:
        return ROBOTS[name]
    except KeyError:
        raise KeyError(f"no robot named {name!r}; known: {', '.join(sorted(ROBOTS))}") from None
