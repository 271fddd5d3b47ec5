"""The rendered camera against the pinhole model: known 3-D points project and back-project true.

Thin tiles (1 mm) lie at known places; the centroid of each tile's silhouette (segmentation: a label,
allowed in tests) must sit within 0.5 px of where the intrinsics project the tile's centre, and the
depth read at that pixel must back-project within 0.5 mm of the tile's surface.
"""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.camera import backproject, pixel_rays_cam, project
from pickdemo.scenario.layout import sample_layout
from pickdemo.scenario.load import parse_scenario

pytestmark = pytest.mark.sim

TILE = 0.001
SPOTS = [(0.5, 0.0), (0.42, -0.2), (0.62, 0.22), (0.35, 0.1), (0.7, -0.15)]


@pytest.fixture(scope="module")
def tile_scene():
    from pickdemo.sim.render import Camera
    from pickdemo.sim.scene import Scene

    objects = [
        {
            "name": f"tile{i}",
            "shape": "box",
            "size": [0.04, 0.04, TILE],
            "color": [0.2, 0.3, 0.9],
            "position": list(xy),
            "yaw_deg": 15.0 * i,
            "target": i == 0,
        }
        for i, xy in enumerate(SPOTS)
    ]
    scenario = parse_scenario({"name": "tiles", "objects": objects, "place": {"position": [0.4, 0.3]}})
    scene = Scene(scenario, sample_layout(scenario, np.random.default_rng(0)))
    camera = Camera(scenario.camera, np.random.default_rng(0))
    frame, seg = camera.capture_labels(scene)
    yield scene, frame, seg
    scene.close()


def test_projection_within_half_pixel(tile_scene) -> None:
    scene, frame, seg = tile_scene
    T_cam_world = frame.T_world_cam.inverse()
    for i, (x, y) in enumerate(SPOTS):
        v, u = np.nonzero(seg == scene.bodies[f"tile{i}"])
        centroid = np.array([u.mean(), v.mean()])
        predicted = project(T_cam_world.transform_points(np.array([[x, y, TILE]])), frame.intrinsics)[0]
        assert np.linalg.norm(centroid - predicted) < 0.5, (i, centroid, predicted)


def test_backprojection_within_half_millimetre(tile_scene) -> None:
    scene, frame, _ = tile_scene
    K, T = frame.intrinsics, frame.T_world_cam
    for x, y in SPOTS:
        uv = np.round(project(T.inverse().transform_points(np.array([[x, y, TILE]])), K))
        p_world = T.transform_points(backproject(uv, np.array([frame.depth_m[int(uv[0, 1]), int(uv[0, 0])]]), K))[0]
        # Where that pixel's ray truly meets the tile's top face:
        ray = T.rotation @ pixel_rays_cam(uv, K)[0]
        truth = T.position + ray * (TILE - T.position[2]) / ray[2]
        assert np.linalg.norm(p_world - truth) < 0.5e-3, (x, y, p_world, truth)


def test_table_plane_is_z_zero(tile_scene) -> None:
    scene, frame, seg = tile_scene
    from pickdemo.perception import world_points

    z = world_points(frame)[..., 2][seg == scene.bodies["table"]]
    assert np.max(np.abs(z)) < 0.5e-3


@pytest.mark.parametrize("roi", [(200, 150, 330, 270), (0, 0, 100, 90), (517, 371, 640, 480)])
def test_region_of_interest_is_the_same_pixels(tile_scene, roi) -> None:
    """A crop rendered with the ROI's frustum holds exactly the whole frame's pixels [y0:y1, x0:x1],
    and its intrinsics project the tiles to the same places, shifted by the corner."""
    from pickdemo.sim.render import Camera

    scene, frame, _ = tile_scene
    camera = Camera(scene.scenario.camera, np.random.default_rng(0))
    scenario_noise = scene.scenario.camera.depth_noise
    crop = camera.capture(scene, roi)
    x0, y0, x1, y1 = roi
    assert crop.rgb.shape == (y1 - y0, x1 - x0, 3) and crop.roi == roi
    np.testing.assert_array_equal(crop.rgb, frame.rgb[y0:y1, x0:x1])
    whole = frame.depth_m[y0:y1, x0:x1]
    finite = np.isfinite(whole)
    assert np.array_equal(finite, np.isfinite(crop.depth_m))
    tol = 5e-6 if scenario_noise == "none" else 0.02  # Kinect noise is drawn per frame
    assert np.max(np.abs(crop.depth_m[finite] - whole[finite])) < tol
    assert (crop.intrinsics.cx, crop.intrinsics.cy) == (frame.intrinsics.cx - x0, frame.intrinsics.cy - y0)
