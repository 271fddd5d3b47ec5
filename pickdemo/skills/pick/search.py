"""Where to look for a target no view has shown: the table within reach that no camera has seen (the
world model's never seen: behind a tall box, under the arm), looked at from above with a camera on
the hand. A part of the pick skill: it returns a posture and what it is for, never writes the
machine's state.

The table within reach is sampled on a grid (:data:`GRID_M`) just above its top; the cells no view
saw past are grouped (touching cells, as an image's blobs), and the largest group not looked at yet
is looked at from :data:`LOOK_FROM_M` above its middle, the hand camera pointing straight down (the
hand turned about the vertical until the arm reaches it, by IK).
"""

from __future__ import annotations

import cv2
import numpy as np

from pickdemo.core.geometry import Pose
from pickdemo.robot.kinematics import Kinematics
from pickdemo.skills.pick.params import CameraModel, MachineParams
from pickdemo.worldmodel import UNKNOWN, WorldModel

#: The table's grid (m), and how far from the robot's base it reaches (m) ...
GRID_M = 0.02
REACH_M = (0.25, 0.8)
#: ... sampled this high above the table's top (m): a target on it hides the table under it
SAMPLE_Z_M = 0.01
#: A group of cells never seen smaller than this (m^2) hides no target worth looking for.
MIN_HIDDEN_M2 = 0.0016
#: The hand camera looks from this high above the group's middle (m).
LOOK_FROM_M = 0.35
#: A group within this of a spot already looked at (m) is not looked at again.
LOOKED_M = 0.05
#: The hand's turns about the vertical tried for a posture to look from (rad).
TURNS_RAD = (0.0, np.pi / 2.0, -np.pi / 2.0, np.pi)


class Searcher:
    """Spots to look at with a camera on the hand (see the module docstring)."""

    def __init__(self, kin: Kinematics, cameras: list[CameraModel], params: MachineParams) -> None:
        self.kin, self.p = kin, params
        self.camera = next((c for c in cameras if c.on_hand), None)
        r = np.arange(-REACH_M[1], REACH_M[1] + 1e-9, GRID_M)
        gx, gy = np.meshgrid(r, r, indexing="ij")
        dist = np.hypot(gx, gy)
        self._inside = (dist >= REACH_M[0]) & (dist <= REACH_M[1]) & (gx > 0.0)
        self._grid = np.stack([gx, gy, np.full(gx.shape, SAMPLE_Z_M)], axis=-1)

    def spot(
        self, world: WorldModel, looked: list[np.ndarray], q_seed: np.ndarray, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray, float] | None:
        """(where to look at, the joint posture to look from, the area never seen there, m^2), or None
        (no camera on the hand, nothing never seen that is large enough, or no posture reaches it)."""
        if self.camera is None:
            return None
        pts = self._grid[self._inside]
        never = np.zeros(self._inside.shape, dtype=np.uint8)
        never[self._inside] = world.classify(pts) == UNKNOWN
        n, labels, stats, centroids = cv2.connectedComponentsWithStats(never, connectivity=4)
        order = np.argsort(-stats[1:, cv2.CC_STAT_AREA]) + 1
        for k in order:
            area = float(stats[k, cv2.CC_STAT_AREA]) * GRID_M**2
            if area < MIN_HIDDEN_M2:
                break
            cells = self._grid[labels == k]
            at = cells[np.argmin(np.linalg.norm(cells - cells.mean(axis=0), axis=1))]  # (a cell of it)
            if any(np.hypot(*(at[:2] - p[:2])) < LOOKED_M for p in looked):
                continue
            q = self._posture(at, q_seed, rng)
            if q is not None:
                return at, q, area
        return None

    def _posture(self, at: np.ndarray, q_seed: np.ndarray, rng: np.random.Generator) -> np.ndarray | None:
        """Joint angles with the hand camera above ``at``, looking straight down (None: none reached)."""
        down = np.diag([1.0, -1.0, -1.0])  # the camera's z along the world's -z
        for turn in TURNS_RAD:
            c, s = np.cos(turn), np.sin(turn)
            Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
            cam = Pose(np.array([at[0], at[1], LOOK_FROM_M]), Rz @ down)
            tcp = cam @ self.camera.pose.inverse()
            res = self.kin.solve(tcp, q_seed, rng, self.p.goals.ik)
            if res.success and self.kin.limit_margin(res.q) >= self.p.goals.min_margin_rad:
                return res.q
        return None
