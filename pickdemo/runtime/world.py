"""One world, built from (scenario, seed): the seed's random streams, the layout, the scene and the camera.

Shared by an episode (:class:`pickdemo.runtime.episode.Episode`) and ``perceive`` (:mod:`pickdemo.apps.perceive`),
so that one seed lays out, renders and sees one world whoever builds it. Two steps: ``World(scenario,
seed)`` samples the layout (cheap and pure: a :class:`~pickdemo.scenario.layout.LayoutError` when the objects do
not fit), :meth:`World.open` builds the simulator's scene and places the camera (the simulator's
side is imported then). :meth:`World.build` does both.

The true poses (:meth:`true_pose`) are the simulator's: for scoring and viewers, never for control.
"""

from __future__ import annotations

import numpy as np

from pickdemo.core.camera import calibration_error, hand_camera_pose
from pickdemo.core.geometry import Pose
from pickdemo.core.streams import spawn_rngs
from pickdemo.robot.description import RobotDescription
from pickdemo.robot.kinematics import Kinematics, kinematics_of
from pickdemo.scenario.layout import Placement, camera_position, sample_layout, sample_place, sample_round
from pickdemo.scenario.load import Scenario, WristCameraSpec
from pickdemo.scenario.tray import Tray
from pickdemo.sim.render import Camera, WristCamera
from pickdemo.sim.scene import Scene

#: The scenario's cameras by name: ``[camera]`` (fixed) and ``[wrist_camera]`` (on the hand)
FIXED_CAMERA = "camera"
WRIST_CAMERA = "wrist_camera"


class World:
    """The seed's world: its random streams (``rngs``), its ``layout``, and once opened its ``scene``
    and ``camera``. Closing it closes the scene (also as a context manager)."""

    def __init__(self, scenario: Scenario, seed: int) -> None:
        self.scenario = scenario
        self.seed = seed
        self.rngs: dict[str, np.random.Generator] = spawn_rngs(seed)
        self.layout: list[Placement] = list(sample_layout(scenario, self.rngs["layout"], self.rngs["objects"]))
        if scenario.clear is not None:  # a clear round: its objects drawn and laid out
            self.layout.extend(sample_round(scenario, self.rngs["clear"], self.layout))
        #: a clear round's tray (None: no tray)
        self.tray: Tray | None = Tray.of(scenario)
        #: where the target is to be put down (the scenario's spot, or drawn for this seed; the tray's middle)
        self.place_xy: tuple[float, float] = sample_place(scenario, self.layout, self.rngs["place"])
        self.robot: RobotDescription = scenario.robot_description
        self.scene: Scene | None = None
        self.camera: Camera | None = None
        self.wrist_camera: WristCamera | None = None  # a camera on the hand, if the scenario has one
        #: every camera by its name (what frames and estimates carry): the fixed one first
        self.cameras: dict[str, Camera] = {}

    @classmethod
    def build(cls, scenario: Scenario, seed: int, *, gui: bool = False) -> World:
        """The world laid out and opened."""
        return cls(scenario, seed).open(gui=gui)

    def open(self, *, gui: bool = False) -> World:
        """Build the scene (the laid-out objects, the robot at home) and place the camera: at the
        position drawn for this seed, told its pose with the calibration error drawn for it."""
        sc = self.scenario
        self.scene = Scene(sc, self.layout, gui=gui, tray=self.tray, robot=self.robot)
        where = camera_position(sc.camera, self.rngs["camera_pose"])
        error = calibration_error(*sc.camera.extrinsic_error, self.rngs["calibration"])
        self.camera = Camera(sc.camera, self.rngs["camera"], position=where, calibration_error=error)
        self.cameras = {FIXED_CAMERA: self.camera}
        if sc.wrist_camera is not None:
            self.wrist_camera = wrist_camera(
                sc.wrist_camera, self.rngs["wrist_camera"], self.rngs["hand_eye"], kinematics_of(self.robot)
            )
            self.cameras[WRIST_CAMERA] = self.wrist_camera
        return self

    def placement(self, name: str) -> Placement:
        return next(p for p in self.layout if p.name == name)

    def true_pose(self, name: str) -> Pose:
        """An object's true pose (truth: for scoring and viewers only)."""
        assert self.scene is not None, "the world is not open"
        return self.scene.true_pose(name)

    def true_position(self, name: str) -> np.ndarray:
        """An object's true position (truth: for scoring only)."""
        assert self.scene is not None, "the world is not open"
        return self.scene.true_position(name)

    @property
    def sim_time_s(self) -> float:
        return self.scene.sim_time_s if self.scene is not None else 0.0

    def close(self) -> None:
        if self.scene is not None:
            self.scene.close()

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def wrist_camera(
    spec: WristCameraSpec, rng: np.random.Generator, hand_eye_rng: np.random.Generator, kin: Kinematics
) -> WristCamera:
    """The hand's camera where the scenario mounts it, told its pose with the hand-eye error drawn for it."""
    T_tcp_cam = hand_camera_pose(kin.tcp_to_frame(spec.mount or kin.robot.hand_frame), spec.position, spec.look_at)
    return WristCamera(spec, rng, T_tcp_cam, calibration_error(*spec.hand_eye_error, hand_eye_rng))
