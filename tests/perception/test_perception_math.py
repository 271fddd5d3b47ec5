"""The paper's equations and our fits, on values worked by hand and synthetic data with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pickdemo.core.shapes import Box
from pickdemo.perception import (
    MIXTURE_KERNEL,
    TargetModel,
    condition_on_plane,
    fit_outline,
    fit_plane_weighted,
    mixture_at,
    mixture_moments,
    point_covariance,
    refine_circle,
)


def test_mixture_weights() -> None:
    # Eqs. (9)-(12): 1/4 at the feature, 1/8 on the four edge neighbours, 1/16 on the diagonals.
    assert MIXTURE_KERNEL[1, 1] == 1 / 4
    assert MIXTURE_KERNEL[0, 1] == MIXTURE_KERNEL[1, 0] == MIXTURE_KERNEL[1, 2] == MIXTURE_KERNEL[2, 1] == 1 / 8
    assert MIXTURE_KERNEL[0, 0] == MIXTURE_KERNEL[0, 2] == MIXTURE_KERNEL[2, 0] == MIXTURE_KERNEL[2, 2] == 1 / 16
    assert MIXTURE_KERNEL.sum() == pytest.approx(1.0)


def test_mixture_by_hand_depth_step() -> None:
    # A feature on a depth edge: centre 2 m, the rest 1 m, each reading exact (variance 0).
    # mu = 0.25 * 2 + 0.75 * 1 = 1.25; var = 0.25 * 4 + 0.75 * 1 - 1.25^2 = 0.1875 (eqs. 9-10).
    z = np.ones((3, 3))
    z[1, 1] = 2.0
    mu, var = mixture_at(z, 0.0, 1, 1)
    assert mu == pytest.approx(1.25)
    assert var == pytest.approx(0.1875)


def test_mixture_by_hand_column_edge() -> None:
    # Left column at 0.9 m (weights 1/16 + 1/8 + 1/16 = 1/4), rest at 1.0 m, each with variance 1e-6.
    # mu = 0.25 * 0.9 + 0.75 * 1.0 = 0.975
    # var = 1e-6 + 0.25 * 0.81 + 0.75 * 1.0 - 0.975^2 = 1e-6 + 0.001875
    z = np.ones((3, 3))
    z[:, 0] = 0.9
    mu, var = mixture_at(z, 1e-6, 1, 1)
    assert mu == pytest.approx(0.975)
    assert var == pytest.approx(0.001876, rel=1e-9)


def test_colour_mixture_constant_sigma_c() -> None:
    # Eq. (12) on a flat colour patch: the mixture variance is sigma_c^2 itself.
    r = np.full((3, 3), 200.0)
    mu, var = mixture_at(r, 4.0, 1, 1)
    assert (mu, var) == (pytest.approx(200.0), pytest.approx(4.0))


@settings(max_examples=50, deadline=None)
@given(arrays(np.float64, (6, 7), elements=st.floats(0.3, 3.0)), st.floats(0.0, 1e-3))
def test_vectorised_mixture_matches_pointwise(z: np.ndarray, var: float) -> None:
    mu_img, var_img = mixture_moments(z, var)
    for v in range(1, 5):
        for u in range(1, 6):
            mu, vv = mixture_at(z, var, u, v)
            assert mu_img[v, u] == pytest.approx(mu, abs=1e-12)
            assert var_img[v, u] == pytest.approx(vv, abs=1e-9)


def test_eq14_by_hand() -> None:
    # u = 420, v = 290, c = (320, 240), f = 500, z = 1 m, var_z = 1e-6 m^2, sigma_u = sigma_v = 1 px:
    # sxx = (1e-6 * 100^2 + 1) / 500^2 = 4.04e-6; syy = (1e-6 * 50^2 + 1) / 500^2 = 4.01e-6
    # sxy = 1e-6 * 100 * 50 / 500^2 = 2e-8; sxz = 1e-6 * 100 / 500 = 2e-7; syz = 1e-6 * 50 / 500 = 1e-7
    S = point_covariance(420.0, 290.0, 1.0, 1e-6, 500.0, 500.0, 320.0, 240.0)
    expected = np.array([[4.04e-6, 2e-8, 2e-7], [2e-8, 4.01e-6, 1e-7], [2e-7, 1e-7, 1e-6]])
    np.testing.assert_allclose(S, expected, rtol=1e-12)


def test_eq14_matches_monte_carlo() -> None:
    """Sampling u, v, z and back-projecting gives eq. (14)'s covariance (first order)."""
    rng = np.random.default_rng(7)
    u0, v0, z0, sz, f, cx, cy = 500.0, 100.0, 0.9, 2e-3, 600.0, 320.0, 240.0
    n = 400_000
    u = u0 + rng.standard_normal(n)
    v = v0 + rng.standard_normal(n)
    z = z0 + sz * rng.standard_normal(n)
    pts = np.column_stack([z * (u - cx) / f, z * (v - cy) / f, z])
    S = point_covariance(u0, v0, z0, sz**2, f, f, cx, cy)
    np.testing.assert_allclose(np.cov(pts.T), S, rtol=0.03, atol=1e-9)


