"""The scenario's cameras: ``[camera]`` (fixed, placed or drawn per seed) and ``[wrist_camera]`` (on
the hand), with their sensors' faults and presets."""

from __future__ import annotations

from typing import Annotated, ClassVar, Literal

from pydantic import Field, model_validator

from pickdemo.scenario.base import Angle, Model, Vec3

#: Realistic sensor faults at once (``[camera] sensor = "..."``); the file's own keys take precedence.
SENSOR_PRESETS: dict[str, dict[str, object]] = {
    "realsense_d435": {"depth_noise": "d435", "depth_holes": 0.02, "depth_edge_dropout": 0.2, "depth_invalid": 0.0,
                       "depth_quantum_m": 0.001, "rgb_noise_sigma": 5.0, "extrinsic_error": (1.0, 0.1)},
    "realsense_d415": {"depth_noise": "d415", "depth_holes": 0.01, "depth_edge_dropout": 0.1, "depth_invalid": 0.0,
                       "depth_quantum_m": 0.001, "rgb_noise_sigma": 4.0, "extrinsic_error": (1.0, 0.1)},
    "kinect": {"depth_noise": "kinect", "depth_holes": 0.01, "depth_edge_dropout": 0.1, "depth_invalid": 0.0,
               "depth_quantum_m": 0.001, "rgb_noise_sigma": 3.0, "extrinsic_error": (2.0, 0.2)},
}  # fmt: skip


class _SensorSpec(Model):
    """What an RGB-D sensor gives: its image, its field of view, its depth range and its faults."""

    width: Annotated[int, Field(ge=16, le=4096)] = 640  # px
    height: Annotated[int, Field(ge=16, le=4096)] = 480  # px
    fov_deg: tuple[Annotated[float, Field(gt=1.0, lt=170.0)], Annotated[float, Field(gt=1.0, lt=170.0)]] = (
        57.0,
        43.0,
    )  # horizontal, vertical
    depth_noise: Literal["none", "kinect", "d415", "d435"] = "kinect"
    # A real sensor's faults (all off by default; `sensor = "realsense_d435"` sets them all at once).
    depth_holes: Annotated[float, Field(ge=0.0, le=0.5)] = 0.0  # fraction of pixels with no return, at random
    depth_edge_dropout: Annotated[float, Field(ge=0.0, le=1.0)] = 0.0  # fraction of pixels at depth edges dropped
    depth_invalid: Literal[0.0, "nan"] = 0.0  # what a hole reads as: 0.0 (like real drivers) or "nan"
    depth_quantum_m: Annotated[float, Field(ge=0.0, le=0.01)] = 0.0  # depth reported in steps of this (0: none)
    rgb_noise_sigma: Annotated[float, Field(ge=0.0, le=50.0)] = 0.0  # 8-bit units
    sensor: Literal["realsense_d435", "realsense_d415", "kinect"] | None = None  # a preset for the keys above
    near_m: Annotated[float, Field(ge=0.01, le=1.0)] = 0.1
    far_m: Annotated[float, Field(gt=0.1, le=20.0)] = 3.0

    #: the key a preset's calibration error goes to
    calibration_key: ClassVar[str] = "extrinsic_error"

    @model_validator(mode="before")
    @classmethod
    def _preset(cls, data: object) -> object:
        """A sensor preset fills the fault keys the file does not give itself."""
        if isinstance(data, dict) and isinstance(data.get("sensor"), str) and data["sensor"] in SENSOR_PRESETS:
            preset = dict(SENSOR_PRESETS[data["sensor"]])
            preset[cls.calibration_key] = preset.pop("extrinsic_error")
            return {**preset, **data}
        return data

    @model_validator(mode="after")
    def _placed(self) -> _SensorSpec:
        """Every sensor has a depth range and looks from its ``position`` at its ``look_at`` (its class's)."""
        if self.far_m <= self.near_m:
            raise ValueError("far_m must exceed near_m")
        if sum((a - b) ** 2 for a, b in zip(self.position, self.look_at, strict=True)) < 1e-6:  # type: ignore[attr-defined]
            raise ValueError("look_at must differ from position")
        return self

    @property
    def extrinsic_sigma(self) -> tuple[float, float]:
        """How far the pose the robot is told may be off (mm, deg)."""
        return getattr(self, self.calibration_key)


