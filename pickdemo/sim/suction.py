"""The simulated vacuum cup: a seal made and broken by :mod:`pickdemo.robot.suction`'s model, a fixed
constraint while it holds, and the vacuum sensor a real cell reads.

Each physics step with the vacuum on, the rim's points are cast along the cup's axis (a ray each, from
inside the cup to the bellows' stroke past its lip): touching one body all round within the stroke,
the cup seals, and the body is held by a fixed constraint where it is (the bellows' pull, rigid); a
rim over an edge, across two bodies or a step deeper than the stroke leaks. While sealed and the body
hangs free (touching nothing but the robot), the wrench the cup must give it for the motion it makes
(its weight and its smoothed accelerations), in the cup's frame, is the seal's load: above what the
vacuum holds (pull, shear, peel or twist) for :data:`BREAK_STEPS` steps in a row, the seal breaks, the
body drops, and the cup leaks until its valve is shut again. An object marked porous never seals (air
passes through it). The robot reads only the vacuum sensor (:meth:`VacuumCup.vacuum_kpa`); the seal
itself is the simulator's truth.
"""

from __future__ import annotations

import numpy as np
import pybullet as p

from pickdemo.core.geometry import Pose
from pickdemo.robot.suction import GRAVITY_M_S2, Cup, Seal, load, rim_points, seal

#: A load above what the seal holds for this many physics steps in a row breaks it (a contact's
#: one-step impulse is not a pull).
BREAK_STEPS = 3
#: The held body's accelerations are smoothed over this (s): from one physics step to the next, a
#: constrained body's velocity jitters (measured: 2.5 N of shear on a 0.1 kg part, its sign flipping each
#: step, as the arm carried it); a seal lets air in over tens of milliseconds, not in one step.
SMOOTH_S = 0.02
#: The rim's rays start this far inside the cup (m): Bullet's ray ignores the shape it starts in.
RAY_BEHIND_M = 0.005
#: Each rim ray's first hits looked at (the robot's own shapes among them are passed over)
RAY_HITS = 3