def test_weighted_plane_fit_recovers_tilt() -> None:
    rng = np.random.default_rng(3)
    xy = rng.uniform(-0.03, 0.03, size=(500, 2))
    a, b, c = 0.02, -0.05, 0.05
    z = a * xy[:, 0] + b * xy[:, 1] + c + 1e-5 * rng.standard_normal(500)
    normal, height, cov, centroid = fit_plane_weighted(np.column_stack([xy, z]), np.full(500, 1e10))
    expected = np.array([-a, -b, 1.0]) / np.linalg.norm([-a, -b, 1.0])
    np.testing.assert_allclose(normal, expected, atol=1e-4)
    assert height == pytest.approx(a * centroid[0] + b * centroid[1] + c, abs=1e-5)
    assert np.all(np.diag(cov) > 0)


def _rectangle_outline(cx: float, cy: float, yaw: float, sx: float, sy: float, n: int = 60) -> np.ndarray:
    t = np.linspace(-0.5, 0.5, n)
    sides = [
        np.column_stack([np.full(n, sx / 2), t * sy]),
        np.column_stack([np.full(n, -sx / 2), t * sy]),
        np.column_stack([t * sx, np.full(n, sy / 2)]),
        np.column_stack([t * sx, np.full(n, -sy / 2)]),
    ]
    pts = np.vstack(sides)
    R = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    return pts @ R.T + np.array([cx, cy])


def test_rectangle_fit_recovers_centre_and_yaw() -> None:
    rng = np.random.default_rng(1)
    xy = _rectangle_outline(0.01, -0.02, 0.4, 0.05, 0.03) + 2e-4 * rng.standard_normal((240, 2))
    centre, yaw, size, cov = fit_outline(xy, TargetModel(Box((0.05, 0.03, 0.02)), (1.0, 0.0, 0.0)))
    np.testing.assert_allclose(centre, [0.01, -0.02], atol=5e-5)
    assert np.cos(2 * (yaw - 0.4)) == pytest.approx(1.0, abs=1e-5)  # yaw modulo the half turn
    assert size == pytest.approx((0.05, 0.03), abs=2e-3)  # minAreaRect hull: inflated by the noise


def test_circle_fit_recovers_centre_from_an_arc() -> None:
    a = np.linspace(0.2, 3.0, 80)  # under half the circle: the far arc that a camera sees
    xy = np.column_stack([0.03 + 0.02 * np.cos(a), -0.01 + 0.02 * np.sin(a)])
    centre, cov = refine_circle(xy, np.array([0.025, -0.005]), 0.02)
    np.testing.assert_allclose(centre, [0.03, -0.01], atol=1e-9)
    assert cov.shape == (2, 2) and np.all(np.linalg.eigvalsh(cov) > 0)


def test_rectangle_fit_covariance_matches_scatter() -> None:
    """Over many noisy outlines, the fit's reported covariance matches its actual errors."""
    rng = np.random.default_rng(5)
    model = TargetModel(Box((0.05, 0.03, 0.02)), (1.0, 0.0, 0.0))
    sigma = 3e-4
    errs, covs = [], []
    for _ in range(200):
        xy = _rectangle_outline(0.0, 0.0, 0.3, 0.05, 0.03, n=30) + sigma * rng.standard_normal((120, 2))
        c, yaw, _, cov = fit_outline(xy, model, np.full(120, 1.0 / sigma**2))
        errs.append([c[0], c[1], yaw - 0.3])
        covs.append(cov)
    nees = [e @ np.linalg.solve(C, e) for e, C in zip(np.array(errs), covs, strict=True)]
    assert 2.4 < np.mean(nees) < 3.6  # chi-square with 3 degrees of freedom


def test_conditioning_on_a_plane() -> None:
    # A point 1 cm above the plane z = 0, uncertain mostly along a slanted ray: it slides along the
    # ray onto the plane, and keeps no spread along the normal.
    ray = np.array([0.6, 0.0, -0.8])
    cov = 1e-4 * np.outer(ray, ray) + 1e-8 * np.eye(3)
    mean, c = condition_on_plane(np.array([0.1, 0.2, 0.01]), cov, np.array([0.0, 0.0, 1.0]), np.zeros(3))
    assert mean[2] == pytest.approx(0.0, abs=1e-12)
    assert mean[0] == pytest.approx(0.1 + 0.0075, rel=1e-3)  # 1 cm down the ray moves 7.5 mm in x
    assert c[2, 2] == pytest.approx(0.0, abs=1e-15)
