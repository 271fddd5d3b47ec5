"""The simulated world: one PyBullet client owning the robot (its fingers, or a suction cup:
:mod:`pickdemo.sim.suction`), the table and the scenario's objects.

The :class:`Scene` is the only owner of the physics client; the renderer and the controller are
handed it. Bodies, joints and links are looked up by name. The true poses it can report are for the
metrics and labels only: the controller never asks for them.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import pybullet as p
from pybullet_utils.bullet_client import BulletClient

from pickdemo.core.geometry import Pose
from pickdemo.core.meshes import resolve
from pickdemo.core.shapes import Box, Cylinder, Mesh
from pickdemo.robot import robot_named
from pickdemo.robot.description import RobotDescription
from pickdemo.scenario.fixtures import FixtureSpec
from pickdemo.scenario.layout import Placement
from pickdemo.scenario.load import ObjectSpec, Scenario
from pickdemo.scenario.objects import TABLE_THICKNESS_M
from pickdemo.scenario.tray import Tray
from pickdemo.sim import quiet_c_stdout
from pickdemo.sim.contacts import ContactLog
from pickdemo.sim.conveyor import Belt
from pickdemo.sim.suction import VacuumCup

#: The scene's bodies that are not objects on the table.
FIXTURES = ("robot", "table", "conveyor", "tray")

#: The pads' torsional friction (m: torque per newton pressed). PyBullet's contact is a point, whose
#: friction about the normal is near zero: an object held at one point pivots about the finger axis.
#: A rubber pad pressed onto a patch of radius a resists with about (2/3) mu a: 0.003 m is a 4.5 mm
#: patch (evidence: docs/decisions.md#physics-and-the-scene).
PAD_TORSIONAL_FRICTION_M = 0.003
#: The objects are at rest when each moves slower than this (m/s), and turns slowly enough that no
#: point of it moves faster than this from the turning (its angular speed times its bounding radius:
#: the farthest a point of it is from its centre of mass; a 5 cm duck: 0.04 rad/s) ...
REST_SPEED_M_S = 2e-3
#: ... for this many steps in a row (:meth:`Scene.settle`).
REST_STEPS = 10
#: Rolling friction of round objects (cylinders, meshes); a box rests and is held on its faces and
#: has none: its rolling-friction rows would cost a held step's solver time for nothing (evidence:
#: docs/decisions.md#speed).
ROLLING_FRICTION_M = 0.0001


def cylinder_mesh(radius: float, height: float, segments: int = 64) -> tuple[list, list, list]:
    """Vertices, normals and triangle indices of a closed cylinder about z, centred at the origin.

    Caps have their own vertices with normals along z, so they render flat; the side's vertices
    have radial normals, so it renders smooth.
    """
    angles = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    ring = np.column_stack([np.cos(angles), np.sin(angles)])
    verts: list[list[float]] = []
    normals: list[list[float]] = []
    indices: list[int] = []

    def add(v: list[float], n: list[float]) -> int:
        verts.append(v)
        normals.append(n)
        return len(verts) - 1

    for z, up in ((height / 2.0, 1.0), (-height / 2.0, -1.0)):
        centre = add([0.0, 0.0, z], [0.0, 0.0, up])
        rim = [add([radius * x, radius * y, z], [0.0, 0.0, up]) for x, y in ring]
        for i in range(segments):
            j = (i + 1) % segments
            indices += [centre, rim[i], rim[j]] if up > 0 else [centre, rim[j], rim[i]]
    top = [add([radius * x, radius * y, height / 2.0], [x, y, 0.0]) for x, y in ring]
    bottom = [add([radius * x, radius * y, -height / 2.0], [x, y, 0.0]) for x, y in ring]
    for i in range(segments):
        j = (i + 1) % segments
        indices += [bottom[i], bottom[j], top[j], bottom[i], top[j], top[i]]
    return verts, normals, indices


@dataclass(frozen=True)
class JointState:
    """What the robot's encoders report."""

    arm_q: np.ndarray  # (7,) rad
    arm_dq: np.ndarray  # (7,) rad/s
    fingers_m: np.ndarray  # (2,) m, each finger's opening from the centre (a jaw's: half the gap, each)