class VacuumCup:
    """The cup of ``robot``: its link ``cup_link``, its lip at ``tcp_link``'s frame (z out of the lip)."""

    def __init__(self, client, robot: int, tcp_link: int, cup_link: int, cup: Cup) -> None:  # noqa: ANN001 - a BulletClient
        self.c, self.robot, self.tcp_link, self.cup_link, self.cup = client, robot, tcp_link, cup_link, cup
        self.porous: set[int] = set()  # the bodies air passes through
        self.on = False
        self.state = Seal.OPEN
        self.held: int | None = None  # the body sealed on
        self._constraint: int | None = None
        self._over = 0
        self.last_load = 0.0  # the worst share of the hold the last step asked (for tests and the log)
        self._dt = float(client.getPhysicsEngineParameters()["fixedTimeStep"])
        self._last_v: tuple[np.ndarray, np.ndarray] | None = None
        self._acc = (np.zeros(3), np.zeros(3))
        self.broke_at_s: float | None = None
        rim = rim_points(cup)
        self._rim = np.column_stack([rim, np.zeros(len(rim))])

    # ------------------------------------------------------------------------------ commanded
    def set(self, on: bool) -> None:
        """The vacuum valve: on (suck) or off (release: the seal lets go at once, as a blow-off does)."""
        if on == self.on:
            return
        self.on = on
        if not on:
            self._release()
            self.state = Seal.OPEN
            self.broke_at_s = None

    # -------------------------------------------------------------------------------- stepped
    def after_step(self, time_s: float) -> None:
        if not self.on or self.broke_at_s is not None:  # (broken: it leaks until the valve is shut again)
            return
        if self._constraint is not None:
            self._hold(time_s)
            return
        self.state, body = self._seal()
        if self.state is Seal.SEALED and body is not None:
            self._grip(body)

    def _tcp(self) -> tuple[np.ndarray, np.ndarray]:
        state = self.c.getLinkState(self.robot, self.tcp_link, computeForwardKinematics=True)
        return np.array(state[4]), np.array(self.c.getMatrixFromQuaternion(state[5])).reshape(3, 3)

    def _seal(self) -> tuple[Seal, int | None]:
        origin, rot = self._tcp()
        axis = rot[:, 2]
        points = origin + self._rim @ rot.T
        start = points - axis * RAY_BEHIND_M
        reach = RAY_BEHIND_M + self.cup.stroke_m + 0.002
        bodies, fractions = self._first_hits(start, start + axis * reach)
        gaps = np.where(bodies >= 0, fractions * reach - RAY_BEHIND_M, np.nan)
        found = bodies[bodies >= 0]
        if found.size == 0:
            return Seal.OPEN, None
        body = int(np.bincount(found).argmax())
        state = seal(self.cup, gaps, bodies == body)
        if state is Seal.SEALED and body in self.porous:
            state = Seal.LEAK
        return state, body

    def _first_hits(self, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each ray's nearest hit on anything but the robot (its body, -1 for none, and its fraction of
        the way). The robot's own links are no surface to seal on, and a ray starting inside the cup's
        shape at times meets it at once (measured: one rim ray of 16 in 5 of 7 leaks in ``suction_clear_bin``
        seeds 0-9, each sealing 1 mm away): Bullet is asked for each ray's first :data:`RAY_HITS` hits."""
        bodies = np.full(len(start), -1)
        fractions = np.ones(len(start))
        for k in range(RAY_HITS):
            hits = self.c.rayTestBatch(start.tolist(), end.tolist(), reportHitNumber=k)
            for i, h in enumerate(hits):
                if h[0] >= 0 and h[0] != self.robot and h[2] < fractions[i]:
                    bodies[i], fractions[i] = h[0], h[2]
        return bodies, fractions

    def _grip(self, body: int) -> None:
        """Held where it is: a fixed constraint from the cup's lip to the body."""
        origin, rot = self._tcp()
        pos, orn = self.c.getBasePositionAndOrientation(body)
        inv_pos, inv_orn = self.c.invertTransform(pos, orn)
        tcp_orn = Pose(np.zeros(3), rot).quaternion_xyzw.tolist()
        in_body = self.c.multiplyTransforms(inv_pos, inv_orn, origin.tolist(), tcp_orn)
        # (the TCP link's inertial frame is its own: a massless frame; a base's is its centre of mass)
        self._constraint = self.c.createConstraint(
            self.robot, self.tcp_link, body, -1, p.JOINT_FIXED, [0, 0, 0],
            [0, 0, 0], list(in_body[0]),
            parentFrameOrientation=[0, 0, 0, 1], childFrameOrientation=list(in_body[1]),
        )  # fmt: skip
        self.c.changeConstraint(self._constraint, maxForce=20.0 * self.cup.holding_force_n)
        # the lip's contact with the face is the seal itself: the two no longer collide while it holds
        # (a contact and the constraint would fight over the same millimetre)
        self.c.setCollisionFilterPair(self.robot, body, self.cup_link, -1, 0)
        self.held, self._over, self._last_v = body, 0, None

    def _hold(self, time_s: float) -> None:
        """The seal's load this step; broken after :data:`BREAK_STEPS` over what it holds.

        The load is what the cup must give the body, hanging free, for it to move as it did: its mass
        times its acceleration less gravity, and the moment of that about the cup's centre with its
        inertia's. While the body touches anything but the robot, what it rests on or is pressed against
        carries it, and the step asks nothing of the seal (Bullet's own report of a constraint's force,
        where contacts share the load, is the solver's split, not the physics': measured, a box pressed
        flat on the ground read 2-8 N of shear from one step to the next)."""
        c, body = self.c, self.held
        v, w = (np.array(x) for x in c.getBaseVelocity(body))
        com = np.array(c.getBasePositionAndOrientation(body)[0])
        origin, rot = self._tcp()
        if self._last_v is None:
            self._acc = (np.zeros(3), np.zeros(3))
        else:  # (the body's accelerations, smoothed over SMOOTH_S: a step's difference is the solver's jitter)
            k = self._dt / (SMOOTH_S + self._dt)
            step = ((v - self._last_v[0]) / self._dt, (w - self._last_v[1]) / self._dt)
            self._acc = (self._acc[0] + k * (step[0] - self._acc[0]), self._acc[1] + k * (step[1] - self._acc[1]))
        self._last_v = (v, w)
        a, alpha = self._acc
        if any(pt[2] != self.robot for pt in c.getContactPoints(bodyA=body)):
            self._over = 0  # (resting on, or pressed against, something: that carries it; not a load)
            return
        mass = float(c.getDynamicsInfo(body, -1)[0])
        need = mass * (a - np.array([0.0, 0.0, -GRAVITY_M_S2]))  # what acts on it, in all
        moment = np.cross(com - origin, need) + self._inertia(body) @ alpha
        # the cup gives ``need`` to the body: the body pulls the cup with -need (along the cup's +z: a pull)
        share = load(self.cup, rot.T @ -need, rot.T @ -moment)
        self.last_load = share.worst
        self._over = 0 if share.holds else self._over + 1
        if self._over >= BREAK_STEPS:
            self._release()
            self.state = Seal.LEAK
            self.broke_at_s = time_s

    def _inertia(self, body: int) -> np.ndarray:
        """The body's inertia about its centre of mass, in the world frame."""
        info = self.c.getDynamicsInfo(body, -1)
        local = np.diag(info[2])
        orn = self.c.getBasePositionAndOrientation(body)[1]
        rot = np.array(self.c.getMatrixFromQuaternion(orn)).reshape(3, 3)
        return rot @ local @ rot.T

    def _release(self) -> None:
        if self._constraint is not None:
            self.c.removeConstraint(self._constraint)
            self.c.setCollisionFilterPair(self.robot, self.held, self.cup_link, -1, 1)
        self._constraint, self.held, self._over = None, None, 0

    # ------------------------------------------------------------------------------ sensed
    def vacuum_kpa(self) -> float:
        """The vacuum sensor: the generator's vacuum at a sealed cup, a little through a leak, none open."""
        if not self.on:
            return 0.0
        if self.state is Seal.SEALED and self._constraint is not None:
            return self.cup.vacuum_kpa
        return self.cup.leak_share * self.cup.vacuum_kpa if self.state is Seal.LEAK else 0.0
