"""Shared fixtures. Simulator tests are marked ``sim``; everything else runs without PyBullet."""

from __future__ import annotations

import pytest

from pickdemo.scenario.load import Scenario, load_scenario


@pytest.fixture(scope="session")
def cube_scenario() -> Scenario:
    return load_scenario("pick_cube")


@pytest.fixture(scope="session")
def cylinder_scenario() -> Scenario:
    return load_scenario("pick_cylinder")