@dataclass(frozen=True)
class Settling:
    """How the objects settled before the robot's first tick: the steps it took, and a note when they
    had not come to rest within the steps allowed (the episode records it among its phases)."""

    steps: int
    note: str | None = None


@dataclass(frozen=True)
class StillBox:
    """A box of the scene that never moves (the table, a bin's walls), as it was built: what a camera
    that never moves either may render once (:class:`~pickdemo.sim.render.Backdrop`)."""

    body: int
    half_extents: tuple[float, float, float]
    position: tuple[float, float, float]
    orientation_xyzw: tuple[float, float, float, float]
    rgba: tuple[float, float, float, float]


class Scene:
    """A PyBullet world built from a scenario and a sampled layout."""

    def __init__(
        self,
        scenario: Scenario,
        layout: tuple[Placement, ...],
        *,
        gui: bool = False,
        tray: Tray | None = None,
        robot: RobotDescription | None = None,
    ) -> None:
        """``robot``: the arm and hand to load (default: the default robot)."""
        self.scenario = scenario
        self.robot = robot or robot_named()
        self.gui = gui
        with quiet_c_stdout():
            self.client = BulletClient(connection_mode=p.GUI if gui else p.DIRECT)
        c = self.client
        if gui:
            c.configureDebugVisualizer(p.COV_ENABLE_GUI, 0)
            c.configureDebugVisualizer(p.COV_ENABLE_SHADOWS, 0)
            c.resetDebugVisualizerCamera(
                cameraDistance=0.9, cameraYaw=40.0, cameraPitch=-35.0, cameraTargetPosition=[0.45, 0.0, 0.05]
            )
        c.setGravity(0.0, 0.0, -9.81)
        c.setTimeStep(scenario.sim.time_step_s)
        c.setPhysicsEngineParameter(numSolverIterations=150, deterministicOverlappingPairs=1)
        # The calls made every tick, bound once (the client builds a new partial on each lookup).
        self._step_simulation = c.stepSimulation
        self._joint_states = c.getJointStates
        self._contact_points = c.getContactPoints
        self.time_step_s = scenario.sim.time_step_s
        self.steps = 0
        self.bodies: dict[str, int] = {}
        self.radius_m: dict[str, float] = {}  # each object's bounding radius (about its centre of mass)
        self.fixture_bodies: dict[str, list[int]] = {}  # a bin's parts (not objects on the table)
        self.still_boxes: list[StillBox] = []  # in the order they were built
        self.belt = None
        #: the truth, for scoring: :func:`~pickdemo.sim.contacts.log_contacts`
        self.contact_log: ContactLog | None = None
        if scenario.conveyor is not None:  # before the table: TinyRenderer then shades only the belt where both are
            self.belt = Belt(self.client, scenario.conveyor)
            self.bodies["conveyor"] = self.belt.body
        self._build_table()
        if self.belt is not None:
            self.belt.ignore(self.bodies["table"])
        self._build_robot()
        if tray is not None:
            self._build_tray(tray)
        for fixture in scenario.fixtures:
            self._build_fixture(fixture)
        specs = {o.name: o for o in scenario.objects}
        for placement in layout:
            spec = specs.get(placement.name)
            if spec is None:  # drawn by a clear round: a mesh as its file has it
                xy = (float(placement.pose.position[0]), float(placement.pose.position[1]))
                spec = ObjectSpec(name=placement.name, shape="mesh", urdf=placement.geometry.urdf, position=xy)
            self._build_object(spec, placement)
        if self.cup is not None:  # (what air passes through: a cup on it never seals)
            self.cup.porous = {self.bodies[o.name] for o in scenario.objects if o.porous and o.name in self.bodies}

    # ----------------------------------------------------------------------------------- building
    def _build_table(self) -> None:
        c, t = self.client, self.scenario.table
        half = (t.size[0] / 2.0, t.size[1] / 2.0, TABLE_THICKNESS_M / 2.0)
        centre = (t.center[0], t.center[1], -TABLE_THICKNESS_M / 2.0)
        body = self._still_box(half, centre, (0.0, 0.0, 0.0, 1.0), t.color)
        c.changeDynamics(body, -1, lateralFriction=t.friction)
        self.bodies["table"] = body

    def _still_box(self, half: tuple, position: tuple, orientation_xyzw: tuple, color: tuple) -> int:
        """A box fixed where it is put, of one colour; recorded in :attr:`still_boxes`."""
        c, rgba = self.client, (*(float(v) for v in color), 1.0)
        col = c.createCollisionShape(p.GEOM_BOX, halfExtents=list(half))
        vis = c.createVisualShape(p.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba))
        body = c.createMultiBody(0.0, col, vis, basePosition=list(position), baseOrientation=list(orientation_xyzw))
        self.still_boxes.append(StillBox(body, tuple(half), tuple(position), tuple(orientation_xyzw), rgba))
        return body

    def _build_tray(self, tray: Tray) -> None:
        """A clear round's tray, fixed to the table where the scenario puts it."""
        c = self.client
        pose = tray.pose
        position = [*tray.position, tray.base_z]
        with quiet_c_stdout():
            body = c.loadURDF(
                str(resolve(tray.urdf, None)), basePosition=position, baseOrientation=list(pose.quaternion_xyzw),
                globalScaling=tray.scale, useFixedBase=True,
            )  # fmt: skip
        self.bodies["tray"] = body

    def _build_fixture(self, fixture: FixtureSpec) -> None:
        """A bin's parts, each a box fixed to the table, of the table's friction; a model's file, fixed
        where the scenario puts its frame (PyBullet places a body by its inertial frame)."""
        c = self.client
        if fixture.kind == "model":
            path = str(resolve(fixture.file, None))
            with quiet_c_stdout():
                if path.lower().endswith(".sdf"):
                    body = c.loadSDF(path, globalScaling=fixture.scale)[0]
                else:
                    body = c.loadURDF(path, useFixedBase=True, globalScaling=fixture.scale)
            at = fixture.inertial_pose
            c.resetBasePositionAndOrientation(body, at.position.tolist(), list(at.quaternion_xyzw))
            c.changeDynamics(body, -1, lateralFriction=self.scenario.table.friction)
            if fixture.color is not None:
                c.changeVisualShape(body, -1, rgbaColor=[*fixture.color, 1.0])
            self.fixture_bodies[fixture.name] = [body]
            return
        parts = []
        for box in fixture.boxes():
            half = tuple(((box.hi - box.lo) / 2.0).tolist())
            centre = box.pose.transform_points(((box.lo + box.hi) / 2.0)[None, :])[0]
            orientation = tuple(box.pose.quaternion_xyzw.tolist())
            body = self._still_box(half, tuple(centre.tolist()), orientation, fixture.color)
            c.changeDynamics(body, -1, lateralFriction=self.scenario.table.friction)
            parts.append(body)
        self.fixture_bodies[fixture.name] = parts

    def _build_robot(self) -> None:
        c = self.client
        flags = p.URDF_USE_INERTIA_FROM_FILE
        desc, gripper = self.robot, self.robot.gripper
        with quiet_c_stdout():  # (PyBullet prints a URDF's warnings, a link without inertia, on stdout)
            robot = c.loadURDF(str(desc.render_urdf()), basePosition=[0, 0, 0], useFixedBase=True, flags=flags)
        self.bodies["robot"] = robot
        self.joint_index: dict[str, int] = {}
        self.link_index: dict[str, int] = {}
        for j in range(c.getNumJoints(robot)):
            info = c.getJointInfo(robot, j)
            self.joint_index[info[1].decode()] = j
            self.link_index[info[12].decode()] = j
        self.arm_joints = [self.joint_index[n] for n in desc.arm_joints]
        self.finger_joints = [self.joint_index[n] for n in gripper.finger_joints]
        self.finger_links = [self.link_index[n] for n in gripper.finger_links]
        self.tcp_link = self.link_index[desc.tcp_frame]
        self.cup = (
            None if gripper.cup is None else VacuumCup(c, robot, self.tcp_link, self.finger_links[0], gripper.cup)
        )
        # The wrist's force sensor: the reaction of the flange-to-hand joint, in the hand's frame.
        self.wrist_joint = self.joint_index[desc.wrist_joint]
        c.enableJointForceTorqueSensor(robot, self.wrist_joint, True)
        for j, q in zip(self.arm_joints, desc.home_q, strict=True):
            c.resetJointState(robot, j, float(q))
        for j, q in zip(self.finger_joints, gripper.joint_targets(gripper.finger_max_m), strict=True):
            c.resetJointState(robot, j, q)
        for link in self.finger_links:
            c.changeDynamics(
                robot, link, lateralFriction=gripper.pad_friction, spinningFriction=PAD_TORSIONAL_FRICTION_M
            )
        if gripper.coupled:
            # The real gripper couples its fingers mechanically (the URDF's <mimic>, which PyBullet
            # ignores). Without the coupling a held object drifts sideways with both fingers in transit.
            gear = c.createConstraint(
                robot,
                self.finger_joints[0],
                robot,
                self.finger_joints[1],
                p.JOINT_GEAR,
                [0, 1, 0],
                [0, 0, 0],
                [0, 0, 0],
            )
            c.changeConstraint(gear, gearRatio=-1, erp=0.1, maxForce=50)
        # Hold the home pose until the controller takes over.
        c.setJointMotorControlArray(robot, self.arm_joints, p.POSITION_CONTROL, targetPositions=list(desc.home_q))
        n = len(self.finger_joints)
        c.setJointMotorControlArray(
            robot,
            self.finger_joints,
            p.POSITION_CONTROL,
            targetPositions=gripper.joint_targets(gripper.finger_max_m),
            forces=[gripper.joint_force(gripper.open_force_n)] * n,
        )

    def _build_object(self, spec: ObjectSpec, placement: Placement) -> None:
        c, pose, shape = self.client, placement.pose, placement.geometry
        self.radius_m[spec.name] = shape.bounding_radius_m
        if isinstance(shape, Box):
            half = [s / 2.0 for s in shape.size_m]
            col = c.createCollisionShape(p.GEOM_BOX, halfExtents=half)
            vis = c.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=[*spec.color, 1.0])
        elif isinstance(shape, Cylinder):
            radius, height = shape.diameter_m / 2.0, shape.height_m
            col = c.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=height)
            # PyBullet's own cylinder visual renders 1 mm taller than its collision shape (measured)
            # and smooth-shades the rim; a mesh of the exact size with flat caps renders true.
            verts, normals, indices = cylinder_mesh(radius, height)
            vis = c.createVisualShape(
                p.GEOM_MESH, vertices=verts, normals=normals, indices=indices, rgbaColor=[*spec.color, 1.0]
            )
        elif isinstance(shape, Mesh):
            self._build_mesh(spec, shape, pose)
            return
        else:
            raise TypeError(f"objects.{spec.name}: the scene cannot build a {shape.kind}")
        mass = 0.0 if spec.static else spec.mass  # a static body stays where it is put
        body = c.createMultiBody(
            mass, col, vis, basePosition=list(pose.position), baseOrientation=list(pose.quaternion_xyzw)
        )
        rolling = 0.0 if isinstance(shape, Box) else ROLLING_FRICTION_M
        c.changeDynamics(body, -1, lateralFriction=spec.friction, spinningFriction=0.001, rollingFriction=rolling)
        self.bodies[spec.name] = body

    def _build_mesh(self, spec: ObjectSpec, shape: Mesh, pose: Pose) -> None:
        """A mesh object from its URDF, scaled; its inertia computed by PyBullet from its shape (the
        files' inertia is often a placeholder), its mass and friction the file's unless the scenario
        gives them. Placed by its centre of mass (PyBullet's base frame, the frame of its vertices)."""
        c = self.client
        with quiet_c_stdout():
            body = c.loadURDF(
                str(resolve(shape.urdf, None)), basePosition=list(pose.position),
                baseOrientation=list(pose.quaternion_xyzw), globalScaling=shape.scale, useFixedBase=spec.static,
            )  # fmt: skip
        c.resetBasePositionAndOrientation(body, list(pose.position), list(pose.quaternion_xyzw))
        given = spec.model_fields_set
        if "mass" in given and not spec.static:
            c.changeDynamics(body, -1, mass=spec.mass)
        if "friction" in given:
            c.changeDynamics(body, -1, lateralFriction=spec.friction)
        c.changeDynamics(body, -1, spinningFriction=0.001, rollingFriction=ROLLING_FRICTION_M)
        self.bodies[spec.name] = body

    # ---------------------------------------------------------------------------------- stepping
    @property
    def sim_time_s(self) -> float:
        return self.steps * self.time_step_s

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            if self.belt is not None:
                self.belt.before_step(self.sim_time_s)
            self._step_simulation()
            self.steps += 1
            if self.contact_log is not None:
                self.contact_log.read(self.sim_time_s)
            if self.cup is not None:
                self.cup.after_step(self.sim_time_s)
            if self.gui:  # pace the window for a human; never affects the simulation's outcome
                time.sleep(self.time_step_s)

    # ------------------------------------------------------------------------------ its state
    def state(self) -> np.ndarray:
        """The simulator's state as numbers, for a demonstration's exact replay: every body's base pose
        and velocity, every joint's position and velocity (not the solver's warm start: a replay set from
        states steps on as the original did, to within the contact solver's tolerance)."""
        c, parts = self.client, []
        for i in range(c.getNumBodies()):
            body = c.getBodyUniqueId(i)
            pos, orn = c.getBasePositionAndOrientation(body)
            lin, ang = c.getBaseVelocity(body)
            parts.append(np.array([*pos, *orn, *lin, *ang]))
            n = c.getNumJoints(body)
            if n:
                js = c.getJointStates(body, range(n))
                parts.append(np.array([v for j in js for v in j[:2]]))
        return np.concatenate([[self.steps], *parts])

    def set_state(self, state: np.ndarray) -> None:
        """Put the simulator in a state :meth:`state` gave (of this scene: the same bodies)."""
        state = np.asarray(state, dtype=float)
        if int(state[0]) != self.steps:
            raise ValueError(f"a state of step {int(state[0])} set at step {self.steps}: replay in order")
        c, k = self.client, 1
        for i in range(c.getNumBodies()):
            body = c.getBodyUniqueId(i)
            v = state[k : k + 13]
            c.resetBasePositionAndOrientation(body, v[:3].tolist(), v[3:7].tolist())
            c.resetBaseVelocity(body, v[7:10].tolist(), v[10:13].tolist())
            k += 13
            for j in range(c.getNumJoints(body)):
                c.resetJointState(body, j, float(state[k]), float(state[k + 1]))
                k += 2
        if k != len(state):
            raise ValueError(f"a state of {len(state)} numbers; this scene's has {k}")

    def start_belt(self) -> None:
        """Start the conveyor (if there is one): what rests on it rides along from now. World set-up."""
        if self.belt is None:
            return
        riders = [
            b for n, b in self.bodies.items()
            if n not in FIXTURES and self.scenario.conveyor.holds(*self.true_pose(n).position[:2])
        ]  # fmt: skip
        self.belt.start(self.sim_time_s, riders)

    # --------------------------------------------------------------------- what the robot senses
    def joint_state(self) -> JointState:
        robot = self.bodies["robot"]
        arm = self._joint_states(robot, self.arm_joints)
        fingers = self._joint_states(robot, self.finger_joints)
        return JointState(
            arm_q=np.array([s[0] for s in arm]),
            arm_dq=np.array([s[1] for s in arm]),
            fingers_m=self.robot.gripper.fingers_of([s[0] for s in fingers]),
        )

    def wrist_force(self) -> np.ndarray:
        """(3,) N: the force the hand puts on the wrist flange, in the hand's frame (a wrist sensor)."""
        return np.array(self.client.getJointState(self.bodies["robot"], self.wrist_joint)[2][:3])

    def finger_contacts(self) -> tuple[int, int]:
        """Number of contact points on each finger with anything but the robot (a tactile sense; a
        suction cup has none: its vacuum sensor says what it holds)."""
        if self.cup is not None:
            return 0, 0
        robot = self.bodies["robot"]
        counts = []
        for link in self.finger_links:
            pts = self._contact_points(bodyA=robot, linkIndexA=link)
            counts.append(sum(1 for pt in pts if pt[2] != robot))
        return counts[0], counts[1]

    # ------------------------------------------------------------ ground truth: metrics and labels only
    def true_pose(self, name: str) -> Pose:
        pos, quat = self.client.getBasePositionAndOrientation(self.bodies[name])
        return Pose.from_quaternion_xyzw(np.array(pos), np.array(quat))

    def true_position(self, name: str) -> np.ndarray:
        """An object's true position alone (no orientation: the referee's cheap per-tick read)."""
        return np.asarray(self.client.getBasePositionAndOrientation(self.bodies[name])[0], dtype=float)

    def true_speed(self, name: str) -> float:
        lin, ang = self.client.getBaseVelocity(self.bodies[name])
        return float(np.linalg.norm(lin))

    def _speeds(self) -> list[tuple[float, str]]:
        """Each movable object's speed (m/s) and its points' speed from its turning (angular speed
        times its bounding radius), whichever is larger, with its name."""
        out = []
        for name, body in self.bodies.items():
            if name in FIXTURES:
                continue
            lin, ang = self.client.getBaseVelocity(body)
            turning = float(np.linalg.norm(ang)) * self.radius_m.get(name, 0.0)
            out.append((max(float(np.linalg.norm(lin)), turning), name))
        return out

    def objects_at_rest(self, speed_m_s: float = REST_SPEED_M_S) -> bool:
        """Whether every movable object is (nearly) still, travelling and turning: for setting the world
        up, never for control."""
        return all(speed < speed_m_s for speed, _ in self._speeds())

    def _fastest_object(self) -> tuple[str, float]:
        """The movable object moving fastest now (travelling or turning), and that speed (m/s): what a
        note on settling names."""
        speed, name = max(self._speeds(), default=(0.0, ""))
        return name, speed

    def let_objects_sleep(self) -> None:
        """Let the movable objects sleep once at rest (Bullet's deactivation: a body still for a while
        leaves the solver until something touches it). A clear round's objects mostly lie still, on the
        table or in the tray: a step costs a quarter as much. Behaviour, not set-up: a round only."""
        for name, body in self.bodies.items():
            if name not in FIXTURES:
                self.client.changeDynamics(body, -1, activationState=p.ACTIVATION_STATE_ENABLE_SLEEPING)

    def settle(self, max_steps: int) -> Settling:
        """Step until the objects have come to rest (:data:`REST_STEPS` steps in a row), at most
        ``max_steps``; the robot holds its pose meanwhile. World set-up, not robot behaviour. Objects
        still moving when the steps run out are not passed over in silence: the note names the fastest
        (the robot's first look then sees the scene in motion)."""
        still = 0
        for i in range(max_steps):
            self.step()
            still = still + 1 if self.objects_at_rest() else 0
            if still >= REST_STEPS:
                return Settling(i + 1)
        name, speed = self._fastest_object()
        return Settling(
            max_steps,
            f"the objects had not come to rest in {max_steps * self.time_step_s:.2f} s of settling ({REST_STEPS} "
            f"steps in a row each slower than {REST_SPEED_M_S * 1e3:.0f} mm/s, travelling and turning): {name} at "
            f"{speed * 1e3:.1f} mm/s at the end",
        )

    def set_pose(self, name: str, pose: Pose) -> None:
        """Move a body kinematically (a disturbance): pose set, velocity zeroed."""
        body = self.bodies[name]
        self.client.resetBasePositionAndOrientation(body, list(pose.position), list(pose.quaternion_xyzw))
        self.client.resetBaseVelocity(body, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0])

    def true_tcp_pose(self) -> Pose:
        state = self.client.getLinkState(self.bodies["robot"], self.tcp_link, computeForwardKinematics=True)
        return Pose.from_quaternion_xyzw(np.array(state[4]), np.array(state[5]))

    def close(self) -> None:
        if self.client is not None:
            try:
                self.client.disconnect()
            except p.error:  # already gone
                pass
            self.client = None  # type: ignore[assignment]

    def __enter__(self) -> Scene:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
