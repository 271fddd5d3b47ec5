"""Whether the arm stands between the fixed camera and what it should see, and where the arm could
stand instead: the robot's own links (their bounding boxes where its joint states put them, as
the self-filter has them) against the camera's lines of sight. A part of the pick skill: it returns
values, never writes the machine's state.

Looking for the target from home, a camera over the robot's shoulder may see the arm where the
target is. The arm then moves aside to the posture that shows most of the table it hid (the target
is not where the camera sees the table), and looks again: turned about its first joint (when that
joint turns it about the vertical, as a Panda's, a UR's and an SO-101's do), or, when no turn will
do (a camera right behind the shoulder), a posture drawn about home with every link clear of the
table all the way there.
"""

from __future__ import annotations

import numpy as np

from pickdemo.robot.kinematics import Kinematics
from pickdemo.robot.self_geometry import hidden_by, hidden_by_the_base, robot_body
from pickdemo.skills.pick.params import CameraModel

#: Turns of the first joint (rad) the arm may take to look from, nearest first.
ASIDE_TURNS_RAD = (0.6, -0.6, 1.0, -1.0, 1.4, -1.4)
#: ... then postures drawn about home: this many, each joint within this of home's (rad)
ASIDE_DRAWS = 24
ASIDE_SPREAD_RAD = 1.2
#: ... then, none of those showing enough, this many drawn over the joints' whole ranges (measured: a
#: cube 0.41 m in front of the base, hidden from every posture within 1.2 rad of home, showed from
#: postures with the elbow folded far back)
ASIDE_WIDE_DRAWS = 48
#: A posture to look from keeps every link this far above the table (m), on its way there too.
ASIDE_CLEAR_M = 0.1
#: The table the camera sees, sampled on this grid of its image (columns, rows).
TABLE_GRID = (16, 12)
#: ... within this of the robot's base (m): where it picks.
TABLE_REACH_M = 0.85
#: Moving aside is worth it when it shows at least this share of the table the arm hid.
ASIDE_GAIN = 0.5
#: ... and when the arm hides at least this share of it (a point or two is no hiding place for a target)
ASIDE_MIN_HIDDEN = 0.02


class Sightline:
    """The fixed camera's lines of sight against the arm's links."""

    def __init__(self, kin: Kinematics, camera: CameraModel) -> None:
        self.kin, self.camera = kin, camera
        self.body = robot_body(kin.robot)
        self.fingers = np.full(2, kin.robot.gripper.finger_max_m)
        self._table: np.ndarray | None = None
        self._base: np.ndarray | None = None

    def hidden(self, q: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Which of the world points (N, 3) the arm at ``q`` hides from the camera."""
        boxes = self.body.boxes(np.asarray(q, dtype=float), self.fingers)
        return hidden_by(boxes, self.camera.pose.position, points)

    def table(self) -> np.ndarray:
        """Points of the table top (z = 0) the camera sees, within reach of the robot's base."""
        if self._table is None:
            K, T = self.camera.intrinsics, self.camera.pose
            us = np.linspace(0.5, K.width - 0.5, TABLE_GRID[0])
            vs = np.linspace(0.5, K.height - 0.5, TABLE_GRID[1])
            uv = np.array([(u, v) for v in vs for u in us])
            rays = np.column_stack([(uv[:, 0] - K.cx) / K.fx, (uv[:, 1] - K.cy) / K.fy, np.ones(len(uv))])
            d = rays @ T.rotation.T
            down = d[:, 2] < -1e-6
            s = -T.position[2] / d[down, 2]
            pts = T.position + d[down] * s[:, None]
            self._table = pts[np.hypot(pts[:, 0], pts[:, 1]) <= TABLE_REACH_M]
        return self._table

    def aside(self, looked_from: list[np.ndarray], rng: np.random.Generator) -> tuple[np.ndarray, float, float] | None:
        """Where to look from next, having looked from the postures ``looked_from`` (the last is where the
        arm is) and not found the target: the configuration, the share of the table the arm hid from
        all of them, and the share of that it still hides from there; None when no posture tried
        shows ``ASIDE_GAIN`` of it (or the arm hides nothing). ``rng``: the draws about home."""
        table = self.table()
        if self.camera.on_hand or len(table) == 0:
            return None
        q = np.asarray(looked_from[-1], dtype=float)
        hid = np.ones(len(table), dtype=bool)
        for seen_from in looked_from:  # (the target is where none of them showed the table)
            hid &= self.hidden(np.asarray(seen_from, dtype=float), table)
        hid &= ~self.base_hides()  # (what the base hides, no posture shows)
        if hid.mean() < ASIDE_MIN_HIDDEN:
            return None
        behind = table[hid]
        turns = []
        first = np.asarray(looked_from[0], dtype=float)
        if self._first_joint_vertical(first):
            for turn in ASIDE_TURNS_RAD:
                cand = first.copy()
                cand[0] += turn
                if not any(np.allclose(cand, seen_from) for seen_from in looked_from):
                    turns.append(cand)
        home = np.asarray(self.kin.robot.home_q, dtype=float)
        draws = [home + rng.uniform(-ASIDE_SPREAD_RAD, ASIDE_SPREAD_RAD, len(home)) for _ in range(ASIDE_DRAWS)]
        limits = self.kin.robot.limits
        wide = lambda: [rng.uniform(limits.min_position_rad, limits.max_position_rad) for _ in range(ASIDE_WIDE_DRAWS)]  # noqa: E731,E501
        for group in (turns, draws, None):  # a turn, if one will do; the whole ranges last (drawn only then)
            group = wide() if group is None else group
            best: tuple[np.ndarray, float, float] | None = None
            for cand in group:
                if not self.kin.within_limits(cand) or not self._clear_on_the_way(q, cand):
                    continue
                still = float(self.hidden(cand, behind).mean())
                if still <= 1.0 - ASIDE_GAIN and (best is None or still < best[2] - 1e-9):
                    best = (cand, float(hid.mean()), still)
            if best is not None:
                return best
        return None

    def base_hides(self) -> np.ndarray:
        """Which of :meth:`table`'s points the robot's base hides whatever the arm does."""
        if self._base is None:
            self._base = hidden_by_the_base(self.kin.robot, self.camera.pose.position, self.table())
        return self._base

    def _clear_on_the_way(self, q0: np.ndarray, q1: np.ndarray) -> bool:
        """Every link ``ASIDE_CLEAR_M`` above the table (or as high as at ``q0``, the base's, if lower)
        at ``q1`` and along the straight joint path to it."""
        floor = [min(float(b.corners()[:, 2].min()), ASIDE_CLEAR_M) for b in self.body.boxes(q0, self.fingers)]
        for s in np.linspace(0.25, 1.0, 4):
            boxes = self.body.boxes(q0 + s * (q1 - q0), self.fingers)
            if any(float(b.corners()[:, 2].min()) < f - 1e-9 for b, f in zip(boxes, floor, strict=True)):
                return False
        return True

    def _first_joint_vertical(self, q: np.ndarray) -> bool:
        """Whether turning the first joint turns the hand about the vertical through the base (its
        height kept, its distance from the base axis kept)."""
        a = self.kin.forward(np.asarray(q, dtype=float)).position
        turned = np.asarray(q, dtype=float).copy()
        turned[0] += 0.5
        b = self.kin.forward(turned).position
        return abs(a[2] - b[2]) < 1e-6 and abs(np.hypot(a[0], a[1]) - np.hypot(b[0], b[1])) < 1e-6
