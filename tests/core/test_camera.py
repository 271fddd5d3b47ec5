"""Camera maths (pure) against values worked by hand, and round trips."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pickdemo.core.camera import (
    Intrinsics,
    backproject,
    backproject_image,
    depth_from_buffer,
    kinect_sigma_m,
    look_at_pose,
    opengl_projection_matrix,
    opengl_view_matrix,
    project,
)


def test_xtion_intrinsics_from_fov() -> None:
    # fx = 320 / tan(28.5 deg) = 589.37..., fy = 240 / tan(21.5 deg) = 609.28... (FIELD_NOTES: 589.4, 609.4)
    K = Intrinsics.from_fov(640, 480, 57.0, 43.0)
    assert K.fx == pytest.approx(589.37, abs=0.01)
    assert K.fy == pytest.approx(609.28, abs=0.01)
    assert (K.cx, K.cy) == (319.5, 239.5)


def test_backproject_by_hand() -> None:
    K = Intrinsics(width=640, height=480, fx=500.0, fy=400.0, cx=320.0, cy=240.0)
    # u = 420, v = 280, z = 2: x = 2 * 100 / 500 = 0.4, y = 2 * 40 / 400 = 0.2 (eqs. 5-7)
    p = backproject(np.array([[420.0, 280.0]]), np.array([2.0]), K)
    np.testing.assert_allclose(p, [[0.4, 0.2, 2.0]])
    np.testing.assert_allclose(project(p, K), [[420.0, 280.0]])


@settings(max_examples=200, deadline=None)
@given(
    x=st.floats(-1.0, 1.0),
    y=st.floats(-1.0, 1.0),
    z=st.floats(0.2, 3.0),
    fx=st.floats(200.0, 1200.0),
    fy=st.floats(200.0, 1200.0),
)
def test_project_backproject_round_trip(x: float, y: float, z: float, fx: float, fy: float) -> None:
    K = Intrinsics(width=640, height=480, fx=fx, fy=fy, cx=320.0, cy=239.0)
    p = np.array([[x, y, z]])
    uv = project(p, K)
    np.testing.assert_allclose(backproject(uv, np.array([z]), K), p, atol=1e-9)


def test_backproject_image_matches_pointwise() -> None:
    K = Intrinsics(width=8, height=6, fx=10.0, fy=12.0, cx=3.5, cy=2.0)
    depth = np.arange(48, dtype=float).reshape(6, 8) / 10.0 + 0.5
    pts = backproject_image(depth, K)
    v, u = 4, 6
    np.testing.assert_allclose(pts[v, u], backproject(np.array([[u, v]]), np.array([depth[v, u]]), K)[0])


def test_depth_buffer_conversion() -> None:
    near, far = 0.1, 3.0
    assert depth_from_buffer(np.array(0.0), near, far) == pytest.approx(near)
    assert depth_from_buffer(np.array(1.0), near, far) == pytest.approx(far)
    # A point at 1 m: OpenGL stores zbuf = (far / (far - near)) * (1 - near / z) = 0.931034...
    zbuf = far / (far - near) * (1.0 - near / 1.0)
    assert depth_from_buffer(np.array(zbuf), near, far) == pytest.approx(1.0)


def test_kinect_noise_model() -> None:
    # Paper eq. (8): 1.45e-3 z^2; FIELD_NOTES: 0.3 / 0.9 / 2.0 mm at 0.47 / 0.78 / 1.17 m.
    np.testing.assert_allclose(kinect_sigma_m(np.array([0.47, 0.78, 1.17])) * 1e3, [0.32, 0.88, 1.98], atol=0.01)


def test_look_at_axes() -> None:
    T = look_at_pose(np.array([1.0, 0.0, 1.0]), np.array([0.0, 0.0, 0.0]))
    z = T.rotation[:, 2]
    np.testing.assert_allclose(z, np.array([-1.0, 0.0, -1.0]) / np.sqrt(2.0))
    assert T.rotation[2, 1] < 0  # image "down" points down in the world
    np.testing.assert_allclose(T.rotation.T @ T.rotation, np.eye(3), atol=1e-12)


def test_opengl_matrices_agree_with_pinhole() -> None:
    """The GL view and projection put a point at the pixel the pinhole model says (symmetric frustum)."""
    K = Intrinsics.from_fov(640, 480, 57.0, 43.0, cx=320.0, cy=240.0)
    T = look_at_pose(np.array([1.1, 0.0, 0.75]), np.array([0.5, 0.0, 0.0]))
    view = np.array(opengl_view_matrix(T)).reshape(4, 4).T
    proj = np.array(opengl_projection_matrix(K, 0.1, 3.0)).reshape(4, 4).T
    pw = np.array([0.55, -0.08, 0.03, 1.0])
    clip = proj @ view @ pw
    ndc = clip[:3] / clip[3]
    # NDC x in [-1, 1] spans the image width; y is up in GL, down in images.
    u = (ndc[0] + 1.0) / 2.0 * K.width
    v = (1.0 - ndc[1]) / 2.0 * K.height
    uv = project(T.inverse().transform_points(pw[None, :3]), K)[0]
    np.testing.assert_allclose([u, v], uv, atol=1e-6)
