"""The robot's own body as its joint states place it: each link's collision geometry bounded by a
box in the link's frame, posed by forward kinematics. What a real cell's self-filter does (MoveIt's
``robot_self_filter``): a camera that sees the arm is told which of its points are the arm.

Pure: Pinocchio and numpy (no simulator). The boxes come from the robot's URDF: its links' collision
meshes (STL, OBJ or COLLADA, found as :func:`~pickdemo.robot.urdf_files.mesh_path` finds them, read
once per process) and boxes; the link poses from the arm's joint angles and the fingers' openings,
which the robot measures. Padded by :data:`PAD_M` for the
depth sensor's noise and the encoders' (sub-millimetre) error.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin

from pickdemo.core.geometry import OrientedBox, Pose
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.kinematics import link_frame_id
from pickdemo.robot.stl import mesh_vertices
from pickdemo.robot.urdf_files import mesh_path, model_urdf

#: A point this close to a link's bounding box counts as the link (depth noise, encoders).
PAD_M = 0.005


@functools.cache
def link_bounds(robot: RobotDescription) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each link's collision geometry (meshes, boxes, cylinders, spheres) bounded by a box in the link's frame:
    {link: (lo, hi)} (m)."""
    files = robot.files()
    root = ET.fromstring(files.urdf.read_bytes())
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for link in root.findall("link"):
        pts = []
        for col in link.findall("collision"):
            mesh, box = col.find("geometry/mesh"), col.find("geometry/box")
            if mesh is not None:
                path = mesh_path(mesh.get("filename", ""), files)
                if path is None:  # (a robot file's URDF has every mesh: load_robot_file checks)
                    raise FileNotFoundError(mesh.get("filename", ""))
                scale = np.array([float(x) for x in mesh.get("scale", "1 1 1").split()])
                v = mesh_vertices(path) * scale
            elif box is not None:
                v = _corners(np.array([float(x) for x in box.get("size", "0 0 0").split()]) / 2.0)
            elif (cyl := col.find("geometry/cylinder")) is not None:  # (its axis along z)
                r, length = float(cyl.get("radius", "0")), float(cyl.get("length", "0"))
                v = _corners(np.array([r, r, length / 2.0]))
            elif (ball := col.find("geometry/sphere")) is not None:
                v = _corners(np.full(3, float(ball.get("radius", "0"))))
            else:
                continue
            origin = col.find("origin")
            if origin is not None:
                xyz = np.array([float(x) for x in origin.get("xyz", "0 0 0").split()])
                rpy = np.array([float(x) for x in origin.get("rpy", "0 0 0").split()])
                v = v @ pin.rpy.rpyToMatrix(rpy).T + xyz
            pts.append(v)
        if pts:
            v = np.vstack(pts)
            out[link.get("name", "")] = (v.min(axis=0), v.max(axis=0))
    return out


def _corners(half: np.ndarray) -> np.ndarray:
    """The 8 corners of a box of these half sizes about the origin."""
    return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half


class RobotBody:
    """A robot's links posed by its joint states (forward kinematics of the full model, fingers
    included)."""

    def __init__(self, robot: RobotDescription) -> None:
        urdf, renamed = model_urdf(robot.files())
        self.model = pin.buildModelFromUrdf(str(urdf))
        self.data = self.model.createData()
        self.bounds = [(link_frame_id(self.model, name), lo, hi) for name, (lo, hi) in link_bounds(robot).items()]

        def q_index(joint: str) -> int:
            return self.model.joints[self.model.getJointId(renamed.get(joint, joint))].idx_q

        self._arm = [q_index(n) for n in robot.arm_joints]
        self._fingers = [q_index(n) for n in robot.gripper.finger_joints]
        self.gripper = robot.gripper

    def boxes(self, arm_q: np.ndarray, fingers_m: np.ndarray, pad_m: float = PAD_M) -> tuple[OrientedBox, ...]:
        """Every link's bounding box in the world, padded by ``pad_m``, at these joint states."""
        q = pin.neutral(self.model)
        q[self._arm] = np.asarray(arm_q, dtype=float)
        q[self._fingers] = self.gripper.joint_positions(fingers_m)
        pin.framesForwardKinematics(self.model, self.data, q)
        out = []
        for fid, lo, hi in self.bounds:
            M = self.data.oMf[fid]
            out.append(OrientedBox(Pose(M.translation.copy(), M.rotation.copy()), lo - pad_m, hi + pad_m))
        return tuple(out)


#: Samples along a line of sight (the links are some centimetres thick or more).
RAY_SAMPLES = 48


def hidden_by(boxes: tuple[OrientedBox, ...], eye: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Which of the world points (N, 3) these boxes hide from an eye at ``eye`` (a camera's centre)."""
    t = np.linspace(0.02, 0.97, RAY_SAMPLES)[None, :, None]
    samples = eye + (np.atleast_2d(points)[:, None, :] - eye) * t  # (N, S, 3)
    flat = samples.reshape(-1, 3)
    inside = np.zeros(len(flat), dtype=bool)
    for box in boxes:
        inside |= box.contains(flat)
    return inside.reshape(samples.shape[:2]).any(axis=1)


#: Turns of the first joint over its range tried for the base's links (they turn with nothing else).
BASE_TURNS = 13


def hidden_by_the_base(robot: RobotDescription, eye: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Which of the world points (N, 3) the robot's base hides from an eye whatever the arm does: its
    links that no joint but the first moves, at every turn of the first joint."""
    body = robot_body(robot)
    fingers = np.full(2, robot.gripper.finger_max_m)
    home = robot.home_q.astype(float)
    bent = home + np.r_[0.0, np.full(len(home) - 1, 0.3)]
    pairs = zip(body.boxes(home, fingers), body.boxes(bent, fingers), strict=True)
    still = [i for i, (a, b) in enumerate(pairs) if np.allclose(a.corners(), b.corners())]
    hidden = np.ones(len(np.atleast_2d(points)), dtype=bool)
    for q1 in np.linspace(robot.limits.min_position_rad[0], robot.limits.max_position_rad[0], BASE_TURNS):
        boxes = body.boxes(np.r_[q1, home[1:]], fingers)
        hidden &= hidden_by(tuple(boxes[i] for i in still), eye, points)
    return hidden


@functools.cache
def robot_body(robot: RobotDescription) -> RobotBody:
    """One shared model per robot and process."""
    return RobotBody(robot)