class CameraSpec(_SensorSpec):
    """A fixed RGB-D camera. Defaults match the paper's Xtion Pro Live (57 x 43 deg, 640x480)."""

    position: Vec3 = (1.1, 0.0, 0.75)  # m, world frame
    look_at: Vec3 = (0.5, 0.0, 0.0)  # m, world frame
    extrinsic_error: tuple[Annotated[float, Field(ge=0.0, le=50.0)], Annotated[float, Field(ge=0.0, le=5.0)]] = (
        0.0,
        0.0,
    )  # mm, deg: the true camera pose differs from the one the robot is told, drawn per seed
    # Instead of a fixed position: sampled around look_at per seed (all three, or none).
    distance_range_m: tuple[Annotated[float, Field(ge=0.2, le=5.0)], Annotated[float, Field(ge=0.2, le=5.0)]] | None = (
        None
    )
    elevation_range_deg: tuple[Angle, Angle] | None = None  # above the table plane
    azimuth_range_deg: tuple[Angle, Angle] | None = None  # about world z, 0 = from +x

    @model_validator(mode="after")
    def _check(self) -> CameraSpec:
        ranges = (self.distance_range_m, self.elevation_range_deg, self.azimuth_range_deg)
        if any(r is not None for r in ranges) and any(r is None for r in ranges):
            raise ValueError("give all of distance_range_m, elevation_range_deg, azimuth_range_deg, or none")
        for r in ranges:
            if r is not None and r[0] > r[1]:
                raise ValueError("camera ranges must be [min, max]")
        if self.elevation_range_deg is not None and not (
            0 < self.elevation_range_deg[0] and self.elevation_range_deg[1] < 90
        ):
            raise ValueError("elevation_range_deg must lie in (0, 90)")
        return self

    @property
    def sampled(self) -> bool:
        return self.distance_range_m is not None


HandCoord = Annotated[float, Field(ge=-0.5, le=0.5)]  # m, in the mount link's frame


class WristCameraSpec(_SensorSpec):
    """An RGB-D camera on the hand (``[wrist_camera]``), as real pick cells mount a small one on the
    Franka hand. Defaults: a RealSense D405-like camera (87 x 58 deg, 424x240, from 5 cm) 9 cm beside the
    hand, looking down past the fingertips; the hand-eye calibration exact."""

    #: a link of the robot's hand (the frame ``position`` and ``look_at`` are in; checked against the
    #: robot's camera mounts by the scenario); None: the robot's hand frame
    mount: Annotated[str, Field(min_length=1, max_length=100)] | None = None
    #: m, in the mount's frame (the hand's z points from the flange to the fingertips)
    position: tuple[HandCoord, HandCoord, HandCoord] = (0.09, 0.0, 0.04)
    look_at: tuple[HandCoord, HandCoord, HandCoord] = (0.0, 0.0, 0.16)
    width: Annotated[int, Field(ge=16, le=4096)] = 424
    height: Annotated[int, Field(ge=16, le=4096)] = 240
    fov_deg: tuple[Annotated[float, Field(gt=1.0, lt=170.0)], Annotated[float, Field(gt=1.0, lt=170.0)]] = (
        87.0,
        58.0,
    )
    depth_noise: Literal["none", "kinect", "d415", "d435"] = "d415"
    near_m: Annotated[float, Field(ge=0.01, le=1.0)] = 0.05
    far_m: Annotated[float, Field(gt=0.1, le=20.0)] = 1.0
    #: mm, deg: the true pose of the camera on the hand differs from the one the robot is told (drawn per seed)
    hand_eye_error: tuple[Annotated[float, Field(ge=0.0, le=50.0)], Annotated[float, Field(ge=0.0, le=5.0)]] = (
        0.0,
        0.0,
    )

    calibration_key: ClassVar[str] = "hand_eye_error"
