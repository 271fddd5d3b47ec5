"""The sensor model: a real RGB-D camera's faults, and perception that treats holes as holes."""

from __future__ import annotations

import numpy as np
import pytest

from pickdemo.core.camera import (
    MIN_VALID_DEPTH_M,
    calibration_error,
    depth_edges,
    depth_noise_coeff,
    holes_as_nan,
    sensor_faults,
)
from pickdemo.scenario.load import CameraSpec


def test_d4xx_noise_follows_intels_rms_model() -> None:
    # The datasheet cameras: a D435 (848 px wide, 87 deg) and a D415 (1280 px, 65 deg) at 1 m.
    fx_435 = 424.0 / np.tan(np.radians(87.0 / 2))
    fx_415 = 640.0 / np.tan(np.radians(65.0 / 2))
    assert depth_noise_coeff("d435", fx_435) == pytest.approx(3.6e-3, rel=0.05)  # ~3.7 mm at 1 m
    assert depth_noise_coeff("d415", fx_415) == pytest.approx(1.45e-3, rel=0.05)  # ~1.45 mm at 1 m
    assert depth_noise_coeff("kinect", 589.0) == pytest.approx(1.45e-3)


def test_holes_are_holes() -> None:
    d = np.array([[0.0, np.nan, np.inf, 0.01, 0.8, -1.0]])
    out = holes_as_nan(d)
    assert np.isnan(out[0, :4]).all() and out[0, 4] == 0.8 and np.isnan(out[0, 5])
    assert MIN_VALID_DEPTH_M > 0.0


def test_faults_do_what_they_say() -> None:
    rng = np.random.default_rng(0)
    depth = np.full((200, 200), 0.9)
    depth[60:140, 60:140] = 0.85  # an object 5 cm nearer: its outline is a depth edge
    rgb = np.full((200, 200, 3), 128, np.uint8)
    edges = depth_edges(depth)
    assert edges.sum() == pytest.approx(2 * 4 * 80, rel=0.05)
    new_rgb, d = sensor_faults(rgb, depth, rng, noise_coeff=3.6e-3, holes=0.02, edge_dropout=0.5, invalid=0.0,
                               quantum_m=0.001, rgb_sigma=5.0)  # fmt: skip
    holes = d == 0.0
    assert holes[~edges].mean() == pytest.approx(0.02, abs=0.005)
    assert holes[edges].mean() == pytest.approx(0.51, abs=0.06)
    valid = d[~holes]
    assert np.allclose(valid / 0.001, np.round(valid / 0.001))  # 1 mm steps
    assert np.std(d[~holes & (depth == 0.9)]) == pytest.approx(3.6e-3 * 0.81, rel=0.15)
    assert np.std(new_rgb.astype(float)) == pytest.approx(5.0, rel=0.1)
    _, as_nan = sensor_faults(rgb, depth, np.random.default_rng(0), noise_coeff=0.0, holes=0.1, invalid=np.nan)
    assert np.isnan(as_nan).mean() == pytest.approx(0.1, abs=0.01)


def test_no_fault_draws_nothing() -> None:
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    rgb, d = sensor_faults(np.zeros((4, 4, 3), np.uint8), np.ones((4, 4)), rng, noise_coeff=0.0)
    assert rng.bit_generator.state == state and (d == 1.0).all()


def test_calibration_error_has_the_given_size() -> None:
    err = calibration_error(2.0, 0.2, np.random.default_rng(1))
    assert np.linalg.norm(err.position) == pytest.approx(2e-3)
    angle = np.degrees(np.arccos((np.trace(err.rotation) - 1) / 2))
    assert angle == pytest.approx(0.2, abs=1e-6)
    assert calibration_error(0.0, 0.0, np.random.default_rng(1)) is None


def test_preset_fills_what_the_file_leaves_out() -> None:
    spec = CameraSpec.model_validate({"sensor": "realsense_d435", "rgb_noise_sigma": 0.0})
    assert spec.depth_noise == "d435" and spec.depth_holes == 0.02 and spec.depth_edge_dropout == 0.2
    assert spec.rgb_noise_sigma == 0.0  # the file's own key wins
    assert spec.extrinsic_error == (1.0, 0.1)


@pytest.mark.sim
def test_perception_through_holes_written_as_zero() -> None:
    """20 % of the object's edge pixels as 0.0 (what drivers write) and 2 % at random: never a point
    at the camera; the estimate stays within a millimetre."""
    from pickdemo.core.streams import spawn_rngs
    from pickdemo.perception import estimate_pose
    from pickdemo.scenario.layout import sample_layout
    from pickdemo.scenario.load import load_scenario
    from pickdemo.scenario.task import target_model
    from pickdemo.sim.render import Camera
    from pickdemo.sim.scene import Scene

    base = load_scenario("pick_cube")
    cam = base.camera.model_copy(update={"depth_holes": 0.02, "depth_edge_dropout": 0.5, "depth_invalid": 0.0})
    sc = base.model_copy(update={"camera": cam})
    errors = []
    for seed in range(4):
        rngs = spawn_rngs(seed)
        layout = sample_layout(sc, rngs["layout"])
        with Scene(sc, layout) as scene:
            scene.settle(480)
            frame = Camera(sc.camera, rngs["camera"]).capture(scene)
            truth = scene.true_pose("cube")
        assert (frame.depth_m == 0.0).mean() > 0.015
        est = estimate_pose(frame, target_model(sc, layout[0]))
        errors.append(np.linalg.norm(est.pose.position - truth.position))
    assert max(errors) < 1e-3, errors


@pytest.mark.sim
@pytest.mark.parametrize("name", ["perceive_boxes_d435", "perceive_boxes_d435_miscal"])
@pytest.mark.slow
def test_covariance_stays_honest_under_a_real_sensors_faults(name: str) -> None:
    """Position NEES in [1.5, 6] (3 is honest) with the D435 preset, with and without miscalibration;
    the outline term was calibrated on seeds 100-199, this checks seeds 0-39."""
    from pickdemo.apps.perceive import perceive_seed
    from pickdemo.scenario.load import load_scenario

    sc = load_scenario(name)
    nees = [s["nees"] for seed in range(40) for s in perceive_seed(sc, seed, ["paper"]) if s["nees"] is not None]
    assert len(nees) >= 38
    assert 1.5 <= float(np.mean(nees)) <= 6.0


@pytest.mark.sim
@pytest.mark.slow
def test_wrong_estimates_under_the_d435_preset_are_not_acted_on() -> None:
    """With the hand over the target part of it is hidden, and some estimates land far off (one fit
    diverged to tens of metres). In pick_cube_d435 they have grown rare (9 over seeds 0-39 with the
    self-filter, 2 since readings are matched along their rays, none over seeds 0-59 since a box has
    no rolling friction, measured), so pick_box_d435 (a 7 x 3.5 x 4 cm box: every seed of 0-59 has
    2-22 of them, 473 in all, measured) exercises the checks: perception's own fit check or the loop's
    checks reject them (the fit check has its own tests in test_pose_fit); at most one is acted on
    (1 of 125 over 100 seeds, measured once; 0 of 477 over 180 episodes since), and the targets are
    placed."""
    from episodes import at_least, episodes

    rs = episodes("pick_cube_d435", tuple(range(40))) + episodes("pick_box_d435", tuple(range(6)))
    at_least(rs, len(rs) - 2)
    assert sum(r.estimates_off for r in rs) >= 1, [r.estimates_off for r in rs]  # the checks were exercised
    assert sum(r.estimates_off_accepted for r in rs) <= 1
